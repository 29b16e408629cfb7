// Corpus tools (core/word_table.h, sentence_profile.h, list_balance.h,
// keyword_proposals.h) and the shipped English corpus and
// protocol: word lookup, viseme classes, the one-way ANOVA, the seeded list
// balancing, keyword proposals, and the properties the study's material needs
// (protocols/corpus/sentences.csv, protocols/beskow2004-en.toml).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <set>

#include "avsi/core/corpus.h"
#include "avsi/core/keyword_proposals.h"
#include "avsi/core/list_balance.h"
#include "avsi/core/word_table.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;
const fs::path protocols = AVSI_PROTOCOLS_DIR;

TEST(WordTable, FindsLemmasOfRegularAndIrregularForms) {
    const WordTable& t = WordTable::builtin();
    ASSERT_GT(t.size(), 10000u);
    auto lemma = [&](const char* w) {
        const auto f = t.lookup(w);
        return f.empty() ? std::string("(none)") : f.front().lemma;
    };
    EXPECT_EQ(lemma("dogs"), "dog");
    EXPECT_EQ(lemma("Barked"), "bark");
    EXPECT_EQ(lemma("children"), "child");
    EXPECT_EQ(lemma("mice"), "mouse");
    EXPECT_EQ(lemma("ran"), "run");
    EXPECT_EQ(lemma("dog's"), "dog");
    EXPECT_TRUE(t.lookup("qzxv").empty());
    EXPECT_EQ(t.log_frequency("qzxv"), 0.0);
    // A form shares its lemma's frequency.
    EXPECT_DOUBLE_EQ(t.log_frequency("dogs"), t.log_frequency("dog"));
    EXPECT_GT(t.log_frequency("man"), t.log_frequency("ladder"));
}

TEST(WordTable, KnowsFunctionWords) {
    const WordTable& t = WordTable::builtin();
    for (const char* w : {"the", "The", "of", "was", "her", "into", "o'clock"}) EXPECT_TRUE(t.is_function_word(w)) << w;
    for (const char* w : {"dog", "window", "barked", "green"}) EXPECT_FALSE(t.is_function_word(w)) << w;
}

TEST(VisemeClass, FollowsLipShapeFirst) {
    const auto& inv = PhoneInventory::builtin();
    const std::map<std::string, VisemeClass> expected{
        {"P", VisemeClass::Bilabial},    {"M", VisemeClass::Bilabial},     {"F", VisemeClass::Labiodental},
        {"DH", VisemeClass::Dental},     {"W", VisemeClass::Rounded},      {"SH", VisemeClass::Rounded},
        {"UW", VisemeClass::Rounded},    {"AA", VisemeClass::OpenVowel},   {"AE", VisemeClass::OpenVowel},
        {"IY", VisemeClass::SpreadVowel}, {"AH", VisemeClass::SpreadVowel}, {"T", VisemeClass::Lingual},
        {"K", VisemeClass::Lingual}};
    for (const auto& [symbol, c] : expected) EXPECT_EQ(viseme_class(inv.info(symbol)), c) << symbol;
    // Every speech phone gets a class.
    for (const auto& p : inv.phones())
        if (p.symbol != "sil") {
            EXPECT_LT(static_cast<std::size_t>(viseme_class(p)), viseme_class_count) << p.symbol;
        }
}

TEST(OneWayAnova, MatchesAHandComputedExample) {
    // Means 2 and 5: SSB 13.5 (df 1), SSW 4 (df 4), F = 13.5; p = I_{4/17.5}(2, 0.5).
    const OneWayAnova a = one_way_anova({{1, 2, 3}, {4, 5, 6}});
    EXPECT_EQ(a.df_between, 1);
    EXPECT_EQ(a.df_within, 4);
    EXPECT_NEAR(a.f, 13.5, 1e-12);
    EXPECT_NEAR(a.p, 0.0213116, 1e-6);
    const OneWayAnova same = one_way_anova({{1, 2, 3}, {1, 2, 3}});
    EXPECT_NEAR(same.f, 0.0, 1e-12);
    EXPECT_NEAR(same.p, 1.0, 1e-12);
}

std::vector<SentenceProfile> synthetic_profiles(std::size_t n, std::uint64_t seed) {
    Rng rng(seed);
    std::vector<SentenceProfile> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        out[i].id = "s" + std::to_string(i);
        out[i].syllables = 7 + static_cast<int>(rng.uniform_int(3));
        for (int k = 0; k < 3; ++k) out[i].keyword_log_frequency.push_back(rng.uniform(0.0, 3.0));
        for (auto& v : out[i].keyword_visemes) v = static_cast<int>(rng.uniform_int(4));
    }
    return out;
}

