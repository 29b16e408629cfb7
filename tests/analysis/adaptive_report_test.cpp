// The adaptive SRT analysis (analysis/adaptive_report.h) on a simulated
// 12-subject study: SRTs, the visual benefit and the ANOVA on SRTs, each
// checked against a computation written here from the CSV columns alone.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <numeric>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/analysis/adaptive_report.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "support/temp_dir.h"

using namespace avsi;
using namespace avsi::analysis;
namespace fs = std::filesystem;

namespace {

const fs::path kProtocol = fs::path(AVSI_TEST_DATA_DIR) / "adaptive" / "protocol.toml";

// 12 simulated subjects: audio-only L50 ~ N(−4, 1.5²), audiovisual 5 dB
// better ± N(0, 1²), slope 0.15/dB, 3 keywords, one track of 10 sentences per
// condition under the test protocol's rules. Writes adaptive_trials.csv.
void write_study(const fs::path& csv) {
    const Protocol protocol = load_protocol(kProtocol);
    const TrackSettings settings = adaptive_protocol(protocol).track;
    Rng rng(12);
    std::string text = "subject,phase,condition,presentation,sentence_index,attempt,level_db,keywords,correct,next_level_db\n";
    for (int subject = 1; subject <= 12; ++subject) {
        const double ao = rng.normal(-4.0, 1.5);
        const double av = ao - 5.0 + rng.normal(0.0, 1.0);
        text += fmt::format("{},warmup,audio-only,1,1,1,10,3,3,10\n", subject);  // no track: skipped
        for (const auto& [condition, l50] : {std::pair{"audio-only", ao}, std::pair{"audiovisual", av}}) {
            AdaptiveTrack t(settings);
            const SimulatedListener listener{l50, 0.15, 3};
            while (t.sentences() < protocol.design.sentences_per_list) {
                const TrackStep& s = t.record(3, simulate_response(listener, t.level_db(), rng));
                text += fmt::format("{},test,{},{},{},{},{},{},{},{}\n", subject, condition, s.presentation, s.sentence,
                                    s.attempt, s.level_db, s.keywords, s.correct, s.next_level_db);
            }
        }
    }
    write_text_file(csv, text);
}

}  // namespace

