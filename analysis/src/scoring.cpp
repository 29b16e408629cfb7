// Keyword scoring: rules, assignment, overrides and the CSV files of
// `avsi score`. See scoring.h for the rule order and the assignment.
#include "avsi/analysis/scoring.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <map>
#include <set>

#include <fmt/format.h>
#include <libstemmer.h>

#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"

namespace avsi::analysis {

const char* rule_name(MatchRule rule) {
    switch (rule) {
    case MatchRule::Exact: return "exact";
    case MatchRule::Alternate: return "alternate";
    case MatchRule::Homophone: return "homophone";
    case MatchRule::Stem: return "stem";
    case MatchRule::Typo: return "typo";
    case MatchRule::None: return "none";
    }
    return "none";
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

}  // namespace

// ---------------------------------------------------------------- homophones

void HomophoneTable::add_group(const std::vector<std::string>& words) {
    const std::size_t id = m_group_count++;
    for (const auto& w : words) m_groups_of[w].push_back(id);
}

bool HomophoneTable::are_homophones(const std::string& a, const std::string& b) const {
    const auto ia = m_groups_of.find(a), ib = m_groups_of.find(b);
    if (ia == m_groups_of.end() || ib == m_groups_of.end()) return false;
    for (std::size_t g : ia->second)
        if (std::find(ib->second.begin(), ib->second.end(), g) != ib->second.end()) return true;
    return false;
}

HomophoneTable HomophoneTable::read(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::size_t c_words = table.require_column("words");
    HomophoneTable out;
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
            const auto words = normalize_words(part);
            if (words.size() != 1)
                problems.add(path.string(), row.line, 0, "words",
                             fmt::format("expected one word per entry, got \"{}\" (normalised to {} words)",
                                         trim(part), words.size()));
            else
                group.push_back(words.front());
            part.clear();
        }
        if (group.size() < 2 && problems.empty())
            problems.add(path.string(), row.line, 0, "words",
                         fmt::format("expected at least two words separated by '|', got \"{}\"", row.fields[c_words]));
        out.add_group(group);
    }
    problems.throw_if_any();
    return out;
}

// ---------------------------------------------------------------- scorer

struct KeywordScorer::Impl {
    ScoringSettings settings;
    HomophoneTable homophones;
    sb_stemmer* stemmer = nullptr;
    std::map<std::string, std::string> stem_cache;

    ~Impl() {
        if (stemmer) sb_stemmer_delete(stemmer);
    }

    std::string stem(const std::string& word) {
        if (auto it = stem_cache.find(word); it != stem_cache.end()) return it->second;
        const sb_symbol* s = sb_stemmer_stem(stemmer, reinterpret_cast<const sb_symbol*>(word.data()),
                                             static_cast<int>(word.size()));
        std::string out = s ? std::string(reinterpret_cast<const char*>(s),
                                          static_cast<std::size_t>(sb_stemmer_length(stemmer)))
                            : word;
        stem_cache.emplace(word, out);
        return out;
    }

    bool typo_close(const std::string& a, const std::string& b) const {
        if (is_number(a) || is_number(b)) return false;
        if (a.size() < settings.typo_min_letters || b.size() < settings.typo_min_letters) return false;
        return edit_distance(a, b) <= 1;
    }

    // Does response word `r` match keyword word `k` under `rule`?
    bool word_matches(MatchRule rule, const std::string& k, const std::string& r) {
        switch (rule) {
        case MatchRule::Exact:
        case MatchRule::Alternate: return k == r;
        case MatchRule::Homophone: return k == r || homophones.are_homophones(k, r);
        case MatchRule::Stem: return k == r || stem(k) == stem(r);
        case MatchRule::Typo: return k == r || typo_close(k, r);
        case MatchRule::None: return false;
        }
        return false;
    }
};

KeywordScorer::KeywordScorer(ScoringSettings settings, HomophoneTable homophones)
    : m_impl(std::make_unique<Impl>()) {
    m_impl->settings = std::move(settings);
    m_impl->homophones = std::move(homophones);
    m_impl->stemmer = sb_stemmer_new("english", nullptr);
    AVSI_ASSERT(m_impl->stemmer != nullptr);
}

