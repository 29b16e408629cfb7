// The report for the 25 × 6 reference data set: self-contained valid HTML,
// a non-empty PNG, and HTML numbers equal to anova.json.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <algorithm>
#include <cctype>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "avsi/analysis/report.h"
#include "avsi/analysis/scores.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace avsi::analysis {
namespace {

namespace fs = std::filesystem;

class Report : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir = test::temp_dir("report_test");
        AnalyzeSettings s;
        s.input = AVSI_TEST_DATA_DIR "/analysis/balanced.csv";
        s.out_dir = dir / "report";
        result = *analyze_file(s);
        html = read_text_file(dir / "report" / "index.html");
        doc = nlohmann::json::parse(read_text_file(dir / "report" / "anova.json"));
    }
    static void TearDownTestSuite() { fs::remove_all(dir); }
    static inline fs::path dir;
    static inline AnalysisResult result;
    static inline std::string html;
    static inline nlohmann::json doc;
};

TEST_F(Report, WritesEveryFile) {
    for (const char* f : {"index.html", "report.md", "anova.json", "pairwise.csv", "descriptives.csv", "plot.png",
                          "plot.svg", "glmer.R"}) {
        SCOPED_TRACE(f);
        ASSERT_TRUE(fs::exists(dir / "report" / f));
        EXPECT_GT(fs::file_size(dir / "report" / f), 100u);
    }
    EXPECT_EQ(result.anova.n, 25u);
    EXPECT_EQ(result.anova.k, 6u);
}

TEST_F(Report, PngIsANonEmptyImage) {
    const std::string png = read_text_file(dir / "report" / "plot.png");
    ASSERT_GT(png.size(), 2000u);
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
    const std::string svg = read_text_file(dir / "report" / "plot.svg");
    EXPECT_NE(svg.find("<svg"), std::string::npos);
}

TEST_F(Report, HtmlIsSelfContained) {
    EXPECT_EQ(html.find("http://"), std::string::npos);
    EXPECT_EQ(html.find("https://"), std::string::npos);
    EXPECT_EQ(html.find("<link"), std::string::npos);
    EXPECT_EQ(html.find("<script"), std::string::npos);
    // Every src is inline data (std::regex would recurse through the base64).
    int images = 0;
    for (std::size_t at = html.find("src=\""); at != std::string::npos; at = html.find("src=\"", at + 1)) {
        EXPECT_EQ(html.compare(at + 5, 22, "data:image/png;base64,"), 0);
        ++images;
    }
    EXPECT_EQ(images, 1);
}

TEST_F(Report, HtmlTagsAreBalanced) {
    // A small parser: every non-void element closed in order.
    const std::vector<std::string> void_elements = {"meta", "img", "br", "hr", "link", "input"};
    std::vector<std::string> stack;
    for (std::size_t at = html.find('<'); at != std::string::npos; at = html.find('<', at + 1)) {
        const std::size_t end = html.find('>', at);
        ASSERT_NE(end, std::string::npos);
        std::string inside = html.substr(at + 1, end - at - 1);
        if (inside.empty() || inside[0] == '!') continue;
        const bool closing = inside[0] == '/';
        if (closing) inside.erase(0, 1);
        std::size_t name_end = 0;
        while (name_end < inside.size() && std::isalnum(static_cast<unsigned char>(inside[name_end]))) ++name_end;
        ASSERT_GT(name_end, 0u) << "bad tag <" << inside << ">";
        const std::string name = inside.substr(0, name_end);
        const std::string rest = inside.substr(name_end);
        if (closing) {
            ASSERT_FALSE(stack.empty()) << "unexpected </" << name << ">";
            ASSERT_EQ(stack.back(), name) << "</" << name << "> closes <" << stack.back() << ">";
            stack.pop_back();
        } else if (std::find(void_elements.begin(), void_elements.end(), name) == void_elements.end() &&
                   (rest.empty() || rest.back() != '/')) {
            stack.push_back(name);
        }
    }
    EXPECT_TRUE(stack.empty()) << "unclosed <" << (stack.empty() ? "" : stack.back()) << ">";
    EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
    // xmllint, when installed, must accept it as well-formed markup.
    if (std::system("command -v xmllint >/dev/null 2>&1") == 0) {
        const std::string cmd = "xmllint --noout '" + (dir / "report" / "index.html").string() + "' 2>/dev/null";
        EXPECT_EQ(std::system(cmd.c_str()), 0);
    }
}

