// The main of every helper executable (libexec/avsi-<group>): the commands
// of its group, registered by their cmd_<name>.cpp files, parsed with CLI11
// under avsi's top level (app.h) and run; exceptions become exit codes. The
// front end (front_end.cpp) runs a helper in its own place with the user's
// arguments, so the helper sees `avsi <command> …` as typed. Started as
// `avsi-<group> --avsi-registry FILE`, a helper writes its commands' names
// and summaries for the front end's registry (see cli/CMakeLists.txt).
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <string_view>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "app.h"
#include "command.h"

namespace avsi::cli {

std::vector<Command>& commands() {
    static std::vector<Command> registry;
    return registry;
}

bool register_command(Command command) {
    commands().push_back(std::move(command));
    return true;
}

bool stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

namespace {

std::string format_duration(double seconds) {
    if (seconds < 0) return "--:--";
    const long s = std::lround(seconds);
    if (s >= 3600) return fmt::format("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60);
    return fmt::format("{:02}:{:02}", s / 60, s % 60);
}

// Renders log lines and progress on stderr: a redrawn bar with ETA on a
// terminal; on a file or pipe, one line per 10 % step.
class ConsoleSink : public LogSink {
public:
    ConsoleSink(bool terminal, bool verbose) : m_terminal(terminal), m_verbose(verbose) {}

    void message(LogLevel level, std::string_view text) override {
        if (level == LogLevel::Debug && !m_verbose) return;
        std::lock_guard lock(m_mutex);
        clear_bar();
        const char* prefix = level == LogLevel::Warning ? "warning: "
                             : level == LogLevel::Error ? "error: "
                                                        : "";
        fmt::print(stderr, "{}{}\n", prefix, text);
        std::fflush(stderr);
    }

    void progress(const ProgressUpdate& u) override {
        std::lock_guard lock(m_mutex);
        if (m_terminal) {
            const double fraction = u.total ? std::min(1.0, double(u.done) / double(u.total)) : 0.0;
            const int width = 30;
            const int filled = static_cast<int>(fraction * width);
            std::string bar(filled, '#');
            bar.resize(width, '.');
            fmt::print(stderr, "\r{} [{}] {}/{} {:3.0f}% elapsed {} eta {}", u.task, bar, u.done,
                       u.total, fraction * 100.0, format_duration(u.elapsed_s),
                       format_duration(u.eta_s()));
            m_bar_visible = true;
            if (u.finished) {
                fmt::print(stderr, "\n");
                m_bar_visible = false;
            }
        } else {
            const int step = u.total ? static_cast<int>(10.0 * double(u.done) / double(u.total)) : 0;
            if (u.finished) {
                fmt::print(stderr, "{}: done, {} items in {:.1f} s\n", u.task, u.done, u.elapsed_s);
                m_last_step.erase(u.task);
            } else if (u.total && m_last_step[u.task] != step) {
                m_last_step[u.task] = step;
                if (step > 0)
                    fmt::print(stderr, "{}: {}/{} ({}%), eta {}\n", u.task, u.done, u.total,
                               step * 10, format_duration(u.eta_s()));
            }
        }
        std::fflush(stderr);
    }

private:
    void clear_bar() {
        if (m_bar_visible) {
            fmt::print(stderr, "\r\033[K");
            m_bar_visible = false;
        }
    }

    bool m_terminal;
    bool m_verbose;
    bool m_bar_visible = false;
    std::mutex m_mutex;
    std::map<std::string, int> m_last_step;
};

// Prints an exception and any nested causes, outermost first.
void print_exception_chain(const std::exception& e, int depth = 0) {
    if (depth == 0)
        fmt::print(stderr, "{}\n", e.what());
    else
        fmt::print(stderr, "  caused by: {}\n", e.what());
    try {
        std::rethrow_if_nested(e);
    } catch (const std::exception& nested) {
        print_exception_chain(nested, depth + 1);
    } catch (...) {
    }
}

// `text` as a C++ string literal.
std::string literal(std::string_view text) {
    std::string out = "\"";
    for (const char c : text) {
        if (c == '"' || c == '\\') out += '\\';
        if (c == '\n') {
            out += "\\n";
            continue;
        }
        out += c;
    }
    return out + "\"";
}

// Writes one row per command of this helper, AVSI_CLI_ROW("name", "summary"),
// for the front end's table of commands (compiled into it at build time).
int write_registry(const char* path) {
    std::ofstream out(path);
    for (const Command& command : commands())
        out << "AVSI_CLI_ROW(" << literal(command.name) << ", " << literal(command.summary) << ")\n";
    out.close();
    if (!out) {
        fmt::print(stderr, "cannot write the command registry to {}\n", path);
        return ExitFailure;
    }
    return ExitSuccess;
}

}  // namespace
}  // namespace avsi::cli

int main(int argc, char** argv) {
    using namespace avsi;
    using namespace avsi::cli;

    if (argc == 3 && std::strcmp(argv[1], "--avsi-registry") == 0) return write_registry(argv[2]);

    CLI::App app;
    bool verbose = false;
    configure_top_level(app, verbose);

    auto& registry = commands();
    std::sort(registry.begin(), registry.end(),
              [](const Command& a, const Command& b) { return less_by_workflow(a.name, b.name); });
    std::function<int()> to_run;
    for (const auto& command : registry) {
        CLI::App* sub = add_command(app, command.name, command.summary);
        auto run = command.setup(*sub);
        sub->callback([&to_run, run] { to_run = run; });
    }

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return report_parse_error(app, e);
    }

    set_log_sink(std::make_shared<ConsoleSink>(stderr_is_terminal(), verbose));
    try {
        return to_run ? to_run() : ExitUsage;
    } catch (const UsageError& e) {
        report_usage_error(chosen_command(app), e.what());
        return ExitUsage;
    } catch (const std::exception& e) {
        print_exception_chain(e);
        return ExitFailure;
    }
}