TEST(AdaptiveReport, SimulatedTwelveSubjectStudyMatchesAnIndependentComputation) {
    const fs::path dir = test::temp_dir("adaptive_report_study");
    write_study(dir / "adaptive_trials.csv");
    AdaptiveAnalyzeSettings s;
    s.input = dir / "adaptive_trials.csv";
    s.protocol = kProtocol;
    s.out_dir = dir / "report";
    const SrtAnalysis a = analyze_adaptive_file(s);
    ASSERT_EQ(a.tracks.size(), 24u);
    ASSERT_TRUE(a.anova.has_value());

    // Independent SRTs: the level of each sentence's last presentation from
    // sentence 5 on, plus the last next_level_db, averaged.
    const CsvTable trials = read_csv(s.input);
    std::map<std::pair<std::string, std::string>, std::vector<double>> levels;
    std::map<std::pair<std::string, std::string>, std::map<int, double>> last_of_sentence;
    std::map<std::pair<std::string, std::string>, double> next_level;
    for (const auto& r : trials.rows) {
        if (r.fields[1] != "test") continue;
        const auto key = std::make_pair(r.fields[0], r.fields[2]);
        const int sentence = std::stoi(r.fields[4]);
        if (sentence >= 5) last_of_sentence[key][sentence] = std::stod(r.fields[6]);
        next_level[key] = std::stod(r.fields[9]);
    }
    std::map<std::pair<std::string, std::string>, double> srt;
    for (auto& [key, by_sentence] : last_of_sentence) {
        double sum = next_level[key];
        for (const auto& [sentence, level] : by_sentence) sum += level;
        srt[key] = sum / (by_sentence.size() + 1);
    }
    const CsvTable srt_csv = read_csv(s.out_dir / "srt.csv");
    ASSERT_EQ(srt_csv.rows.size(), 24u);
    for (const auto& r : srt_csv.rows) {
        SCOPED_TRACE(r.fields[0] + " " + r.fields[1]);
        EXPECT_NEAR(std::stod(r.fields[2]), srt.at({r.fields[0], r.fields[1]}), 1e-9);
    }

    // Visual benefit: paired differences, t(0.975, 11) = 2.200985 from tables.
    std::vector<double> d;
    for (int subject = 1; subject <= 12; ++subject)
        d.push_back(srt.at({std::to_string(subject), "audio-only"}) - srt.at({std::to_string(subject), "audiovisual"}));
    const double mean = std::accumulate(d.begin(), d.end(), 0.0) / 12.0;
    double ss = 0.0;
    for (double v : d) ss += (v - mean) * (v - mean);
    const double se = std::sqrt(ss / 11.0) / std::sqrt(12.0);
    ASSERT_EQ(a.benefits.size(), 1u);
    const VisualBenefit& b = a.benefits[0];
    EXPECT_EQ(b.reference, "audio-only");
    EXPECT_EQ(b.n, 12u);
    EXPECT_NEAR(b.mean_db, mean, 1e-9);
    EXPECT_NEAR(b.ci_low_db, mean - 2.200985 * se, 1e-5);
    EXPECT_NEAR(b.ci_high_db, mean + 2.200985 * se, 1e-5);
    // The simulated benefit is 5 dB in L50; the estimate lands near it.
    EXPECT_GT(b.mean_db, 3.0);
    EXPECT_LT(b.mean_db, 7.0);
    const CsvTable benefit_csv = read_csv(s.out_dir / "benefit.csv");
    ASSERT_EQ(benefit_csv.rows.size(), 1u);
    EXPECT_NEAR(std::stod(benefit_csv.rows[0].fields[3]), mean, 1e-9);

    // ANOVA on SRTs with two conditions: F(1, 11) = t² of the paired t; and
    // SS_conditions = n·Σ_j (mean_j − grand)² by hand.
    const double t = mean / se;
    const auto doc = nlohmann::json::parse(read_text_file(s.out_dir / "anova.json"));
    const double F = doc.at("anova").at("F").get<double>();
    EXPECT_NEAR(F, t * t, 1e-8 * t * t);
    EXPECT_NEAR(doc.at("anova").at("df_conditions").get<double>(), 1.0, 0.0);
    EXPECT_NEAR(doc.at("anova").at("df_error").get<double>(), 11.0, 0.0);
    ASSERT_TRUE(b.p_value.has_value());
    EXPECT_NEAR(doc.at("anova").at("p").get<double>(), *b.p_value, 1e-12 + 1e-9 * *b.p_value);
    double m_ao = 0, m_av = 0;
    for (int subject = 1; subject <= 12; ++subject) {
        m_ao += srt.at({std::to_string(subject), "audio-only"}) / 12.0;
        m_av += srt.at({std::to_string(subject), "audiovisual"}) / 12.0;
    }
    const double grand = (m_ao + m_av) / 2;
    EXPECT_NEAR(a.anova->anova.ss_conditions, 12.0 * ((m_ao - grand) * (m_ao - grand) + (m_av - grand) * (m_av - grand)),
                1e-8);

    // The report files, with the numbers in them.
    for (const char* f : {"index.html", "report.md", "srt.csv", "benefit.csv", "anova.json", "pairwise.csv",
                          "psychometric.csv", "srt.png", "psychometric.png", "tracks/subject_1.png", "tracks/subject_12.png"})
        EXPECT_TRUE(fs::is_regular_file(s.out_dir / f)) << f;
    const std::string md = read_text_file(s.out_dir / "report.md");
    EXPECT_NE(md.find(fmt::format("| audiovisual | 12 | {:.2f} |", mean)), std::string::npos) << md;
    EXPECT_NE(md.find("F(1, 11) = "), std::string::npos) << md;
    const std::string html = read_text_file(s.out_dir / "index.html");
    EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
    // Pooled psychometric fits: the audiovisual function lies left of the audio-only one.
    ASSERT_EQ(a.fits.size(), 2u);
    ASSERT_TRUE(a.fits[0].fit.converged && a.fits[1].fit.converged);
    EXPECT_LT(a.fits[1].fit.l50_db, a.fits[0].fit.l50_db);
    fs::remove_all(dir);
}

