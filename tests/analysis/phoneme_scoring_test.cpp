// Phoneme scoring (phoneme_scoring.h): the substitution costs and the
// alignment of the hand-built case in tests/data/analysis/phonemes, whose
// outcomes were worked out by hand (expected_phonemes.csv); the numpy
// reference tests/analysis/phoneme_reference.py checks the same file.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "avsi/analysis/phoneme_scoring.h"
#include "avsi/analysis/scoring.h"
#include "avsi/core/corpus.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using namespace avsi::analysis;

const fs::path kCase = fs::path(AVSI_TEST_DATA_DIR) / "analysis" / "phonemes";

double cost(const char* a, const char* b) {
    const auto& inventory = avsi::PhoneInventory::builtin();
    return phone_substitution_cost(inventory.info(a), inventory.info(b));
}

TEST(PhoneCost, FeatureDistanceByHand) {
    EXPECT_EQ(cost("P", "P"), 0.0);
    EXPECT_EQ(cost("P", "B"), 0.75);   // voiced
    EXPECT_EQ(cost("T", "D"), 0.75);   // voiced
    EXPECT_EQ(cost("S", "P"), 1.5);    // alveolar, bilabial, fricative, stop
    EXPECT_EQ(cost("AO", "AA"), 1.0);  // open 0.5, rounded 1, protruded 0.5
    EXPECT_EQ(cost("G", "T"), 1.25);   // velar, alveolar, voiced
    EXPECT_EQ(cost("DH", "AH"), 1.5);  // vowel, dental, fricative, open 0.5, front 0.5
    EXPECT_EQ(cost("P", "AA"), 1.75);  // vowel, bilabial, stop, voiced, open
    EXPECT_EQ(cost("P", "UW"), 2.0);   // vowel, bilabial, stop, voiced, rounded, protruded
    EXPECT_EQ(cost("CH", "AE"), 2.0);  // 9.5 apart: capped at deletion + insertion
    EXPECT_EQ(cost("B", "P"), cost("P", "B"));
}

TEST(PhoneAlignment, InsertionInsideAWord) {
    // P AE T against S P AE T: insert S (1) beats substituting S for P (1.5) and inserting P.
    const Alignment a = align_phones({"P", "AE", "T"}, {"S", "P", "AE", "T"});
    EXPECT_EQ(a.cost, 1.0);
    ASSERT_EQ(a.pairs.size(), 4u);
    EXPECT_EQ(a.pairs[0].target, -1);
    EXPECT_EQ(a.pairs[0].response, 0);
    for (long i = 0; i < 3; ++i) {
        EXPECT_EQ(a.pairs[static_cast<std::size_t>(i) + 1].target, i);
        EXPECT_EQ(a.pairs[static_cast<std::size_t>(i) + 1].response, i + 1);
    }
}

TEST(PhoneAlignment, TieTakesTheSubstitutionFirst) {
    // Two items against one, every step costing 1: the backtrace keeps the
    // last pair as a substitution and deletes the first item.
    const Alignment a = align_weighted(
        2, 1, [](std::size_t, std::size_t) { return 1.0; }, 1.0, 1.0);
    EXPECT_EQ(a.cost, 2.0);
    ASSERT_EQ(a.pairs.size(), 2u);
    EXPECT_EQ(a.pairs[0].target, 0);
    EXPECT_EQ(a.pairs[0].response, -1);
    EXPECT_EQ(a.pairs[1].target, 1);
    EXPECT_EQ(a.pairs[1].response, 0);
}

TEST(SpokenWords, DigitsReadOutAndApostrophesKept) {
    EXPECT_EQ(spoken_words("Don't take 7 of the 21st, 'dear'!"),
              (std::vector<std::string>{"don't", "take", "seven", "of", "the", "twenty", "first", "dear"}));
    EXPECT_EQ(spoken_words("1,305 boats"),
              (std::vector<std::string>{"one", "thousand", "three", "hundred", "five", "boats"}));
    EXPECT_EQ(spoken_words("the 12th"), (std::vector<std::string>{"the", "twelfth"}));
}

