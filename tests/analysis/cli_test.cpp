// End-to-end: `avsi score`, `avsi analyze` and `avsi power` through the
// executable (skipped when it has not been built).

#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <gtest/gtest.h>

#include "avsi/core/corpus.h"
#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace {

namespace fs = std::filesystem;

using avsi::test::CliResult;
using avsi::test::run_avsi;

class Cli : public ::testing::Test {
protected:
    void SetUp() override {
        if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
        dir = avsi::test::temp_dir("analysis_cli_test");
    }
    void TearDown() override { fs::remove_all(dir); }
    fs::path dir;
};

TEST_F(Cli, ScoreThenAnalyze) {
    // 4 subjects × 2 conditions × 2 sentences.
    avsi::write_text_file(dir / "sentences.csv",
                          "id,text,keywords\n"
                          "s1,\"The dog barked at the mailman.\",\"dog;barked;mailman|postman\"\n"
                          "s2,\"Seven kittens slept in the kitchen.\",\"seven;kittens;kitchen\"\n"
                          "s3,\"A red car stopped by the gate.\",\"red;car;gate\"\n"
                          "s4,\"Her brother sold the old boat.\",\"brother;sold;boat\"\n");
    std::string responses = "subject,session,trial,phase,condition,list,sentence,response\n";
    const char* answers[4][4] = {{"dog barked mailman", "7 kittens kitchen", "red car", "brother"},
                                 {"the dog", "seven kitten", "red car gate", "brother sold boat"},
                                 {"dog barking postman", "kittens", "a car", "sold a boat"},
                                 {"", "seven kittens in the kitchne", "red", "brother boat"}};
    for (int s = 0; s < 4; ++s)
        for (int t = 0; t < 4; ++t)
            responses += fmt::format("p{},1,{},test,{},{},s{},\"{}\"\n", s + 1, t + 1,
                                     (t + s) % 2 ? "face" : "audio", t % 2 + 1, t + 1, answers[s][t]);
    avsi::write_text_file(dir / "responses.csv", responses);

    const CliResult score = run_avsi(fmt::format("score --corpus {0}/sentences.csv --responses {0}/responses.csv --out {0}/out",
                                      dir.string()));
    ASSERT_EQ(score.exit_code, 0) << score.output();
    const auto scores = avsi::read_csv(dir / "out" / "scores.csv");
    EXPECT_EQ(scores.rows.size(), 8u);

    const CliResult analyze = run_avsi(fmt::format("analyze {0}/out/scores.csv --out {0}/report", dir.string()));
    ASSERT_EQ(analyze.exit_code, 0) << analyze.output();
    EXPECT_NE(analyze.output().find("F(1, 3) = "), std::string::npos) << analyze.output();
    EXPECT_TRUE(fs::exists(dir / "report" / "index.html"));
    // glmer.R points at the keywords.csv beside scores.csv.
    EXPECT_NE(avsi::read_text_file(dir / "report" / "glmer.R").find((dir / "out" / "keywords.csv").string()),
              std::string::npos);
}

