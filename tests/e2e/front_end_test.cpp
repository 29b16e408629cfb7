// The light front end (issue 21, docs/cli-design.md): `avsi` links no heavy
// library and runs each command's helper executable, so that --version,
// --help and the light commands load nothing heavy; every command listed by
// --help answers `avsi <command> --help`; a missing helper is reported.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "../cli_run.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

fs::path work_dir() {
    const fs::path dir = fs::temp_directory_path() / ("avsi_e2e_front_end_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    return dir;
}

// Standard output of a shell command.
std::string output_of(const std::string& command) {
    std::string out;
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) return out;
    char buffer[4096];
    while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
    ::pclose(pipe);
    return out;
}

// The shared libraries an executable names (DT_NEEDED), from readelf.
std::vector<std::string> needed(const fs::path& executable) {
    std::vector<std::string> libraries;
    std::istringstream lines(output_of("readelf -d " + test::shell_quote(executable.string()) + " 2>/dev/null"));
    const std::regex pattern(R"(\(NEEDED\).*\[(.*)\])");
    for (std::string line; std::getline(lines, line);) {
        std::smatch m;
        if (std::regex_search(line, m, pattern)) libraries.push_back(m[1]);
    }
    return libraries;
}

// The command names `avsi --help` lists.
std::vector<std::string> listed_commands() {
    const test::CliResult r = test::run_avsi("--help", work_dir());
    std::vector<std::string> names;
    std::istringstream lines(r.out);
    bool in_list = false;
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("Subcommands:", 0) == 0) {
            in_list = true;
            continue;
        }
        std::smatch m;
        if (in_list && std::regex_search(line, m, std::regex(R"(^  ([a-z0-9-]+)\s)"))) names.push_back(m[1]);
    }
    return names;
}

const fs::path cli = AVSI_CLI_PATH;
const fs::path helpers = cli.parent_path() / "libexec";

TEST(FrontEnd, LinksNoModuleOrHeavyLibrary) {
    const std::vector<std::string> libraries = needed(cli);
    ASSERT_FALSE(libraries.empty()) << "readelf gave nothing for " << cli;
    const std::set<std::string> allowed = {"libstdc++.so.6", "libm.so.6", "libgcc_s.so.1", "libc.so.6"};
    for (const std::string& library : libraries) EXPECT_TRUE(allowed.count(library)) << cli << " needs " << library;
}

TEST(FrontEnd, LightHelpersLoadNoHeavyLibrary) {
    const std::regex heavy("torch|c10|ceres|OSMesa|GL|avcodec|avformat|swscale|glfw|portaudio|OpenImageIO|cairo|"
                           "sqlite|imgui|zip|boost",
                           std::regex::icase);
    for (const char* helper : {"avsi-speech", "avsi-audio"}) {
        const std::vector<std::string> libraries = needed(helpers / helper);
        ASSERT_FALSE(libraries.empty()) << helper;
        for (const std::string& library : libraries)
            EXPECT_FALSE(std::regex_search(library, heavy)) << helper << " needs " << library;
    }
    // The trainer does load them (the check above can fail).
    bool torch = false;
    for (const std::string& library : needed(helpers / "avsi-learn")) torch |= library.find("torch") != std::string::npos;
    EXPECT_TRUE(torch);
}

// The speech engines are loaded only by a process that speaks: espeak-ng with
// dlopen on the first utterance, Festival in its own server, avsi-festival.
// No helper links them, so `avsi synth --phones` and the rest never pay
// their 35 libraries at start-up.
TEST(FrontEnd, NoHelperLinksASpeechEngine) {
    const std::regex engine("espeak|estools|estbase|eststring|festival", std::regex::icase);
    std::size_t checked = 0;
    for (const auto& entry : fs::directory_iterator(helpers)) {
        const std::string name = entry.path().filename().string();
        if (name == "avsi-festival") continue;
        ++checked;
        for (const std::string& library : needed(entry.path()))
            EXPECT_FALSE(std::regex_search(library, engine)) << name << " needs " << library;
    }
    EXPECT_GE(checked, 7u) << "expected the helpers in " << helpers;
    // The Festival server does link them (the check above can fail).
    bool estools = false;
    for (const std::string& library : needed(helpers / "avsi-festival"))
        estools |= library.find("estools") != std::string::npos;
    EXPECT_TRUE(estools);
}

