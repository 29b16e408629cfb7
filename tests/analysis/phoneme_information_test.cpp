// Confusion matrices and information transmitted (phoneme_information.h):
// the hand-built case of tests/data/analysis/phonemes against hand counts
// and the numpy reference (expected_information.csv), and the properties
// of T and RTI: invariant to relabelling, 0 for independence, 1 for perfect
// transmission.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "avsi/analysis/phoneme_information.h"
#include "avsi/analysis/phoneme_scoring.h"
#include "avsi/core/corpus.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/rng.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;
using namespace avsi::analysis;
using Table = std::vector<std::vector<double>>;

const fs::path kCase = fs::path(AVSI_TEST_DATA_DIR) / "analysis" / "phonemes";

std::vector<PhonemeRow> case_rows() {
    return score_phonemes(avsi::read_corpus(kCase / "corpus.csv"), read_responses(kCase / "responses.csv"),
                          read_pronunciations(kCase / "pronunciations.tsv"))
        .rows;
}

double cell(const ConfusionMatrix& m, const std::string& target, const std::string& response) {
    const auto r = std::find(m.rows.begin(), m.rows.end(), target) - m.rows.begin();
    const auto c = std::find(m.columns.begin(), m.columns.end(), response) - m.columns.begin();
    EXPECT_LT(static_cast<std::size_t>(r), m.rows.size()) << target;
    EXPECT_LT(static_cast<std::size_t>(c), m.columns.size()) << response;
    return m.counts.at(static_cast<std::size_t>(r)).at(static_cast<std::size_t>(c));
}

TEST(PhonemeConfusions, HandBuiltCaseCounts) {
    const auto rows = case_rows();
    const auto face = confusion_matrices("face", rows);
    ASSERT_EQ(face.size(), 3u);
    const ConfusionMatrix& consonants = face[0];
    EXPECT_EQ(consonants.kind, "consonants");
    EXPECT_EQ(cell(consonants, "T", "T"), 1.0);   // "pat"
    EXPECT_EQ(cell(consonants, "T", "-"), 3.0);   // "pat" loses sat's T, the empty answer both
    EXPECT_EQ(cell(consonants, "G", "G"), 1.0);   // "big"
    EXPECT_EQ(cell(consonants, "G", "T"), 1.0);   // "dot" for "dog"
    EXPECT_EQ(cell(consonants, "DH", "-"), 1.0);  // "a" for "the"
    const ConfusionMatrix& vowels = face[1];
    EXPECT_EQ(cell(vowels, "AO", "AA"), 1.0);
    EXPECT_EQ(cell(vowels, "AE", "-"), 3.0);
    const ConfusionMatrix& visemes = face[2];
    EXPECT_EQ(cell(visemes, "rounded", "open vowel"), 1.0);  // AO -> AA
    EXPECT_EQ(cell(visemes, "lingual", "lingual"), 4.0);     // T of "pat"; G, D and G->T of "a big dot"
    const auto audio = confusion_matrices("audio", rows);
    EXPECT_EQ(cell(audio[0], "B", "P"), 1.0);
    EXPECT_EQ(cell(audio[0], "P", "B"), 1.0);
    EXPECT_EQ(cell(audio[0], "P", "P"), 1.0);
    EXPECT_EQ(cell(audio[0], "T", "D"), 1.0);
    EXPECT_EQ(cell(audio[0], "T", "T"), 3.0);
    double total = 0.0;
    for (const auto& r : audio[0].counts) total += std::accumulate(r.begin(), r.end(), 0.0);
    EXPECT_EQ(total, 13.0);  // consonant targets of the audio answers (insertions left out)
}