TEST(AdaptiveReport, AStoredLevelTheRulesDoNotGiveIsRefusedWithItsLine) {
    const fs::path dir = test::temp_dir("adaptive_report_tampered");
    write_study(dir / "adaptive_trials.csv");
    std::string text = read_text_file(dir / "adaptive_trials.csv");
    // Line 4 is subject 1's second audio-only presentation; change its level.
    std::vector<std::string> lines;
    std::size_t start = 0;
    while (start < text.size()) {
        const std::size_t end = text.find('\n', start);
        lines.push_back(text.substr(start, end - start));
        start = end + 1;
    }
    auto fields = parse_csv(lines[3] + "\n", "x", {.has_header = false}).rows[0].fields;
    fields[6] = "-17";
    lines[3] = fmt::format("{}", fmt::join(fields, ","));
    write_text_file(dir / "adaptive_trials.csv", fmt::format("{}\n", fmt::join(lines, "\n")));
    AdaptiveAnalyzeSettings s;
    s.input = dir / "adaptive_trials.csv";
    s.protocol = kProtocol;
    s.out_dir = dir / "report";
    try {
        analyze_adaptive_file(s);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("adaptive_trials.csv:4:7: error: level_db: expected"), std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(s.out_dir / "index.html"));
    fs::remove_all(dir);
}

TEST(AdaptiveReport, BadFieldsAreReportedWithFileLineAndColumn) {
    const fs::path dir = test::temp_dir("adaptive_report_bad");
    write_text_file(dir / "t.csv", "subject,condition,presentation,level_db,keywords,correct\n1,audio-only,1,x,3,4\n");
    try {
        read_adaptive_trials(dir / "t.csv");
        FAIL() << "accepted";
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("t.csv:2:4: error: level_db: expected a level"), std::string::npos) << m;
        EXPECT_NE(m.find("t.csv:2:6: error: correct: expected at most keywords (3), got 4"), std::string::npos)
            << m;
    }
    fs::remove_all(dir);
}

