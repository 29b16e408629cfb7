// Phoneme-level scoring of typed answers: spoken words, word then phone
// alignment by weighted edit distance, phonemes.csv and the alignment audit
// (phoneme_scoring.h has the costs and the tie rule).
#include "avsi/analysis/phoneme_scoring.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

#include "avsi/analysis/phoneme_information.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"

namespace avsi::analysis {
namespace {

// Features that enter the substitution cost: all but Stress.
constexpr std::size_t k_cost_features = static_cast<std::size_t>(Feature::Stress);

constexpr const char* k_units[] = {"zero",     "one",     "two",     "three",     "four",     "five",    "six",
                                   "seven",    "eight",   "nine",    "ten",       "eleven",   "twelve",  "thirteen",
                                   "fourteen", "fifteen", "sixteen", "seventeen", "eighteen", "nineteen"};
constexpr const char* k_tens[] = {"", "", "twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety"};

// 0 <= n < 1000 as words ("three hundred and five" in British usage is
// "three hundred five" here: the words a listener typing digits meant).
void below_thousand_words(long n, std::vector<std::string>& out) {
    if (n >= 100) {
        out.emplace_back(k_units[n / 100]);
        out.emplace_back("hundred");
        n %= 100;
        if (n == 0) return;
    }
    if (n < 20) {
        out.emplace_back(k_units[n]);
        return;
    }
    out.emplace_back(k_tens[n / 10]);
    if (n % 10) out.emplace_back(k_units[n % 10]);
}

std::vector<std::string> number_words(long n) {
    std::vector<std::string> out;
    if (n >= 1000) {
        below_thousand_words(n / 1000, out);
        out.emplace_back("thousand");
        if (n % 1000) below_thousand_words(n % 1000, out);
    } else {
        below_thousand_words(n, out);
    }
    return out;
}

// The last number word as an ordinal ("one" -> "first", "twenty" -> "twentieth").
std::string ordinal_word(const std::string& w) {
    static const std::map<std::string, std::string> irregular = {
        {"one", "first"},    {"two", "second"}, {"three", "third"},   {"five", "fifth"},
        {"eight", "eighth"}, {"nine", "ninth"}, {"twelve", "twelfth"}};
    if (auto it = irregular.find(w); it != irregular.end()) return it->second;
    if (w.back() == 'y') return w.substr(0, w.size() - 1) + "ieth";
    return w + "th";
}

// A token of digits (and an ordinal suffix) read out; nullopt otherwise.
std::optional<std::vector<std::string>> read_out_number(const std::string& token) {
    std::size_t digits = 0;
    while (digits < token.size() && std::isdigit(static_cast<unsigned char>(token[digits]))) ++digits;
    if (digits == 0 || digits > 6) return std::nullopt;
    const std::string suffix = token.substr(digits);
    const bool ordinal = suffix == "st" || suffix == "nd" || suffix == "rd" || suffix == "th";
    if (!suffix.empty() && !ordinal) return std::nullopt;
    auto words = number_words(std::stol(token.substr(0, digits)));
    if (ordinal) words.back() = ordinal_word(words.back());
    return words;
}

struct WordItem {
    const WordTranscription* transcription = nullptr;
    std::vector<std::string> phones;  // base symbols
};

std::vector<WordItem> transcribed(const std::vector<std::string>& words, const Pronunciations& pronunciations) {
    std::vector<WordItem> out;
    for (const auto& w : words) {
        const auto it = pronunciations.find(w);
        if (it == pronunciations.end()) throw std::out_of_range(fmt::format("no transcription of \"{}\"", w));
        WordItem item{&it->second, {}};
        for (const auto& p : it->second.phones) item.phones.push_back(p.symbol);
        out.push_back(std::move(item));
    }
    return out;
}

// Step 2: the word alignment of target and answer.
Alignment align_words(const std::vector<WordItem>& target, const std::vector<WordItem>& response) {
    const auto substitution = [&](std::size_t i, std::size_t j) {
        if (target[i].transcription->word == response[j].transcription->word) return 0.0;
        const std::size_t length = target[i].phones.size() + response[j].phones.size();
        if (length == 0) return 0.0;
        return align_phones(target[i].phones, response[j].phones).cost / double(length);
    };
    return align_weighted(target.size(), response.size(), substitution, 0.5, 0.5);
}

// The tiers of the audit: each aligned pair padded to the wider symbol.
void append_tiers(AnswerAlignment& a, const std::string& t, const std::string& r) {
    const std::size_t width = std::max(t.size(), r.size());
    const auto pad = [width](const std::string& s) { return s + std::string(width - s.size(), ' '); };
    if (!a.target_tier.empty()) {
        a.target_tier += ' ';
        a.response_tier += ' ';
    }
    a.target_tier += pad(t);
    a.response_tier += pad(r);
}

void append_word_boundary(AnswerAlignment& a) {
    if (a.target_tier.empty()) return;
    a.target_tier += " |";
    a.response_tier += " |";
}

void trim_tiers(AnswerAlignment& a) {
    for (auto* s : {&a.target_tier, &a.response_tier})
        while (!s->empty() && s->back() == ' ') s->pop_back();
}

// One answer: the rows of its phones and its audit line.
struct AnswerScorer {
    const Response& response;
    std::vector<WordItem> target, answer;
    std::vector<PhonemeRow>& rows;
    AnswerAlignment audit;
    std::size_t position = 0;  // target phones so far

