// The top level of the avsi command line, shared by the front end (avsi,
// front_end.cpp) and the helper executables that run the commands
// (helper_main.cpp): both parse the same top-level options with the same
// texts, list the commands in the same workflow groups and report a
// mistyped command or option the same way, so `avsi …` behaves the same
// whichever of them reads the arguments. Header-only: the front end links no
// avsi library.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "avsi/core/closest_match.h"
#include "avsi/core/error.h"  // ExitUsage (declarations only: nothing here needs avsi_core linked)

namespace avsi::cli {

inline constexpr const char* kVersion = "avsi 0.1.0";

// The workflows `avsi --help` lists the commands under, in this order (as
// git's command list groups its commands). A command in none of them is
// listed under "Other commands"; tests/e2e/front_end_test.cpp checks there
// is none.
struct Workflow {
    const char* title;
    std::vector<std::string_view> commands;
};
inline const std::vector<Workflow>& workflows() {
    static const std::vector<Workflow> list = {
        {"Prepare (sentence and articulatory corpora, speech, control models, planning)",
         {"corpus", "markers", "phones", "synth", "fap2traj", "stream", "train", "evaluate", "calibrate", "power",
          "simulate-srt"}},
        {"Build (stimuli, their checks, the design, the online study)",
         {"vocode", "mix", "render", "contact-sheet", "measure", "export-head", "build-stimuli", "design",
          "export-web"}},
        {"Run (sessions, playback, online results)", {"run", "play", "import-web", "export"}},
        {"Analyse (scores, statistics, objective intelligibility)", {"score", "analyze", "stoi"}},
    };
    return list;
}
inline constexpr const char* kOtherCommands = "Other commands";

// Where `command` is listed: its workflow's position in workflows() (their
// number for none) and its own in that workflow.
inline std::pair<std::size_t, std::size_t> workflow_position(std::string_view command) {
    const auto& list = workflows();
    for (std::size_t w = 0; w < list.size(); ++w)
        for (std::size_t c = 0; c < list[w].commands.size(); ++c)
            if (list[w].commands[c] == command) return {w, c};
    return {list.size(), 0};
}

// Sets `app` up as avsi's top level: description, one required subcommand,
// --version, -v/--verbose (into `verbose`). Subcommands are added by the
// caller, through add_command.
inline void configure_top_level(CLI::App& app, bool& verbose) {
    app.name("avsi");
    app.description("avsi — perceptual intelligibility experiments with synthetic audiovisual speech.\n"
                    "Run `avsi <command> --help` for a command's options and their defaults.");
    app.require_subcommand(1);
    app.set_version_flag("--version", kVersion);
    app.add_flag("-v,--verbose", verbose, "Print debug messages");
}

// Adds the command `name` to avsi's top level under its workflow. Add the
// commands in the order of `less_by_workflow`: help lists the groups in the
// order their first command was added.
inline CLI::App* add_command(CLI::App& app, const std::string& name, const std::string& summary) {
    const std::size_t w = workflow_position(name).first;
    return app.add_subcommand(name, summary)->group(w < workflows().size() ? workflows()[w].title : kOtherCommands);
}
// Orders command names as help lists them: by workflow, then in the
// workflow's order (commands in none by name, last).
inline bool less_by_workflow(std::string_view a, std::string_view b) {
    const auto pa = workflow_position(a), pb = workflow_position(b);
    return pa != pb ? pa < pb : a < b;
}

// Prints a usage error of the command `path` ("avsi vocode") with the way
// to its help: "avsi vocode: --snr-db needs --noise speech-shaped|FILE".
inline void report_usage_error(const std::string& path, const std::string& message) {
    std::fprintf(stderr, "%s: %s\nRun '%s --help' for more information.\n", path.c_str(), message.c_str(), path.c_str());
}

namespace detail {

// "avsi", "avsi vocode", "avsi corpus import": the commands `app` stands for.
inline std::string command_path(const CLI::App* app) {
    std::string path;
    for (; app; app = app->get_parent()) path = app->get_name() + (path.empty() ? "" : " " + path);
    return path;
}

// The names `app` takes as options: --long and -s forms.
inline std::vector<std::string> option_names(const CLI::App* app) {
    std::vector<std::string> names;
    for (const CLI::Option* option : app->get_options()) {
        for (const std::string& n : option->get_lnames()) names.push_back("--" + n);
        for (const std::string& n : option->get_snames()) names.push_back("-" + n);
    }
    return names;
}

// " Did you mean 'x'?" for the nearest of `candidates`, or "".
inline std::string did_you_mean(const std::string& typed, const std::vector<std::string>& candidates) {
    const std::string hint = closest_match(typed, candidates);
    return hint.empty() ? "" : " Did you mean '" + hint + "'?";
}

// What the user typed wrong in `app` (its unparsed arguments), as a message:
// where a command was expected, an unknown command with the nearest command
// (what follows it is that command's, so it is not reported); otherwise the
// first unknown option with the nearest of the app's options. Empty when
// neither applies.
inline std::string unknown_argument(const CLI::App* app) {
    const std::string path = command_path(app);
    const std::vector<std::string> remaining = app->remaining();
    if (remaining.empty()) return {};
    const auto commands = app->get_subcommands([](const CLI::App*) { return true; });
    if (remaining.front()[0] != '-' && !commands.empty() && app->get_subcommands().empty()) {
        std::vector<std::string> names;
        for (const CLI::App* sub : commands) names.push_back(sub->get_name());
        return path + ": '" + remaining.front() + "' is not an " + path + " command." +
               did_you_mean(remaining.front(), names) + "\nRun '" + path + " --help' for the commands.";
    }
    for (const std::string& item : remaining) {
        if (item.size() < 2 || item[0] != '-') continue;
        const std::string typed = item.substr(0, item.find('='));
        return path + ": unknown option '" + typed + "'." + did_you_mean(typed, option_names(app)) + "\nRun '" + path +
               " --help' for its options.";
    }
    return {};
}

}  // namespace detail

// "avsi vocode", "avsi corpus import": the commands named on the parsed line.
inline std::string chosen_command(const CLI::App& app) {
    const CLI::App* deepest = &app;
    while (!deepest->get_subcommands().empty()) deepest = deepest->get_subcommands().front();
    return detail::command_path(deepest);
}

// Reports a parse error of the command line `app` read: help and --version
// are printed as asked (exit 0); an unknown command or option is named with
// the nearest valid one ("avsi: 'vocod' is not an avsi command. Did you mean
// 'vocode'?", "avsi vocode: unknown option '--band'. Did you mean
// '--bands'?"); any other usage error is CLI11's message after the command
// ("avsi vocode: --spacing: expected one of …"). Returns the exit code:
// ExitUsage for every usage error.
inline int report_parse_error(CLI::App& app, const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    // The commands named on the line, outermost first.
    std::vector<const CLI::App*> chain{&app};
    while (!chain.back()->get_subcommands().empty()) chain.push_back(chain.back()->get_subcommands().front());
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
        const std::string message = detail::unknown_argument(*it);
        if (message.empty()) continue;
        std::fprintf(stderr, "%s\n", message.c_str());
        return ExitUsage;
    }
    report_usage_error(chosen_command(app), e.what());
    return ExitUsage;
}

}  // namespace avsi::cli
