// The synthetic reference speaker: overlapping gestures on lip and jaw tract
// variables (undershoot on short vowels, closure in every bilabial, the vowel
// with its onset consonant, no command lead), seeded and reproducible corpus
// generation.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>

#include "avsi/core/files.h"
#include "avsi/learn/reference_speaker.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

using TaskTrack = std::vector<std::array<double, tract_variable_count>>;

TaskTrack tract(const PhoneSequence& phones) {
    return simulate_tract_variables(phones, UtteranceVariation{}, ReferenceSpeakerSettings{});
}

double tv_at(const TaskTrack& z, TractVariable tv, double time_s) {
    return z[static_cast<std::size_t>(std::lround(time_s * 60.0))][static_cast<std::size_t>(tv)];
}

double tv_min(const TaskTrack& z, TractVariable tv, double from_s, double to_s) {
    double m = 1e9;
    for (std::size_t k = 0; k < z.size(); ++k)
        if (k / 60.0 >= from_s && k / 60.0 <= to_s) m = std::min(m, z[k][static_cast<std::size_t>(tv)]);
    return m;
}

double tv_max(const TaskTrack& z, TractVariable tv, double from_s, double to_s) {
    double m = -1e9;
    for (std::size_t k = 0; k < z.size(); ++k)
        if (k / 60.0 >= from_s && k / 60.0 <= to_s) m = std::max(m, z[k][static_cast<std::size_t>(tv)]);
    return m;
}

}  // namespace

// Constrictions are made within their segments however short (stiffer
// gestures in shorter segments, a virtual target beyond contact); vowels
// undershoot when short.
TEST(ReferenceSpeaker, ShortVowelsUndershootButEveryBilabialCloses) {
    const auto short_b = tract({{"sil", 0, 0.2}, {"AA", 0.2, 0.5, true}, {"B", 0.5, 0.53}, {"AA", 0.53, 0.9, true}, {"sil", 0.9, 1.1}});
    const auto long_b = tract({{"sil", 0, 0.2}, {"AA", 0.2, 0.5, true}, {"B", 0.5, 0.7}, {"AA", 0.7, 1.1, true}, {"sil", 1.1, 1.3}});
    // The long /b/ goes well beyond contact toward its virtual target (−2 mm;
    // the overlapping vowel, blended at 1/100 of the consonant's strength,
    // holds it a little short).
    EXPECT_LT(tv_min(long_b, TractVariable::LipAperture, 0.5, 0.7), -1.5);
    EXPECT_GT(tv_min(long_b, TractVariable::LipAperture, 0.5, 0.7), -2.0);
    // The 30 ms one closes within it.
    EXPECT_LE(tv_min(short_b, TractVariable::LipAperture, 0.5, 0.53), 0.0);
    // A 60 ms /aa/ between bilabials stays well short of its jaw opening.
    const auto short_a = tract({{"sil", 0, 0.2}, {"B", 0.2, 0.3}, {"AA", 0.3, 0.36, true}, {"B", 0.36, 0.46}, {"sil", 0.46, 0.7}});
    const double full = tv_max(long_b, TractVariable::JawOpening, 0.2, 0.5);
    EXPECT_LT(tv_max(short_a, TractVariable::JawOpening, 0.2, 0.5), full - 3.0);
    EXPECT_GT(full, 10.0);  // the long /aa/ opens the jaw ~11 mm below its rest (stressed 13 mm target)
}

// Onset consonant and vowel start together: the lips round through the /s/
// of "soo" and spread through the /s/ of "see" (the vowel shows on the tract
// variables the consonant leaves free).
TEST(ReferenceSpeaker, TheVowelStartsWithItsOnsetConsonant) {
    const auto soo = tract({{"sil", 0, 0.2}, {"S", 0.2, 0.35}, {"UW", 0.35, 0.7, true}, {"sil", 0.7, 0.9}});
    const auto see = tract({{"sil", 0, 0.2}, {"S", 0.2, 0.35}, {"IY", 0.35, 0.7, true}, {"sil", 0.7, 0.9}});
    EXPECT_GT(tv_at(soo, TractVariable::UpperProtrusion, 0.33), tv_at(see, TractVariable::UpperProtrusion, 0.33) + 2.0);
    EXPECT_LT(tv_at(soo, TractVariable::LipWidth, 0.33), tv_at(see, TractVariable::LipWidth, 0.33) - 8.0);
}

// No command lead: between two vowels nothing changes before the second starts.
TEST(ReferenceSpeaker, NoGestureStartsBeforeItsSegment) {
    const auto iy_aa = tract({{"sil", 0, 0.2}, {"IY", 0.2, 0.6, true}, {"AA", 0.6, 1.0, true}, {"sil", 1.0, 1.2}});
    const auto iy_iy = tract({{"sil", 0, 0.2}, {"IY", 0.2, 0.6, true}, {"IY", 0.6, 1.0, true}, {"sil", 1.0, 1.2}});
    // 5 ms before /aa/: within 0.05 mm of the same sentence with /iy/ instead
    // (the 10 ms activation ramp starts 5 ms before the segment).
    const double before = 0.6 - 0.01;
    for (std::size_t tv = 0; tv < tract_variable_count; ++tv)
        EXPECT_NEAR(iy_aa[static_cast<std::size_t>(std::lround(before * 60))][tv],
                    iy_iy[static_cast<std::size_t>(std::lround(before * 60))][tv], 0.05)
            << tract_variable_name(static_cast<TractVariable>(tv));
    EXPECT_GT(tv_at(iy_aa, TractVariable::JawOpening, 0.8), tv_at(iy_iy, TractVariable::JawOpening, 0.8) + 5.0);
}

// The gesture targets are their own table, not the rule model's: a
// different file, in millimetres, with its provenance column per cell.
TEST(ReferenceSpeaker, TargetsComeFromTheTaskTargetTable) {
    const auto table = read_task_targets();
    ASSERT_TRUE(table.count("UW") && table.count("P") && table.count("sil"));
    EXPECT_DOUBLE_EQ(*table.at("P").first.target_mm[static_cast<std::size_t>(TractVariable::LipAperture)], -2.0);
    EXPECT_TRUE(table.at("AW").second.has_value());
    EXPECT_FALSE(table.at("K").first.target_mm[static_cast<std::size_t>(TractVariable::LipAperture)].has_value());
}

TEST(ReferenceSpeaker, NoiseIsSeeded) {
    const PhoneSequence phones{{"sil", 0, 0.2}, {"AA", 0.2, 0.5, true}, {"sil", 0.5, 0.7}};
    UtteranceVariation v;
    v.add_noise = true;
    Rng a(5), b(5), c(6);
    const ParamTrack ta = simulate_reference_speaker(phones, v, {}, a);
    const ParamTrack tb = simulate_reference_speaker(phones, v, {}, b);
    const ParamTrack tc = simulate_reference_speaker(phones, v, {}, c);
    EXPECT_EQ(ta.frames, tb.frames);
    EXPECT_NE(ta.frames, tc.frames);
    EXPECT_EQ(ta.size(), frame_count(0.7, 60.0));
}

TEST(ReferenceCorpus, WritesALoadableCorpus) {
    const fs::path a = test::temp_dir("refcorpus_a");
    ReferenceSpeakerSettings s;
    s.max_utterances = 4;
    EXPECT_EQ(write_reference_corpus(a, s), 4u);
    const ArticulatoryCorpus ca = load_articulatory_corpus(a);
    ASSERT_EQ(ca.entries.size(), 4u);
    const CorpusUtterance u = load_corpus_utterance(ca, ca.entries[2]);
    EXPECT_DOUBLE_EQ(u.track.fps, 60.0);
    EXPECT_TRUE(std::all_of(u.track.present.begin(), u.track.present.end(), [](bool p) { return p; }));
    EXPECT_EQ(u.phones.front().symbol, "sil");
    EXPECT_EQ(u.track.size(), frame_count(u.phones.back().end_s, 60.0));
    EXPECT_NE(read_text_file(a / "sentences.tsv").find("ref003\t"), std::string::npos);
}

// espeak-ng's phone timing depends (by well under a millisecond) on what the
// process synthesised before, so reproducibility is a property of a fresh
// `avsi corpus reference` run: two runs give byte-identical corpora.
TEST(ReferenceCorpus, CliRunsAreByteIdentical) {
    const fs::path base = test::temp_dir("refcorpus_cli");
    auto run = [&](const std::string& name, const std::string& seed) {
        const test::CliResult r =
            test::run_avsi({"corpus", "reference", "--count", "3", "--seed", seed, "--out", (base / name).string()});
        EXPECT_EQ(r.exit_code, 0) << r.err;
        return load_articulatory_corpus(base / name).hash;
    };
    const std::string a = run("a", "2004");
    EXPECT_EQ(run("b", "2004"), a);
    EXPECT_NE(run("c", "7"), a);
}

namespace {

// The Swedish speaker: espeak-ng sv timing over the Swedish list, with the
// gestures of languages/sv/task_targets.tsv for the phones English lacks.
TEST(ReferenceCorpus, SwedishSpeakerSpeaksSwedishPhones) {
    const fs::path dir = test::temp_dir("refcorpus_sv");
    const test::CliResult r =
        test::run_avsi({"corpus", "reference", "--language", "sv", "--count", "12", "--out", dir.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const ArticulatoryCorpus corpus = load_articulatory_corpus(dir);
    ASSERT_EQ(corpus.entries.size(), 12u);
    std::set<std::string> seen;
    for (const auto& e : corpus.entries)
        for (const auto& p : load_corpus_utterance(corpus, e).phones) seen.insert(p.symbol);
    for (const char* phone : {"YY", "UX", "EU", "OE", "A", "RR", "SJ", "TJ"}) EXPECT_TRUE(seen.count(phone)) << phone;
    const auto& table = PhoneInventory::builtin().language_phones("sv");
    for (const auto& s : seen) EXPECT_NE(std::find(table.begin(), table.end(), s), table.end()) << s;
    const std::string readme = read_text_file(dir / "README.md");
    EXPECT_NE(readme.find("languages/sv/task_targets.tsv"), std::string::npos) << readme;
    EXPECT_NE(readme.find("(voice sv)"), std::string::npos) << readme;
}

TEST(ReferenceCorpus, ALanguageWithoutAReferenceSpeakerIsRefused) {
    const test::CliResult r =
        test::run_avsi({"corpus", "reference", "--language", "fr", "--count", "1", "--out",
                        test::temp_dir("refcorpus_fr").string()});
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("no reference speaker for language \"fr\""), std::string::npos) << r.err;
}

}  // namespace
