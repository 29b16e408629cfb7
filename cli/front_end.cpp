// avsi: the front end users type. It knows every command's name, summary
// and helper executable (the registry, written at build time by the helpers
// themselves: cli/CMakeLists.txt), parses avsi's top level exactly as the
// helpers do (app.h), and once a command is named runs that command's helper
// (libexec/avsi-<group>) in its own place with the same arguments (execv:
// same process, standard streams, exit code and signals). It links no avsi
// module library, so `avsi --version`, `avsi --help` and a mistyped command
// (named with the nearest command, app.h) load no heavy library, and each
// command loads only what its helper links.
// Why helper executables rather than plugins or lazy loading:
// docs/cli-design.md.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "app.h"
#include "avsi/core/executable_folder.h"

namespace avsi::cli {
namespace {

struct Entry {
    const char* name;
    const char* summary;
    const char* helper;  // the executable's file name, avsi-<group>
};

constexpr Entry kRegistry[] = {
#include "registry.inc"
};

// Where helpers are looked for, first match wins: $AVSI_EXEC_PATH (a folder,
// as git's GIT_EXEC_PATH), then libexec/ beside this executable (the build
// tree: build/cli/avsi, build/cli/libexec/), then ../libexec/avsi/ (an
// installed tree: bin/avsi, libexec/avsi/).
std::vector<std::string> helper_folders() {
    std::vector<std::string> folders;
    if (const char* env = std::getenv("AVSI_EXEC_PATH"); env && *env) folders.emplace_back(env);
    const std::string own = executable_folder();
    if (!own.empty()) {
        folders.push_back(own + "/libexec");
        folders.push_back(own + "/../libexec/avsi");
    }
    return folders;
}

// Runs `entry`'s helper with argv; returns only when that failed.
int run_helper(const Entry& entry, char** argv) {
    const std::vector<std::string> folders = helper_folders();
    for (const std::string& folder : folders) {
        const std::string path = folder + "/" + entry.helper;
        if (::access(path.c_str(), X_OK) != 0) continue;
        ::execv(path.c_str(), argv);
        std::fprintf(stderr, "avsi: cannot run the %s command: %s: %s\n", entry.name, path.c_str(),
                     std::strerror(errno));
        return 1;
    }
    std::string searched;
    for (const std::string& folder : folders) searched += (searched.empty() ? "" : ", ") + folder;
    std::fprintf(stderr,
                 "avsi: cannot run the %s command: its helper executable %s is not in %s (build all of "
                 "avsi's targets, or set AVSI_EXEC_PATH to the folder that holds it)\n",
                 entry.name, entry.helper, searched.empty() ? "any folder" : searched.c_str());
    return 1;
}

}  // namespace
}  // namespace avsi::cli

int main(int argc, char** argv) {
    using namespace avsi::cli;

    CLI::App app;
    bool verbose = false;
    configure_top_level(app, verbose);
    // Each command as a placeholder that takes the rest of the line as it
    // is: the helper parses it (and prints the command's help and errors).
    std::vector<const Entry*> sorted;
    for (const Entry& entry : kRegistry) sorted.push_back(&entry);
    std::sort(sorted.begin(), sorted.end(),
              [](const Entry* a, const Entry* b) { return less_by_workflow(a->name, b->name); });
    for (const Entry* entry : sorted) add_command(app, entry->name, entry->summary)->prefix_command();

    // Once a command is named, whatever else the line holds (help, an
    // unknown option, a missing argument) is the helper's to report: it
    // parses the same top level, so the messages are the ones it always gave.
    auto chosen = [&]() -> const Entry* {
        const auto subcommands = app.get_subcommands();
        if (subcommands.empty()) return nullptr;
        for (const Entry* entry : sorted)
            if (subcommands.front()->get_name() == entry->name) return entry;
        return nullptr;
    };
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (const Entry* entry = chosen()) return run_helper(*entry, argv);
        return report_parse_error(app, e);
    }
    if (const Entry* entry = chosen()) return run_helper(*entry, argv);
    return avsi::ExitUsage;
}