    PhonemeRow row(std::size_t word, const WordItem* t, const WordItem* r) const {
        PhonemeRow x;
        x.subject = response.subject;
        x.session = response.session;
        x.trial = response.trial;
        x.condition = response.condition;
        x.sentence = response.sentence;
        x.word = word;
        if (t) {
            x.target_word = t->transcription->word;
            x.target_letter_to_sound = !t->transcription->in_lexicon;
        }
        if (r) {
            x.response_word = r->transcription->word;
            x.response_letter_to_sound = !r->transcription->in_lexicon;
        }
        return x;
    }

    void add(std::size_t word, const WordItem* t, const WordItem* r, long ti, long ri) {
        PhonemeRow x = row(word, t, r);
        if (ti >= 0) {
            x.target = t->phones[static_cast<std::size_t>(ti)];
            ++position;
        }
        x.position = position;
        if (ri >= 0) x.response = r->phones[static_cast<std::size_t>(ri)];
        x.outcome = ti < 0                   ? PhoneOutcome::Inserted
                    : ri < 0                 ? PhoneOutcome::Deleted
                    : x.target == x.response ? PhoneOutcome::Correct
                                             : PhoneOutcome::Substituted;
        std::size_t* counts[] = {&audit.correct, &audit.substituted, &audit.deleted, &audit.inserted};
        ++*counts[static_cast<int>(x.outcome)];
        audit.cost += ti < 0 || ri < 0 ? 1.0
                                       : phone_substitution_cost(PhoneInventory::builtin().info(x.target),
                                                                 PhoneInventory::builtin().info(x.response));
        append_tiers(audit, x.target.empty() ? "-" : x.target, x.response.empty() ? "-" : x.response);
        rows.push_back(std::move(x));
    }

    void add_word_pair(std::size_t word, const WordItem* t, const WordItem* r) {
        append_word_boundary(audit);
        // A word typed as the target is spelled conveys the target's phones:
        // a recording's reduced or dialectal phones (with_recorded_phones)
        // are not substitutions when the listener got the word.
        const WordItem same = t && r && t->transcription->word == r->transcription->word
                                  ? WordItem{r->transcription, t->phones}
                                  : WordItem{};
        if (same.transcription) r = &same;
        if (t && r) {
            const Alignment phones = align_phones(t->phones, r->phones);
            for (const auto& p : phones.pairs) add(word, t, r, p.target, p.response);
        } else if (t) {
            for (std::size_t i = 0; i < t->phones.size(); ++i) add(word, t, nullptr, static_cast<long>(i), -1);
        } else {
            for (std::size_t j = 0; j < r->phones.size(); ++j) add(0, nullptr, r, -1, static_cast<long>(j));
        }
    }