TEST_F(Cli, ScoreSwedishTakesTheLanguageFromTheProtocolVoice) {
    // A Swedish protocol (espeak:sv) with split compounds credited under
    // strict: scores.csv counts them, audit.csv shows them as "compound";
    // the definite form is in audit.csv only as a loose credit.
    avsi::write_text_file(dir / "sentences.csv",
                          "id,text,keywords\n"
                          "s1,Pojken tappade sin bilnyckel.,pojken;tappade;bilnyckel\n"
                          "s2,Fem bilar stod i garaget.,fem;bilar;garaget\n");
    avsi::write_text_file(dir / "study.toml",
                          "[experiment]\nname = \"sv-test\"\n[corpus]\nsentences = \"sentences.csv\"\n"
                          "tts = \"espeak:sv\"\n[[condition]]\nname = \"audio-only\"\nface = \"still\"\n"
                          "[design]\nlists = 1\nsentences_per_list = 2\nwarmup = 0\npractice = 0\n"
                          "[scoring]\nrules = \"strict\"\nsplit_compounds = \"strict\"\n");
    avsi::write_text_file(dir / "responses.csv",
                          "subject,session,trial,phase,condition,list,sentence,response\n"
                          "p1,1,1,test,audio-only,1,s1,pojken tappade sin bil nyckel\n"
                          "p1,1,2,test,audio-only,1,s2,5 bilen stod i garage\n");
    const CliResult score = run_avsi(fmt::format("score --protocol {0}/study.toml --responses {0}/responses.csv --out {0}/out",
                                                 dir.string()));
    ASSERT_EQ(score.exit_code, 0) << score.output();
    const auto scores = avsi::read_csv(dir / "out" / "scores.csv");
    ASSERT_EQ(scores.rows.size(), 1u);
    // pojken, tappade, bil nyckel (compound), 5 (number); bilen (loose only), garage (not garaget) wrong.
    EXPECT_EQ(scores.rows[0].fields[scores.require_column("correct")], "4");
    const std::string audit = avsi::read_text_file(dir / "out" / "audit.csv");
    EXPECT_NE(audit.find("bilnyckel,bil nyckel,compound,strict,1"), std::string::npos) << audit;
    EXPECT_NE(audit.find("fem,5,number,strict,1"), std::string::npos) << audit;
    EXPECT_NE(audit.find("bilar,bilen,inflection,loose,0"), std::string::npos) << audit;

    // --language overrides; an unknown one is a usage error naming the choices.
    const CliResult fr = run_avsi(fmt::format("score --protocol {0}/study.toml --responses {0}/responses.csv --out {0}/fr "
                                              "--language fr",
                                              dir.string()));
    EXPECT_EQ(fr.exit_code, 2) << fr.output();
    EXPECT_NE(fr.output().find("sv"), std::string::npos) << fr.output();
}

TEST_F(Cli, AnalyzeTakesTheConditionOrderFromTheProtocol) {
    // Scores in session order (rule first); the report follows the protocol's [[condition]] order.
    const std::vector<std::string> session_order = {"rule", "ann2", "audio-only", "ohman", "cohen-massaro", "ann1"};
    std::string scores = "subject,condition,keywords,correct,percent\n";
    for (int s = 1; s <= 3; ++s)
        for (std::size_t c = 0; c < session_order.size(); ++c)
            scores += fmt::format("p{},{},45,{},{}\n", s, session_order[c], 20 + 3 * int(c) + s,
                                  100.0 * (20 + 3 * int(c) + s) / 45.0);
    avsi::write_text_file(dir / "scores.csv", scores);
    const CliResult r = run_avsi(fmt::format("analyze {0}/scores.csv --out {0}/report --protocol {1}/beskow2004-en.toml",
                                         dir.string(), AVSI_PROTOCOLS_DIR));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const std::string md = avsi::read_text_file(dir / "report" / "report.md");
    std::size_t previous = 0;
    for (const char* name : {"| audio-only |", "| cohen-massaro |", "| ohman |", "| ann1 |", "| ann2 |", "| rule |"}) {
        const std::size_t at = md.find(name);
        ASSERT_NE(at, std::string::npos) << name << " not in\n" << md;
        EXPECT_GT(at, previous) << name << " out of the protocol's order in\n" << md;
        previous = at;
    }
    const CliResult both = run_avsi(fmt::format("analyze {0}/scores.csv --out {0}/r2 --conditions rule,ohman --protocol {1}/beskow2004-en.toml",
                                            dir.string(), AVSI_PROTOCOLS_DIR));
    EXPECT_NE(both.exit_code, 0) << both.output();
    const CliResult typo = run_avsi(fmt::format("analyze {0}/scores.csv --out {0}/r3 --conditions rule,ohmann", dir.string()));
    EXPECT_EQ(typo.exit_code, 1) << typo.output();
    EXPECT_NE(typo.output().find("did you mean 'ohman'"), std::string::npos) << typo.output();
    EXPECT_FALSE(fs::exists(dir / "r3"));
}

