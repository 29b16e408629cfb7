// Keyword scoring: rules, rule sets, assignment, overrides, the audit, the
// agreement with a second scorer (Cohen 1960) and the CSV files of
// `avsi score`. See scoring.h for the rule order and the assignment.
#include "avsi/analysis/scoring.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <mutex>
#include <set>
#include <tuple>

#include <fmt/format.h>

#include "avsi/analysis/inflection.h"
#include "avsi/analysis/language.h"
#include "avsi/analysis/lexicon.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "avsi/core/ui_strings.h"
#include "hunspell_dictionary.h"

namespace avsi::analysis {

const char* rule_name(MatchRule rule) {
    switch (rule) {
    case MatchRule::Exact: return "exact";
    case MatchRule::Number: return "number";
    case MatchRule::Alternate: return "alternate";
    case MatchRule::Variant: return "variant";
    case MatchRule::Homophone: return "homophone";
    case MatchRule::Compound: return "compound";
    case MatchRule::Inflection: return "inflection";
    case MatchRule::Typo: return "typo";
    case MatchRule::None: return "none";
    }
    return "none";
}

const char* rule_set_name(RuleSet set) {
    switch (set) {
    case RuleSet::Strict: return "strict";
    case RuleSet::Loose: return "loose";
    case RuleSet::Lenient: return "lenient";
    }
    return "strict";
}

std::optional<RuleSet> parse_rule_set(std::string_view name) {
    for (RuleSet set : kRuleSets)
        if (name == rule_set_name(set)) return set;
    return std::nullopt;
}

std::vector<std::string> rule_set_names() {
    std::vector<std::string> out;
    for (RuleSet set : kRuleSets) out.emplace_back(rule_set_name(set));
    return out;
}

bool rule_set_allows(RuleSet set, MatchRule rule) {
    switch (rule) {
    case MatchRule::Inflection: return set != RuleSet::Strict;
    case MatchRule::Typo: return set == RuleSet::Lenient;
    case MatchRule::None: return false;
    default: return true;
    }
}

namespace {

std::string join(const std::vector<std::string>& words) {
    std::string out;
    for (const auto& w : words) out += (out.empty() ? "" : " ") + w;
    return out;
}

bool is_number(const std::string& w) {
    return !w.empty() && std::isdigit(static_cast<unsigned char>(w.front()));
}

std::filesystem::path protocols_file(const std::filesystem::path& given, const char* name) {
    return given.empty() ? std::filesystem::path(AVSI_PROTOCOLS_DIR) / name : given;
}

std::filesystem::path given_or(const std::filesystem::path& given, const std::filesystem::path& fallback) {
    return given.empty() ? fallback : given;
}

// A normalised word with one byte per letter (its Latin-1 bytes: the kept
// letters of every language are below U+0100), so that an edit is one
// letter; "" when a letter is not Latin-1.
std::string one_byte_per_letter(const std::string& utf8) {
    std::string out;
    for (std::size_t i = 0; i < utf8.size(); ++i) {
        const auto b = static_cast<unsigned char>(utf8[i]);
        if (b < 0x80) out += static_cast<char>(b);
        else if ((b == 0xC2 || b == 0xC3) && i + 1 < utf8.size())
            out += static_cast<char>(((b & 0x03) << 6) | (static_cast<unsigned char>(utf8[++i]) & 0x3F));
        else return "";
    }
    return out;
}

}  // namespace

// ---------------------------------------------------------------- word groups

void WordGroups::add_group(const std::vector<std::string>& words) {
    const std::size_t id = m_group_count++;
    m_groups.push_back(words);
    for (const auto& w : words) m_groups_of[w].push_back(id);
}

bool WordGroups::same_group(const std::string& a, const std::string& b) const {
    if (a == b) return false;
    const auto ia = m_groups_of.find(a), ib = m_groups_of.find(b);
    if (ia == m_groups_of.end() || ib == m_groups_of.end()) return false;
    for (std::size_t g : ia->second)
        if (std::find(ib->second.begin(), ib->second.end(), g) != ib->second.end()) return true;
    return false;
}

std::vector<std::string> WordGroups::partners(const std::string& word) const {
    std::vector<std::string> out;
    const auto it = m_groups_of.find(word);
    if (it == m_groups_of.end()) return out;
    for (std::size_t g : it->second)
        for (const auto& w : m_groups[g])
            if (w != word && std::find(out.begin(), out.end(), w) == out.end()) out.push_back(w);
    return out;
}

WordGroups WordGroups::read(const std::filesystem::path& path, std::string_view language) {
    const CsvTable table = read_csv(path);
    const std::size_t c_words = table.require_column("words");
    WordGroups out;
    DiagnosticList problems;
    for (const auto& row : table.rows) {
        std::vector<std::string> group;
        std::string part;
        const std::string field = row.fields[c_words] + "|";
        for (char c : field) {
            if (c != '|') {
                part += c;
                continue;
            }
            const auto words = normalize_words(part, language);
            if (words.size() != 1)
                problems.add(path.string(), row.line, int(c_words) + 1, "words",
                             fmt::format("expected one word per entry, got \"{}\" (normalised to {} words)",
                                         trim(part), words.size()));
            else
                group.push_back(words.front());
            part.clear();
        }
        if (group.size() < 2 && problems.empty())
            problems.add(path.string(), row.line, int(c_words) + 1, "words",
                         fmt::format("expected at least two words separated by '|', got \"{}\"", row.fields[c_words]));
        out.add_group(group);
    }
    problems.throw_if_any();
    return out;
}

// ---------------------------------------------------------------- scorer

ScoringSettings scoring_settings(const Protocol& protocol) {
    ScoringSettings s;
    const auto set = parse_rule_set(protocol.scoring.rules);
    AVSI_ASSERT(set.has_value());  // load_protocol accepts protocol_rule_sets() only
    s.rules = *set;
    s.homophones = protocol.scoring.homophones;
    s.split_compounds = parse_rule_set(protocol.scoring.split_compounds);  // "never": nullopt
    s.language = protocol_language(protocol);
    try {
        scoring_language(s.language);
    } catch (const InputError& e) {
        throw InputError(protocol.path.string(), protocol.corpus.tts_line, protocol.corpus.tts_column, "corpus.tts",
                         e.first().message);
    }
    return s;
}

std::string protocol_language(const Protocol& protocol) { return protocol.corpus.language; }

std::vector<std::string> corpus_vocabulary(const Corpus& corpus, std::string_view language) {
    std::set<std::string> words;
    for (const auto& s : corpus.sentences) {
        for (auto& w : normalize_words(s.text, language)) words.insert(std::move(w));
        for (const auto& k : s.keywords) {
            for (auto& w : normalize_words(k.word, language)) words.insert(std::move(w));
            for (const auto& a : k.alternates)
                for (auto& w : normalize_words(a, language)) words.insert(std::move(w));
        }
    }
    return {words.begin(), words.end()};
}

namespace {

// The tables of a path, read once per process (scorers of every rule set
// share them).
template <typename T, typename Read>
std::shared_ptr<const T> shared_table(const std::vector<std::filesystem::path>& key, Read read) {
    static std::mutex mutex;
    static std::map<std::vector<std::filesystem::path>, std::shared_ptr<const T>> cache;
    std::lock_guard lock(mutex);
    auto& slot = cache[key];
    if (!slot) slot = std::make_shared<const T>(read());
    return slot;
}

}  // namespace

struct KeywordScorer::Impl {
    ScoringSettings settings;
    const ScoringLanguage* language = nullptr;
    std::shared_ptr<const WordGroups> homophones, variants;
    std::shared_ptr<const Inflections> inflections;  // English, loose and lenient
    std::shared_ptr<const Lexicon> lexicon;          // lenient
    std::shared_ptr<const detail::HunspellDictionary> hunspell;  // Swedish, German
    Inflections::OpenWords vocabulary;
    Inflections::OpenWords open_words;  // vocabulary words that may be bases though WordNet lacks them

