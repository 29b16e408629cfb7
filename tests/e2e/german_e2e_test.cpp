// A German study end to end (issue 41): a tiny protocol in the layout of
// protocols/german-small.toml (espeak-ng's German voice, the German models of
// protocols/models/de/, 3-band vocoder) at 64×48 builds its stimulus set
// (verified against the manifest), `avsi design` plans three subjects, and
// typed answers written for those plans are scored by `avsi score` with
// German's tables: umlaut and ß typed as ae/ss, a digit for a number word, a
// compound typed apart (split_compounds = "strict"), and a real-word
// neighbour not credited.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

std::string quote(const fs::path& p) { return test::shell_quote(p.string()); }

// What each subject types for each sentence, and the rule each keyword is
// then credited by under strict ("none": not credited).
struct Answer {
    std::string typed;
    std::vector<std::string> rules;
};
const std::map<std::string, Answer>& answers() {
    static const std::map<std::string, Answer> a{
        {"g1", {"der junge isst 5 aepfel", {"exact", "number", "variant"}}},
        {"g2", {"die strasse ist heute nase", {"variant", "exact", "none"}}},    // Nase: a real word, not nass
        {"g3", {"mein vater schliesst die haus tür", {"exact", "variant", "compound"}}},
        {"g4", {"die kinder spielen", {}}},  // the warm-up: not scored
    };
    return a;
}

std::string protocol_text() {
    const fs::path models = fs::path(AVSI_PROTOCOLS_DIR) / "models" / "de";
    return fmt::format(
        "[experiment]\nname = \"german-e2e\"\nseed = 41\n\n"
        "[corpus]\nsentences = \"corpus.csv\"\naudio = \"tts\"\ntts = \"espeak:de\"\nlevel_dbfs = -26\n\n"
        "[[condition]]\nname = \"audio-only\"\nface = \"still\"\n\n"
        "[[condition]]\nname = \"cohen-massaro\"\nmodel = \"{}\"\n\n"
        "[[condition]]\nname = \"rule\"\nmodel = \"{}\"\n\n"
        "[vocoder]\nbands = 3\nlow_hz = 100\nhigh_hz = 5000\n\n"
        "[design]\nlists = 3\nsentences_per_list = 1\nwarmup = 1\nwarmup_condition = \"audio-only\"\n"
        "practice = 0\ncounterbalance = \"latin-square\"\n\n"
        "[render]\nfps = 30\nwidth = 64\nheight = 48\n\n"
        "[scoring]\nrules = \"strict\"\nsplit_compounds = \"strict\"\n",
        (models / "cohen-massaro.json").string(), (models / "rule.json").string());
}

TEST(GermanStudy, BuildsPlansAndScoresInGerman) {
    const fs::path dir = test::temp_dir("e2e_german");
    write_text_file(dir / "corpus.csv",
                    "id,text,keywords,list\n"
                    "g1,Der Junge isst fünf Äpfel.,Junge;fünf;Äpfel,1\n"
                    "g2,Die Straße ist heute nass.,Straße;heute;nass,2\n"
                    "g3,Mein Vater schließt die Haustür.,Vater;schließt;Haustür,3\n"
                    "g4,Die Kinder spielen im Garten.,Kinder;spielen;Garten,warmup\n");
    write_text_file(dir / "german.toml", protocol_text());

    const test::CliResult build = test::run_avsi("build-stimuli " + quote(dir / "german.toml") + " --out " +
                                                 quote(dir / "stimuli") + " --jobs 1");
    ASSERT_EQ(build.exit_code, 0) << build.output();
    const test::CliResult verify = test::run_avsi("build-stimuli " + quote(dir / "german.toml") + " --out " +
                                                  quote(dir / "stimuli") + " --verify");
    ASSERT_EQ(verify.exit_code, 0) << verify.output();
    const auto manifest = nlohmann::json::parse(read_text_file(dir / "stimuli" / "manifest.json"));
    // 3 test sentences × 3 conditions, and the warm-up sentence audio only.
    EXPECT_GE(manifest["stimuli"].size(), 10u);
    for (const auto& e : manifest["stimuli"]) {
        SCOPED_TRACE(e.dump());
        EXPECT_TRUE(fs::is_regular_file(dir / "stimuli" / std::string(e["path"])));
        EXPECT_GT(double(e["duration_s"]), 0.5);
    }

    const test::CliResult design = test::run_avsi("design " + quote(dir / "german.toml") + " --subjects 3 --out " +
                                                  quote(dir / "lists.csv"));
    ASSERT_EQ(design.exit_code, 0) << design.output();
    const CsvTable lists = read_csv(dir / "lists.csv");
    std::string responses = "subject,session,trial,phase,condition,list,sentence,response\n";
    int test_trials = 0;
    for (const auto& row : lists.rows) {
        const auto field = [&](const char* column) { return row.fields[lists.require_column(column)]; };
        test_trials += field("phase") == "test";
        responses += fmt::format("{},1,{},{},{},{},{},{}\n", field("subject"), field("position"), field("phase"),
                                 field("condition"), field("list"), field("sentence"),
                                 answers().at(field("sentence")).typed);
    }
    ASSERT_EQ(test_trials, 9);  // each subject hears each test sentence, in a condition of the Latin square
    write_text_file(dir / "responses.csv", responses);

    const test::CliResult score = test::run_avsi("score --protocol " + quote(dir / "german.toml") + " --responses " +
                                                 quote(dir / "responses.csv") + " --out " + quote(dir / "scores"));
    ASSERT_EQ(score.exit_code, 0) << score.output();
    const CsvTable keywords = read_csv(dir / "scores" / "keywords.csv");
    ASSERT_EQ(keywords.rows.size(), 27u);  // 9 test trials × 3 keywords; the warm-up is not scored
    for (const auto& row : keywords.rows) {
        const auto field = [&](const char* column) { return row.fields[keywords.require_column(column)]; };
        const Answer& a = answers().at(field("sentence"));
        const std::string& expected = a.rules.at(std::stoul(field("keyword_index")) - 1);  // 1-based
        SCOPED_TRACE(field("sentence") + " " + field("keyword") + " <- " + field("response"));
        EXPECT_EQ(field("rule_set"), "strict");
        EXPECT_EQ(field("correct"), expected == "none" ? "0" : "1");
        if (expected != "none") {
            EXPECT_EQ(field("rule"), expected);
        }
    }
    // Per subject and condition one sentence: 8 of 9 keywords over the three.
    const CsvTable scores = read_csv(dir / "scores" / "scores.csv");
    ASSERT_EQ(scores.rows.size(), 9u);
    std::map<std::string, int> correct;
    for (const auto& row : scores.rows)
        correct[row.fields[scores.require_column("subject")]] += std::stoi(row.fields[scores.require_column("correct")]);
    for (const auto& [subject, n] : correct) EXPECT_EQ(n, 8) << subject;
    // The compound typed apart is in the audit as a strict credit.
    const std::string audit = read_text_file(dir / "scores" / "audit.csv");
    EXPECT_NE(audit.find("Haustür,haus tür,compound,strict,1"), std::string::npos) << audit;
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi
