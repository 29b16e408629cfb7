// Articulatory corpus format: parameter track CSV with any subset of the
// parameters, manifests (JSON and CSV), seeded split, corpus hash.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/learn/articulatory_corpus.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

using test::temp_dir;

// A corpus of n utterances with two-column tracks and TSV labels.
fs::path make_corpus(const std::string& name, int n, const std::string& extra_utterance_fields = "") {
    const fs::path dir = temp_dir(name);
    std::string utts;
    for (int i = 0; i < n; ++i) {
        const std::string id = "u" + std::to_string(i);
        write_text_file(dir / "tracks" / (id + ".csv"),
                        "time_s,jaw_rotation,lip_rounding\n0.0,0.1,0\n0.02,0.2,\n0.04,0.3,0.1\n0.06,0.4,0.2\n");
        write_text_file(dir / "labels" / (id + ".tsv"),
                        "start_s\tend_s\tphone\n0\t0.02\tsil\n0.02\t0.05\tAA1\n0.05\t0.08\tP\n");
        utts += (i ? ",\n" : "") + std::string("{\"id\": \"") + id + "\", \"track\": \"tracks/" + id +
                ".csv\", \"labels\": \"labels/" + id + ".tsv\"" + (i == 0 ? extra_utterance_fields : "") + "}";
    }
    write_text_file(dir / "corpus.json",
                    "{\"format\": \"avsi-articulatory-corpus\", \"version\": 1, \"name\": \"t\",\n"
                    " \"split\": {\"seed\": 7, \"test_fraction\": 0.3},\n \"utterances\": [" +
                        utts + "]}\n");
    return dir;
}

}  // namespace

TEST(ParamTrackCsv, ReadsSubsetOfParametersAndMissingCells) {
    const fs::path dir = temp_dir("subset");
    write_text_file(dir / "t.csv", "lip_rounding,time_s,jaw_rotation\n0.5,1.0,0.1\n,1.01,0.2\nnan,1.02,0.3\n");
    const ParamTrack t = read_param_track_csv(dir / "t.csv");
    EXPECT_DOUBLE_EQ(t.fps, 100.0);
    EXPECT_DOUBLE_EQ(t.start_s, 1.0);
    ASSERT_EQ(t.size(), 3u);
    EXPECT_TRUE(t.has(Param::JawRotation));
    EXPECT_TRUE(t.has(Param::LipRounding));
    EXPECT_FALSE(t.has(Param::JawShift));
    EXPECT_DOUBLE_EQ(t.frames[1][index(Param::JawRotation)], 0.2);
    EXPECT_DOUBLE_EQ(t.frames[0][index(Param::LipRounding)], 0.5);
    EXPECT_TRUE(std::isnan(t.frames[1][index(Param::LipRounding)]));
    EXPECT_TRUE(std::isnan(t.frames[2][index(Param::LipRounding)]));
    EXPECT_TRUE(std::isnan(t.frames[0][index(Param::JawShift)]));

    // Round trip keeps the columns and the missing cells.
    write_param_track_csv(dir / "u.csv", t);
    const ParamTrack u = read_param_track_csv(dir / "u.csv");
    EXPECT_EQ(u.present, t.present);
    EXPECT_TRUE(std::isnan(u.frames[1][index(Param::LipRounding)]));
    EXPECT_DOUBLE_EQ(u.frames[2][index(Param::JawRotation)], 0.3);
}

TEST(ParamTrackCsv, UnknownColumnSuggestsTheParameter) {
    const fs::path dir = temp_dir("unknown");
    write_text_file(dir / "t.csv", "time_s,jaw_rotaton\n0,0\n0.1,0\n");
    try {
        read_param_track_csv(dir / "t.csv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("did you mean \"jaw_rotation\""), std::string::npos) << e.what();
    }
}