    bool english() const { return language->code == "en"; }

    bool is_word(const std::string& w) const {
        return vocabulary.count(w) > 0 || (lexicon && lexicon->contains(w)) || (hunspell && hunspell->spell(w));
    }

    // Does the set credit by `rule`? Compound: from settings.split_compounds on.
    bool allows(MatchRule rule) const {
        if (rule == MatchRule::Compound)
            return settings.split_compounds && std::size_t(settings.rules) >= std::size_t(*settings.split_compounds);
        return rule_set_allows(settings.rules, rule);
    }

    // The keyboard spelling of a word without the language's letters (schoen
    // for schön), credited only when it is not itself another word (masse is
    // not maße).
    bool ascii_spelling_of(const std::string& k, const std::string& r) const {
        if (english() || k == r || ascii_spelling(k, language->code) != r) return false;
        return !is_word(r);
    }

    // Swedish, German: a shared hunspell stem (bilarna and bil: bil).
    bool shares_stem(const std::string& k, const std::string& r) const {
        const auto ks = hunspell->stems(k), rs = hunspell->stems(r);
        for (const auto& a : ks)
            if (std::find(rs.begin(), rs.end(), a) != rs.end()) return true;
        return false;
    }

    bool inflection_of(const std::string& k, const std::string& r) const {
        if (is_number(k) || is_number(r)) return false;
        if (!english()) return hunspell && shares_stem(k, r);
        if (!inflections) return false;
        if (inflections->same_lemma(k, r, &open_words)) return true;
        // An inflection of a spelling variant (colours for color).
        for (const auto& v : variants->partners(r))
            if (inflections->same_lemma(k, v, &open_words)) return true;
        return false;
    }