TEST_F(Cli, ScoreRuleSetsByNameAndStrictAlias) {
    avsi::write_text_file(dir / "sentences.csv",
                          "id,text,keywords\n"
                          "s1,\"The boys found the garden.\",\"boys;found;garden\"\n");
    avsi::write_text_file(dir / "responses.csv",
                          "subject,session,trial,phase,condition,list,sentence,response\n"
                          "p1,1,1,test,a,1,s1,\"the boy pound the gardne\"\n");
    const std::string base = fmt::format("score --corpus {0}/sentences.csv --responses {0}/responses.csv", dir.string());
    // boy: inflection (loose); pound: never; gardne: non-word typo (lenient).
    const std::vector<std::pair<std::string, std::string>> expected = {
        {"--rules strict", "0"}, {"--strict", "0"}, {"--rules loose", "1"}, {"--rules lenient", "2"}, {"", "0"}};
    for (const auto& [option, correct] : expected) {
        SCOPED_TRACE(option);
        const CliResult r = run_avsi(base + " --out " + (dir / "o").string() + " " + option);
        ASSERT_EQ(r.exit_code, 0) << r.output();
        const auto scores = avsi::read_csv(dir / "o" / "scores.csv");
        ASSERT_EQ(scores.rows.size(), 1u);
        EXPECT_EQ(scores.rows[0].fields[scores.require_column("correct")], correct);
        const std::string set = option.empty() ? "strict" : option == "--strict" ? "strict" : option.substr(8);
        EXPECT_EQ(scores.rows[0].fields[scores.require_column("rule_set")], set);
        EXPECT_NE(r.output().find("with the " + set + " rule set"), std::string::npos) << r.output();
    }
    const CliResult typo = run_avsi(base + " --out " + (dir / "x").string() + " --rules lose");
    EXPECT_EQ(typo.exit_code, 2) << typo.output();
    EXPECT_NE(typo.output().find("did you mean \"loose\""), std::string::npos) << typo.output();
    const CliResult both = run_avsi(base + " --out " + (dir / "x").string() + " --strict --rules loose");
    EXPECT_EQ(both.exit_code, 2) << both.output();
    EXPECT_FALSE(fs::exists(dir / "x"));
}