TEST_F(Report, HtmlNumbersEqualAnovaJson) {
    int compared = 0;
    const std::string key = "data-key=\"", value = "\" data-value=\"";
    for (std::size_t at = html.find(key); at != std::string::npos; at = html.find(key, at + 1)) {
        const std::size_t key_end = html.find('"', at + key.size());
        const std::string pointer = html.substr(at + key.size(), key_end - at - key.size());
        if (html.compare(key_end, value.size(), value) != 0) continue;  // the APA paragraph
        const std::size_t v0 = key_end + value.size();
        SCOPED_TRACE(pointer);
        const auto shown = nlohmann::json::parse(html.substr(v0, html.find('"', v0) - v0));
        const auto& stored = doc.at(nlohmann::json::json_pointer(pointer));
        if (stored.is_null()) {
            EXPECT_TRUE(shown.is_null());
        } else {
            EXPECT_EQ(shown.get<double>(), stored.get<double>());
        }
        ++compared;
    }
    EXPECT_GT(compared, 150);  // ANOVA, sphericity, 6 descriptives, 15 pairs
    // The values stored are the computed ones.
    EXPECT_EQ(doc["anova"]["F"].get<double>(), *result.anova.F);
    EXPECT_EQ(doc["anova"]["p"].get<double>(), *result.anova.p_value);
    EXPECT_EQ(doc["sphericity"]["huynh_feldt"]["epsilon"].get<double>(), *result.anova.huynh_feldt.epsilon);
    // The APA line shown is the stored one, built from the stored numbers.
    const std::string apa = doc["apa"].get<std::string>();
    std::string apa_html;
    for (char c : apa) apa_html += c == '<' ? std::string("&lt;") : std::string(1, c);
    EXPECT_NE(html.find(apa_html), std::string::npos);
    char expected[128];
    std::snprintf(expected, sizeof expected, "F(5, 120) = %.2f, p < .001", doc["anova"]["F"].get<double>());
    EXPECT_EQ(apa.rfind(expected, 0), 0u) << apa;
}

TEST_F(Report, GlmerScriptFitsTheKeywordModel) {
    const std::string r = read_text_file(dir / "report" / "glmer.R");
    EXPECT_NE(r.find("glmer(correct ~ condition + (1 | subject) + (1 | sentence)"), std::string::npos);
    EXPECT_NE(r.find("family = binomial"), std::string::npos);
    EXPECT_NE(r.find(R"(levels = c("c1", "c2", "c3", "c4", "c5", "c6"))"), std::string::npos);
}

TEST(ReportSphericity, HuynhFeldtWithTwoSubjectsIsNotEstimableNotNan) {
    // Two subjects, three conditions: one non-zero eigenvalue, HF's formula is 0/0.
    const auto data = make_within_data({"a", "b"}, {"x", "y", "z"}, {10, 30, 20, 40, 35, 70});
    const AnalysisResult r = analyze(data);
    EXPECT_FALSE(r.anova.huynh_feldt.epsilon.has_value());
    ASSERT_TRUE(r.anova.greenhouse_geisser.epsilon.has_value());
    const fs::path dir = test::temp_dir("report_hf_n2");
    ReportSettings s;
    s.out_dir = dir;
    write_report(r, s);
    for (const char* f : {"report.md", "index.html", "anova.json"}) {
        SCOPED_TRACE(f);
        std::string text = read_text_file(dir / f);
        std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
        EXPECT_FALSE(std::regex_search(text, std::regex("(^|[^a-z])-?nan([^a-z]|$)")));
    }
    EXPECT_NE(read_text_file(dir / "report.md").find("Huynh-Feldt ε not estimable with n = 2."), std::string::npos);
    fs::remove_all(dir);
}