// Swedish and German keep their letters (läste is not laste) and leave
// digits to the language's front end.
TEST(SpokenWords, SwedishAndGermanKeepTheirLettersAndDigits) {
    EXPECT_EQ(spoken_words("Flickan läste 5 böcker i Åre.", "sv"),
              (std::vector<std::string>{"flickan", "läste", "5", "böcker", "i", "åre"}));
    EXPECT_EQ(spoken_words("Die Straße, geht's? Über 21 Brötchen!", "de"),
              (std::vector<std::string>{"die", "straße", "gehts", "über", "21", "brötchen"}));
    EXPECT_EQ(spoken_words("läste", "en"), (std::vector<std::string>{"laste"}));
}

PhonemeScoringResult score_case() {
    const auto corpus = avsi::read_corpus(kCase / "corpus.csv");
    const auto responses = read_responses(kCase / "responses.csv");
    return score_phonemes(corpus, responses, read_pronunciations(kCase / "pronunciations.tsv"));
}

TEST(PhonemeScoring, HandBuiltCaseMatchesTheHandAlignment) {
    // Word costs that decide the case: "bat sad the" for "pat sat" pairs
    // pat-bat (0.75/6) and sat-sad (0.75/6) and inserts "the" (0.5); "pat"
    // for "pat sat" deletes "sat" (0.5) rather than pairing it (0.25 + 0.5);
    // "a big dot" pairs the-a (1/3, DH deleted) and dog-dot (2.25/6: AO->AA
    // 1.0, G->T 1.25).
    const PhonemeScoringResult result = score_case();
    const avsi::CsvTable expected = avsi::read_csv(kCase / "expected_phonemes.csv");
    ASSERT_EQ(result.rows.size(), expected.rows.size());
    for (std::size_t i = 0; i < result.rows.size(); ++i) {
        const PhonemeRow& r = result.rows[i];
        const std::vector<std::string> got = {r.subject,
                                              r.condition,
                                              r.sentence,
                                              std::to_string(r.position),
                                              r.target,
                                              r.response,
                                              outcome_name(r.outcome)};
        EXPECT_EQ(got, expected.rows[i].fields) << "row " << i + 1 << " (file line " << expected.rows[i].line << ")";
    }
    ASSERT_EQ(result.answers.size(), 6u);  // the practice answer is not scored
    const AnswerAlignment& bat = result.answers[3];
    EXPECT_EQ(bat.target_tier, "P AE T | S AE T | -  -");
    EXPECT_EQ(bat.response_tier, "B AE T | S AE D | DH AH");
    EXPECT_EQ(bat.substituted, 2u);
    EXPECT_EQ(bat.inserted, 2u);
    EXPECT_EQ(bat.cost, 3.5);  // 0.75 + 0.75 + 1 + 1
    const AnswerAlignment& dot = result.answers[4];
    EXPECT_EQ(dot.correct, 5u);
    EXPECT_EQ(dot.substituted, 2u);
    EXPECT_EQ(dot.deleted, 1u);
    EXPECT_EQ(dot.cost, 3.25);  // 1 + 1.0 + 1.25
}

TEST(PhonemeScoring, LetterToSoundWordsAreMarked) {
    const auto corpus = avsi::read_corpus(kCase / "corpus.csv");
    auto responses = read_responses(kCase / "responses.csv");
    Pronunciations p = read_pronunciations(kCase / "pronunciations.tsv");
    p.at("spat").in_lexicon = false;
    const PhonemeScoringResult result = score_phonemes(corpus, responses, p);
    std::size_t marked = 0;
    for (const auto& r : result.rows) marked += r.response_letter_to_sound ? 1 : 0;
    EXPECT_EQ(marked, 4u);  // S P AE T of "spat"
    EXPECT_EQ(result.answers[2].letter_to_sound, std::vector<std::string>{"spat"});
}

TEST(PhonemeScoring, WordsToTranscribeOnlyFromTestAnswers) {
    const auto corpus = avsi::read_corpus(kCase / "corpus.csv");
    const auto words = words_to_transcribe(corpus, read_responses(kCase / "responses.csv"));
    EXPECT_EQ(words,
              (std::vector<std::string>{"the", "big", "dog", "pig", "pat", "sat", "spat", "bat", "sad", "a", "dot"}));
}

