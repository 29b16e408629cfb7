// Keyword proposals for sentence lists (keyword_proposals.h): reading a list
// as people write it, ranking each sentence's content words and choosing its
// keywords, with the report of every choice.
#include "avsi/core/keyword_proposals.h"

#include <algorithm>
#include <optional>
#include <regex>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/sentence_profile.h"
#include "avsi/core/text.h"

namespace avsi {

namespace {

// "noun, verb" for the WordNet letters "nv" (each once, in nvar order).
std::string pos_names(const std::string& letters) {
    std::string out;
    for (const auto& [letter, name] : {std::pair{'n', "noun"}, {'v', "verb"}, {'a', "adjective"}, {'r', "adverb"}})
        if (letters.find(letter) != std::string::npos) out += (out.empty() ? "" : ", ") + std::string(name);
    return out;
}

}  // namespace

std::vector<ListedSentence> read_sentence_lines(const std::filesystem::path& path) {
    // "List 3", "## List 3", "Harvard list 3:", "LIST 03."
    static const std::regex heading(R"(^#*\s*(?:[A-Za-z][A-Za-z ]*\s)?list\s+0*(\d+)\s*[:.]?\s*$)",
                                    std::regex::icase);
    // "1.", "1)", "(1)", "[1]", "1:", "1<TAB>", "-", "*", "•" before the sentence.
    static const std::regex numbering(R"(^(\(\d+\)|\[\d+\]|\d+[.):]|\d+\t|[-*]|\xE2\x80\xA2)\s*)");
    // A Markdown rule or heading underline ("---", "***", "===").
    static const std::regex rule(R"(^[-*_=\s]{3,}$)");
    const std::string file = path.string();
    std::istringstream in(read_text_file(path));
    std::vector<ListedSentence> out;
    std::string line, list;
    int number = 0;
    long long last_item = 0;  // the last item number in the current list (0: none yet)
    int last_item_line = 0;
    while (std::getline(in, line)) {
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        const std::string trimmed = trim(line);
        if (trimmed.empty()) continue;
        std::smatch m;
        if (std::regex_match(trimmed, m, heading)) {
            list = m[1].str();
            last_item = 0;
            continue;
        }
        if (trimmed[0] == '#' || std::regex_match(trimmed, rule)) continue;
        ListedSentence s;
        s.line = number;
        s.list = list;
        std::string text = trimmed;
        if (std::regex_search(text, m, numbering) && m.position(0) == 0) {
            s.numbering = trim(m[1].str());
            text = text.substr(static_cast<std::size_t>(m.length(0)));
            if (trim(text).empty())
                throw InputError(file, number, 1, "sentence",
                                 fmt::format("expected a sentence after the numbering \"{}\", got nothing", s.numbering));
            // Item numbers rise within a list; a repeated or falling number is
            // a pasted or misplaced line (a list may start again at 1).
            const std::string digits = std::regex_replace(s.numbering, std::regex(R"(\D)"), "");
            if (const auto item = digits.empty() ? std::nullopt : parse_int(digits)) {
                if (last_item > 0 && *item <= last_item && *item != 1)
                    throw InputError(file, number, 1, "numbering",
                                     fmt::format("expected an item number above {} (line {}{}), got {}; a new list "
                                                 "starts at 1 or with a heading such as \"List 2\"",
                                                 last_item, last_item_line,
                                                 list.empty() ? std::string() : fmt::format(", list {}", list), *item));
                last_item = *item;
                last_item_line = number;
            }
        }
        s.text = trim(text);
        out.push_back(std::move(s));
    }
    if (out.empty()) throw InputError(path, "expected one sentence a line, got no sentences");
    return out;
}

std::vector<std::string> read_sentence_list(const std::filesystem::path& path) {
    std::vector<std::string> out;
    for (const auto& s : read_sentence_lines(path)) out.push_back(s.text);
    return out;
}

ImportOutcome import_sentences(const std::vector<std::string>& texts, const ImportSettings& s, const WordTable& words) {
    std::vector<ListedSentence> sentences;
    for (std::size_t i = 0; i < texts.size(); ++i) sentences.push_back({texts[i], "", static_cast<int>(i + 1), ""});
    return import_listed_sentences(sentences, s, words);
}

namespace {

// The import's plain-text report: per sentence its keywords, syllables and
// notes, then the totals and what the user has to check.
void write_import_report(ImportOutcome& o, const std::vector<ListedSentence>& listed, const ImportSettings& s,
                         bool count, std::size_t complete, std::size_t out_of_range) {
    std::string& rep = o.report;
    for (const auto& r : o.sentences) {
        std::string kws;
        for (const auto& k : r.sentence.keywords) kws += (kws.empty() ? "" : ";") + k.word;
        rep += fmt::format("{} \"{}\"\n  keywords: {}{}\n", r.sentence.id, r.sentence.text, kws.empty() ? "(none)" : kws,
                           r.complete ? "" : fmt::format("  <- only {} of {}: check by hand", r.sentence.keywords.size(),
                                                         s.keywords));
        if (count)
            rep += fmt::format("  syllables: {}{}\n", r.syllables,
                               r.syllables < s.min_syllables || r.syllables > s.max_syllables
                                   ? fmt::format("  <- outside {}–{}", s.min_syllables, s.max_syllables)
                                   : "");
        for (const auto& n : r.notes) rep += "    " + n + "\n";
    }
    rep += fmt::format("\n{} sentences: {} with {} keywords, {} with fewer", o.sentences.size(), complete, s.keywords,
                       o.sentences.size() - complete);
    std::size_t none = o.sentences.size() - o.corpus.sentences.size();
    if (none) rep += fmt::format(" ({} with none, left out of the corpus)", none);
    if (count) rep += fmt::format(", {} outside {}–{} syllables", out_of_range, s.min_syllables, s.max_syllables);
    rep += ".\n";
    if (s.alternates) {
        std::size_t proposed = 0;
        for (const auto& r : o.sentences) proposed += !r.sentence.review.empty();
        rep += fmt::format("Alternates proposed for {} sentences (inflections and spelling variants) are in the "
                           "`review` column, not in the keywords: check each and move the ones to accept into "
                           "`keywords` as keyword|alternate.\n",
                           proposed);
    } else {
        rep += "No alternates are proposed; add accepted forms by hand as keyword|alternate.\n";
    }
    std::size_t numbered = 0;
    std::set<std::string> lists;
    for (const auto& l : listed) {
        numbered += !l.numbering.empty();
        if (!l.list.empty()) lists.insert(l.list);
    }
    if (numbered) rep += fmt::format("Numbering removed from {} lines.\n", numbered);
    if (!lists.empty())
        rep += fmt::format("List headings set the list column: {} list{}.\n", lists.size(), lists.size() == 1 ? "" : "s");
}

}  // namespace

ImportOutcome import_listed_sentences(const std::vector<ListedSentence>& listed, const ImportSettings& s,
                                      const WordTable& words) {
    std::vector<std::string> texts;
    for (const auto& l : listed) texts.push_back(l.text);
    if (s.keywords < 1) throw InputError("", 0, 0, "keywords", fmt::format("expected ≥ 1 keyword, got {}", s.keywords));
    ImportOutcome o;
    const bool count = s.min_syllables > 0 || s.max_syllables > 0;
    const int digits = std::max(3, static_cast<int>(std::to_string(texts.size()).size()));
    Progress progress("import", texts.size());
    std::size_t complete = 0, out_of_range = 0;
    for (std::size_t t = 0; t < texts.size(); ++t) {
        ImportedSentence r;
        r.sentence.id = fmt::format("{}{:0{}}", s.id_prefix, t + 1, digits);
        r.sentence.text = texts[t];
        r.sentence.line = listed[t].line;
        r.sentence.list = listed[t].list;
        if (!listed[t].numbering.empty())
            r.notes.push_back(fmt::format("line {}: numbering \"{}\" removed", listed[t].line, listed[t].numbering));
        // Rank 0: noun/verb/adjective; 1: adverb only; 2: not in WordNet; function words are skipped.
        struct Candidate {
            std::size_t position;
            std::string word;
            int rank;
            std::optional<double> zipf;  // frequency; nullopt: unknown (ranked as rarest)
            std::string pos;             // "noun, verb" …
        };
        std::vector<Candidate> candidates;
        std::set<std::string> seen;
        const auto ws = text_words(texts[t]);
        for (std::size_t w = 0; w < ws.size(); ++w) {
            const std::string key = ascii_lower(ws[w]);
            if (words.is_function_word(key)) {
                r.notes.push_back(fmt::format("{}: function word", ws[w]));
                continue;
            }
            if (!seen.insert(key).second) {
                r.notes.push_back(fmt::format("{}: repeated, used once", ws[w]));
                continue;
            }
            const auto found = words.lookup(key);
            std::string pos;
            for (const auto& f : found) pos += f.pos;
            const bool nva = pos.find_first_of("nva") != std::string::npos;
            const int rank = found.empty() ? 2 : nva ? 0 : 1;
            candidates.push_back({w, ws[w], rank, words.zipf(key), pos_names(pos)});
        }
        std::vector<Candidate> ranked = candidates;
        std::stable_sort(ranked.begin(), ranked.end(), [](const Candidate& a, const Candidate& b) {
            if (a.rank != b.rank) return a.rank < b.rank;
            const double za = a.zipf.value_or(0.0), zb = b.zipf.value_or(0.0);
            if (za != zb) return za < zb;
            return a.position < b.position;
        });
        const std::size_t n = std::min<std::size_t>(ranked.size(), static_cast<std::size_t>(s.keywords));
        std::vector<Candidate> chosen(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(n));
        std::sort(chosen.begin(), chosen.end(), [](const Candidate& a, const Candidate& b) { return a.position < b.position; });

        for (const auto& c : ranked) {
            const bool taken = std::any_of(chosen.begin(), chosen.end(),
                                           [&](const Candidate& k) { return k.position == c.position; });
            const std::string what = c.rank == 2 ? "not in WordNet, taken as a content word"
                                                 : "content word (WordNet: " + c.pos + ")";
            r.notes.push_back(fmt::format("{}: {}, {}: {}", c.word, what,
                                          c.zipf ? fmt::format("Zipf {:.2f}", *c.zipf)
                                                 : std::string("frequency unknown (ranked as rarest)"),
                                          taken ? "keyword" : "not chosen (better-ranked or rarer words filled the slots)"));
        }
        for (const auto& c : chosen) r.sentence.keywords.push_back({c.word, {}});
        // Proposed alternates: for review, not accepted here.
        if (s.alternates) {
            std::string review;
            for (const auto& c : chosen) {
                const auto proposals = s.alternates(ascii_lower(c.word));
                if (proposals.empty()) continue;
                std::string forms, reasons;
                for (const auto& p : proposals) {
                    forms += "|" + p.word;
                    reasons += fmt::format("{}{} ({})", reasons.empty() ? "" : ", ", p.word, p.reason);
                }
                review += (review.empty() ? "" : ";") + c.word + forms;
                r.notes.push_back(fmt::format("{}: proposed alternates, to review: {}", c.word, reasons));
            }
            r.sentence.review = review;
        }
        r.complete = static_cast<int>(n) == s.keywords;
        complete += r.complete;
        if (count) {
            r.syllables = count_syllables(texts[t], s.voice);
            out_of_range += r.syllables < s.min_syllables || r.syllables > s.max_syllables;
        }
        if (!r.sentence.keywords.empty()) o.corpus.sentences.push_back(r.sentence);
        o.sentences.push_back(std::move(r));
        progress.advance();
    }
    progress.finish();

    write_import_report(o, listed, s, count, complete, out_of_range);
    if (o.corpus.sentences.empty()) throw InputError("", 0, 0, "sentences", "expected sentences with content words, got none");
    return o;
}

}  // namespace avsi