TEST_F(Cli, ScoreAgreementWithASecondScorer) {
    avsi::write_text_file(dir / "sentences.csv",
                          "id,text,keywords\n"
                          "s1,\"The boys found the garden.\",\"boys;found;garden\"\n");
    avsi::write_text_file(dir / "responses.csv",
                          "subject,session,trial,phase,condition,list,sentence,response\n"
                          "p1,1,1,test,a,1,s1,\"the boy pound the gardne\"\n");
    // The second scorer credits only the misspelt garden.
    avsi::write_text_file(dir / "second.csv", "subject,trial,keyword_index,correct\np1,1,1,0\np1,1,2,0\np1,1,3,1\n");
    const CliResult r = run_avsi(fmt::format("score --corpus {0}/sentences.csv --responses {0}/responses.csv --out {0}/o "
                                         "--agreement {0}/second.csv",
                                         dir.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("Cohen's kappa"), std::string::npos) << r.output();
    const auto agreement = avsi::read_csv(dir / "o" / "agreement.csv");
    ASSERT_EQ(agreement.rows.size(), 3u);
    // strict: 0 0 0 vs 0 0 1 -> 2 of 3 agree, kappa NA (the automatic side has one verdict throughout).
    EXPECT_EQ(agreement.rows[0].fields[agreement.require_column("agreements")], "2");
    EXPECT_EQ(agreement.rows[0].fields[agreement.require_column("kappa")], "NA");
    // lenient: 1 0 1 vs 0 0 1 -> 2 of 3; pa = 2/3, pb = 1/3, pe = 2/9 + 2/9 = 4/9, kappa = (6/9-4/9)/(5/9) = 0.4.
    EXPECT_EQ(agreement.rows[2].fields[agreement.require_column("kappa")], "0.400000");
    EXPECT_EQ(avsi::read_csv(dir / "o" / "disagreements.csv").rows.size(), 1u + 2u + 1u);
}

// The default protocol's dry run, scoring and report part: lists from `avsi
// design` for one subject, typed answers with an inflection slip and a
// misspelling, `avsi score --protocol`, `avsi analyze`. The rule set the
// protocol names is in scores.csv, keywords.csv and the report.
TEST_F(Cli, DefaultProtocolDryRunReportsItsRuleSet) {
    const std::string protocol = std::string(AVSI_PROTOCOLS_DIR) + "/beskow2004-en.toml";
    const CliResult design = run_avsi(fmt::format("design {} --subjects 1 --out {}/lists.csv", protocol, dir.string()));
    ASSERT_EQ(design.exit_code, 0) << design.output();
    const auto corpus = avsi::read_corpus(std::string(AVSI_PROTOCOLS_DIR) + "/corpus/sentences.csv");
    const auto lists = avsi::read_csv(dir / "lists.csv");
    std::string responses = "subject,session,trial,phase,condition,list,sentence,response\n";
    int trial = 0, test_trials = 0;
    for (const auto& row : lists.rows) {
        const std::string phase = row.fields[lists.require_column("phase")];
        const std::string id = row.fields[lists.require_column("sentence")];
        std::string answer = corpus.sentence(id).text;
        ++trial;
        if (phase == "test" && ++test_trials % 3 == 1) {
            // Misspell the last keyword by swapping its last two letters.
            std::string k = corpus.sentence(id).keywords.back().word;
            const auto at = answer.find(k);
            if (at != std::string::npos && k.size() >= 5) std::swap(answer[at + k.size() - 1], answer[at + k.size() - 2]);
        }
        std::erase(answer, '"');
        responses += fmt::format("1,1,{},{},{},{},{},\"{}\"\n", trial, phase, row.fields[lists.require_column("condition")],
                                 row.fields[lists.require_column("list")], id, answer);
    }
    avsi::write_text_file(dir / "responses.csv", responses);
    const CliResult score = run_avsi(fmt::format("score --protocol {} --responses {}/responses.csv --out {}/scores", protocol,
                                             dir.string(), dir.string()));
    ASSERT_EQ(score.exit_code, 0) << score.output();
    EXPECT_NE(score.output().find("with the strict rule set"), std::string::npos) << score.output();
    const auto scores = avsi::read_csv(dir / "scores" / "scores.csv");
    ASSERT_EQ(scores.rows.size(), 6u);
    for (const auto& row : scores.rows) EXPECT_EQ(row.fields[scores.require_column("rule_set")], "strict");
    const auto audit = avsi::read_csv(dir / "scores" / "audit.csv");
    std::size_t typos = 0;
    for (const auto& row : audit.rows)
        if (row.fields[audit.require_column("rule")] == "typo") {
            ++typos;
            EXPECT_EQ(row.fields[audit.require_column("correct")], "0");  // strict does not credit them
        }
    EXPECT_GT(typos, 10u);
    const CliResult analyze = run_avsi(fmt::format("analyze {0}/scores/scores.csv --out {0}/report --protocol {1}",
                                               dir.string(), protocol));
    ASSERT_EQ(analyze.exit_code, 0) << analyze.output();
    const std::string report = avsi::read_text_file(dir / "report" / "report.md");
    EXPECT_NE(report.find("Keywords scored with the strict rule set"), std::string::npos) << report;
    EXPECT_NE(avsi::read_text_file(dir / "report" / "index.html").find("strict rule set"), std::string::npos);
}

TEST_F(Cli, AnalyzeRefusesDatabase) {
    avsi::write_text_file(dir / "session.db", std::string("SQLite format 3\0........", 24));
    const CliResult r = run_avsi(fmt::format("analyze {0}/session.db --out {0}/report", dir.string()));
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output().find("avsi export"), std::string::npos) << r.output();
}

TEST_F(Cli, PowerIsLabelledSimulation) {
    const CliResult r = run_avsi(fmt::format("power --means 50,60,70 --subjects 6,12 --sentences-per-cell 4 --sims 20 --seed 3 "
                                  "--contrast 2-1 --out {}/power",
                                  dir.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("Power by simulation"), std::string::npos);
    EXPECT_NE(r.output().find("c2 - c1"), std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "power" / "power.csv"));
    const CliResult bad = run_avsi("power --means 50,150");
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.output().find("--means"), std::string::npos) << bad.output();
}

