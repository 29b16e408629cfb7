// The Swedish and German corpora (protocols/languages/<lang>/sentences/) and
// their protocols: the counts their READMEs state, 5-9 words per sentence,
// three keywords each found in the sentence, and every sentence scored
// against itself in its language credits all three keywords exactly (so each
// keyword is spelled as in the text after the language's normalisation),
// while English normalisation would not (å ä ö folded).
#include <filesystem>
#include <map>

#include <gtest/gtest.h>

#include "avsi/analysis/scoring.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/corpus.h"
#include "avsi/core/protocol.h"

namespace avsi::analysis {
namespace {

const std::filesystem::path kProtocols = AVSI_PROTOCOLS_DIR;

std::map<std::string, int> list_counts(const Corpus& c) {
    std::map<std::string, int> counts;
    for (const auto& s : c.sentences) ++counts[s.list];
    return counts;
}

void expect_sentences_well_formed(const Corpus& c, const std::string& language) {
    ScoringSettings settings;
    settings.language = language;
    const KeywordScorer scorer(settings);
    for (const auto& s : c.sentences) {
        SCOPED_TRACE(s.id + ": " + s.text);
        const auto words = normalize_words(s.text, language);
        EXPECT_GE(words.size(), 5u);
        EXPECT_LE(words.size(), 9u);
        ASSERT_EQ(s.keywords.size(), 3u);
        for (const auto& m : scorer.score(s, s.text)) EXPECT_EQ(m.rule, MatchRule::Exact) << m.keyword;
    }
}

TEST(LanguageCorpus, SwedishCorpusHasTheListsItsReadmeStates) {
    const Corpus c = read_corpus(kProtocols / "languages/sv/sentences/sentences.csv");
    ASSERT_EQ(c.sentences.size(), 130u);
    const auto counts = list_counts(c);
    for (const char* list : {"1", "2", "3", "4", "5", "6"}) EXPECT_EQ(counts.at(list), 15) << list;
    EXPECT_EQ(counts.at("warmup"), 15);
    EXPECT_EQ(counts.at("practice"), 6);
    EXPECT_EQ(counts.at(""), 19);
    expect_sentences_well_formed(c, "sv");
}

TEST(LanguageCorpus, GermanCorpusHasTheListsItsReadmeStates) {
    const Corpus c = read_corpus(kProtocols / "languages/de/sentences/sentences.csv");
    ASSERT_GE(c.sentences.size(), 25u);
    const auto counts = list_counts(c);
    for (const char* list : {"1", "2", "3"}) EXPECT_EQ(counts.at(list), 8) << list;
    EXPECT_EQ(counts.at("warmup"), 4);
    EXPECT_EQ(counts.at("practice"), 2);
    expect_sentences_well_formed(c, "de");
}

TEST(LanguageCorpus, ProtocolsScoreInTheLanguageOfTheirVoice) {
    const Protocol sv = load_protocol(kProtocols / "beskow2004-sv.toml");
    EXPECT_EQ(scoring_settings(sv).language, "sv");
    EXPECT_EQ(scoring_settings(sv).split_compounds, RuleSet::Strict);
    const Protocol de = load_protocol(kProtocols / "german-small.toml");
    EXPECT_EQ(scoring_settings(de).language, "de");
    const Protocol en = load_protocol(kProtocols / "beskow2004-en.toml");
    EXPECT_EQ(scoring_settings(en).language, "en");
    EXPECT_EQ(scoring_settings(en).split_compounds, std::nullopt);
}

// Each language's protocol shows that language's own models
// (protocols/models/<lang>/), not the English ones whose per-phone tables
// lack its phones; German has no ANNs, so its protocol has no ANN condition.
void expect_models_of_language(const Protocol& p, const std::string& language, std::size_t model_conditions) {
    std::size_t models = 0;
    for (const auto& c : p.conditions) {
        if (c.face != FaceMode::Model) continue;
        ++models;
        SCOPED_TRACE(c.name);
        EXPECT_TRUE(std::filesystem::equivalent(c.model.parent_path(), kProtocols / "models" / language))
            << c.model;
        EXPECT_TRUE(std::filesystem::is_regular_file(c.model)) << c.model;
    }
    EXPECT_EQ(models, model_conditions);
}

TEST(LanguageCorpus, ProtocolsShowTheModelsOfTheirLanguage) {
    const Protocol sv = load_protocol(kProtocols / "beskow2004-sv.toml");
    const Protocol en = load_protocol(kProtocols / "beskow2004-en.toml");
    EXPECT_EQ(sv.condition_names(), en.condition_names());  // the reference study's six
    expect_models_of_language(sv, "sv", 5);
    expect_models_of_language(load_protocol(kProtocols / "german-small.toml"), "de", 2);
}

}  // namespace
}  // namespace avsi::analysis