TEST(PhonemeScoring, BadPronunciationTableNamesLineAndField) {
    const fs::path dir = avsi::test::temp_dir("phoneme_pronunciations");
    avsi::write_text_file(dir / "p.tsv", "big\tB IH1 G\nbig\tB IH1 K\ndog\tD QQ G\nTwo Words\tT UW1\n");
    try {
        read_pronunciations(dir / "p.tsv");
        FAIL() << "no error";
    } catch (const avsi::InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 3u);
        EXPECT_EQ(e.diagnostics()[0].line, 2);
        EXPECT_EQ(e.diagnostics()[0].field, "word");
        EXPECT_EQ(e.diagnostics()[1].line, 3);
        EXPECT_EQ(e.diagnostics()[1].field, "phones");
        EXPECT_NE(e.diagnostics()[1].message.find("QQ"), std::string::npos);
        EXPECT_EQ(e.diagnostics()[2].line, 4);
    }
    fs::remove_all(dir);
}

// Recorded speech: the target phones come from the recording's labels, split
// into the sentence's words by aligning them to the lexicon's phones.
TEST(RecordedPhones, LabelPhonesAreSplitIntoTheSentencesWords) {
    const std::vector<std::vector<std::string>> words = {{"DH", "AH"}, {"B", "IH", "G"}, {"D", "AO", "G"}};
    // Reduced and dialectal vowels: each phone to the word of its lexical partner.
    EXPECT_EQ(recorded_phones_by_word(words, {"DH", "IH", "B", "IH", "G", "D", "AA", "G"}),
              (std::vector<std::vector<std::string>>{{"DH", "IH"}, {"B", "IH", "G"}, {"D", "AA", "G"}}));
    // An elided word gets no phones.
    EXPECT_EQ(recorded_phones_by_word(words, {"B", "IH", "G", "D", "AO", "G"}),
              (std::vector<std::vector<std::string>>{{}, {"B", "IH", "G"}, {"D", "AO", "G"}}));
    // An epenthetic phone belongs to the word of the phone before it.
    EXPECT_EQ(recorded_phones_by_word(words, {"DH", "AH", "B", "IH", "G", "AH", "D", "AO", "G"}),
              (std::vector<std::vector<std::string>>{{"DH", "AH"}, {"B", "IH", "G", "AH"}, {"D", "AO", "G"}}));
    // Before the first lexical phone: the first word.
    EXPECT_EQ(recorded_phones_by_word({{"AH"}, {"D", "AO", "G"}}, {"HH", "AH", "D", "AO", "G"}),
              (std::vector<std::vector<std::string>>{{"HH", "AH"}, {"D", "AO", "G"}}));
}

// "The big dog." recorded, as TIMIT labels it (16 kHz samples): a reduced
// vowel in "the" (ix -> IH) and /ɑ/ in "dog" (aa), closures merged with
// releases; two answers. Returns the folder.
// A corpus of one recorded sentence s1 (`text`, `keywords`; its labels in
// the file `labels` holding `label_text`) and subject a's two answers to it.
fs::path write_recorded_sentence(const std::string& name, const std::string& text, const std::string& keywords,
                                 const std::string& labels, const std::string& label_text,
                                 const std::string& first_answer, const std::string& second_answer) {
    const fs::path dir = avsi::test::temp_dir(name);
    avsi::write_text_file(dir / labels, label_text);
    avsi::write_text_file(dir / "s1.wav", "");
    avsi::write_text_file(dir / "corpus.csv",
                          fmt::format("id,text,keywords,audio,labels\ns1,{},{},s1.wav,{}\n", text, keywords, labels));
    avsi::write_text_file(dir / "responses.csv",
                          fmt::format("subject,session,trial,phase,condition,list,sentence,response\n"
                                      "a,1,1,test,audio,1,s1,{}\na,1,2,test,audio,1,s1,{}\n",
                                      first_answer, second_answer));
    return dir;
}

fs::path write_recorded_case(const std::string& name) {
    return write_recorded_sentence(
        name, "The big dog.", "big;dog", "s1.phn",
        "0 2000 h#\n2000 2800 dh\n2800 3600 ix\n3600 4200 bcl\n4200 4800 b\n4800 6000 ih\n"
        "6000 6600 gcl\n6600 7200 g\n7200 7800 dcl\n7800 8400 d\n8400 10400 aa\n10400 11000 gcl\n"
        "11000 11600 g\n11600 13000 h#\n",
        "the big dog", "a big dot");
}