TEST(ReportTiming, CertificateSectionAndExclusionOfFailingSubjects) {
    const fs::path dir = test::temp_dir("report_timing");
    const std::string header =
        "subject,verdict,trials,frames_total,frames_shown,dropped_frames,dropped_share,repeated_frames,offset_frames,"
        "offset_min_ms,offset_p5_ms,offset_median_ms,offset_mean_ms,offset_p95_ms,offset_max_ms,audio_leading_frames,"
        "audio_lagging_frames,outside_share,refresh_hz,output_latency_ms,audio_path_ms,tolerance_audio_lead_ms,"
        "tolerance_audio_lag_ms,tolerance_outside_share,tolerance_dropped_share,reasons\n";
    write_text_file(dir / "timing_certificate.csv",
                    header +
                        "s01,pass,90,3600,3598,2,0.0006,0,3598,-49.0,-40.2,-23.1,-23.5,-8.0,10.0,0,0,0.0000,59.880,"
                        "32.000,36.300,45,125,0.05,0.05,\n"
                        "s02,fail,90,3600,3600,0,0.0000,0,3600,30.0,50.0,60.0,60.0,70.0,80.0,3600,0,1.0000,60.000,,,45,"
                        "125,0.05,0.05,\"100.0 % of frames outside [-125, +45] ms\"\n");
    AnalyzeSettings s;
    s.input = AVSI_TEST_DATA_DIR "/analysis/balanced.csv";
    s.out_dir = dir / "kept";
    s.timing_certificate = dir / "timing_certificate.csv";
    const auto kept = analyze_file(s);
    ASSERT_TRUE(kept.has_value());
    EXPECT_EQ(kept->anova.n, 25u);
    const std::string md = read_text_file(dir / "kept" / "report.md");
    EXPECT_NE(md.find("## Presentation timing (online)"), std::string::npos);
    EXPECT_NE(md.find("| s01 | pass | 90 | -23.1 | -40.2 … -8.0 | -49.0 … 10.0 | 0.0 | 2 of 3600 (0.1 %) | 59.88 | 32.0 |"),
              std::string::npos)
        << md;
    EXPECT_NE(md.find("| s02 | fail |"), std::string::npos);
    EXPECT_NE(md.find("not reported"), std::string::npos);
    EXPECT_NE(md.find("No subject was excluded for timing."), std::string::npos);
    EXPECT_NE(read_text_file(dir / "kept" / "index.html").find("<h2>Presentation timing (online)</h2>"), std::string::npos);

    s.out_dir = dir / "excluded";
    s.exclude_timing_fail = true;
    const auto excluded = analyze_file(s);
    ASSERT_TRUE(excluded.has_value());
    EXPECT_EQ(excluded->anova.n, 24u);
    EXPECT_NE(read_text_file(dir / "excluded" / "report.md").find("(--exclude-timing-fail): subject s02."),
              std::string::npos);

    // A damaged certificate file is an input error at its line.
    write_text_file(dir / "bad.csv", header + "s01,maybe,90,3600,3598,2,x,0,3598,0,0,0,0,0,0,0,0,0,60,,,45,125,0.05,0.05,\n");
    s.timing_certificate = dir / "bad.csv";
    try {
        analyze_file(s);
        ADD_FAILURE() << "a bad certificate was read";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("bad.csv:2:1: error: verdict: expected pass, fail or unknown, got \"maybe\""), std::string::npos) << what;
        EXPECT_NE(what.find("dropped_share: expected a number, got \"x\""), std::string::npos) << what;
    }
    fs::remove_all(dir);
}

TEST(Apa, FormatsLikeThePaper) {
    AnovaResult a;
    a.df_conditions = 5;
    a.df_error = 120;
    a.F = 9.1312;
    a.p_value = 2.1e-7;
    a.partial_eta_sq = 0.2747;
    EXPECT_EQ(apa_anova(a), "F(5, 120) = 9.13, p < .001, ηp² = .27");
    a.p_value = 0.0321;
    EXPECT_EQ(apa_anova(a), "F(5, 120) = 9.13, p = .032, ηp² = .27");
    EXPECT_EQ(table_p(2.5e-150), "2.50e-150");
}

