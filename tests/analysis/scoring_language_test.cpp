// Keyword scoring in Swedish and German (docs/scoring.md "Languages"): the
// keyword/response tables tests/data/analysis/scoring_rules_{sv,de}.csv with
// the verdict a careful human scorer gives under each rule set (exact, number
// words, homophones, spellings, compounds as the settings say, inflections
// under loose only, a real-word neighbour never credited), the number words
// against hand-computed values, and English left as it was.
#include <array>
#include <set>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "avsi/analysis/language.h"
#include "avsi/analysis/scoring.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/core/ui_strings.h"

namespace avsi::analysis {
namespace {

KeywordScorer make_scorer(const std::string& language, RuleSet set, std::optional<RuleSet> split) {
    ScoringSettings s;
    s.language = language;
    s.rules = set;
    s.split_compounds = split;
    return KeywordScorer(s);
}

// The scorers of the tables: every rule set, split compounds from loose on.
const KeywordScorer& scorer(const std::string& language, RuleSet set) {
    static std::map<std::pair<std::string, int>, KeywordScorer> scorers;
    const auto key = std::make_pair(language, int(set));
    auto it = scorers.find(key);
    if (it == scorers.end()) it = scorers.emplace(key, make_scorer(language, set, RuleSet::Loose)).first;
    return it->second;
}

Sentence sentence_of(const std::string& keyword) {
    Sentence s;
    s.id = "s";
    Keyword k;
    k.word = keyword;
    s.keywords = {k};
    s.text = keyword;
    return s;
}

struct Row {
    std::string keyword, response, note;
    std::array<std::string, 3> expected;
    int line = 0;
};

std::vector<Row> table(const std::string& language) {
    const CsvTable t = read_csv(std::filesystem::path(AVSI_TEST_DATA_DIR) / "analysis" /
                                fmt::format("scoring_rules_{}.csv", language));
    std::vector<Row> rows;
    for (const auto& r : t.rows) {
        Row row;
        row.keyword = r.fields[t.require_column("keyword")];
        row.response = r.fields[t.require_column("response")];
        row.expected = {trim(r.fields[t.require_column("strict")]), trim(r.fields[t.require_column("loose")]),
                        trim(r.fields[t.require_column("lenient")])};
        row.note = r.fields[t.require_column("what it checks")];
        row.line = r.line;
        rows.push_back(std::move(row));
    }
    return rows;
}

void expect_table(const std::string& language) {
    const auto rows = table(language);
    ASSERT_GE(rows.size(), 25u);
    std::set<std::string> rules;
    for (const auto& r : rows) {
        const Sentence s = sentence_of(r.keyword);
        for (RuleSet set : kRuleSets) {
            SCOPED_TRACE(fmt::format("scoring_rules_{}.csv:{}: keyword \"{}\", response \"{}\" ({}), rule set {}",
                                     language, r.line, r.keyword, r.response, r.note, rule_set_name(set)));
            const auto m = scorer(language, set).score(s, r.response);
            ASSERT_EQ(m.size(), 1u);
            const std::string& expected = r.expected[std::size_t(set)];
            rules.insert(expected);
            EXPECT_EQ(rule_name(m[0].rule), expected);
            EXPECT_EQ(m[0].correct, expected != "none");
        }
    }
    for (const char* rule : {"exact", "number", "variant", "homophone", "compound", "inflection", "typo", "none"})
        EXPECT_TRUE(rules.count(rule)) << "no row of scoring_rules_" << language << ".csv expects rule " << rule;
}

TEST(ScoringLanguage, SwedishPairsGetTheExpectedVerdicts) { expect_table("sv"); }

TEST(ScoringLanguage, GermanPairsGetTheExpectedVerdicts) { expect_table("de"); }

TEST(ScoringLanguage, SwedishNumberWordsHaveTheirValues) {
    // Hand-computed values of Swedish cardinals (Svenska Akademiens grammatik).
    const std::vector<std::pair<const char*, const char*>> cases = {
        {"noll", "0"},          {"fem", "5"},          {"tio", "10"},        {"tretton", "13"},
        {"tjugo", "20"},        {"tjugoen", "21"},     {"tjugoett", "21"},   {"trettiosju", "37"},
        {"nittionio", "99"},    {"hundra", "100"},     {"etthundra", "100"}, {"tvåhundrafemtio", "250"},
        {"tusen", "1000"},      {"tvåtusentjugosex", "2026"}, {"nittonhundrasextio", "1960"},
        {"sju åtta", "7 8"},    {"tjugo fem", "25"},   {"en bil", "en bil"}, {"ett hus", "ett hus"},
        {"sextio", "60"},       {"sexton", "16"},      {"åttio", "80"}};
    for (const auto& [text, digits] : cases) EXPECT_EQ(fmt::format("{}", fmt::join(normalize_words(text, "sv"), " ")), digits) << text;
}

TEST(ScoringLanguage, GermanNumberWordsHaveTheirValues) {
    const std::vector<std::pair<const char*, const char*>> cases = {
        {"null", "0"},           {"eins", "1"},            {"zwölf", "12"},        {"siebzehn", "17"},
        {"zwanzig", "20"},       {"einundzwanzig", "21"},  {"neunundneunzig", "99"}, {"hundert", "100"},
        {"einhundertdrei", "103"}, {"zweitausendsechsundzwanzig", "2026"},          {"zwo", "2"},
        {"ein Haus", "ein haus"}, {"zwanzigeins", "zwanzigeins"}, {"sieben acht", "7 8"}};
    for (const auto& [text, digits] : cases) EXPECT_EQ(fmt::format("{}", fmt::join(normalize_words(text, "de"), " ")), digits) << text;
}

TEST(ScoringLanguage, LettersOfTheLanguageAreKept) {
    EXPECT_EQ(normalize_text("Får ÅTTA äpplen!"), "far atta applen");  // English folds
    EXPECT_EQ(fmt::format("{}", fmt::join(normalize_words("Får ÄPPLEN", "sv"), " ")), "får äpplen");
    EXPECT_EQ(fmt::format("{}", fmt::join(normalize_words("Die STRASSE, die Straße", "de"), " ")),
              "die strasse die straße");
    EXPECT_EQ(ascii_spelling("straße", "de"), "strasse");
    EXPECT_EQ(ascii_spelling("schön", "de"), "schoen");
    EXPECT_EQ(ascii_spelling("får", "sv"), "får");
}

TEST(ScoringLanguage, SplitCompoundsAreCreditedAsTheSettingsSay) {
    const Sentence s = sentence_of("bilnyckel");
    const std::string typed = "jag tappade min bil nyckel";
    // never: no rule set credits it
    for (RuleSet set : kRuleSets) EXPECT_FALSE(make_scorer("sv", set, std::nullopt).score(s, typed)[0].correct);
    // strict: every rule set credits it
    for (RuleSet set : kRuleSets) {
        const auto m = make_scorer("sv", set, RuleSet::Strict).score(s, typed)[0];
        EXPECT_EQ(m.rule, MatchRule::Compound);
        EXPECT_EQ(m.matched_word, "bil nyckel");
    }
    // lenient: only the lenient set
    EXPECT_FALSE(make_scorer("sv", RuleSet::Loose, RuleSet::Lenient).score(s, typed)[0].correct);
    EXPECT_TRUE(make_scorer("sv", RuleSet::Lenient, RuleSet::Lenient).score(s, typed)[0].correct);
}

TEST(ScoringLanguage, UnknownLanguageIsAClearError) {
    try {
        (void)scoring_language("fr");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("no tables for language 'fr' (known: en, sv, de)"), std::string::npos)
            << e.what();
    }
    // The voice's language, the one source of the protocol's (read_language).
    const auto voice_language = [](TtsEngine engine, const std::string& voice) {
        TtsSettings t;
        t.engine = engine;
        t.voice = voice;
        return tts_voice_language(t);
    };
    EXPECT_EQ(voice_language(TtsEngine::Espeak, "sv"), "sv");
    EXPECT_EQ(voice_language(TtsEngine::Espeak, "en-us"), "en");
    EXPECT_EQ(voice_language(TtsEngine::Espeak, "sv+m3"), "sv");
    EXPECT_EQ(voice_language(TtsEngine::Espeak, "gmw/de"), "de");
    EXPECT_EQ(voice_language(TtsEngine::Espeak, "fr"), "");
    EXPECT_EQ(voice_language(TtsEngine::Festival, "cmu_us_slt_arctic_hts"), "en");
}

}  // namespace
}  // namespace avsi::analysis