TEST(RecordedPhones, TargetsFromTimitLabelsAndWordsTypedRightStayCorrect) {
    const fs::path dir = write_recorded_case("phoneme_recorded");
    const auto corpus = avsi::read_corpus(dir / "corpus.csv");
    const RecordedPhones recorded = read_recorded_phones(corpus);
    ASSERT_EQ(recorded.size(), 1u);
    EXPECT_EQ(recorded.at("s1"), (std::vector<std::string>{"DH", "IH", "B", "IH", "G", "D", "AA", "G"}));
    const PhonemeScoringResult result = score_phonemes(corpus, read_responses(dir / "responses.csv"),
                                                       read_pronunciations(kCase / "pronunciations.tsv"), recorded);
    ASSERT_EQ(result.answers.size(), 2u);
    // Every word typed right: the talker's phones, all correct.
    EXPECT_EQ(result.answers[0].target_tier, "DH IH | B IH G | D AA G");
    EXPECT_EQ(result.answers[0].correct, 8u);
    EXPECT_EQ(result.answers[0].substituted, 0u);
    // "a" for "the": the recorded DH deleted, IH heard as AH; "dot" for "dog":
    // AA matches the talker's vowel, G -> T.
    EXPECT_EQ(result.answers[1].target_tier, "DH IH | B IH G | D AA G");
    EXPECT_EQ(result.answers[1].response_tier, "-  AH | B IH G | D AA T");
    EXPECT_EQ(result.answers[1].deleted, 1u);
    EXPECT_EQ(result.answers[1].substituted, 2u);
    EXPECT_EQ(result.answers[1].correct, 5u);
    fs::remove_all(dir);
}

// score_phoneme_files takes the labels only when asked (`avsi score
// --protocol` of a synthesised protocol does not: its stimuli ignore them).
TEST(RecordedPhones, FilesUseTheLabelsOnlyForRecordings) {
    const fs::path dir = write_recorded_case("phoneme_recorded_files");
    PhonemeFilesSettings s;
    s.corpus = dir / "corpus.csv";
    s.responses = dir / "responses.csv";
    s.pronunciations = kCase / "pronunciations.tsv";
    s.bootstrap = 0;
    s.out_dir = dir / "recorded";
    EXPECT_EQ(score_phoneme_files(s).answers[0].target_tier, "DH IH | B IH G | D AA G");
    s.recorded_targets = false;
    s.out_dir = dir / "synthesised";
    EXPECT_EQ(score_phoneme_files(s).answers[0].target_tier, "DH AH | B IH G | D AO G");
    fs::remove_all(dir);
}

// `avsi score --phonemes` in Swedish of dir's corpus.csv and responses.csv, into dir/out.
avsi::test::CliResult score_swedish_phonemes(const fs::path& dir) {
    return avsi::test::run_avsi(fmt::format(
        "score --corpus {0}/corpus.csv --responses {0}/responses.csv --language sv --phonemes --out {0}/out",
        dir.string()));
}