TEST(ParamTrackCsv, NonConstantStepIsAnErrorWithTheLine) {
    const fs::path dir = temp_dir("step");
    write_text_file(dir / "t.csv", "time_s,jaw_rotation\n0,0\n0.1,0\n0.25,0\n0.3,0\n");
    try {
        read_param_track_csv(dir / "t.csv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4) << e.what();  // the row with 0.25
    }
}

TEST(ArticulatoryCorpus, LoadsManifestAndLabels) {
    const fs::path dir = make_corpus("load", 3);
    const ArticulatoryCorpus c = load_articulatory_corpus(dir);
    ASSERT_EQ(c.entries.size(), 3u);
    EXPECT_EQ(c.split_seed, 7u);
    EXPECT_EQ(c.hash.size(), 64u);
    const CorpusUtterance u = load_corpus_utterance(c, c.entries[1]);
    EXPECT_EQ(u.id, "u1");
    ASSERT_EQ(u.phones.size(), 3u);
    EXPECT_EQ(u.phones[1].symbol, "AA");
    EXPECT_TRUE(u.phones[1].stressed);
    EXPECT_EQ(u.track.size(), 4u);
}

TEST(ArticulatoryCorpus, HashChangesWhenAnyFileChanges) {
    const fs::path dir = make_corpus("hash", 2);
    const std::string before = load_articulatory_corpus(dir).hash;
    EXPECT_EQ(load_articulatory_corpus(dir).hash, before);
    write_text_file(dir / "tracks" / "u1.csv", "time_s,jaw_rotation\n0,0.1\n0.02,0.25\n");
    EXPECT_NE(load_articulatory_corpus(dir).hash, before);
}

TEST(ArticulatoryCorpus, ReportsEveryProblemAtOnce) {
    const fs::path dir = make_corpus("problems", 2, ", \"split\": \"tset\"");
    fs::remove(dir / "labels" / "u1.tsv");
    try {
        load_articulatory_corpus(dir);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.diagnostics().size(), 2u) << e.what();
        const std::string text = e.what();
        EXPECT_NE(text.find("utterances[0].split"), std::string::npos) << text;
        EXPECT_NE(text.find("utterances[1].labels"), std::string::npos) << text;
    }
}

TEST(CorpusSplit, SeededReproducibleAndAboutSeventyThirty) {
    const fs::path dir = make_corpus("split", 20);
    const ArticulatoryCorpus c = load_articulatory_corpus(dir);
    const CorpusSplit a = split_corpus(c), b = split_corpus(c);
    EXPECT_EQ(a.test_ids, b.test_ids);
    EXPECT_EQ(a.test_ids.size(), 6u);
    EXPECT_EQ(a.train_ids.size(), 14u);
    std::set<std::string> all(a.test_ids.begin(), a.test_ids.end());
    all.insert(a.train_ids.begin(), a.train_ids.end());
    EXPECT_EQ(all.size(), 20u);
    // Another seed gives another split (checked over a few seeds).
    bool differs = false;
    for (std::uint64_t seed = 1; seed < 5; ++seed) differs |= split_corpus(c, {seed, {}}).test_ids != a.test_ids;
    EXPECT_TRUE(differs);
}

TEST(CorpusSplit, FixedSplitIsKept) {
    const fs::path dir = make_corpus("fixed", 10, ", \"split\": \"test\"");
    const ArticulatoryCorpus c = load_articulatory_corpus(dir);
    for (std::uint64_t seed = 0; seed < 10; ++seed) {
        SCOPED_TRACE(seed);
        const CorpusSplit s = split_corpus(c, {seed, 0.2});
        EXPECT_NE(std::find(s.test_ids.begin(), s.test_ids.end(), "u0"), s.test_ids.end());
        EXPECT_EQ(s.test_ids.size(), 1u + 2u);  // u0 plus round(9 · 0.2)
    }
}

TEST(ArticulatoryCorpus, CsvManifest) {
    const fs::path dir = make_corpus("csvmanifest", 2);
    fs::remove(dir / "corpus.json");
    write_text_file(dir / "corpus.csv",
                    "id,track,labels,split\nu0,tracks/u0.csv,labels/u0.tsv,train\nu1,tracks/u1.csv,labels/u1.tsv,test\n");
    const ArticulatoryCorpus c = load_articulatory_corpus(dir);
    const CorpusSplit s = split_corpus(c);
    EXPECT_EQ(s.train_ids, std::vector<std::string>{"u0"});
    EXPECT_EQ(s.test_ids, std::vector<std::string>{"u1"});
}

TEST(PhoneAt, FindsTheSegmentOfATime) {
    const PhoneSequence phones{{"sil", 0.0, 0.1, false}, {"AA", 0.1, 0.3, true}, {"P", 0.3, 0.4, false}};
    EXPECT_EQ(phone_at(phones, 0.05), 0u);
    EXPECT_EQ(phone_at(phones, 0.1), 1u);
    EXPECT_EQ(phone_at(phones, 0.3999), 2u);
    EXPECT_EQ(phone_at(phones, 0.4), 2u);
    EXPECT_FALSE(phone_at(phones, 0.41));
    EXPECT_FALSE(phone_at(phones, -0.01));
}