    void score() {
        const Alignment words = align_words(target, answer);
        for (const auto& p : words.pairs) {
            const WordItem* t = p.target >= 0 ? &target[static_cast<std::size_t>(p.target)] : nullptr;
            const WordItem* r = p.response >= 0 ? &answer[static_cast<std::size_t>(p.response)] : nullptr;
            add_word_pair(p.target >= 0 ? static_cast<std::size_t>(p.target) + 1 : 0, t, r);
        }
        trim_tiers(audit);
        for (const auto* words : {&target, &answer})
            for (const auto& w : *words)
                if (!w.transcription->in_lexicon &&
                    std::find(audit.letter_to_sound.begin(), audit.letter_to_sound.end(), w.transcription->word) ==
                        audit.letter_to_sound.end())
                    audit.letter_to_sound.push_back(w.transcription->word);
    }
};

std::vector<std::string> whitespace_split(const std::string& text) {
    std::vector<std::string> out;
    std::string current;
    for (char c : text) {
        if (std::isspace(static_cast<unsigned char>(c))) {
            if (!current.empty()) out.push_back(std::move(current));
            current.clear();
        } else {
            current += c;
        }
    }
    if (!current.empty()) out.push_back(std::move(current));
    return out;
}

// confusions.csv, information.csv and information_comparisons.csv of the rows.
void write_information_files(const PhonemeFilesSettings& s, const std::vector<PhonemeRow>& rows) {
    std::vector<ConfusionMatrix> matrices;
    std::vector<std::string> conditions;
    for (const auto& r : rows)
        if (std::find(conditions.begin(), conditions.end(), r.condition) == conditions.end())
            conditions.push_back(r.condition);
    for (const auto& c : conditions)
        for (auto& m : confusion_matrices(c, rows)) matrices.push_back(std::move(m));
    write_confusions_csv(s.out_dir / "confusions.csv", matrices);
    const InformationResult info = information_by_condition(rows, {s.bootstrap, s.seed});
    write_information_csv(s.out_dir / "information.csv", info);
    write_information_comparisons_csv(s.out_dir / "information_comparisons.csv", info);
}

std::string format_cost(double cost) { return fmt::format("{:.3f}", cost); }

}  // namespace

std::vector<std::string> spoken_words(std::string_view text, std::string_view language) {
    if (language != "en")
        if (auto words = words_keeping_letters(text, language)) return std::move(*words);
    const std::string ascii = fold_to_ascii(text);
    std::vector<std::string> out;
    std::size_t i = 0;
    while (i < ascii.size()) {
        const std::size_t end = std::min(ascii.find(' ', i), ascii.size());
        std::string token = ascii.substr(i, end - i);
        i = end + 1;
        while (!token.empty() && token.front() == '\'') token.erase(token.begin());
        while (!token.empty() && token.back() == '\'') token.pop_back();
        if (token.empty()) continue;
        if (auto number = read_out_number(token)) {
            out.insert(out.end(), number->begin(), number->end());
        } else {
            out.push_back(std::move(token));
        }
    }
    return out;
}

double phone_substitution_cost(const PhoneInfo& a, const PhoneInfo& b) {
    if (a.symbol == b.symbol) return 0.0;
    double distance = 0.0;
    for (std::size_t f = 0; f < k_cost_features; ++f)
        distance += std::fabs(double(a.features[f]) - double(b.features[f]));
    return std::min(2.0, 0.5 + 0.25 * distance);
}

Alignment align_weighted(std::size_t n, std::size_t m,
                         const std::function<double(std::size_t, std::size_t)>& substitution, double deletion,
                         double insertion) {
    // cost[i][j]: best cost of target[0, i) against answer[0, j).
    std::vector<double> cost((n + 1) * (m + 1), 0.0), sub(n * m, 0.0);
    const auto at = [m](std::size_t i, std::size_t j) { return i * (m + 1) + j; };
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < m; ++j) sub[i * m + j] = substitution(i, j);
    for (std::size_t i = 1; i <= n; ++i) cost[at(i, 0)] = cost[at(i - 1, 0)] + deletion;
    for (std::size_t j = 1; j <= m; ++j) cost[at(0, j)] = cost[at(0, j - 1)] + insertion;
    for (std::size_t i = 1; i <= n; ++i)
        for (std::size_t j = 1; j <= m; ++j)
            cost[at(i, j)] = std::min({cost[at(i - 1, j - 1)] + sub[(i - 1) * m + j - 1], cost[at(i - 1, j)] + deletion,
                                       cost[at(i, j - 1)] + insertion});
    Alignment out;
    out.cost = cost[at(n, m)];
    std::size_t i = n, j = m;
    while (i > 0 || j > 0) {
        const double here = cost[at(i, j)];
        if (i > 0 && j > 0 && here == cost[at(i - 1, j - 1)] + sub[(i - 1) * m + j - 1]) {
            out.pairs.push_back({static_cast<long>(--i), static_cast<long>(--j)});
        } else if (i > 0 && here == cost[at(i - 1, j)] + deletion) {
            out.pairs.push_back({static_cast<long>(--i), -1});
        } else {
            out.pairs.push_back({-1, static_cast<long>(--j)});
        }
    }
    std::reverse(out.pairs.begin(), out.pairs.end());
    return out;
}

