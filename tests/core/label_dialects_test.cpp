// Label files as other tools write them (issue 20): Festival mono labels
// (radio phone set: pau, ax), HTS full-context labels phone- and
// state-aligned, TIMIT .phn (sample indices, 61 symbols, closures), MOCHA's
// .lab (seconds, sil/breath, MOCHA's phone set); each read correctly from a
// file the test writes, and a damaged copy of each refused at file:line. Also
// the plausibility check of label times (a file in the wrong unit).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

class LabelDialects : public ::testing::Test {
protected:
    void SetUp() override {
        dir = test::temp_dir("label_dialects");
    }
    void TearDown() override { fs::remove_all(dir); }

    fs::path write(const std::string& name, const std::string& text) {
        write_text_file(dir / name, text);
        return dir / name;
    }
    // The first diagnostic of reading `path`, or "" when it reads.
    static Diagnostic error_of(const fs::path& path, const LabelReadOptions& options = {}) {
        try {
            (void)read_phones(path, options);
        } catch (const InputError& e) {
            return e.first();
        }
        return {};
    }
    static std::string symbols(const PhoneSequence& phones) {
        std::string out;
        for (const auto& p : phones) out += (out.empty() ? "" : " ") + p.symbol + (p.stressed ? "1" : "");
        return out;
    }
    fs::path dir;
};

// One HTS full-context label (English demo layout) with the centre phone and
// the stress of its syllable (b1 of /B:).
std::string full_context(const std::string& p1, const std::string& p2, const std::string& centre,
                         const std::string& p4, const std::string& p5, const std::string& stress) {
    return p1 + "^" + p2 + "-" + centre + "+" + p4 + "=" + p5 + "@1_1/A:0_0_0/B:" + stress +
           "-0-2@1-1&1-3#1-1$1-1!0-1;0-1|" + centre + "/C:0+0+2/D:0_0/E:content+1@1+2&1+0#0+1/F:0_0/G:0_0/"
           "H:x=x^1=2|0/I:2=1/J:3+2-1";
}

TEST_F(LabelDialects, FestivalMonoLabelsWithPauAndAx) {
    // A Festival/HTS mono label: HTK times, Festival's radio phone set.
    const fs::path path = write("festival.lab",
                                "0 2000000 pau\n"
                                "2000000 2600000 dh\n"
                                "2600000 3200000 ax\n"
                                "3200000 4100000 k\n"
                                "4100000 5600000 ae\n"
                                "5600000 6400000 t\n"
                                "6400000 8000000 pau\n");
    const PhoneSequence phones = read_phones(path);
    EXPECT_EQ(symbols(phones), "sil DH AH K AE T sil");
    ASSERT_EQ(phones.size(), 7u);
    EXPECT_DOUBLE_EQ(phones[2].start_s, 0.26);
    EXPECT_FALSE(phones[2].stressed);  // ax is the reduced vowel AH0
    // The same with an explicit phone set.
    LabelReadOptions festival;
    festival.phone_set = LabelPhoneSet::Festival;
    EXPECT_EQ(read_phones(path, festival), phones);

    const fs::path damaged = write("festival_damaged.lab",
                                   "0 2000000 pau\n"
                                   "2000000 2600000 dh\n"
                                   "2600000 3200000 axx\n");
    const Diagnostic d = error_of(damaged);
    EXPECT_EQ(d.path, damaged.string());
    EXPECT_EQ(d.line, 3);
    EXPECT_NE(d.message.find("\"axx\""), std::string::npos) << d.message;
    EXPECT_NE(d.format().find("festival_damaged.lab:3:"), std::string::npos) << d.format();
}

TEST_F(LabelDialects, HtsFullContextPhoneAligned) {
    std::string text;
    text += "0 2000000 " + full_context("x", "x", "pau", "dh", "ax", "x") + "\n";
    text += "2000000 2600000 " + full_context("x", "pau", "dh", "ax", "k", "0") + "\n";
    text += "2600000 3200000 " + full_context("pau", "dh", "ax", "k", "ae", "0") + "\n";
    text += "3200000 4100000 " + full_context("dh", "ax", "k", "ae", "t", "1") + "\n";
    text += "4100000 5600000 " + full_context("ax", "k", "ae", "t", "pau", "1") + "\n";
    text += "5600000 6400000 " + full_context("k", "ae", "t", "pau", "x", "1") + "\n";
    text += "6400000 8000000 " + full_context("ae", "t", "pau", "x", "x", "x") + "\n";
    const PhoneSequence phones = read_phones(write("hts.lab", text));
    // The centre phones, AE stressed from its syllable's b1 = 1.
    EXPECT_EQ(symbols(phones), "sil DH AH K AE1 T sil");
    EXPECT_DOUBLE_EQ(phones[4].start_s, 0.41);
    EXPECT_DOUBLE_EQ(phones[4].end_s, 0.56);

    // Damaged: the centre phone's '+' is lost on line 4.
    std::string bad = text;
    const std::size_t line4 = bad.find("3200000 4100000");
    bad.erase(bad.find('+', line4), 1);
    const Diagnostic d = error_of(write("hts_damaged.lab", bad));
    EXPECT_EQ(d.line, 4) << d.format();
    EXPECT_NE(d.message.find("full-context"), std::string::npos) << d.message;

    // Labels without times (a front end's training labels) are refused with the reason.
    const Diagnostic untimed = error_of(write("hts_untimed.lab", full_context("x", "x", "pau", "dh", "ax", "x") + "\n"));
    EXPECT_EQ(untimed.line, 1);
    EXPECT_NE(untimed.message.find("without times"), std::string::npos) << untimed.message;
}