TEST(PhonemeInformation, VoicingOfTheAudioAnswersByHand) {
    // Voiced targets DH B G D G -> 4 voiced, 1 voiceless (B->P); voiceless
    // targets P T S T, P T S T -> 6 voiceless, 2 voiced (P->B, T->D).
    const ConfusionMatrix m = feature_matrix("audio", "voicing", case_rows());
    EXPECT_EQ(cell(m, "voiced", "voiced"), 4.0);
    EXPECT_EQ(cell(m, "voiced", "voiceless"), 1.0);
    EXPECT_EQ(cell(m, "voiceless", "voiced"), 2.0);
    EXPECT_EQ(cell(m, "voiceless", "voiceless"), 6.0);
    const double n = 13.0;
    const double t = 4 / n * std::log2(4 * n / (5 * 6)) + 1 / n * std::log2(1 * n / (5 * 7)) +
                     2 / n * std::log2(2 * n / (8 * 6)) + 6 / n * std::log2(6 * n / (8 * 7));
    const double h = -(5 / n) * std::log2(5 / n) - (8 / n) * std::log2(8 / n);
    const double per_bin = 1.0 / (2.0 * n * std::log(2.0));  // Miller-Madow: 4 cells, 2 rows, 2 columns
    const Transmission got = information_transmitted(m.counts);
    EXPECT_NEAR(got.t_plugin, t, 1e-12);
    EXPECT_NEAR(got.t_plugin, 0.218815, 1e-6);
    EXPECT_NEAR(got.h_x, h, 1e-12);
    EXPECT_NEAR(got.t_corrected, t - (4 - 2 - 2 + 1) * per_bin, 1e-12);
    EXPECT_NEAR(got.rti, (t - per_bin) / (h + per_bin), 1e-12);
}

TEST(PhonemeInformation, HandBuiltCaseEqualsTheNumpyReference) {
    InformationSettings settings;
    settings.bootstrap = 0;
    const InformationResult result = information_by_condition(case_rows(), settings);
    const avsi::CsvTable expected = avsi::read_csv(kCase / "expected_information.csv");
    ASSERT_EQ(result.rows.size(), expected.rows.size());
    for (const auto& e : expected.rows) {
        SCOPED_TRACE(fmt::format("expected_information.csv:{}", e.line));
        const auto it = std::find_if(result.rows.begin(), result.rows.end(), [&](const InformationRow& r) {
            return r.condition == e.fields[0] && r.feature == e.fields[1];
        });
        ASSERT_NE(it, result.rows.end());
        const double values[] = {it->t.n, it->t.h_x, it->t.t_plugin, it->t.h_x_corrected, it->t.t_corrected, it->t.rti};
        for (std::size_t k = 0; k < 6; ++k)
            EXPECT_NEAR(values[k], std::stod(e.fields[2 + k]), 1e-9) << expected.header[2 + k];
    }
}

Table random_table(avsi::Rng& rng, std::size_t rows, std::size_t columns) {
    Table t(rows, std::vector<double>(columns));
    for (auto& r : t)
        for (auto& c : r) c = double(rng.uniform_int(20));
    return t;
}

TEST(PhonemeInformation, InvariantToRelabelling) {
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
        SCOPED_TRACE(fmt::format("seed {}", seed));
        avsi::Rng rng(seed);
        const Table t = random_table(rng, 4 + seed % 3, 5 + seed % 4);
        std::vector<std::size_t> rp(t.size()), cp(t[0].size());
        std::iota(rp.begin(), rp.end(), 0);
        std::iota(cp.begin(), cp.end(), 0);
        for (std::size_t i = rp.size(); i > 1; --i) std::swap(rp[i - 1], rp[rng.uniform_int(i)]);
        for (std::size_t i = cp.size(); i > 1; --i) std::swap(cp[i - 1], cp[rng.uniform_int(i)]);
        Table u(t.size(), std::vector<double>(t[0].size()));
        for (std::size_t i = 0; i < t.size(); ++i)
            for (std::size_t j = 0; j < t[0].size(); ++j) u[rp[i]][cp[j]] = t[i][j];
        const Transmission a = information_transmitted(t), b = information_transmitted(u);
        EXPECT_NEAR(a.t_plugin, b.t_plugin, 1e-12);
        EXPECT_NEAR(a.t_corrected, b.t_corrected, 1e-12);
        EXPECT_NEAR(a.rti, b.rti, 1e-12);
        EXPECT_GT(a.h_x, 0.0);
    }
}