    bool typo_of(const std::string& k, const std::string& r) const {
        if (is_number(k) || is_number(r)) return false;
        if (english()) {
            if (k.size() < settings.typo_min_letters || r.size() < settings.typo_min_letters) return false;
            if (is_word(r)) return false;  // a word of English is never a misspelling
            return edit_distance(k, r) <= 1;
        }
        const std::string k1 = one_byte_per_letter(k), r1 = one_byte_per_letter(r);
        if (k1.empty() || r1.empty()) return false;
        if (k1.size() < settings.typo_min_letters || r1.size() < settings.typo_min_letters) return false;
        if (is_word(r)) return false;  // a word of the language is never a misspelling
        return edit_distance(k1, r1) <= 1;
    }

    // Does response word `r` match keyword word `k` under `rule`?
    bool word_matches(MatchRule rule, const NormalizedWord& k, const NormalizedWord& r) const {
        const bool equal = k.text == r.text;
        switch (rule) {
        case MatchRule::Exact: return equal && k.number_in_words == r.number_in_words;
        case MatchRule::Number: return equal && k.number_in_words != r.number_in_words;
        case MatchRule::Alternate: return equal;
        case MatchRule::Variant:
            return equal || variants->same_group(k.text, r.text) || ascii_spelling_of(k.text, r.text);
        case MatchRule::Homophone: return equal || homophones->same_group(k.text, r.text);
        case MatchRule::Compound: return false;  // several response words: KeywordScorer::score
        case MatchRule::Inflection: return equal || inflection_of(k.text, r.text);
        case MatchRule::Typo: return equal || typo_of(k.text, r.text);
        case MatchRule::None: return false;
        }
        return false;
    }
};

KeywordScorer::KeywordScorer(ScoringSettings settings) : m_impl(std::make_unique<Impl>()) {
    Impl& m = *m_impl;
    m.settings = std::move(settings);
    m.language = &scoring_language(m.settings.language);
    const std::string code = m.language->code;
    const auto homophones = given_or(m.settings.homophones, m.language->homophones);
    m.homophones = shared_table<WordGroups>({homophones, code}, [&] { return WordGroups::read(homophones, code); });
    const auto variants = given_or(m.settings.spelling_variants, m.language->spelling_variants);
    m.variants = shared_table<WordGroups>({variants, code}, [&] { return WordGroups::read(variants, code); });
    for (const auto& w : m.settings.vocabulary) m.vocabulary.insert(w);
    if (!m.english()) {
        // Every rule set: the keyboard spellings (variant) ask whether a word is a word.
        m.hunspell = detail::HunspellDictionary::shared(m.language->hunspell, m.language->hunspell_package);
        if (rule_set_allows(m.settings.rules, MatchRule::Typo))
            m.lexicon = Lexicon::shared(m.settings.lexicon.empty() ? m.language->word_lists : m.settings.lexicon,
                                        code);
        return;
    }
    if (rule_set_allows(m.settings.rules, MatchRule::Inflection)) {
        const auto table = protocols_file(m.settings.inflections, "inflections.csv");
        const auto pos = protocols_file(m.settings.parts_of_speech, "lemma_pos.tsv");
        m.inflections = shared_table<Inflections>({table, pos}, [&] { return Inflections::read(table, pos); });
        // Corpus words WordNet lacks (goldfish, doorstep) may be bases, but
        // not words that are forms of a known lemma themselves (rang, chefs):
        // "ranged" is no form of "rang".
        for (const auto& w : m.vocabulary)
            if (m.inflections->lemmas(w).size() == 1) m.open_words.insert(w);
    }
    if (rule_set_allows(m.settings.rules, MatchRule::Typo)) m.lexicon = Lexicon::shared(m.settings.lexicon);
}

KeywordScorer::~KeywordScorer() = default;
KeywordScorer::KeywordScorer(KeywordScorer&&) noexcept = default;
KeywordScorer& KeywordScorer::operator=(KeywordScorer&&) noexcept = default;

const ScoringSettings& KeywordScorer::settings() const { return m_impl->settings; }
bool KeywordScorer::is_word(const std::string& w) const { return m_impl->lexicon && m_impl->is_word(w); }
std::size_t KeywordScorer::lexicon_size() const { return m_impl->lexicon ? m_impl->lexicon->size() : 0; }
double KeywordScorer::lexicon_load_ms() const { return m_impl->lexicon ? m_impl->lexicon->load_ms() : 0.0; }

std::vector<KeywordMatch> KeywordScorer::score(const Sentence& sentence, std::string_view response) const {
    const std::string& language = m_impl->language->code;
    const std::vector<NormalizedWord> words = normalize_tokens(response, language);
    std::vector<bool> used(words.size(), false);

    // Each keyword's candidate phrases: [0] the keyword, then its alternates.
    std::vector<std::vector<std::vector<NormalizedWord>>> phrases;
    std::vector<KeywordMatch> result;
    for (std::size_t i = 0; i < sentence.keywords.size(); ++i) {
        const Keyword& kw = sentence.keywords[i];
        std::vector<std::vector<NormalizedWord>> p{normalize_tokens(kw.word, language)};
        auto same_text = [](const std::vector<NormalizedWord>& a, const std::vector<NormalizedWord>& b) {
            return std::equal(a.begin(), a.end(), b.begin(), b.end(),
                              [](const NormalizedWord& x, const NormalizedWord& y) { return x.text == y.text; });
        };
        for (const auto& alt : kw.alternates) {
            auto a = normalize_tokens(alt, language);
            if (!a.empty() && std::none_of(p.begin(), p.end(), [&](const auto& q) { return same_text(q, a); }))
                p.push_back(std::move(a));
        }
        phrases.push_back(std::move(p));
        KeywordMatch m;
        m.keyword_index = i + 1;
        m.keyword = kw.word;
        result.push_back(std::move(m));
    }

    // The first unused run of words matching `phrase` under `rule`, or npos.
    auto find_phrase = [&](MatchRule rule, const std::vector<NormalizedWord>& phrase) -> std::size_t {
        if (phrase.empty() || phrase.size() > words.size()) return std::string::npos;
        for (std::size_t start = 0; start + phrase.size() <= words.size(); ++start) {
            bool ok = true;
            for (std::size_t j = 0; j < phrase.size() && ok; ++j)
                ok = !used[start + j] && m_impl->word_matches(rule, phrase[j], words[start + j]);
            if (ok) return start;
        }
        return std::string::npos;
    };

    // The first run of 2-3 unused words whose letters together spell the
    // one-word `phrase` ("bil nyckel" for "bilnyckel"): (start, length) or npos.
    auto find_split = [&](const std::vector<NormalizedWord>& phrase) -> std::pair<std::size_t, std::size_t> {
        if (phrase.size() != 1 || phrase.front().number_in_words || is_number(phrase.front().text))
            return {std::string::npos, 0};
        for (std::size_t start = 0; start < words.size(); ++start) {
            std::string joined;
            for (std::size_t n = 1; n <= 3 && start + n <= words.size(); ++n) {
                const NormalizedWord& w = words[start + n - 1];
                if (used[start + n - 1] || w.number_in_words || is_number(w.text)) break;
                joined += w.text;
                if (n >= 2 && joined == phrase.front().text) return {start, n};
            }
        }
        return {std::string::npos, 0};
    };

    static constexpr std::array<MatchRule, 8> kRules = {MatchRule::Exact,     MatchRule::Number,
                                                        MatchRule::Alternate, MatchRule::Variant,
                                                        MatchRule::Homophone, MatchRule::Compound,
                                                        MatchRule::Inflection, MatchRule::Typo};
    for (MatchRule rule : kRules) {
        if (!m_impl->allows(rule)) continue;
        for (std::size_t i = 0; i < result.size(); ++i) {
            if (result[i].correct) continue;
            // exact, number: the keyword only; alternate: alternates only;
            // later rules: the keyword and its alternates.
            const bool keyword_only = rule == MatchRule::Exact || rule == MatchRule::Number;
            const std::size_t from = rule == MatchRule::Alternate ? 1 : 0;
            const std::size_t to = keyword_only ? 1 : phrases[i].size();
            for (std::size_t p = from; p < to; ++p) {
                std::size_t start = std::string::npos, length = phrases[i][p].size();
                if (rule == MatchRule::Compound) std::tie(start, length) = find_split(phrases[i][p]);
                else start = find_phrase(rule, phrases[i][p]);
                if (start == std::string::npos) continue;
                std::vector<std::string> matched;
                for (std::size_t j = 0; j < length; ++j) {
                    used[start + j] = true;
                    matched.push_back(words[start + j].text);
                }
                result[i].matched_word = join(matched);
                result[i].rule = rule;
                result[i].correct = true;
                break;
            }
        }
    }
    return result;
}

// ---------------------------------------------------------------- files

std::vector<Response> read_responses(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::string p = path.string();
    const char* names[] = {"subject", "session", "trial", "phase", "condition", "list", "sentence", "response"};
    std::array<std::size_t, 8> c{};
    for (std::size_t i = 0; i < 8; ++i) c[i] = table.require_column(names[i]);
    std::vector<Response> out;
    DiagnosticList problems;
    // (subject, trial) → line of its first row: a trial answered twice (in
    // any session) would be scored twice.
    std::map<std::pair<std::string, std::string>, int> seen;
    for (const auto& row : table.rows) {
        Response r;
        r.subject = trim(row.fields[c[0]]);
        r.session = trim(row.fields[c[1]]);
        r.trial = trim(row.fields[c[2]]);
        r.phase = trim(row.fields[c[3]]);
        r.condition = trim(row.fields[c[4]]);
        r.list = trim(row.fields[c[5]]);
        r.sentence = trim(row.fields[c[6]]);
        r.response = row.fields[c[7]];
        r.line = row.line;
        if (r.phase != "warmup" && r.phase != "practice" && r.phase != "test")
            problems.add(p, row.line, int(c[3]) + 1, "phase",
                         fmt::format("expected warmup, practice or test, got \"{}\"", r.phase));
        if (r.subject.empty()) problems.add(p, row.line, int(c[0]) + 1, "subject", "expected a subject id, got \"\"");
        if (r.sentence.empty())
            problems.add(p, row.line, int(c[6]) + 1, "sentence", "expected a sentence id, got \"\"");
        if (r.phase == "test" && r.condition.empty())
            problems.add(p, row.line, int(c[4]) + 1, "condition", "expected a condition for a test trial, got \"\"");
        const auto [first, inserted] = seen.emplace(std::make_pair(r.subject, r.trial), row.line);
        if (!inserted && !r.trial.empty())
            problems.add(p, row.line, int(c[2]) + 1, "trial",
                         fmt::format("expected each trial of a subject once, got subject {} trial {} again (first "
                                     "on line {})",
                                     r.subject, r.trial, first->second));
        out.push_back(std::move(r));
    }
    problems.throw_if_any();
    if (out.empty()) throw InputError(path, "expected at least one response, got none");
    return out;
}

std::vector<Override> read_overrides(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::string p = path.string();
    const std::size_t c_subject = table.require_column("subject");
    const auto c_trial = table.column("trial");
    const auto c_sentence = table.column("sentence");
    const std::size_t c_index = table.require_column("keyword_index");
    const std::size_t c_correct = table.require_column("correct");
    const auto c_reason = table.column("reason");
    if (!c_trial && !c_sentence)
        throw InputError(p, 1, 0, "header", "expected a 'trial' or a 'sentence' column to identify the response");
    std::vector<Override> out;
    DiagnosticList problems;
    for (const auto& row : table.rows) {
        Override o;
        o.line = row.line;
        o.subject = trim(row.fields[c_subject]);
        if (c_trial) o.trial = trim(row.fields[*c_trial]);
        if (c_sentence) o.sentence = trim(row.fields[*c_sentence]);
        if (o.subject.empty())
            problems.add(p, row.line, int(c_subject) + 1, "subject", "expected a subject id, got \"\"");
        if (o.trial.empty() && o.sentence.empty())
            problems.add(p, row.line, 0, "trial", "expected a trial number or a sentence id, got neither");
        const std::string index = trim(row.fields[c_index]);
        const auto v = parse_int(index);
        if (!v || *v < 1)
            problems.add(p, row.line, int(c_index) + 1, "keyword_index",
                         fmt::format("expected a keyword number from 1, got \"{}\"", index));
        else
            o.keyword_index = std::size_t(*v);
        const std::string correct = trim(row.fields[c_correct]);
        if (correct == "1" || correct == "true" || correct == "TRUE") o.correct = true;
        else if (correct == "0" || correct == "false" || correct == "FALSE") o.correct = false;
        else
            problems.add(p, row.line, int(c_correct) + 1, "correct",
                         fmt::format("expected 1/0 or true/false, got \"{}\"", correct));
        if (c_reason) o.reason = trim(row.fields[*c_reason]);
        out.push_back(std::move(o));
    }
    problems.throw_if_any();
    return out;
}

Scores aggregate_scores(const std::vector<KeywordRow>& rows) {
    Scores scores;
    std::map<std::pair<std::string, std::string>, std::size_t> index;
    for (const auto& r : rows) {
        auto [it, inserted] = index.emplace(std::make_pair(r.subject, r.condition), scores.cells.size());
        if (inserted) scores.cells.push_back({r.subject, r.condition, 0, 0, std::nullopt});
        ScoreCell& c = scores.cells[it->second];
        ++c.keywords;
        c.correct += r.match.correct ? 1 : 0;
    }
    for (auto& c : scores.cells) c.percent = 100.0 * double(c.correct) / double(c.keywords);
    return scores;
}

namespace {

// The keyword rows a judgment (override or second scorer's mark) names.
std::vector<std::size_t> rows_of(const std::vector<KeywordRow>& rows, const Override& o) {
    std::vector<std::size_t> hits;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const KeywordRow& row = rows[i];
        if (row.subject == o.subject && row.match.keyword_index == o.keyword_index &&
            (o.trial.empty() ? row.sentence == o.sentence : row.trial == o.trial) &&
            (o.sentence.empty() || row.sentence == o.sentence))
            hits.push_back(i);
    }
    return hits;
}

// The diagnostic for a judgment that names no keyword or several.
std::string judgment_mismatch(const Override& o, std::size_t hits) {
    return hits == 0 ? fmt::format("no scored keyword {} for subject '{}' {} '{}'", o.keyword_index, o.subject,
                                   o.trial.empty() ? "sentence" : "trial", o.trial.empty() ? o.sentence : o.trial)
                     : fmt::format("matches {} keywords (subject '{}' saw sentence '{}' more than once); give the "
                                   "trial",
                                   hits, o.subject, o.sentence);
}

}  // namespace