// Swedish answers transcribed by espeak-ng's Swedish voice: its phones,
// features and visemes, the words its rules spelled out marked.
TEST(PhonemeScoringCli, SwedishAnswersAreScoredWithTheSwedishVoice) {
    if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
    const fs::path dir = avsi::test::temp_dir("phoneme_sv");
    avsi::write_text_file(dir / "corpus.csv",
                          "id,text,keywords\ns1,Pojken sprang snabbt till bussen.,pojken;sprang;bussen\n"
                          "s2,Han läste en bok om barn.,läste;bok;barn\n");
    avsi::write_text_file(dir / "responses.csv",
                          "subject,session,trial,phase,condition,list,sentence,response\n"
                          "a,1,1,test,audio,1,s1,pojken sprang till bussen\n"
                          "a,1,2,test,face,1,s2,han läste en bock om barn\n"
                          "b,1,1,test,face,1,s1,pojken sprang snabbt till bussen\n"
                          "b,1,2,test,audio,1,s2,han läste en bok om barn\n");
    const auto r = score_swedish_phonemes(dir);
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("transcribed by espeak:sv"), std::string::npos) << r.output();
    const avsi::CsvTable alignment = avsi::read_csv(dir / "out" / "phoneme_alignment.csv");
    ASSERT_EQ(alignment.rows.size(), 4u);
    // "snabbt" left out: its five phones deleted.
    EXPECT_EQ(alignment.rows[0].fields[alignment.require_column("deleted")], "5");
    // "bock" for "bok": long /uː/ heard as short /ɔ/; barn's r + n is one
    // retroflex nasal.
    EXPECT_EQ(alignment.rows[1].fields[alignment.require_column("target_phones")],
              "HH A N | L EH S T AH | EH N | B UW K | AO M | B AA RN");
    EXPECT_EQ(alignment.rows[1].fields[alignment.require_column("response_phones")],
              "HH A N | L EH S T AH | EH N | B AO K | AO M | B AA RN");
    const avsi::CsvTable phonemes = avsi::read_csv(dir / "out" / "phonemes.csv");
    std::size_t substituted = 0;
    for (const auto& row : phonemes.rows) {
        const auto field = [&](const char* name) { return row.fields[phonemes.require_column(name)]; };
        if (field("outcome") != "substituted") continue;
        ++substituted;
        EXPECT_EQ(field("target") + ">" + field("response"), "UW>AO");
    }
    EXPECT_EQ(substituted, 1u);
    // espeak-ng's dictionary gives the phones of "han" and "en"; "om" has
    // only flags there and "pojken" (an inflected form) none, so the rules
    // spell them out.
    std::map<std::string, std::string> letter_to_sound;
    for (const auto& row : phonemes.rows)
        letter_to_sound[row.fields[phonemes.require_column("target_word")]] =
            row.fields[phonemes.require_column("target_letter_to_sound")];
    EXPECT_EQ(letter_to_sound["han"], "0");
    EXPECT_EQ(letter_to_sound["en"], "0");
    EXPECT_EQ(letter_to_sound["om"], "1");
    EXPECT_EQ(letter_to_sound["pojken"], "1");
    EXPECT_EQ(letter_to_sound["läste"], "1");  // the word as written: läste, not laste
    // The consonant matrix's rows are Swedish's: the retroflexes are there.
    const std::string confusions = avsi::read_text_file(dir / "out" / "confusions.csv");
    EXPECT_NE(confusions.find("face,consonants,RN,RN,1,100.00"), std::string::npos);
    EXPECT_NE(confusions.find("audio,consonants,SJ,"), std::string::npos);
    EXPECT_EQ(avsi::read_csv(dir / "out" / "information.csv").rows.size(), 10u);  // 2 conditions x 5 groupings
    // A front end of another language than the scoring's is refused.
    const auto mismatch = avsi::test::run_avsi(fmt::format(
        "score --corpus {0}/corpus.csv --responses {0}/responses.csv --language sv --phonemes --tts espeak:de "
        "--out {0}/bad",
        dir.string()));
    EXPECT_EQ(mismatch.exit_code, 2) << mismatch.output();
    EXPECT_NE(mismatch.output().find("--tts espeak:de speaks \"de\", but the answers are scored as \"sv\""),
              std::string::npos)
        << mismatch.output();
    fs::remove_all(dir);
}

// A Swedish recording: the target phones are its labels' (the talker's
// full [ɛ] at the end of "läste", where espeak-ng's citation form has a
// schwa), the answers transcribed by the Swedish voice.
TEST(PhonemeScoringCli, SwedishRecordingIsScoredAgainstItsLabels) {
    if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
    std::string labels = "0.00\t0.20\tsil\n";
    double t = 0.2;
    for (const char* phone : {"HH", "A", "N", "L", "EH1", "S", "T", "EH0", "EH0", "N", "B", "UW1", "K"}) {
        labels += fmt::format("{:.2f}\t{:.2f}\t{}\n", t, t + 0.08, phone);
        t += 0.08;
    }
    labels += fmt::format("{:.2f}\t{:.2f}\tsil\n", t, t + 0.2);
    const fs::path dir = write_recorded_sentence("phoneme_sv_recorded", "Han läste en bok.", "läste;bok", "s1.tsv",
                                                 labels, "han läste en bok", "han läser en bock");
    const auto r = score_swedish_phonemes(dir);
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("1 sentences' target phones from their recordings' labels"), std::string::npos)
        << r.output();
    const avsi::CsvTable alignment = avsi::read_csv(dir / "out" / "phoneme_alignment.csv");
    ASSERT_EQ(alignment.rows.size(), 2u);
    const auto field = [&](std::size_t row, const char* name) {
        return alignment.rows[row].fields[alignment.require_column(name)];
    };
    EXPECT_EQ(field(0, "target_phones"), "HH A N | L EH S T EH | EH N | B UW K");
    EXPECT_EQ(field(0, "correct"), "13");  // every word typed as spelled: the talker's phones, all correct
    // läser (L EH S AH RR in espeak-ng's Swedish) for läste: T deleted,
    // the talker's EH heard as AH, RR inserted; bock's short AO for UW.
    EXPECT_EQ(field(1, "response_phones"), "HH A N | L EH S - AH RR | EH N | B AO K");
    EXPECT_EQ(field(1, "substituted"), "2");
    EXPECT_EQ(field(1, "deleted"), "1");
    EXPECT_EQ(field(1, "inserted"), "1");
    fs::remove_all(dir);
}