TEST(AnalyzeFile, RefusesSessionDatabaseWithAdvice) {
    const fs::path dir = test::temp_dir("analyze_refuse");
    const fs::path db = dir / "session.sqlite";
    write_text_file(db, std::string("SQLite format 3\0rest-of-header-bytes", 36));
    AnalyzeSettings s;
    s.input = db;
    s.out_dir = dir / "report";
    try {
        analyze_file(s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("avsi export"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("avsi score"), std::string::npos);
    }
    EXPECT_FALSE(fs::exists(s.out_dir));
    fs::remove_all(dir);
}

TEST(AnalyzeFile, OneSubjectDryRunGivesPilotReportWithPooledPercent) {
    const fs::path dir = test::temp_dir("analyze_pilot");
    write_text_file(dir / "scores.csv",
                    "subject,condition,keywords,correct,percent\n"
                    "s01,audio,45,9,20\n"
                    "s01,face,45,18,40\n"
                    "s02,audio,45,27,60\n");  // s02 has no face score: not complete
    AnalyzeSettings s;
    s.input = dir / "scores.csv";
    s.out_dir = dir / "report";
    EXPECT_FALSE(analyze_file(s).has_value());
    const std::string csv = read_text_file(dir / "report" / "descriptives.csv");
    // audio pools s01 and s02: 36 of 90 keywords = 40 %; face: s01 only.
    EXPECT_NE(csv.find("audio,2,90,36,40\n"), std::string::npos) << csv;
    EXPECT_NE(csv.find("face,1,45,18,40\n"), std::string::npos) << csv;
    const std::string md = read_text_file(dir / "report" / "report.md");
    EXPECT_NE(md.find("No repeated-measures ANOVA"), std::string::npos);
    EXPECT_NE(md.find("has 1 (2 subjects in all)"), std::string::npos) << md;
    EXPECT_TRUE(fs::exists(dir / "report" / "index.html"));
    EXPECT_FALSE(fs::exists(dir / "report" / "anova.json"));
    fs::remove_all(dir);
}

TEST(AnalyzeFile, ConditionsListOrdersAndSelectsTheAnalysedConditions) {
    const fs::path dir = test::temp_dir("analyze_order");
    write_text_file(dir / "scores.csv",
                    "subject,condition,keywords,correct,percent\n"
                    "s01,rule,45,30,66.7\ns01,audio,45,20,44.4\ns01,face,45,25,55.6\n"
                    "s02,rule,45,33,73.3\ns02,audio,45,18,40\ns02,face,45,27,60\n"
                    "s03,rule,45,28,62.2\ns03,audio,45,24,53.3\ns03,face,45,22,48.9\n");
    AnalyzeSettings s;
    s.input = dir / "scores.csv";
    s.out_dir = dir / "report";
    const auto all = analyze_file(s);
    ASSERT_TRUE(all.has_value());
    EXPECT_EQ(all->data.conditions, (std::vector<std::string>{"rule", "audio", "face"}));  // file order

    s.conditions = {"audio", "rule"};
    const auto two = analyze_file(s);
    ASSERT_TRUE(two.has_value());
    EXPECT_EQ(two->data.conditions, (std::vector<std::string>{"audio", "rule"}));
    ASSERT_EQ(two->descriptives.size(), 2u);
    EXPECT_EQ(two->descriptives[0].condition, "audio");
    EXPECT_NEAR(two->descriptives[0].mean, (44.4 + 40 + 53.3) / 3, 1e-9);
    EXPECT_EQ(two->anova.df_conditions, 1.0);

    s.conditions = {"audio", "rulle", "audio"};
    s.conditions_source = "study.toml";
    try {
        analyze_file(s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("study.toml"), std::string::npos) << what;
        EXPECT_NE(what.find("did you mean 'rule'"), std::string::npos) << what;
        EXPECT_NE(what.find("'audio' is listed twice"), std::string::npos) << what;
    }
    fs::remove_all(dir);
}

TEST(AnalyzeFile, OneConditionIsStillAnError) {
    const fs::path dir = test::temp_dir("analyze_onecond");
    write_text_file(dir / "scores.csv", "subject,condition,keywords,correct,percent\ns01,audio,45,9,20\n");
    AnalyzeSettings s;
    s.input = dir / "scores.csv";
    s.out_dir = dir / "report";
    EXPECT_THROW(analyze_file(s), InputError);
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi::analysis