TEST_F(LabelDialects, HtsStateAlignedMergesFiveStatesPerPhone) {
    // 3 phones × 5 states of 50 ms; HSMMAlign writes the phone's label after its first state.
    const std::vector<std::pair<std::string, std::string>> phones_in = {
        {"pau", full_context("x", "x", "pau", "m", "ay", "x")},
        {"m", full_context("x", "pau", "m", "ay", "pau", "1")},
        {"ay", full_context("pau", "m", "ay", "pau", "x", "1")}};
    std::string text;
    long long t = 0;
    int line = 0;
    for (const auto& [name, label] : phones_in)
        for (int state = 2; state <= 6; ++state, ++line) {
            text += std::to_string(t) + " " + std::to_string(t + 500000) + " " + label + "[" + std::to_string(state) +
                    "]" + (state == 2 ? " " + label : "") + "\n";
            t += 500000;
        }
    const PhoneSequence phones = read_phones(write("states.lab", text));
    ASSERT_EQ(phones.size(), 3u);
    EXPECT_EQ(symbols(phones), "sil M AY1");
    EXPECT_DOUBLE_EQ(phones[1].start_s, 0.25);
    EXPECT_DOUBLE_EQ(phones[1].end_s, 0.5);
    EXPECT_DOUBLE_EQ(phones[2].end_s, 0.75);

    // Mono state-aligned labels merge the same way.
    const PhoneSequence mono = read_phones(write("states_mono.lab",
                                                 "0 500000 pau[2]\n500000 1000000 pau[3]\n1000000 1500000 pau[4]\n"
                                                 "1500000 2000000 m[2]\n2000000 2500000 m[3]\n2500000 3000000 m[4]\n"));
    EXPECT_EQ(symbols(mono), "sil M");
    EXPECT_DOUBLE_EQ(mono[1].start_s, 0.15);

    // Damaged: the second phone starts at state [4] (states [2], [3] lost).
    std::string bad;
    t = 0;
    line = 0;
    int damaged_line = 0;
    for (std::size_t p = 0; p < phones_in.size(); ++p)
        for (int state = 2; state <= 6; ++state) {
            if (p == 1 && state < 4) continue;
            ++line;
            if (p == 1 && state == 4) damaged_line = line;
            bad += std::to_string(t) + " " + std::to_string(t + 500000) + " " + phones_in[p].second + "[" +
                   std::to_string(state) + "]\n";
            t += 500000;
        }
    const Diagnostic d = error_of(write("states_damaged.lab", bad));
    EXPECT_EQ(d.line, damaged_line) << d.format();
    EXPECT_EQ(d.field, "state");
}

TEST_F(LabelDialects, TimitPhnWithSampleRateAndClosures) {
    // "She had your dark suit" (start), TIMIT style: sample indices at 16 kHz.
    const fs::path path = write("sa1.phn",
                                "0 3050 h#\n"
                                "3050 4559 sh\n"
                                "4559 5723 ix\n"
                                "5723 6642 hv\n"
                                "6642 8772 eh\n"
                                "8772 9190 dcl\n"
                                "9190 10337 jh\n"
                                "10337 11517 ih\n"
                                "11517 12500 dcl\n"
                                "12500 12750 d\n"
                                "12750 13500 q\n"
                                "13500 14400 aa\n"
                                "14400 15000 kcl\n"
                                "15000 16000 h#\n");
    const PhoneSequence phones = read_phones(path);
    // ix -> IH, hv -> HH, dcl jh -> JH, dcl d -> D (q joins D), an unreleased kcl -> K.
    EXPECT_EQ(symbols(phones), "sil SH IH HH EH JH IH D AA K sil");
    ASSERT_EQ(phones.size(), 11u);
    EXPECT_DOUBLE_EQ(phones[0].end_s, 3050.0 / 16000.0);
    EXPECT_DOUBLE_EQ(phones[5].start_s, 8772.0 / 16000.0);   // JH from its closure
    EXPECT_DOUBLE_EQ(phones[7].start_s, 11517.0 / 16000.0);  // D from its closure …
    EXPECT_DOUBLE_EQ(phones[7].end_s, 13500.0 / 16000.0);    // … to the end of q
    // The same numbers at 8 kHz are twice as long.
    LabelReadOptions at8k;
    at8k.sample_rate_hz = 8000.0;
    EXPECT_DOUBLE_EQ(read_phones(path, at8k)[0].end_s, 3050.0 / 8000.0);

    const fs::path damaged = write("sa1_damaged.phn", "0 3050 h#\n3050 4559 sh\n4559 4000 ix\n");
    const Diagnostic d = error_of(damaged);
    EXPECT_EQ(d.line, 3) << d.format();
    EXPECT_EQ(d.field, "end");
    const Diagnostic unknown = error_of(write("sa1_unknown.phn", "0 3050 h#\n3050 4559 shh\n"));
    EXPECT_EQ(unknown.line, 2) << unknown.format();
}