TEST(FrontEnd, VersionAndHelpComeFromTheFrontEnd) {
    const test::CliResult version = test::run_avsi("--version", work_dir());
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_EQ(version.out, "avsi 0.1.0\n");
    const test::CliResult none = test::run_avsi("", work_dir());
    EXPECT_EQ(none.exit_code, 2);
    EXPECT_NE(none.err.find("A subcommand is required"), std::string::npos) << none.err;
    // A mistyped command is not a command (CLI11 reads it as an extra argument).
    const test::CliResult typo = test::run_avsi("vocod in.wav out.wav", work_dir());
    EXPECT_EQ(typo.exit_code, 2);
    EXPECT_NE(typo.err.find("A subcommand is required"), std::string::npos) << typo.err;
}

TEST(FrontEnd, EveryListedCommandAnswersHelp) {
    const std::vector<std::string> names = listed_commands();
    // The commands of every group are there.
    for (const char* name : {"phones", "synth", "vocode", "stoi", "score", "power", "corpus", "train", "render",
                             "build-stimuli", "measure", "evaluate", "design", "export-web", "run"})
        EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name << " not listed";
    for (const std::string& name : names) {
        const test::CliResult r = test::run_avsi(name + " --help", work_dir());
        EXPECT_EQ(r.exit_code, 0) << name << ": " << r.err;
        EXPECT_NE(r.out.find("avsi " + name), std::string::npos) << name << ": " << r.out.substr(0, 200);
    }
}

// Every command a cli/cmd_*.cpp file registers (register_command({"name", …)
// is listed by `avsi --help`: none is left out of the helpers or the registry.
TEST(FrontEnd, EveryRegisteredCommandIsListed) {
    const std::vector<std::string> names = listed_commands();
    const std::regex registration(R"re(register_command\(\{\s*"([a-z0-9-]+)")re");
    std::size_t found = 0;
    for (const auto& entry : fs::directory_iterator(AVSI_CLI_SOURCE_DIR)) {
        const std::string file = entry.path().filename().string();
        if (file.rfind("cmd_", 0) != 0 || entry.path().extension() != ".cpp") continue;
        const std::string text = read_text_file(entry.path());
        for (std::sregex_iterator m(text.begin(), text.end(), registration), end; m != end; ++m, ++found)
            EXPECT_NE(std::find(names.begin(), names.end(), (*m)[1].str()), names.end())
                << (*m)[1] << " (registered in cli/" << file << ") is not listed by avsi --help";
    }
    EXPECT_GE(found, 23u) << "the pattern no longer finds the registrations in " << AVSI_CLI_SOURCE_DIR;
    EXPECT_EQ(names.size(), found);
}

TEST(FrontEnd, UsageErrorsOfACommandKeepTheirExitCode) {
    const test::CliResult r = test::run_avsi("vocode --bands 3", work_dir());
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("input is required"), std::string::npos) << r.err;
    const test::CliResult missing = test::run_avsi("stoi /nonexistent/a.wav /nonexistent/b.wav", work_dir());
    EXPECT_EQ(missing.exit_code, 2) << missing.err;
}

TEST(FrontEnd, AMissingHelperIsNamedAndAvsiExecPathFindsIt) {
    const fs::path dir = work_dir() / "alone";
    fs::create_directories(dir);
    const fs::path copy = dir / "avsi";
    fs::copy_file(cli, copy, fs::copy_options::overwrite_existing);
    const std::string command = test::shell_quote(copy.string()) + " power --help";
    const fs::path err = dir / "err.txt";
    const int status = std::system((command + " >/dev/null 2>" + test::shell_quote(err.string())).c_str());
    EXPECT_EQ(WEXITSTATUS(status), 1);
    const std::string message = read_text_file(err);
    EXPECT_NE(message.find("avsi-analysis"), std::string::npos) << message;
    EXPECT_NE(message.find("AVSI_EXEC_PATH"), std::string::npos) << message;
    const int found = std::system(("AVSI_EXEC_PATH=" + test::shell_quote(helpers.string()) + " " + command +
                                   " >/dev/null 2>&1")
                                      .c_str());
    EXPECT_EQ(WEXITSTATUS(found), 0);
}

}  // namespace
}  // namespace avsi
