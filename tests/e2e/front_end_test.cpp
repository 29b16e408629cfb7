// The light front end (issue 21, docs/cli-design.md): `avsi` links no heavy
// library and runs each command's helper executable, so that --version,
// --help and the light commands load nothing heavy; every command listed by
// --help answers `avsi <command> --help`; a missing helper is reported. The
// command line as people type it (issue 40): --help groups the commands by
// workflow; a mistyped command or option is named with the nearest valid
// one; every option that takes one of a set of names fails the same way.
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
    const CliResult help = run_avsi("--help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_EQ(help.out.rfind("avsi — perceptual intelligibility experiments", 0), 0u) << help.out;
    EXPECT_NE(help.out.find("Usage: avsi [OPTIONS] SUBCOMMAND"), std::string::npos) << help.out;
}

// `avsi --help` lists the commands under the four workflows in the order a
// study goes through them, each command once, none left over.
TEST(FrontEnd, HelpGroupsTheCommandsByWorkflow) {
    const auto listed = listed_commands_by_group();
    std::vector<std::string> groups;
    for (const auto& [group, name] : listed)
        if (groups.empty() || groups.back() != group) groups.push_back(group);
    ASSERT_EQ(groups.size(), 4u) << "expected Prepare, Build, Run and Analyse, got " << groups.size() << " groups";
    const char* starts[] = {"Prepare (", "Build (", "Run (", "Analyse ("};
    for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(groups[i].rfind(starts[i], 0), 0u) << groups[i];
    const std::map<std::string, std::string> expected = {
        {"corpus", "Prepare"}, {"synth", "Prepare"},      {"train", "Prepare"}, {"vocode", "Build"},
        {"render", "Build"},   {"build-stimuli", "Build"}, {"design", "Build"},  {"run", "Run"},
        {"export", "Run"},     {"score", "Analyse"},      {"analyze", "Analyse"}};
    std::set<std::string> seen;
    for (const auto& [group, name] : listed) {
        EXPECT_TRUE(seen.insert(name).second) << name << " listed twice";
        if (const auto it = expected.find(name); it != expected.end()) {
            EXPECT_EQ(group.rfind(it->second + " (", 0), 0u) << name << " is under " << group;
        }
    }
    for (const auto& [name, group] : expected) EXPECT_TRUE(seen.count(name)) << name << " not listed";
}

// A mistyped command or option is named, with the nearest valid one (as git
// does), exit status 2: `avsi vocod` suggests vocode, `avsi vocode --band`
// suggests --bands (tests/vocoder/cli_test.cpp runs those with real files).
TEST(FrontEnd, AMistypedCommandOrOptionIsNamedWithTheNearest) {
    const CliResult typo = run_avsi("vocod in.wav out.wav");
    EXPECT_EQ(typo.exit_code, 2);
    EXPECT_EQ(typo.err, "avsi: 'vocod' is not an avsi command. Did you mean 'vocode'?\n"
                        "Run 'avsi --help' for the commands.\n");
    const CliResult far = run_avsi("frobnicate");
    EXPECT_EQ(far.exit_code, 2);
    EXPECT_EQ(far.err, "avsi: 'frobnicate' is not an avsi command.\nRun 'avsi --help' for the commands.\n");
    const CliResult top = run_avsi("--verbos vocode a.wav b.wav");
    EXPECT_EQ(top.exit_code, 2);
    EXPECT_EQ(top.err, "avsi: unknown option '--verbos'. Did you mean '--verbose'?\nRun 'avsi --help' for its options.\n");
    const CliResult option = run_avsi("vocode --band 3 a.wav b.wav");
    EXPECT_EQ(option.exit_code, 2);
    EXPECT_EQ(option.err, "avsi vocode: unknown option '--band'. Did you mean '--bands'?\n"
                          "Run 'avsi vocode --help' for its options.\n");
    // --name=value, and an unknown option that also leaves required ones out.
    const CliResult equals = run_avsi("render --trj=x.csv --out x.mp4");
    EXPECT_EQ(equals.exit_code, 2);
    EXPECT_NE(equals.err.find("avsi render: unknown option '--trj'. Did you mean '--traj'?"), std::string::npos)
        << equals.err;
    const CliResult missing = run_avsi("phones --txt hi");
    EXPECT_EQ(missing.exit_code, 2);
    EXPECT_NE(missing.err.find("avsi phones: unknown option '--txt'. Did you mean '--text'?"), std::string::npos)
        << missing.err;
    // An action of a command, mistyped.
    const CliResult action = run_avsi("corpus improt list.txt --out x.csv");
    EXPECT_EQ(action.exit_code, 2);
    EXPECT_NE(action.err.find("avsi corpus: 'improt' is not an avsi corpus command. Did you mean 'import'?"),
              std::string::npos)
        << action.err;
}

