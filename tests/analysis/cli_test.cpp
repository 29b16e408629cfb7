// End-to-end: `avsi score`, `avsi analyze` and `avsi power` through the
// executable (skipped when it has not been built).
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "avsi/core/csv.h"
#include "avsi/core/files.h"

namespace {

namespace fs = std::filesystem;

struct CliRun {
    int code = -1;
    std::string output;  // stdout + stderr
};

CliRun run_cli(const std::string& args) {
    CliRun r;
    const std::string cmd = std::string(AVSI_CLI_PATH) + " " + args + " 2>&1";
    FILE* pipe = ::popen(cmd.c_str(), "r");
    if (!pipe) return r;
    char buffer[4096];
    while (std::size_t got = std::fread(buffer, 1, sizeof buffer, pipe)) r.output.append(buffer, got);
    const int status = ::pclose(pipe);
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

class Cli : public ::testing::Test {
protected:
    void SetUp() override {
        if (!fs::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
        dir = fs::temp_directory_path() / (std::to_string(::getpid()) + "_avsi_analysis_cli_test");
        fs::remove_all(dir);
        fs::create_directories(dir);
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

    const CliRun score = run_cli(fmt::format("score --corpus {0}/sentences.csv --responses {0}/responses.csv --out {0}/out",
                                      dir.string()));
    ASSERT_EQ(score.code, 0) << score.output;
    const auto scores = avsi::read_csv(dir / "out" / "scores.csv");
    EXPECT_EQ(scores.rows.size(), 8u);

    const CliRun analyze = run_cli(fmt::format("analyze {0}/out/scores.csv --out {0}/report", dir.string()));
    ASSERT_EQ(analyze.code, 0) << analyze.output;
    EXPECT_NE(analyze.output.find("F(1, 3) = "), std::string::npos) << analyze.output;
    EXPECT_TRUE(fs::exists(dir / "report" / "index.html"));
    // glmer.R points at the keywords.csv beside scores.csv.
    EXPECT_NE(avsi::read_text_file(dir / "report" / "glmer.R").find((dir / "out" / "keywords.csv").string()),
              std::string::npos);
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
    const CliRun r = run_cli(fmt::format("analyze {0}/scores.csv --out {0}/report --protocol {1}/beskow2004-en.toml",
                                         dir.string(), AVSI_PROTOCOLS_DIR));
    ASSERT_EQ(r.code, 0) << r.output;
    const std::string md = avsi::read_text_file(dir / "report" / "report.md");
    std::size_t previous = 0;
    for (const char* name : {"| audio-only |", "| cohen-massaro |", "| ohman |", "| ann1 |", "| ann2 |", "| rule |"}) {
        const std::size_t at = md.find(name);
        ASSERT_NE(at, std::string::npos) << name << " not in\n" << md;
        EXPECT_GT(at, previous) << name << " out of the protocol's order in\n" << md;
        previous = at;
    }
    const CliRun both = run_cli(fmt::format("analyze {0}/scores.csv --out {0}/r2 --conditions rule,ohman --protocol {1}/beskow2004-en.toml",
                                            dir.string(), AVSI_PROTOCOLS_DIR));
    EXPECT_NE(both.code, 0) << both.output;
    const CliRun typo = run_cli(fmt::format("analyze {0}/scores.csv --out {0}/r3 --conditions rule,ohmann", dir.string()));
    EXPECT_EQ(typo.code, 1) << typo.output;
    EXPECT_NE(typo.output.find("did you mean 'ohman'"), std::string::npos) << typo.output;
    EXPECT_FALSE(fs::exists(dir / "r3"));
}

TEST_F(Cli, AnalyzeRefusesDatabase) {
    avsi::write_text_file(dir / "session.db", std::string("SQLite format 3\0........", 24));
    const CliRun r = run_cli(fmt::format("analyze {0}/session.db --out {0}/report", dir.string()));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.output.find("avsi export"), std::string::npos) << r.output;
}

TEST_F(Cli, PowerIsLabelledSimulation) {
    const CliRun r = run_cli(fmt::format("power --means 50,60,70 --subjects 6,12 --sentences-per-cell 4 --sims 20 --seed 3 "
                                  "--contrast 2-1 --out {}/power",
                                  dir.string()));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("Power by simulation"), std::string::npos);
    EXPECT_NE(r.output.find("c2 - c1"), std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "power" / "power.csv"));
    const CliRun bad = run_cli("power --means 50,150");
    EXPECT_EQ(bad.code, 1);
    EXPECT_NE(bad.output.find("--means"), std::string::npos) << bad.output;
}

}  // namespace