// A band-count study: the stored levels are band counts, the tracks replay on
// positions of the list, and the thresholds, the benefit and the report are
// on the log2(bands) scale — each SRT checked against the mean of the log2 of
// the CSV's own band levels.
TEST(AdaptiveReport, BandCountTracksAreReportedInBands) {
    const fs::path dir = test::temp_dir("adaptive_report_bands");
    const std::string protocol_text = read_text_file(kProtocol);
    write_text_file(dir / "corpus.csv", read_text_file(kProtocol.parent_path() / "corpus.csv"));
    write_text_file(dir / "bands.toml",
                    protocol_text.substr(0, protocol_text.find("[adaptive]")) +
                        "[adaptive]\nvariable = \"bands\"\nlevels = [1, 2, 3, 4, 6, 8, 12, 16]\nstart_level = 8\n"
                        "srt_from = 3\nsrt_include_next = false\nreference = \"audio-only\"\n");
    const Protocol protocol = load_protocol(dir / "bands.toml");
    const AdaptiveProtocol adaptive = adaptive_protocol(protocol);
    Rng rng(3);
    std::string text = "subject,phase,condition,presentation,sentence_index,attempt,level_db,keywords,correct,next_level_db\n";
    std::map<std::pair<int, std::string>, std::vector<double>> averaged;  // levels of sentences 3..10, by hand below
    for (int subject = 1; subject <= 4; ++subject)
        for (const auto& [condition, l50] : {std::pair{"audio-only", 6.0}, std::pair{"audiovisual", 3.0}}) {
            AdaptiveTrack t(adaptive.track);
            const SimulatedListener listener{l50 + subject * 0.5, 0.4, 3};
            while (t.sentences() < 10) {
                const double bands = adaptive.value_of(t.level_db());
                const TrackStep& s = t.record(3, simulate_response(listener, bands, rng));
                text += fmt::format("{},test,{},{},{},{},{},{},{},{}\n", subject, condition, s.presentation, s.sentence,
                                    s.attempt, bands, s.keywords, s.correct, adaptive.value_of(s.next_level_db));
            }
        }
    write_text_file(dir / "adaptive_trials.csv", text);
    // The hand computation: per track, the band level of the last presentation of sentences 3..10.
    const CsvTable csv = read_csv(dir / "adaptive_trials.csv");
    std::map<std::tuple<int, std::string, int>, double> last;  // (subject, condition, sentence) → bands
    for (const auto& r : csv.rows)
        last[{std::stoi(r.fields[0]), r.fields[2], std::stoi(r.fields[4])}] = std::stod(r.fields[6]);
    for (const auto& [key, bands] : last)
        if (std::get<2>(key) >= 3) averaged[{std::get<0>(key), std::get<1>(key)}].push_back(bands);

    AdaptiveAnalyzeSettings settings;
    settings.input = dir / "adaptive_trials.csv";
    settings.protocol = dir / "bands.toml";
    settings.out_dir = dir / "report";
    const SrtAnalysis a = analyze_adaptive_file(settings);
    EXPECT_EQ(a.unit, "bands");
    EXPECT_EQ(a.scale, "log2(bands)");
    ASSERT_EQ(a.tracks.size(), 8u);
    std::map<int, std::map<std::string, double>> log_mean;  // subject → condition → mean log2 bands (converged tracks)
    for (const auto& t : a.tracks) {
        SCOPED_TRACE(t.subject + " " + t.condition);
        const auto& levels = averaged.at({std::stoi(t.subject), t.condition});
        ASSERT_EQ(levels.size(), 8u);
        double mean = 0.0;
        for (double b : levels) mean += std::log2(b) / levels.size();
        ASSERT_TRUE(t.srt.valid);
        EXPECT_NEAR(t.srt.srt_db, mean, 1e-12);
        for (const auto& st : t.steps)
            EXPECT_NE(std::find(adaptive.levels.begin(), adaptive.levels.end(), st.level_db), adaptive.levels.end());
        if (!t.excluded) log_mean[std::stoi(t.subject)][t.condition] = mean;
    }
    ASSERT_EQ(a.benefits.size(), 1u);
    std::vector<double> benefit;
    for (const auto& [s, m] : log_mean)
        if (m.size() == 2) benefit.push_back(m.at("audio-only") - m.at("audiovisual"));
    ASSERT_GE(benefit.size(), 2u);
    EXPECT_EQ(a.benefits[0].n, benefit.size());
    EXPECT_NEAR(a.benefits[0].mean_db, std::accumulate(benefit.begin(), benefit.end(), 0.0) / benefit.size(), 1e-9);
    const std::string report = read_text_file(dir / "report" / "report.md");
    EXPECT_NE(report.find("## SRT by condition (log2 vocoder bands; lower is better)"), std::string::npos) << report;
    EXPECT_NE(report.find("| condition | n | benefit (log2(bands)) |"), std::string::npos) << report;
    EXPECT_NE(report.find("threshold = mean of the log2 levels"), std::string::npos) << report;
    EXPECT_EQ(report.find("dB"), std::string::npos) << report;
    // A stored band count the rules do not give is refused with its line.
    std::string tampered = text;
    const auto line2 = tampered.find('\n') + 1;
    const auto field = tampered.find(",8,", line2);
    tampered.replace(field, 3, ",6,");
    write_text_file(dir / "tampered.csv", tampered);
    settings.input = dir / "tampered.csv";
    try {
        analyze_adaptive_file(settings);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("tampered.csv:2:"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("level_db: expected 8"), std::string::npos) << e.what();
    }
    fs::remove_all(dir);
}