TEST(PhonemeInformation, ZeroForIndependentInputAndOutput) {
    // Counts = row total × column total / N exactly: p(x,y) = p(x) p(y).
    const std::vector<double> rows = {2, 4, 6}, columns = {1, 3, 5, 7};
    Table t;
    for (double r : rows) {
        t.emplace_back();
        for (double c : columns) t.back().push_back(r * c);
    }
    const Transmission got = information_transmitted(t);
    EXPECT_NEAR(got.t_plugin, 0.0, 1e-12);
    EXPECT_LE(got.t_corrected, 0.0);  // the correction of 12 cells, 3 rows, 4 columns
    EXPECT_NEAR(got.t_corrected, -(12.0 - 3 - 4 + 1) / (2.0 * got.n * std::log(2.0)), 1e-12);
    EXPECT_NEAR(got.rti, got.t_corrected / got.h_x_corrected, 1e-12);
    EXPECT_LT(std::fabs(got.rti), 0.05);
}

TEST(PhonemeInformation, OneForPerfectTransmission) {
    const Table t = {{7, 0, 0}, {0, 3, 0}, {0, 0, 11}};
    const Transmission got = information_transmitted(t);
    EXPECT_NEAR(got.t_plugin, got.h_x, 1e-12);
    EXPECT_NEAR(got.rti, 1.0, 1e-12);  // Miller-Madow: T and H(x) corrected alike
    // Relabelled responses (a permutation) transmit everything too.
    const Table p = {{0, 7, 0}, {0, 0, 3}, {11, 0, 0}};
    EXPECT_NEAR(information_transmitted(p).rti, 1.0, 1e-12);
}

TEST(PhonemeInformation, BootstrapIsSeededAndBracketsTheEstimate) {
    // 8 subjects: the hand case's answers under new subject names.
    std::vector<PhonemeRow> rows;
    const auto base = case_rows();
    for (int s = 0; s < 4; ++s)
        for (auto r : base) {
            r.subject += std::to_string(s);
            rows.push_back(r);
        }
    InformationSettings settings;
    settings.bootstrap = 500;
    const InformationResult a = information_by_condition(rows, settings), b = information_by_condition(rows, settings);
    ASSERT_EQ(a.rows.size(), 10u);
    for (std::size_t i = 0; i < a.rows.size(); ++i) {
        EXPECT_EQ(a.rows[i].ci_low, b.rows[i].ci_low);
        EXPECT_LE(a.rows[i].ci_low, a.rows[i].ci_high);
    }
    ASSERT_EQ(a.comparisons.size(), 5u);  // audio vs face per grouping
    for (const auto& c : a.comparisons) {
        EXPECT_GE(c.p, 1.0 / 500);
        EXPECT_LE(c.p, 1.0);
        EXPECT_GE(c.p_holm, c.p);
        EXPECT_NEAR(c.difference, c.rti_a - c.rti_b, 1e-15);
    }
    // Audio conveys manner perfectly, face not: the difference is positive throughout.
    const auto manner = std::find_if(a.comparisons.begin(), a.comparisons.end(),
                                     [](const InformationComparison& c) { return c.feature == "manner"; });
    EXPECT_GT(manner->ci_low, 0.0);
}

TEST(PhonemeInformation, PhonemesCsvRoundTripAndBadRowsNamed) {
    const fs::path dir = avsi::test::temp_dir("phoneme_information");
    const auto rows = case_rows();
    write_phonemes_csv(dir / "phonemes.csv", rows);
    const auto back = read_phonemes_csv(dir / "phonemes.csv");
    ASSERT_EQ(back.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        EXPECT_EQ(back[i].target, rows[i].target);
        EXPECT_EQ(back[i].outcome, rows[i].outcome);
    }
    avsi::write_text_file(dir / "bad.csv",
                          "subject,condition,sentence,position,target,response,outcome\n"
                          "a,audio,s1,1,P,P,correct\n"
                          "a,audio,s1,2,P,QQ,substituted\n"
                          "a,audio,s1,x,P,B,correct\n");
    try {
        read_phonemes_csv(dir / "bad.csv");
        FAIL() << "no error";
    } catch (const avsi::InputError& e) {
        ASSERT_EQ(e.diagnostics().size(), 3u);
        EXPECT_EQ(e.diagnostics()[0].line, 3);
        EXPECT_EQ(e.diagnostics()[0].field, "response");
        EXPECT_EQ(e.diagnostics()[1].field, "position");
        EXPECT_EQ(e.diagnostics()[2].field, "outcome");  // P answered B is not correct
    }
    fs::remove_all(dir);
}

}  // namespace