TEST_F(Cli, SimulateSrtPrintsBiasAndSpreadAndRefusesShortTracks) {
    const std::string protocol = std::string(AVSI_TEST_DATA_DIR) + "/adaptive/protocol.toml";
    const CliResult r = run_avsi(fmt::format("simulate-srt --protocol {} --sentences 10,20 --listeners 100 --seed 4 --out {}/sim",
                                         protocol, dir.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("SRT by simulation (100 simulated listeners per row, seed 4): sentence scoring"),
              std::string::npos)
        << r.output();
    const auto csv = avsi::read_csv(dir / "sim" / "srt_simulation.csv");
    EXPECT_EQ(csv.rows.size(), 4u);  // 2 lengths × (mean, ml)
    EXPECT_TRUE(fs::exists(dir / "sim" / "srt_simulation.png"));
    const CliResult bad = run_avsi(fmt::format("simulate-srt --protocol {} --sentences 3", protocol));
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.output().find("--sentences: expected sentence counts in [6 (srt_from + 1), 1000], got 3"),
              std::string::npos)
        << bad.output();
    const CliResult both = run_avsi(fmt::format("simulate-srt --protocol {} --procedure word", protocol));
    EXPECT_EQ(both.exit_code, 2) << both.output();
}

// Must-show of issue 39: a listener ceiling of 0.63 flags tracks and counts them;
// --include-unconverged keeps them; a ceiling outside (0, 1] is refused.
TEST_F(Cli, SimulateSrtWithACeilingCountsTheTracksItLeavesOut) {
    const CliResult r = run_avsi(fmt::format("simulate-srt --ceiling 0.63 --sentences 20 --listeners 200 --out {}/sim",
                                         dir.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("ceiling 0.630"), std::string::npos) << r.output();
    EXPECT_NE(r.output().find("is at or above the ceiling: no threshold exists"), std::string::npos) << r.output();
    const auto csv = avsi::read_csv(dir / "sim" / "srt_simulation.csv");
    ASSERT_EQ(csv.rows.size(), 2u);
    const int unconverged = std::stoi(csv.rows[0].fields[csv.require_column("unconverged")]);
    const int valid = std::stoi(csv.rows[0].fields[csv.require_column("valid")]);
    EXPECT_GT(unconverged, 20);
    EXPECT_EQ(valid, 200 - unconverged);
    EXPECT_EQ(csv.rows[0].fields[csv.require_column("true_db")], "NA");
    const CliResult kept = run_avsi(fmt::format("simulate-srt --ceiling 0.63 --sentences 20 --listeners 200 "
                                            "--include-unconverged --out {}/kept", dir.string()));
    ASSERT_EQ(kept.exit_code, 0) << kept.output();
    const auto kept_csv = avsi::read_csv(dir / "kept" / "srt_simulation.csv");
    EXPECT_EQ(kept_csv.rows[0].fields[kept_csv.require_column("valid")], "200");
    EXPECT_EQ(std::stoi(kept_csv.rows[0].fields[kept_csv.require_column("unconverged")]), unconverged);
    const CliResult bad = run_avsi("simulate-srt --ceiling 1.5");
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.output().find("--ceiling: expected a proportion in (0, 1], got 1.5"), std::string::npos) << bad.output();
}

TEST_F(Cli, AnalyzeOfAdaptiveTrialsNeedsTheProtocol) {
    avsi::write_text_file(dir / "adaptive_trials.csv",
                    "subject,condition,presentation,level_db,keywords,correct\n1,audio-only,1,0,3,3\n");
    const CliResult r = run_avsi(fmt::format("analyze {}/adaptive_trials.csv --out {}/r", dir.string(), dir.string()));
    EXPECT_EQ(r.exit_code, 2) << r.output();
    EXPECT_NE(r.output().find("--protocol"), std::string::npos) << r.output();
    const CliResult dv = run_avsi(fmt::format("analyze {}/adaptive_trials.csv --dv level_db --protocol {}/adaptive/protocol.toml",
                                          dir.string(), AVSI_TEST_DATA_DIR));
    EXPECT_EQ(dv.exit_code, 2) << dv.output();
    EXPECT_NE(dv.output().find("--dv: adaptive_trials.csv is analysed as SRTs"), std::string::npos) << dv.output();
}