ScoringResult score_responses(const Corpus& corpus, const std::vector<Response>& responses,
                              const std::vector<Override>& overrides, const ScoringSettings& settings) {
    // One scorer per rule set: the chosen one is reported, all feed the
    // audit and the agreement.
    ScoringSettings with_vocabulary = settings;
    const auto vocabulary = corpus_vocabulary(corpus, settings.language);
    with_vocabulary.vocabulary.insert(with_vocabulary.vocabulary.end(), vocabulary.begin(), vocabulary.end());
    std::vector<KeywordScorer> scorers;
    for (RuleSet set : kRuleSets) {
        ScoringSettings s = with_vocabulary;
        s.rules = set;
        scorers.emplace_back(std::move(s));
    }
    ScoringResult result;
    result.rules = settings.rules;
    const KeywordScorer& lenient = scorers[std::size_t(RuleSet::Lenient)];
    result.lexicon_words = lenient.lexicon_size();
    result.lexicon_load_ms = lenient.lexicon_load_ms();

    std::map<std::string, const Sentence*> by_id;
    for (const auto& s : corpus.sentences) by_id[s.id] = &s;
    DiagnosticList problems;
    for (const auto& r : responses) {
        if (r.phase != "test") continue;
        auto it = by_id.find(r.sentence);
        if (it == by_id.end()) {
            std::vector<std::string> ids;
            for (const auto& s : corpus.sentences) ids.push_back(s.id);
            const std::string hint = closest_match(r.sentence, ids);
            problems.add("responses", r.line, 0, "sentence",
                         fmt::format("sentence '{}' is not in the corpus {}{}", r.sentence, corpus.path.string(),
                                     hint.empty() ? "" : fmt::format(" (did you mean '{}'?)", hint)));
            continue;
        }
        ++result.trials_scored;
        std::array<std::vector<KeywordMatch>, 3> by_set;
        for (RuleSet set : kRuleSets) by_set[std::size_t(set)] = scorers[std::size_t(set)].score(*it->second, r.response);
        for (std::size_t k = 0; k < by_set[0].size(); ++k) {
            KeywordRow row;
            row.subject = r.subject;
            row.session = r.session;
            row.trial = r.trial;
            row.condition = r.condition;
            row.list = r.list;
            row.sentence = r.sentence;
            row.response = r.response;
            for (RuleSet set : kRuleSets) row.by_set[std::size_t(set)] = by_set[std::size_t(set)][k];
            row.match = row.by_set[std::size_t(settings.rules)];
            result.keywords.push_back(std::move(row));
        }
    }
    problems.throw_if_any();

    // Overrides, after the rules. A row that repeats the automatic verdict
    // (an unchanged line of audit.csv) needs no reason and changes nothing.
    for (const auto& o : overrides) {
        const auto hits = rows_of(result.keywords, o);
        if (hits.size() != 1) {
            problems.add("overrides", o.line, 0, "", judgment_mismatch(o, hits.size()));
            continue;
        }
        KeywordRow& row = result.keywords[hits.front()];
        if (o.correct == row.match.correct && o.reason.empty()) continue;
        if (o.reason.empty()) {
            problems.add("overrides", o.line, 0, "reason",
                         fmt::format("expected a reason for changing keyword {} ('{}') of subject '{}' to {} (it "
                                     "goes into the audit trail), got \"\"",
                                     o.keyword_index, row.match.keyword, o.subject, o.correct ? 1 : 0));
            continue;
        }
        result.overrides.push_back({o, row.match.keyword, row.response, row.match.rule, row.match.correct});
        row.match.correct = o.correct;
        row.override_reason = o.reason;
    }
    problems.throw_if_any();
    result.scores = aggregate_scores(result.keywords);
    result.scores.rule_set = rule_set_name(settings.rules);
    return result;
}