Alignment align_phones(const std::vector<std::string>& target, const std::vector<std::string>& response) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    std::vector<const PhoneInfo*> t, r;
    for (const auto& s : target) t.push_back(&inventory.info(s, "target phone"));
    for (const auto& s : response) r.push_back(&inventory.info(s, "response phone"));
    return align_weighted(
        t.size(), r.size(), [&](std::size_t i, std::size_t j) { return phone_substitution_cost(*t[i], *r[j]); }, 1.0,
        1.0);
}

Pronunciations read_pronunciations(const std::filesystem::path& path, std::string_view language) {
    CsvOptions options;
    options.delimiter = '\t';
    options.has_header = false;
    const CsvTable table = read_csv(path, options);
    const PhoneInventory& inventory = PhoneInventory::builtin();
    Pronunciations out;
    std::vector<Diagnostic> problems;
    const auto problem = [&](int line, const char* field, std::string message) {
        problems.push_back({path.string(), line, 1, field, std::move(message)});
    };
    for (const auto& row : table.rows) {
        if (row.fields.size() != 2) {
            problem(row.line, "word", fmt::format("expected word<TAB>phones, got {} fields", row.fields.size()));
            continue;
        }
        const auto words = spoken_words(row.fields[0], language);
        if (words.size() != 1 || words.front() != row.fields[0]) {
            problem(row.line, "word", fmt::format("expected one lower-case word, got \"{}\"", row.fields[0]));
            continue;
        }
        WordTranscription w{row.fields[0], {}, true};
        try {
            for (const auto& label : whitespace_split(row.fields[1]))
                w.phones.push_back(inventory.parse_label(label, fmt::format("{}:{}", path.string(), row.line)));
        } catch (const InputError& e) {
            problem(row.line, "phones", e.first().message);
            continue;
        }
        if (w.phones.empty())
            problem(row.line, "phones", fmt::format("expected phones for \"{}\", got none", w.word));
        else if (!out.emplace(w.word, w).second)
            problem(row.line, "word", fmt::format("\"{}\" is listed twice", w.word));
    }
    if (!problems.empty()) throw InputError(problems);
    return out;
}

const char* outcome_name(PhoneOutcome outcome) {
    switch (outcome) {
        case PhoneOutcome::Correct:
            return "correct";
        case PhoneOutcome::Substituted:
            return "substituted";
        case PhoneOutcome::Deleted:
            return "deleted";
        case PhoneOutcome::Inserted:
            return "inserted";
    }
    return "?";
}