namespace {
HomophoneTable load_homophones(const ScoringSettings& s) {
    return HomophoneTable::read(s.homophones.empty()
                                    ? std::filesystem::path(AVSI_PROTOCOLS_DIR) / "homophones.csv"
                                    : s.homophones);
}
}  // namespace

KeywordScorer::KeywordScorer(ScoringSettings settings)
    : KeywordScorer(settings, load_homophones(settings)) {}
KeywordScorer::~KeywordScorer() = default;
KeywordScorer::KeywordScorer(KeywordScorer&&) noexcept = default;
KeywordScorer& KeywordScorer::operator=(KeywordScorer&&) noexcept = default;

std::string KeywordScorer::stem(const std::string& word) { return m_impl->stem(word); }

std::vector<KeywordMatch> KeywordScorer::score(const Sentence& sentence, std::string_view response) {
    const std::vector<std::string> words = normalize_words(response);
    std::vector<bool> used(words.size(), false);

    // Each keyword's candidate phrases: [0] the keyword, then its alternates.
    std::vector<std::vector<std::vector<std::string>>> phrases;
    std::vector<KeywordMatch> result;
    for (std::size_t i = 0; i < sentence.keywords.size(); ++i) {
        const Keyword& kw = sentence.keywords[i];
        std::vector<std::vector<std::string>> p{normalize_words(kw.word)};
        for (const auto& alt : kw.alternates) {
            auto a = normalize_words(alt);
            if (!a.empty() && std::find(p.begin(), p.end(), a) == p.end()) p.push_back(std::move(a));
        }
        phrases.push_back(std::move(p));
        KeywordMatch m;
        m.keyword_index = i + 1;
        m.keyword = kw.word;
        result.push_back(std::move(m));
    }

    // The first unused run of words matching `phrase` under `rule`, or npos.
    auto find_phrase = [&](MatchRule rule, const std::vector<std::string>& phrase) -> std::size_t {
        if (phrase.empty() || phrase.size() > words.size()) return std::string::npos;
        for (std::size_t start = 0; start + phrase.size() <= words.size(); ++start) {
            bool ok = true;
            for (std::size_t j = 0; j < phrase.size() && ok; ++j)
                ok = !used[start + j] && m_impl->word_matches(rule, phrase[j], words[start + j]);
            if (ok) return start;
        }
        return std::string::npos;
    };

    static constexpr std::array<MatchRule, 5> kRules = {MatchRule::Exact, MatchRule::Alternate,
                                                        MatchRule::Homophone, MatchRule::Stem, MatchRule::Typo};
    for (MatchRule rule : kRules) {
        if (rule == MatchRule::Typo && m_impl->settings.strict) continue;
        for (std::size_t i = 0; i < result.size(); ++i) {
            if (result[i].correct) continue;
            // exact: the keyword only; alternate: alternates only; later
            // rules: the keyword and its alternates.
            const std::size_t from = rule == MatchRule::Alternate ? 1 : 0;
            const std::size_t to = rule == MatchRule::Exact ? 1 : phrases[i].size();
            for (std::size_t p = from; p < to; ++p) {
                const std::size_t start = find_phrase(rule, phrases[i][p]);
                if (start == std::string::npos) continue;
                std::vector<std::string> matched(words.begin() + long(start),
                                                 words.begin() + long(start + phrases[i][p].size()));
                for (std::size_t j = 0; j < matched.size(); ++j) used[start + j] = true;
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
        out.push_back(std::move(r));
    }
    problems.throw_if_any();
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
    const std::size_t c_reason = table.require_column("reason");
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
        o.reason = trim(row.fields[c_reason]);
        if (o.reason.empty())
            problems.add(p, row.line, int(c_reason) + 1, "reason",
                         "expected a reason for the override (it goes into the audit trail), got \"\"");
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

ScoringResult score_responses(const Corpus& corpus, const std::vector<Response>& responses,
                              const std::vector<Override>& overrides, const ScoringSettings& settings) {
    KeywordScorer scorer(settings);
    ScoringResult result;
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
        for (auto& m : scorer.score(*it->second, r.response)) {
            KeywordRow row;
            row.subject = r.subject;
            row.session = r.session;
            row.trial = r.trial;
            row.condition = r.condition;
            row.list = r.list;
            row.sentence = r.sentence;
            row.response = r.response;
            row.match = std::move(m);
            result.keywords.push_back(std::move(row));
        }
    }
    problems.throw_if_any();

    // Overrides, after the rules.
    for (const auto& o : overrides) {
        std::vector<KeywordRow*> hits;
        for (auto& row : result.keywords)
            if (row.subject == o.subject && row.match.keyword_index == o.keyword_index &&
                (o.trial.empty() ? row.sentence == o.sentence : row.trial == o.trial) &&
                (o.sentence.empty() || row.sentence == o.sentence))
                hits.push_back(&row);
        if (hits.size() != 1) {
            problems.add("overrides", o.line, 0, "",
                         hits.empty() ? fmt::format("no scored keyword {} for subject '{}' {} '{}'", o.keyword_index,
                                                    o.subject, o.trial.empty() ? "sentence" : "trial",
                                                    o.trial.empty() ? o.sentence : o.trial)
                                      : fmt::format("matches {} keywords (subject '{}' saw sentence '{}' more than "
                                                    "once); give the trial",
                                                    hits.size(), o.subject, o.sentence));
            continue;
        }
        KeywordRow& row = *hits.front();
        result.overrides.push_back({o, row.match.keyword, row.response, row.match.rule, row.match.correct});
        row.match.correct = o.correct;
        row.override_reason = o.reason;
    }
    problems.throw_if_any();
    result.scores = aggregate_scores(result.keywords);
    return result;
}

void write_keywords_csv(const std::filesystem::path& path, const std::vector<KeywordRow>& rows) {
    std::string out = csv_line({"subject", "condition", "sentence", "keyword_index", "keyword", "matched_word", "rule",
                                "correct", "override_reason", "session", "trial", "list", "response"});
    for (const auto& r : rows)
        out += csv_line({r.subject, r.condition, r.sentence, std::to_string(r.match.keyword_index), r.match.keyword,
                         r.match.matched_word, rule_name(r.match.rule), r.match.correct ? "1" : "0",
                         r.override_reason, r.session, r.trial, r.list, r.response});
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

ScoringResult score_files(const ScoreFilesSettings& s) {
    const Corpus corpus = read_corpus(s.corpus);
    const auto responses = read_responses(s.responses);
    std::vector<Override> overrides;
    if (!s.overrides.empty()) overrides = read_overrides(s.overrides);
    ScoringResult result;
    try {
        result = score_responses(corpus, responses, overrides, s.scoring);
    } catch (const InputError& e) {
        // Put the real file names on the diagnostics.
        std::vector<Diagnostic> d = e.diagnostics();
        for (auto& x : d) {
            if (x.path == "responses") x.path = s.responses.string();
            if (x.path == "overrides") x.path = s.overrides.string();
        }
        throw InputError(d);
    }
    write_keywords_csv(s.out_dir / "keywords.csv", result.keywords);
    write_scores(s.out_dir / "scores.csv", result.scores);
    if (!s.overrides.empty()) write_overrides_log(s.out_dir / "overrides_applied.csv", result.overrides);
    std::size_t correct = 0;
    for (const auto& r : result.keywords) correct += r.match.correct ? 1 : 0;
    log_info("scored {} test trials, {} keywords, {} correct ({:.1f} %), {} overrides{}", result.trials_scored,
             result.keywords.size(), correct,
             result.keywords.empty() ? 0.0 : 100.0 * double(correct) / double(result.keywords.size()),
             result.overrides.size(), s.scoring.strict ? " (strict)" : "");
    return result;
}

}  // namespace avsi::analysis