TEST_F(Cli, AnalyzeAnyDependentVariableReproducesTheReferenceAnova) {
    // The reference data (tests/data/analysis/balanced.csv, R's numbers in
    // balanced.expected.json) as a lab's own long-format table: a score that
    // is not a percentage (score = 0.5 · percent − 20, negative values
    // included). F, p, the sphericity tests and their corrections do not
    // change under a linear transformation of the dependent variable.
    const avsi::CsvTable in = avsi::read_csv(fs::path(AVSI_TEST_DATA_DIR) / "analysis" / "balanced.csv");
    std::string csv = "subject,condition,score\n";
    for (const auto& row : in.rows)
        csv += row.fields[in.require_column("subject")] + "," + row.fields[in.require_column("condition")] + "," +
               fmt::format("{:.12g}", 0.5 * *avsi::parse_double(row.fields[in.require_column("percent")]) - 20.0) +
               "\n";
    avsi::write_text_file(dir / "long.csv", csv);
    const CliResult r = run_avsi("analyze " + (dir / "long.csv").string() + " --dv score --out " + (dir / "report").string());
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const auto doc = nlohmann::json::parse(avsi::read_text_file(dir / "report" / "anova.json"));
    const auto expected = nlohmann::json::parse(
        avsi::read_text_file(fs::path(AVSI_TEST_DATA_DIR) / "analysis" / "balanced.expected.json"));
    EXPECT_EQ(doc["dependent_variable"], "score");
    EXPECT_EQ(doc["anova"]["df_conditions"].get<double>(), expected["df_conditions"].get<double>());
    EXPECT_EQ(doc["anova"]["df_error"].get<double>(), expected["df_error"].get<double>());
    EXPECT_NEAR(doc["anova"]["F"].get<double>(), expected["F"].get<double>(), 1e-9);
    EXPECT_NEAR(doc["anova"]["p"].get<double>() / expected["p"].get<double>(), 1.0, 1e-6);
    EXPECT_NEAR(doc["anova"]["ss_conditions"].get<double>(), 0.25 * expected["ss_conditions"].get<double>(), 1e-6);
    EXPECT_NEAR(doc["sphericity"]["mauchly"]["W"].get<double>(), expected["mauchly_W"].get<double>(), 1e-9);
    EXPECT_NEAR(doc["sphericity"]["greenhouse_geisser"]["epsilon"].get<double>(), expected["gg_epsilon"].get<double>(),
                1e-9);
    EXPECT_NEAR(doc["anova"]["partial_eta_squared"].get<double>(), expected["pes"].get<double>(), 1e-9);
    // The default dependent variable is percent: this file has none, and says so.
    const CliResult missing = run_avsi("analyze " + (dir / "long.csv").string() + " --out " + (dir / "r2").string());
    EXPECT_EQ(missing.exit_code, 1);
    EXPECT_NE(missing.output().find("percent"), std::string::npos) << missing.output();
    // Only percent is held to [0, 100]; a non-number in the score column names file:line:column.
    avsi::write_text_file(dir / "bad.csv", "subject,condition,score\ns1,a,-3.5\ns1,b,x\n");
    const CliResult bad = run_avsi("analyze " + (dir / "bad.csv").string() + " --dv score --out " + (dir / "r3").string());
    EXPECT_EQ(bad.exit_code, 1);
    EXPECT_NE(bad.output().find("bad.csv:3:3: error: score: expected a number or NA, got \"x\""), std::string::npos)
        << bad.output();
    EXPECT_EQ(bad.output().find("bad.csv:2:"), std::string::npos) << bad.output();  // -3.5 is fine
}

}  // namespace