TEST(BalanceLists, FillsDisjointListsFromTheCandidatesDeterministically) {
    const auto profiles = synthetic_profiles(30, 11);
    std::vector<std::size_t> candidates;
    for (std::size_t i = 2; i < 30; ++i) candidates.push_back(i);  // 0 and 1 are not candidates
    BalanceSettings s;
    s.lists = 4;
    s.sentences_per_list = 5;
    s.restarts = 3;
    s.iterations = 3000;
    s.seed = 5;
    const ListAssignment a = balance_lists(profiles, candidates, s);
    ASSERT_EQ(a.lists.size(), 4u);
    std::set<std::size_t> used;
    for (const auto& l : a.lists) {
        EXPECT_EQ(l.size(), 5u);
        for (const auto i : l) {
            EXPECT_GE(i, 2u);
            EXPECT_TRUE(used.insert(i).second) << "sentence " << i << " in two lists";
        }
    }
    for (const auto i : a.unused) EXPECT_TRUE(used.insert(i).second);
    EXPECT_EQ(used.size(), candidates.size());
    EXPECT_NEAR(a.cost, balance_cost(profiles, a.lists, candidates, s), 1e-9);

    const ListAssignment again = balance_lists(profiles, candidates, s);
    EXPECT_EQ(again.lists, a.lists);
    EXPECT_EQ(again.cost, a.cost);

    // Better balanced than the first lists × size candidates taken in order.
    std::vector<std::vector<std::size_t>> in_order(4);
    for (std::size_t k = 0; k < 20; ++k) in_order[k / 5].push_back(candidates[k]);
    EXPECT_LT(a.cost, 0.5 * balance_cost(profiles, in_order, candidates, s));
}

TEST(BalanceLists, RefusesTooFewCandidates) {
    const auto profiles = synthetic_profiles(10, 3);
    std::vector<std::size_t> candidates{0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    BalanceSettings s;
    s.lists = 6;
    s.sentences_per_list = 2;
    try {
        balance_lists(profiles, candidates, s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("expected at least 12 candidate test sentences"), std::string::npos)
            << e.what();
    }
}

TEST(ImportSentences, ProposesRareContentWordsAndReportsShortfalls) {
    ImportSettings s;
    s.min_syllables = 0;  // no syllable counting: no TTS in this test
    s.max_syllables = 0;
    const ImportOutcome o = import_sentences(
        {"The dog barked at the mailman.", "The tall man climbed the ladder.", "It is in the box.", "Of the and."},
        s);
    ASSERT_EQ(o.sentences.size(), 4u);
    auto keywords = [&](std::size_t i) {
        std::string out;
        for (const auto& k : o.sentences[i].sentence.keywords) out += (out.empty() ? "" : ";") + k.word;
        return out;
    };
    EXPECT_EQ(keywords(0), "dog;barked;mailman");
    EXPECT_TRUE(o.sentences[0].complete);
    // Four content words: the most frequent ("man") is left out; sentence order kept.
    EXPECT_EQ(keywords(1), "tall;climbed;ladder");
    EXPECT_EQ(keywords(2), "box");
    EXPECT_FALSE(o.sentences[2].complete);
    EXPECT_TRUE(o.sentences[3].sentence.keywords.empty());
    // The sentence without keywords is left out of the corpus.
    ASSERT_EQ(o.corpus.sentences.size(), 3u);
    EXPECT_EQ(o.corpus.sentences[0].id, "s001");
    EXPECT_NE(o.report.find("only 1 of 3"), std::string::npos) << o.report;
    EXPECT_NE(o.report.find("man: content word (WordNet: noun, verb), Zipf 5.74: not chosen"), std::string::npos) << o.report;
    EXPECT_NE(o.report.find("4 sentences: 2 with 3 keywords, 2 with fewer (1 with none"), std::string::npos)
        << o.report;
}

TEST(ImportSentences, RanksOrdinaryWordsByARealFrequency) {
    // Words SemCor never tagged are WordNet words with a frequency: rare
    // nouns outrank weak common words (issue 20: hemp, tropics over found, parts).
    ImportSettings s;
    s.min_syllables = 0;
    s.max_syllables = 0;
    const WordTable& words = WordTable::builtin();
    for (const char* w : {"birch", "canoe", "peach", "tusk", "hemp", "tropics"}) {
        EXPECT_FALSE(words.lookup(w).empty()) << w << " is a WordNet word";
        ASSERT_TRUE(words.zipf(w).has_value()) << w;
        EXPECT_LT(*words.zipf(w), *words.zipf("found")) << w;
    }
    EXPECT_GT(*words.zipf("the"), 7.0);
    EXPECT_FALSE(words.zipf("qzxv").has_value());
    const ImportOutcome o =
        import_sentences({"Hemp is a weed found in parts of the tropics.", "The birch canoe slid on the smooth planks."}, s);
    auto keywords = [&](std::size_t i) {
        std::string out;
        for (const auto& k : o.sentences[i].sentence.keywords) out += (out.empty() ? "" : ";") + k.word;
        return out;
    };
    EXPECT_EQ(keywords(0), "Hemp;weed;tropics");
    EXPECT_EQ(keywords(1), "birch;canoe;planks");
    EXPECT_EQ(o.report.find("not in WordNet"), std::string::npos) << o.report;
}

TEST(ImportSentences, NumberedAndHeadedListsAsPeopleWriteThem) {
    const fs::path dir = test::temp_dir("import_lists");
    write_text_file(dir / "harvard.md",
                    "# Harvard sentences, as typed by a lab\n"
                    "## List 1\n"
                    "1. The birch canoe slid on the smooth planks.\n"
                    "2) Glue the sheet to the dark blue background.\n"
                    "\n"
                    "List 2:\n"
                    "(11) Hemp is a weed found in parts of the tropics.\n"
                    "  - A rod is used to catch pink salmon.\n"
                    "12 men sailed to the island.\n");
    const auto lines = read_sentence_lines(dir / "harvard.md");
    ASSERT_EQ(lines.size(), 5u);
    EXPECT_EQ(lines[0].text, "The birch canoe slid on the smooth planks.");
    EXPECT_EQ(lines[0].numbering, "1.");
    EXPECT_EQ(lines[0].list, "1");
    EXPECT_EQ(lines[0].line, 3);
    EXPECT_EQ(lines[1].text, "Glue the sheet to the dark blue background.");
    EXPECT_EQ(lines[2].list, "2");
    EXPECT_EQ(lines[2].numbering, "(11)");
    EXPECT_EQ(lines[3].text, "A rod is used to catch pink salmon.");
    EXPECT_EQ(lines[4].text, "12 men sailed to the island.");  // a number that belongs to the sentence
    EXPECT_EQ(lines[4].numbering, "");
    ImportSettings s;  // syllables counted: the numbering no longer counts as one
    const ImportOutcome o = import_listed_sentences(lines, s);
    EXPECT_EQ(o.sentences[0].syllables, count_syllables("The birch canoe slid on the smooth planks."));
    EXPECT_EQ(o.corpus.sentences[0].list, "1");
    EXPECT_EQ(o.corpus.sentences[2].list, "2");
    EXPECT_NE(o.report.find("numbering \"1.\" removed"), std::string::npos) << o.report;
    EXPECT_NE(o.report.find("List headings set the list column: 2 lists."), std::string::npos) << o.report;
    // A file with headings only is an error naming it.
    write_text_file(dir / "empty.md", "## List 1\n# nothing\n");
    EXPECT_THROW((void)read_sentence_lines(dir / "empty.md"), InputError);
    // A list may start again at 1 without a heading; a Markdown rule is not a sentence.
    write_text_file(dir / "restart.md", "1. The birch canoe slid on the smooth planks.\n2. Glue the sheet.\n---\n"
                                        "1. Hemp is a weed.\n");
    EXPECT_EQ(read_sentence_lines(dir / "restart.md").size(), 3u);
    // Damaged copies: a line pasted twice (item 2 again, line 5), and a number whose sentence was lost (line 6).
    auto error_of = [&](const std::string& name, const std::string& text) {
        write_text_file(dir / name, text);
        try {
            (void)read_sentence_lines(dir / name);
        } catch (const InputError& e) {
            return e.first();
        }
        ADD_FAILURE() << name << " was read";
        return Diagnostic{};
    };
    const std::string harvard = read_text_file(dir / "harvard.md");
    const Diagnostic repeated = error_of("repeated.md", "## List 1\n1. The birch canoe slid on the smooth planks.\n"
                                                        "2. Glue the sheet to the dark blue background.\n"
                                                        "3. It is easy to tell the depth of a well.\n"
                                                        "2. Glue the sheet to the dark blue background.\n");
    EXPECT_EQ(repeated.line, 5);
    EXPECT_EQ(repeated.field, "numbering");
    EXPECT_NE(repeated.format().find("repeated.md:5:1: error: numbering: expected an item number above 3 (line 4, "
                                     "list 1), got 2"),
              std::string::npos)
        << repeated.format();
    std::string lost = harvard;
    lost.replace(lost.find("12 men sailed"), std::string("12 men sailed to the island.").size(), "(12)");
    const Diagnostic empty_item = error_of("lost.md", lost);
    EXPECT_EQ(empty_item.line, 9);
    EXPECT_NE(empty_item.format().find("lost.md:9:1: error: sentence: expected a sentence after the numbering "
                                       "\"(12)\", got nothing"),
              std::string::npos)
        << empty_item.format();
    fs::remove_all(dir);
}

TEST(ImportSentences, CountsSyllablesAndFlagsTheOutOfRange) {
    ImportSettings s;
    const ImportOutcome o = import_sentences({"The boy fell from the window.", "Come here."}, s);
    EXPECT_EQ(o.sentences[0].syllables, 7);
    EXPECT_EQ(o.sentences[1].syllables, 2);
    EXPECT_NE(o.report.find("syllables: 2  <- outside 7–9"), std::string::npos) << o.report;
}

// ------------------------------------------------------------ the shipped corpus

TEST(ShippedCorpus, HasTheStudysListsAndThreeContentKeywordsPerSentence) {
    const Corpus c = read_corpus(protocols / "corpus" / "sentences.csv");
    EXPECT_GE(c.sentences.size(), 120u);
    std::map<std::string, int> count;
    const WordTable& words = WordTable::builtin();
    std::set<std::string> texts;
    std::map<std::string, int> keyword_uses;
    for (const auto& s : c.sentences) {
        ++count[s.list];
        EXPECT_TRUE(texts.insert(s.text).second) << "repeated sentence " << s.id;
        ASSERT_EQ(s.keywords.size(), 3u) << s.id;
        for (const auto& k : s.keywords) {
            std::string key = k.word;
            std::transform(key.begin(), key.end(), key.begin(), [](unsigned char ch) { return std::tolower(ch); });
            EXPECT_LE(++keyword_uses[key], 2) << "keyword '" << k.word << "' in more than two sentences";
            EXPECT_FALSE(words.is_function_word(k.word)) << s.id << ": " << k.word;
            for (const auto& alt : k.alternates) EXPECT_NE(alt, k.word) << s.id;
        }
    }
    for (int l = 1; l <= 6; ++l) EXPECT_EQ(count[std::to_string(l)], 15) << "list " << l;
    EXPECT_EQ(count["warmup"], 15);
    EXPECT_EQ(count["practice"], 6);
}

TEST(ShippedCorpus, EverySentenceHasSevenToNineSyllables) {
    const Corpus c = read_corpus(protocols / "corpus" / "sentences.csv");
    for (const auto& s : c.sentences) {
        const int n = count_syllables(s.text);
        EXPECT_GE(n, 7) << s.id << " " << s.text;
        EXPECT_LE(n, 9) << s.id << " " << s.text;
    }
}

TEST(ShippedProtocol, LoadsWithTheStudysSixConditionsAndDesign) {
    const Protocol p = load_protocol(protocols / "beskow2004-en.toml");
    EXPECT_EQ(p.condition_names(),
              (std::vector<std::string>{"audio-only", "cohen-massaro", "ohman", "ann1", "ann2", "rule"}));
    EXPECT_EQ(p.conditions[0].face, FaceMode::Still);
    for (std::size_t i = 1; i < p.conditions.size(); ++i) {
        EXPECT_EQ(p.conditions[i].face, FaceMode::Model);
        EXPECT_TRUE(fs::is_regular_file(p.conditions[i].model)) << p.conditions[i].model;
    }
    for (const auto& c : p.conditions) EXPECT_EQ(c.audio, ConditionAudio::Vocoded);
    EXPECT_EQ(p.design.lists, 6);
    EXPECT_EQ(p.design.sentences_per_list, 15);
    EXPECT_EQ(p.design.warmup, 15);
    EXPECT_EQ(p.design.warmup_condition, "audio-only");
    EXPECT_GT(p.design.practice, 0);
    EXPECT_EQ(p.render.fps, 30);
    DiagnosticList problems;
    EXPECT_EQ(p.vocoder.get_int("bands", 0, 1, 64, problems), 3);
    EXPECT_EQ(p.vocoder.get_number("low_hz", 0, 0, 1e5, problems), 100.0);
    EXPECT_EQ(p.vocoder.get_number("high_hz", 0, 0, 1e5, problems), 5000.0);
    EXPECT_TRUE(problems.empty());
    EXPECT_EQ(p.corpus.sentences, protocols / "corpus" / "sentences.csv");
}

}  // namespace
}  // namespace avsi