std::vector<std::string> words_to_transcribe(const Corpus& corpus, const std::vector<Response>& responses,
                                             std::string_view language) {
    std::vector<std::string> out;
    std::set<std::string, std::less<>> seen;
    const auto add = [&](std::string_view text) {
        for (auto& w : spoken_words(text, language))
            if (seen.insert(w).second) out.push_back(std::move(w));
    };
    std::set<std::string, std::less<>> sentences;
    for (const auto& r : responses) {
        if (r.phase != "test") continue;
        if (sentences.insert(r.sentence).second)
            for (const auto& s : corpus.sentences)
                if (s.id == r.sentence) add(s.text);
        add(r.response);
    }
    return out;
}

std::vector<std::vector<std::string>> recorded_phones_by_word(const std::vector<std::vector<std::string>>& words,
                                                              const std::vector<std::string>& recorded) {
    std::vector<std::string> lexical;
    std::vector<std::size_t> word_of;
    for (std::size_t w = 0; w < words.size(); ++w)
        for (const auto& p : words[w]) {
            lexical.push_back(p);
            word_of.push_back(w);
        }
    std::vector<std::vector<std::string>> out(words.size());
    if (words.empty()) return out;
    std::size_t word = 0;
    for (const auto& pair : align_phones(lexical, recorded).pairs) {
        if (pair.target >= 0) word = word_of[static_cast<std::size_t>(pair.target)];
        if (pair.response >= 0) out[word].push_back(recorded[static_cast<std::size_t>(pair.response)]);
    }
    return out;
}

RecordedPhones read_recorded_phones(const Corpus& corpus) {
    RecordedPhones out;
    for (const auto& s : corpus.sentences) {
        if (s.labels.empty()) continue;
        std::vector<std::string>& phones = out[s.id];
        for (const auto& p : read_phones(s.labels))
            if (p.symbol != "sil") phones.push_back(p.symbol);
    }
    return out;
}

namespace {

// A recorded sentence's words with the recording's phones (recorded_phones_by_word).
std::vector<WordItem> with_recorded_phones(std::vector<WordItem> words, const std::vector<std::string>& recorded) {
    std::vector<std::vector<std::string>> lexical;
    for (const auto& w : words) lexical.push_back(w.phones);
    auto split = recorded_phones_by_word(lexical, recorded);
    for (std::size_t w = 0; w < words.size(); ++w) words[w].phones = std::move(split[w]);
    return words;
}

}  // namespace

PhonemeScoringResult score_phonemes(const Corpus& corpus, const std::vector<Response>& responses,
                                    const Pronunciations& pronunciations) {
    return score_phonemes(corpus, responses, pronunciations, {});
}

PhonemeScoringResult score_phonemes(const Corpus& corpus, const std::vector<Response>& responses,
                                    const Pronunciations& pronunciations, const RecordedPhones& recorded,
                                    std::string_view language) {
    std::map<std::string, const Sentence*, std::less<>> by_id;
    for (const auto& s : corpus.sentences) by_id.emplace(s.id, &s);
    PhonemeScoringResult out;
    std::vector<Diagnostic> missing;
    for (const auto& r : responses) {
        if (r.phase != "test") continue;
        const auto it = by_id.find(r.sentence);
        if (it == by_id.end()) {
            missing.push_back({"responses", r.line, 1, "sentence",
                               fmt::format("\"{}\" is not in the corpus {}", r.sentence, corpus.path.string())});
            continue;
        }
        std::vector<WordItem> target = transcribed(spoken_words(it->second->text, language), pronunciations);
        if (const auto rec = recorded.find(r.sentence); rec != recorded.end())
            target = with_recorded_phones(std::move(target), rec->second);
        AnswerScorer a{r,
                       std::move(target),
                       transcribed(spoken_words(r.response, language), pronunciations),
                       out.rows,
                       {},
                       0};
        a.audit = {r.subject, r.session, r.trial, r.condition, r.sentence, r.response, {}, {}, 0, 0, 0, 0, {}, 0.0};
        a.score();
        out.answers.push_back(std::move(a.audit));
    }
    if (!missing.empty()) throw InputError(missing);
    return out;
}