std::optional<double> cohens_kappa(std::size_t both, std::size_t a_only, std::size_t b_only, std::size_t neither) {
    // kappa = (po - pe) / (1 - pe), po = agreements / n, pe = (a_yes b_yes +
    // a_no b_no) / n^2; multiplied through by n^2 so that the counts stay
    // integers (exact zero when po = pe).
    const long long n = static_cast<long long>(both + a_only + b_only + neither);
    if (n == 0) return std::nullopt;
    const long long a_yes = static_cast<long long>(both + a_only), b_yes = static_cast<long long>(both + b_only);
    // A side with one verdict throughout makes kappa undefined (NA, as
    // docs/scoring.md says): its marginal has no variance, so agreement
    // beyond chance cannot be told from its verdict alone (the formula gives
    // 0 when the other side varies, 0/0 when neither does).
    if (a_yes == 0 || a_yes == n || b_yes == 0 || b_yes == n) return std::nullopt;
    const long long chance = a_yes * b_yes + (n - a_yes) * (n - b_yes);  // pe * n^2
    const long long observed = static_cast<long long>(both + neither) * n;  // po * n^2
    return double(observed - chance) / double(n * n - chance);
}

AgreementResult compare_with_scorer(const ScoringResult& result, const std::vector<Override>& judgments,
                                    const std::string& path) {
    AgreementResult out;
    out.keywords_scored = result.keywords.size();
    DiagnosticList problems;
    std::vector<std::pair<std::size_t, bool>> marks;  // (row, second scorer's verdict)
    std::set<std::size_t> seen;
    for (const auto& j : judgments) {
        const auto hits = rows_of(result.keywords, j);
        if (hits.size() != 1) {
            problems.add(path, j.line, 0, "", judgment_mismatch(j, hits.size()));
            continue;
        }
        if (!seen.insert(hits.front()).second) {
            problems.add(path, j.line, 0, "keyword_index",
                         fmt::format("keyword {} of subject '{}' {} '{}' is judged twice", j.keyword_index, j.subject,
                                     j.trial.empty() ? "sentence" : "trial", j.trial.empty() ? j.sentence : j.trial));
            continue;
        }
        marks.emplace_back(hits.front(), j.correct);
    }
    problems.throw_if_any();

    auto compare = [&](const std::string& name, auto automatic_of) {
        std::size_t both = 0, a_only = 0, b_only = 0, neither = 0;
        for (const auto& [row, scorer] : marks) {
            const bool automatic = automatic_of(result.keywords[row]);
            (automatic ? (scorer ? both : a_only) : (scorer ? b_only : neither)) += 1;
            if (automatic != scorer) out.disagreements.push_back({name, row, automatic, scorer});
        }
        AgreementRow r;
        r.scoring = name;
        r.keywords = marks.size();
        r.agreements = both + neither;
        r.automatic_correct = both + a_only;
        r.scorer_correct = both + b_only;
        r.percent_agreement = marks.empty() ? 0.0 : 100.0 * double(r.agreements) / double(r.keywords);
        r.kappa = cohens_kappa(both, a_only, b_only, neither);
        out.rows.push_back(r);
    };
    for (RuleSet set : kRuleSets)
        compare(rule_set_name(set), [set](const KeywordRow& row) { return row.by_set[std::size_t(set)].correct; });
    if (!result.overrides.empty())
        compare(fmt::format("{}+overrides", rule_set_name(result.rules)),
                [](const KeywordRow& row) { return row.match.correct; });
    return out;
}