// Every option that takes one of a set of names (those `--help` shows with
// {a,b,c}) fails the same way whichever command it belongs to: exit status
// 2, the command, the option, every allowed name and what was given, and
// the nearest name for a near miss. The list below are the ones known when
// this was written: none may lose the check.
TEST(FrontEnd, EveryCommandsNamedChoicesFailTheSameWay) {
    const std::set<std::string> known = {
        "vocode --spacing",   "vocode --envelope",   "vocode --carrier",       "vocode --snr-reference",
        "vocode --noise-stage", "vocode --channels", "mix --snr-reference",    "mix --channels",
        "stoi --channels",    "calibrate --spacing", "calibrate --envelope",   "calibrate --carrier",
        "phones --phone-set", "phones --lab-units",  "synth --format",         "synth --target",
        "synth --param",      "render --camera",     "render --lod",           "contact-sheet --camera",
        "build-stimuli --lod", "evaluate --subset",  "evaluate --plot-param",  "train --model",
        "score --rules",      "run --audio",         "play --audio",           "simulate-srt --procedure"};
    const std::regex choice(R"(^\s+(-[-a-z0-9]*,)?(--[a-z0-9-]+) [A-Z]+:\{([^}]*)\})");
    std::set<std::string> found;
    for (const std::string& command : listed_commands()) {
        const CliResult help = run_avsi(command + " --help");
        std::istringstream lines(help.out);
        for (std::string line; std::getline(lines, line);) {
            std::smatch m;
            if (!std::regex_search(line, m, choice)) continue;
            const std::string option = m[2], names = m[3];
            SCOPED_TRACE(command + " " + option);
            found.insert(command + " " + option);
            std::vector<std::string> allowed;
            std::istringstream split(names);
            for (std::string n; std::getline(split, n, ',');) allowed.push_back(n);
            std::string listed;
            for (const auto& n : allowed) listed += (listed.empty() ? "" : ", ") + n;
            const CliResult bad = run_avsi(command + " " + option + " xyzzy");
            EXPECT_EQ(bad.exit_code, 2) << bad.err;
            EXPECT_EQ(bad.err.substr(0, bad.err.find('\n')),
                      "avsi " + command + ": " + option + ": expected one of " + listed + ", got \"xyzzy\"");
            const std::string longest =
                *std::max_element(allowed.begin(), allowed.end(),
                                  [](const std::string& a, const std::string& b) { return a.size() < b.size(); });
            if (longest.size() < 4) continue;
            const CliResult near = run_avsi(command + " " + option + " " + longest.substr(0, longest.size() - 1));
            EXPECT_EQ(near.exit_code, 2) << near.err;
            EXPECT_NE(near.err.find("(did you mean \"" + longest + "\"?)"), std::string::npos) << near.err;
        }
    }
    for (const std::string& option : known) EXPECT_TRUE(found.count(option)) << option << " takes any value";
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
    EXPECT_NE(r.err.find("avsi vocode: input is required"), std::string::npos) << r.err;
    const CliResult missing = run_avsi("stoi /nonexistent/a.wav /nonexistent/b.wav");
    EXPECT_EQ(missing.exit_code, 2) << missing.err;
    // A usage error found when the command runs is reported the same way.
    const CliResult together = run_avsi("vocode a.wav b.wav --snr-db 3");
    EXPECT_EQ(together.exit_code, 2);
    EXPECT_EQ(together.err, "avsi vocode: --snr-db needs --noise speech-shaped|FILE\n"
                            "Run 'avsi vocode --help' for more information.\n");
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