TEST(PhonemeScoringCli, ScoreWithPronunciationTableWritesPhonemesCsv) {
    if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
    const fs::path dir = avsi::test::temp_dir("phoneme_cli");
    const auto r = avsi::test::run_avsi(fmt::format(
        "score --corpus {0}/corpus.csv --responses {0}/responses.csv --phonemes --tts festival:cmu_us_slt_arctic_hts "
        "--pronunciations {0}/pronunciations.tsv --out {1}",
        kCase.string(), dir.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const avsi::CsvTable got = avsi::read_csv(dir / "phonemes.csv");
    const avsi::CsvTable expected = avsi::read_csv(kCase / "expected_phonemes.csv");
    ASSERT_EQ(got.rows.size(), expected.rows.size());
    for (std::size_t i = 0; i < got.rows.size(); ++i)
        EXPECT_EQ(std::vector<std::string>(got.rows[i].fields.begin(), got.rows[i].fields.begin() + 7),
                  expected.rows[i].fields);
    EXPECT_EQ(avsi::read_csv(dir / "phoneme_alignment.csv").rows.size(), 6u);
    EXPECT_EQ(avsi::read_csv(dir / "information.csv").rows.size(), 10u);  // 2 conditions x 5 groupings
    const auto report = avsi::test::run_avsi(fmt::format(
        "analyze {0}/scores.csv --out {0}/report --phonemes {0}/phonemes.csv --bootstrap 200", dir.string()));
    ASSERT_EQ(report.exit_code, 0) << report.output();
    const std::string html = avsi::read_text_file(dir / "report" / "index.html");
    EXPECT_NE(html.find("What each model conveys"), std::string::npos);
    EXPECT_NE(avsi::read_text_file(dir / "report" / "report.md").find("| audio | voicing | 13 |"), std::string::npos);
    for (const char* f : {"rti.png", "confusion_audio_consonants.png", "confusion_face_visemes.png", "glmer_phonemes.R",
                          "phonemes_glmer.csv"})
        EXPECT_TRUE(fs::exists(dir / "report" / f)) << f;
    EXPECT_EQ(avsi::read_csv(dir / "report" / "phonemes_glmer.csv").rows.size(), 40u);  // target phones
    // The objective viseme information beside the listeners' (build-stimuli's qc/viseme_information.csv).
    avsi::write_text_file(dir / "viseme_information.csv",
                          "condition,segments,lda_accuracy,majority_class,t_bits,rti\nface,100,0.61,0.36,0.9,0.389\n");
    const auto objective = avsi::test::run_avsi(
        fmt::format("analyze {0}/scores.csv --out {0}/report2 --phonemes {0}/phonemes.csv --bootstrap 0 "
                    "--viseme-information {0}/viseme_information.csv",
                    dir.string()));
    ASSERT_EQ(objective.exit_code, 0) << objective.output();
    const std::string md = avsi::read_text_file(dir / "report2" / "report.md");
    EXPECT_NE(md.find("| face | 61.0 % | 36.0 % | 0.389 | 0.535 (NA – NA) |"), std::string::npos) << md;
    avsi::write_text_file(dir / "bad.csv", "condition,segments,lda_accuracy,majority_class,t_bits,rti\nface,1,x,0,0,0\n");
    const auto bad_objective = avsi::test::run_avsi(
        fmt::format("analyze {0}/scores.csv --out {0}/report3 --phonemes {0}/phonemes.csv --viseme-information {0}/bad.csv",
                    dir.string()));
    EXPECT_EQ(bad_objective.exit_code, 1);
    EXPECT_NE(bad_objective.output().find("bad.csv:2:1: error: lda_accuracy"), std::string::npos) << bad_objective.output();
    const auto bad =
        avsi::test::run_avsi(fmt::format("score --corpus {0}/corpus.csv --responses {0}/responses.csv "
                                         "--pronunciations {0}/pronunciations.tsv --out {1}",
                                         kCase.string(), dir.string()));
    EXPECT_EQ(bad.exit_code, 2) << bad.output();
    fs::remove_all(dir);
}

}  // namespace