void write_keywords_csv(const std::filesystem::path& path, const std::vector<KeywordRow>& rows, RuleSet rules) {
    std::string out = csv_line({"subject", "condition", "sentence", "keyword_index", "keyword", "matched_word", "rule",
                                "correct", "override_reason", "session", "trial", "list", "response", "rule_set"});
    for (const auto& r : rows)
        out += csv_line({r.subject, r.condition, r.sentence, std::to_string(r.match.keyword_index), r.match.keyword,
                         r.match.matched_word, rule_name(r.match.rule), r.match.correct ? "1" : "0",
                         r.override_reason, r.session, r.trial, r.list, r.response, rule_set_name(rules)});
    write_text_file(path, out);
}

void write_overrides_log(const std::filesystem::path& path, const std::vector<OverrideLogEntry>& log) {
    std::string out = csv_line({"subject", "trial", "sentence", "keyword_index", "keyword", "response", "rule",
                                "automatic_correct", "override_correct", "reason", "overrides_line"});
    for (const auto& e : log)
        out += csv_line({e.item.subject, e.item.trial, e.item.sentence, std::to_string(e.item.keyword_index),
                         e.keyword, e.response, rule_name(e.rule), e.automatic_correct ? "1" : "0",
                         e.item.correct ? "1" : "0", e.item.reason, std::to_string(e.item.line)});
    write_text_file(path, out);
}

