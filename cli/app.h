// The top level of the avsi command line, shared by the front end (avsi,
// front_end.cpp) and the helper executables that run the commands
// (helper_main.cpp): both parse the same top-level options with the same
// texts, so `avsi …` behaves the same whichever of them reads the arguments.
// Header-only: the front end links no avsi library.
#pragma once

#include <CLI/CLI.hpp>

namespace avsi::cli {

inline constexpr const char* kVersion = "avsi 0.1.0";

// Sets `app` up as avsi's top level: description, one required subcommand,
// --version, -v/--verbose (into `verbose`). Subcommands are added by the caller.
inline void configure_top_level(CLI::App& app, bool& verbose) {
    app.description("avsi — perceptual intelligibility experiments with synthetic audiovisual speech.\n"
                    "Run `avsi <command> --help` for a command's options and their defaults.");
    app.require_subcommand(1);
    app.set_version_flag("--version", kVersion);
    app.add_flag("-v,--verbose", verbose, "Print debug messages");
}

}  // namespace avsi::cli