TEST_F(LabelDialects, TimitFoldingKeepsTheProjectsDistinctions) {
    const PhoneInventory& inv = PhoneInventory::builtin();
    auto one = [&](const char* s) {
        const auto p = inv.from_timit(s, "test");
        return p.empty() ? std::string("-") : p.front().symbol;
    };
    // Lee & Hon's folding where the project set has no separate phone …
    EXPECT_EQ(one("ax-h"), "AH");
    EXPECT_EQ(one("ux"), "UW");
    EXPECT_EQ(one("el"), "L");
    EXPECT_EQ(one("eng"), "NG");
    EXPECT_EQ(one("epi"), "sil");
    EXPECT_EQ(one("q"), "-");
    // … but AO/AA and ZH/SH stay apart, as in CMUdict.
    EXPECT_EQ(one("ao"), "AO");
    EXPECT_EQ(one("zh"), "ZH");
    EXPECT_THROW((void)inv.from_timit("xx", "test"), InputError);
}

TEST_F(LabelDialects, MochaLabInSecondsWithBreath) {
    // MOCHA .lab: "start end phone" in seconds, MOCHA's symbols.
    const fs::path path = write("fsew0_001.lab",
                                "0.0000 0.3200 sil\n"
                                "0.3200 0.4100 dh\n"
                                "0.4100 0.4700 @\n"
                                "0.4700 0.5900 b\n"
                                "0.5900 0.7600 @@\n"
                                "0.7600 0.8300 ch\n"
                                "0.8300 0.9600 k\n"
                                "0.9600 1.1000 @\n"
                                "1.1000 1.2100 n\n"
                                "1.2100 1.3600 uu\n"
                                "1.3600 1.6000 breath\n");
    const PhoneSequence phones = read_phones(path);
    EXPECT_EQ(symbols(phones), "sil DH AH B ER CH K AH N UW sil");
    EXPECT_DOUBLE_EQ(phones.back().start_s, 1.36);
    EXPECT_DOUBLE_EQ(phones.back().end_s, 1.6);
    LabelReadOptions mocha;
    mocha.phone_set = LabelPhoneSet::Mocha;
    EXPECT_EQ(read_phones(path, mocha), phones);

    const fs::path damaged = write("fsew0_001_damaged.lab", "0.0000 0.3200 sil\n0.3200 0.4100 dh\n0.4100 x.47 @\n");
    const Diagnostic d = error_of(damaged);
    EXPECT_EQ(d.line, 3) << d.format();
    EXPECT_EQ(d.field, "end");
}

TEST_F(LabelDialects, SamplesReadAsHtkUnitsAreRefusedWithTheLikelyUnit) {
    // A .phn file renamed .lab: 100 ns units would make it 1.6 ms of speech.
    const fs::path path = write("sa1.lab", "0 3050 h#\n3050 4559 sh\n4559 5723 ix\n5723 6642 hv\n6642 8772 eh\n");
    const Diagnostic d = error_of(path);
    EXPECT_EQ(d.line, 1) << d.format();
    EXPECT_NE(d.message.find("at least 5 ms"), std::string::npos) << d.message;
    EXPECT_NE(d.message.find("100 ns"), std::string::npos) << d.message;
    EXPECT_NE(d.message.find("16000 Hz"), std::string::npos) << d.message;
    // Sample indices at 16 kHz given as seconds in a .tsv are not short: nothing to say. Given as
    // 100 ns units in a MOCHA-style .lab with decimals they are read as seconds and pass.
    EXPECT_NO_THROW((void)read_phones(write("seconds.lab", "0.0 0.19 sil\n0.19 0.28 sh\n0.28 0.36 ix\n")));
    // An utterance under 50 ms with phones of 6 ms each.
    const Diagnostic short_utterance =
        error_of(write("short.tsv", "0\t0.006\tsil\n0.006\t0.012\tAA1\n0.012\t0.018\tsil\n"));
    EXPECT_NE(short_utterance.message.find("at least 50 ms"), std::string::npos) << short_utterance.message;
    EXPECT_EQ(short_utterance.line, 3);
}

TEST_F(LabelDialects, PhonesTsvRoundTripsThroughReadPhones) {
    const PhoneSequence phones = {{"sil", 0.0, 0.2, false}, {"P", 0.2, 0.3, false}, {"AA", 0.3, 0.5, true},
                                  {"sil", 0.5, 0.7, false}};
    const std::string text = phones_tsv(phones);
    EXPECT_EQ(text.substr(0, text.find('\n')), "start_s\tend_s\tphone");
    EXPECT_EQ(read_phones(write("p.tsv", text)), phones);
}

}  // namespace
}  // namespace avsi