void write_audit_csv(const std::filesystem::path& path, const ScoringResult& result) {
    std::string out = csv_line({"subject", "trial", "sentence", "keyword_index", "keyword", "response_word", "rule",
                                "rule_set", "correct", "reason", "condition", "response"});
    auto line = [&](const KeywordRow& r, const KeywordMatch& m, RuleSet set, bool correct) {
        out += csv_line({r.subject, r.trial, r.sentence, std::to_string(m.keyword_index), m.keyword, m.matched_word,
                         rule_name(m.rule), rule_set_name(set), correct ? "1" : "0", "", r.condition, r.response});
    };
    const std::size_t chosen = std::size_t(result.rules);
    // Credits by a rule other than exact, under the chosen set.
    for (const auto& r : result.keywords) {
        const KeywordMatch& m = r.by_set[chosen];
        if (m.correct && m.rule != MatchRule::Exact) line(r, m, result.rules, true);
    }
    // Keywords only a more lenient set credits (the first that does).
    for (const auto& r : result.keywords) {
        if (r.by_set[chosen].correct) continue;
        for (std::size_t s = chosen + 1; s < kRuleSets.size(); ++s)
            if (r.by_set[s].correct) {
                line(r, r.by_set[s], kRuleSets[s], false);
                break;
            }
    }
    write_text_file(path, out);
}

