// The avsi command registry. Each subcommand lives in its own cmd_<name>.cpp,
// registers itself here, parses options into its library's settings struct,
// calls one library function and returns an exit code; exceptions become
// exit codes in main.cpp.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
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

// True when stderr is a terminal (progress bars) rather than a file or pipe.
bool stderr_is_terminal();

}  // namespace avsi::cli