// The SRT report's tests against R (scripts/r/srt_reference.R): 20 simulated
// listeners × 3 conditions whose benefits vary unequally (Mauchly p < .05).
// R computes the SRTs from the stored levels on its own, then afex/car's
// ANOVA with GG and HF corrections and the paired benefits with Holm's
// adjustment; the replayed tracks, the report's numbers and its printed
// tables must agree.
TEST(AdaptiveReport, SphericityViolatedCaseMatchesR) {
    const fs::path data = fs::path(AVSI_TEST_DATA_DIR) / "analysis";
    const nlohmann::json r = nlohmann::json::parse(read_text_file(data / "srt_sphericity.expected.json"));
    const auto rows = read_adaptive_trials(data / "srt_sphericity.adaptive_trials.csv");
    const SrtAnalysis a = analyze_srt(rows, TrackSettings{}, {"audio-only", "av-a", "av-b"}, "audio-only",
                                      "srt_sphericity.adaptive_trials.csv");
    ASSERT_EQ(a.tracks.size(), 60u);
    std::map<std::pair<std::string, std::string>, double> srt;
    for (const auto& t : a.tracks) {
        ASSERT_TRUE(t.srt.valid) << t.subject << " " << t.condition;
        srt[{t.subject, t.condition}] = t.srt.srt_db;
    }
    for (const auto& e : r.at("srt"))
        EXPECT_NEAR((srt.at({e.at("subject").get<std::string>(), e.at("condition").get<std::string>()})),
                    e.at("srt_db").get<double>(), 1e-9);

    ASSERT_TRUE(a.anova.has_value());
    const AnovaResult& an = a.anova->anova;
    const auto near = [](double got, double want, const char* what) {
        EXPECT_NEAR(got, want, 1e-9 * std::max(1.0, std::fabs(want))) << what;
    };
    ASSERT_EQ(an.n, 20u);
    near(an.df_conditions, r.at("df_conditions").get<double>(), "df");
    near(an.df_error, r.at("df_error").get<double>(), "df error");
    near(*an.F, r.at("afex_F").get<double>(), "F");
    near(*an.p_value, r.at("afex_p").get<double>(), "p");
    near(an.mauchly.W, r.at("mauchly_W").get<double>(), "Mauchly W");
    near(*an.mauchly.p_value, r.at("mauchly_p").get<double>(), "Mauchly p");
    ASSERT_LT(r.at("mauchly_p").get<double>(), 0.05) << "the case must violate sphericity";
    near(*an.greenhouse_geisser.epsilon, r.at("gg_epsilon").get<double>(), "GG epsilon");
    near(*an.greenhouse_geisser.p_value, r.at("gg_p").get<double>(), "GG p");
    near(*an.huynh_feldt.epsilon, r.at("hf_epsilon").get<double>(), "HF epsilon");
    near(*an.huynh_feldt.p_value, r.at("hf_p").get<double>(), "HF p");

    ASSERT_EQ(a.benefits.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
        const auto& want = r.at("benefits").at(i);
        const VisualBenefit& b = a.benefits[i];
        EXPECT_EQ(b.condition, want.at("condition").get<std::string>());
        near(b.mean_db, want.at("benefit_db").get<double>(), "benefit");
        near(*b.t, want.at("t").get<double>(), "t");
        near(*b.p_value, want.at("p").get<double>(), "p");
        near(*b.p_holm, want.at("p_holm").get<double>(), "Holm p");
        near(b.ci_low_db, want.at("ci_low_db").get<double>(), "CI low");
        near(b.ci_high_db, want.at("ci_high_db").get<double>(), "CI high");
    }
    // Holm changes at least one p here, so the printed column is not the uncorrected one.
    EXPECT_NE(*a.benefits[0].p_holm, *a.benefits[0].p_value);

    // The printed report: the GG and HF lines with R's ε and p, and the Holm column.
    const fs::path dir = test::temp_dir("adaptive_report_r_case");
    SrtReportSettings rs;
    rs.out_dir = dir;
    rs.source = "srt_sphericity.adaptive_trials.csv";
    write_srt_report(a, rs);
    const std::string md = read_text_file(dir / "report.md");
    const std::string html = read_text_file(dir / "index.html");
    const auto printed_p = [](double p) { return table_p(p); };
    for (const std::string& s :
         {fmt::format("| Greenhouse-Geisser | {:.4f} | ", r.at("gg_epsilon").get<double>()),
          fmt::format("| Huynh-Feldt (raw ε; min(1, ε) used) | {:.4f} | ", r.at("hf_epsilon").get<double>()),
          fmt::format(" | {} |\n", printed_p(r.at("gg_p").get<double>())),
          fmt::format(" | {} |\n", printed_p(r.at("hf_p").get<double>())),
          std::string("| p | p (Holm) |"),
          fmt::format("| {} | {} |\n", printed_p(r.at("benefits").at(1).at("p").get<double>()),
                      printed_p(r.at("benefits").at(1).at("p_holm").get<double>()))})
        EXPECT_NE(md.find(s), std::string::npos) << s << "\n" << md;
    EXPECT_NE(html.find("Greenhouse-Geisser"), std::string::npos);
    EXPECT_NE(html.find("<th>p (Holm)</th>"), std::string::npos);
    const CsvTable benefit_csv = read_csv(dir / "benefit.csv");
    const std::size_t c_holm = benefit_csv.require_column("p_holm");
    EXPECT_NEAR(std::stod(benefit_csv.rows[0].fields[c_holm]), r.at("benefits").at(0).at("p_holm").get<double>(), 1e-12);
    fs::remove_all(dir);
}