void write_agreement(const std::filesystem::path& dir, const AgreementResult& agreement, const ScoringResult& result) {
    std::string a = csv_line({"scoring", "keywords", "agreements", "percent_agreement", "kappa", "automatic_correct",
                              "scorer_correct"});
    for (const auto& r : agreement.rows)
        a += csv_line({r.scoring, std::to_string(r.keywords), std::to_string(r.agreements),
                       fmt::format("{:.4f}", r.percent_agreement), r.kappa ? fmt::format("{:.6f}", *r.kappa) : "NA",
                       std::to_string(r.automatic_correct), std::to_string(r.scorer_correct)});
    write_text_file(dir / "agreement.csv", a);
    std::string d = csv_line({"scoring", "subject", "trial", "sentence", "keyword_index", "keyword", "response_word",
                              "rule", "automatic", "scorer", "response"});
    for (const auto& x : agreement.disagreements) {
        const KeywordRow& r = result.keywords[x.row];
        const auto set = parse_rule_set(x.scoring);
        const KeywordMatch& m = set ? r.by_set[std::size_t(*set)] : r.match;
        d += csv_line({x.scoring, r.subject, r.trial, r.sentence, std::to_string(m.keyword_index), m.keyword,
                       m.matched_word, rule_name(m.rule), x.automatic ? "1" : "0", x.scorer ? "1" : "0", r.response});
    }
    write_text_file(dir / "disagreements.csv", d);
}

ScoreFilesResult score_files(const ScoreFilesSettings& s) {
    const Corpus corpus = read_corpus(s.corpus);
    const auto responses = read_responses(s.responses);
    std::vector<Override> overrides, judgments;
    if (!s.overrides.empty()) overrides = read_overrides(s.overrides);
    if (!s.agreement.empty()) judgments = read_overrides(s.agreement);
    ScoreFilesResult out;
    try {
        out.scoring = score_responses(corpus, responses, overrides, s.scoring);
    } catch (const InputError& e) {
        // Put the real file names on the diagnostics.
        std::vector<Diagnostic> d = e.diagnostics();
        for (auto& x : d) {
            if (x.path == "responses") x.path = s.responses.string();
            if (x.path == "overrides") x.path = s.overrides.string();
        }
        throw InputError(d);
    }
    const ScoringResult& result = out.scoring;
    if (!s.agreement.empty()) out.agreement = compare_with_scorer(result, judgments, s.agreement.string());

    std::filesystem::create_directories(s.out_dir);
    write_keywords_csv(s.out_dir / "keywords.csv", result.keywords, result.rules);
    write_scores(s.out_dir / "scores.csv", result.scores);
    write_audit_csv(s.out_dir / "audit.csv", result);
    if (!s.overrides.empty()) write_overrides_log(s.out_dir / "overrides_applied.csv", result.overrides);
    if (out.agreement) write_agreement(s.out_dir, *out.agreement, result);

    std::size_t correct = 0, non_exact = 0;
    for (const auto& r : result.keywords) {
        correct += r.match.correct ? 1 : 0;
        non_exact += r.match.correct && r.match.rule != MatchRule::Exact && r.override_reason.empty() ? 1 : 0;
    }
    log_info("scored {} test trials with the {} rule set: {} keywords, {} correct ({:.1f} %), {} by a rule other "
             "than exact (audit.csv), {} overrides",
             result.trials_scored, rule_set_name(result.rules), result.keywords.size(), correct,
             result.keywords.empty() ? 0.0 : 100.0 * double(correct) / double(result.keywords.size()), non_exact,
             result.overrides.size());
    std::vector<std::string> lexicon_files;
    for (const auto& f : s.scoring.lexicon.empty() ? scoring_language(s.scoring.language).word_lists : s.scoring.lexicon)
        lexicon_files.push_back(f.string());
    log_info("lexicon: {} words from {} (read once per process in {:.1f} ms)", result.lexicon_words,
             fmt::join(lexicon_files, ", "), result.lexicon_load_ms);
    if (out.agreement) {
        const AgreementResult& a = *out.agreement;
        log_info("second scorer ({}): {} of {} keywords judged", s.agreement.string(),
                 a.rows.empty() ? 0 : a.rows.front().keywords, a.keywords_scored);
        for (const auto& r : a.rows)
            log_info("  {:<18} agreement {:6.2f} %  Cohen's kappa {}  ({} disagreements)", r.scoring,
                     r.percent_agreement, r.kappa ? fmt::format("{:.3f}", *r.kappa) : "undefined (one verdict throughout)",
                     r.keywords - r.agreements);
    }
    return out;
}

}  // namespace avsi::analysis