void write_phonemes_csv(const std::filesystem::path& path, const std::vector<PhonemeRow>& rows) {
    std::string out =
        "subject,condition,sentence,position,target,response,outcome,word,target_word,response_word,"
        "target_letter_to_sound,response_letter_to_sound,session,trial\n";
    for (const auto& r : rows)
        out += csv_line({r.subject, r.condition, r.sentence, std::to_string(r.position), r.target, r.response,
                         outcome_name(r.outcome), std::to_string(r.word), r.target_word, r.response_word,
                         r.target_letter_to_sound ? "1" : "0", r.response_letter_to_sound ? "1" : "0", r.session,
                         r.trial});
    write_text_file(path, out);
}

void write_phoneme_alignment_csv(const std::filesystem::path& path, const std::vector<AnswerAlignment>& answers) {
    std::string out =
        "subject,session,trial,condition,sentence,response,target_phones,response_phones,correct,"
        "substituted,deleted,inserted,letter_to_sound,cost\n";
    for (const auto& a : answers) {
        std::string lts;
        for (const auto& w : a.letter_to_sound) lts += (lts.empty() ? "" : " ") + w;
        out += csv_line({a.subject, a.session, a.trial, a.condition, a.sentence, a.response, a.target_tier,
                         a.response_tier, std::to_string(a.correct), std::to_string(a.substituted),
                         std::to_string(a.deleted), std::to_string(a.inserted), lts, format_cost(a.cost)});
    }
    write_text_file(path, out);
}

PhonemeScoringResult score_phoneme_files(const PhonemeFilesSettings& s) {
    const Corpus corpus = read_corpus(s.corpus);
    const auto responses = read_responses(s.responses);
    Pronunciations pronunciations;
    if (!s.pronunciations.empty()) pronunciations = read_pronunciations(s.pronunciations, s.language);
    std::vector<std::string> needed;
    for (auto& w : words_to_transcribe(corpus, responses, s.language))
        if (!pronunciations.count(w)) needed.push_back(std::move(w));
    std::size_t lts = 0;
    if (!needed.empty())
        for (auto& w : transcribe_words(needed, s.tts)) {
            lts += w.in_lexicon ? 0 : 1;
            std::string word = w.word;
            pronunciations.emplace(std::move(word), std::move(w));
        }
    const RecordedPhones recorded = s.recorded_targets ? read_recorded_phones(corpus) : RecordedPhones{};
    PhonemeScoringResult result;
    try {
        result = score_phonemes(corpus, responses, pronunciations, recorded, s.language);
    } catch (const InputError& e) {
        std::vector<Diagnostic> d = e.diagnostics();
        for (auto& x : d)
            if (x.path == "responses") x.path = s.responses.string();
        throw InputError(d);
    }
    std::filesystem::create_directories(s.out_dir);
    write_phonemes_csv(s.out_dir / "phonemes.csv", result.rows);
    write_phoneme_alignment_csv(s.out_dir / "phoneme_alignment.csv", result.answers);
    write_information_files(s, result.rows);
    std::size_t correct = 0, targets = 0;
    for (const auto& r : result.rows) {
        targets += r.outcome == PhoneOutcome::Inserted ? 0 : 1;
        correct += r.outcome == PhoneOutcome::Correct ? 1 : 0;
    }
    log_info(
        "phonemes: {} answers, {} target phones, {} correct ({:.1f} %); {} words transcribed by {} ({} by "
        "letter-to-sound), {} from the pronunciation table; {} sentences' target phones from their recordings' "
        "labels",
        result.answers.size(), targets, correct, targets ? 100.0 * double(correct) / double(targets) : 0.0,
        needed.size(), tts_voice_spec(s.tts), lts, pronunciations.size() - needed.size(), recorded.size());
    return result;
}

}  // namespace avsi::analysis
