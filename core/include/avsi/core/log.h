// The log and progress sink. Libraries never print: they report messages and
// progress here, and the CLI installs a sink that renders them (a progress bar
// with ETA on a terminal, plain lines otherwise). Thread-safe.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

namespace avsi {

enum class LogLevel { Debug, Info, Warning, Error };

// A snapshot of one task's progress.
struct ProgressUpdate {
    std::string task;
    std::size_t done = 0;
    std::size_t total = 0;  // 0 when unknown
    double elapsed_s = 0.0;
    bool finished = false;

    // Estimated seconds left from the rate so far; negative when unknown.
    double eta_s() const;
};

// Receives log lines and progress. Implementations must be thread-safe.
class LogSink {
public:
    virtual ~LogSink() = default;
    virtual void message(LogLevel level, std::string_view text) = 0;
    virtual void progress(const ProgressUpdate& update) = 0;
};

// Installs the process-wide sink; nullptr discards everything (the default).
void set_log_sink(std::shared_ptr<LogSink> sink);
std::shared_ptr<LogSink> log_sink();

void log_message(LogLevel level, std::string_view text);

template <typename... Args>
void log_debug(fmt::format_string<Args...> f, Args&&... args) {
    log_message(LogLevel::Debug, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void log_info(fmt::format_string<Args...> f, Args&&... args) {
    log_message(LogLevel::Info, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void log_warning(fmt::format_string<Args...> f, Args&&... args) {
    log_message(LogLevel::Warning, fmt::format(f, std::forward<Args>(args)...));
}

// Reports progress of one task to the sink. advance() may be called from any
// thread; updates are throttled so hot loops can call it per item.
class Progress {
public:
    Progress(std::string task, std::size_t total);
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    void advance(std::size_t n = 1);
    // Reports completion now (the destructor does it otherwise).
    void finish();

private:
    void report(bool finished);

    std::string m_task;
    std::size_t m_total;
    std::atomic<std::size_t> m_done{0};
    std::chrono::steady_clock::time_point m_start;
    std::mutex m_mutex;
    std::chrono::steady_clock::time_point m_last_report;
    bool m_finished = false;
};

// A sink that keeps everything in memory (for tests and for embedding).
class MemorySink : public LogSink {
public:
    struct Entry {
        LogLevel level;
        std::string text;
    };
    void message(LogLevel level, std::string_view text) override;
    void progress(const ProgressUpdate& update) override;
    std::vector<Entry> messages() const;
    std::vector<ProgressUpdate> updates() const;

private:
    mutable std::mutex m_mutex;
    std::vector<Entry> m_messages;
    std::vector<ProgressUpdate> m_updates;
};

}  // namespace avsi
