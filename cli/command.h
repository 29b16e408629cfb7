// The avsi command registry. Each subcommand lives in its own cmd_<name>.cpp,
// registers itself here, parses options into its library's settings struct,
// calls one library function and returns an exit code; exceptions become
// exit codes in the helper executables' main (helper_main.cpp). Where
// `avsi --help` lists a command is its workflow in app.h.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace avsi::cli {

struct Command {
    std::string name;
    std::string summary;
    // Adds the subcommand's options to `sub` and returns the function to run
    // once parsing succeeded. The function returns the exit code.
    std::function<std::function<int()>(CLI::App& sub)> setup;
};

// Registers a command at static-initialisation time; returns true.
bool register_command(Command command);
std::vector<Command>& commands();

// An action of a command defined in another file (`avsi corpus import` beside
// `avsi corpus reference`): adds its subcommand to the command's App and, when
// chosen, stores the function to run in `chosen`. The command's setup calls
// add_actions(name, …) to add the actions registered under its name.
using ActionSetup = std::function<void(CLI::App& command, std::function<int()>& chosen)>;
inline std::vector<std::pair<std::string, ActionSetup>>& action_registry() {
    static std::vector<std::pair<std::string, ActionSetup>> registry;
    return registry;
}
// Registers an action of `command` at static-initialisation time; returns true.
inline bool register_action(std::string command, ActionSetup setup) {
    action_registry().emplace_back(std::move(command), std::move(setup));
    return true;
}
// Adds every action registered for `command` to its App.
inline void add_actions(const std::string& command, CLI::App& app, std::function<int()>& chosen) {
    for (auto& [name, setup] : action_registry())
        if (name == command) setup(app, chosen);
}

// True when stderr is a terminal (progress bars) rather than a file or pipe.
bool stderr_is_terminal();

}  // namespace avsi::cli
