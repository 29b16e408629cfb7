// The light front end (issue 21, docs/cli-design.md): `avsi` links no heavy
// library and runs each command's helper executable, so that --version,
// --help and the light commands load nothing heavy; every command listed by
// --help answers `avsi <command> --help`; a missing helper is reported.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "avsi/core/files.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

using test::CliResult;
using test::run_avsi;

// The shared libraries an executable names (DT_NEEDED), from readelf.
std::vector<std::string> needed(const fs::path& executable) {
    std::vector<std::string> libraries;
    std::istringstream lines(test::run_command("readelf -d " + test::shell_quote(executable.string())).out);
    const std::regex pattern(R"(\(NEEDED\).*\[(.*)\])");
    for (std::string line; std::getline(lines, line);) {
        std::smatch m;
        if (std::regex_search(line, m, pattern)) libraries.push_back(m[1]);
    }
    return libraries;
}

// The commands `avsi --help` lists, by the heading of the group each is
// listed under (in the order of the help).
std::vector<std::pair<std::string, std::string>> listed_commands_by_group() {
    const CliResult r = run_avsi("--help");
    std::vector<std::pair<std::string, std::string>> listed;
    std::istringstream lines(r.out);
    std::string group;
    for (std::string line; std::getline(lines, line);) {
        std::smatch m;
        if (std::regex_match(line, m, std::regex(R"(^(\S.*):$)"))) group = m[1];
        else if (group != "Options" && std::regex_search(line, m, std::regex(R"(^  ([a-z][a-z0-9-]*)\s)")))
            listed.emplace_back(group, m[1]);
    }
    return listed;
}

// The command names `avsi --help` lists.
std::vector<std::string> listed_commands() {
    std::vector<std::string> names;
    for (const auto& [group, name] : listed_commands_by_group()) names.push_back(name);
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
    const CliResult version = run_avsi("--version");
    EXPECT_EQ(version.exit_code, 0);
    EXPECT_EQ(version.out, "avsi 0.1.0\n");
    const CliResult none = run_avsi("");
    EXPECT_EQ(none.exit_code, 2);
    EXPECT_NE(none.err.find("A subcommand is required"), std::string::npos) << none.err;
    // A mistyped command is not a command (CLI11 reads it as an extra argument).
    const CliResult typo = run_avsi("vocod in.wav out.wav");
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
        const CliResult r = run_avsi(name + " --help");
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

// The head options are declared once (cli/head_options.h): every command
// that draws or measures a head takes --mesh, --rig, --head and --mapping
// with the same help.
TEST(FrontEnd, EveryCommandThatTakesAHeadTakesTheSameHeadOptions) {
    std::map<std::string, std::string> first;  // option -> its help lines, as the first command gives them
    for (const char* command : {"render", "contact-sheet", "measure", "export-head", "evaluate"}) {
        SCOPED_TRACE(command);
        const CliResult help = run_avsi(std::string(command) + " --help");
        ASSERT_EQ(help.exit_code, 0) << help.err;
        for (const char* option : {"--mesh", "--rig", "--head", "--mapping"}) {
            const std::size_t at = help.out.find(std::string("\n  ") + option + " ");
            ASSERT_NE(at, std::string::npos) << option << " missing in\n" << help.out;
            // The option's entry: its line and the indented lines of its help after it.
            std::size_t end = help.out.find('\n', at + 1);
            while (end != std::string::npos && help.out.compare(end + 1, 6, "      ") == 0) end = help.out.find('\n', end + 1);
            const std::string entry = help.out.substr(at, end - at);
            const auto [it, inserted] = first.emplace(option, entry);
            EXPECT_EQ(entry, it->second) << option;
        }
    }
}

TEST(FrontEnd, UsageErrorsOfACommandKeepTheirExitCode) {
    const CliResult r = run_avsi("vocode --bands 3");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("input is required"), std::string::npos) << r.err;
    const CliResult missing = run_avsi("stoi /nonexistent/a.wav /nonexistent/b.wav");
    EXPECT_EQ(missing.exit_code, 2) << missing.err;
}

TEST(FrontEnd, AMissingHelperIsNamedAndAvsiExecPathFindsIt) {
    const fs::path dir = test::temp_dir("e2e_front_end_alone");
    const fs::path copy = dir / "avsi";
    fs::copy_file(cli, copy, fs::copy_options::overwrite_existing);
    const std::string command = test::shell_quote(copy.string()) + " power --help";
    const CliResult alone = test::run_command(command);
    EXPECT_EQ(alone.exit_code, 1);
    EXPECT_NE(alone.err.find("avsi-analysis"), std::string::npos) << alone.err;
    EXPECT_NE(alone.err.find("AVSI_EXEC_PATH"), std::string::npos) << alone.err;
    const CliResult found = test::run_command("AVSI_EXEC_PATH=" + test::shell_quote(helpers.string()) + " " + command);
    EXPECT_EQ(found.exit_code, 0) << found.err;
}

}  // namespace
}  // namespace avsi
