#include "avsi/core/log.h"

namespace avsi {

namespace {
std::mutex g_sink_mutex;
std::shared_ptr<LogSink> g_sink;
}  // namespace

double ProgressUpdate::eta_s() const {
    if (total == 0 || done == 0 || elapsed_s <= 0.0) return -1.0;
    if (done >= total) return 0.0;
    return elapsed_s / static_cast<double>(done) * static_cast<double>(total - done);
}

void set_log_sink(std::shared_ptr<LogSink> sink) {
    std::lock_guard lock(g_sink_mutex);
    g_sink = std::move(sink);
}

std::shared_ptr<LogSink> log_sink() {
    std::lock_guard lock(g_sink_mutex);
    return g_sink;
}

void log_message(LogLevel level, std::string_view text) {
    if (auto sink = log_sink()) sink->message(level, text);
}

Progress::Progress(std::string task, std::size_t total)
    : m_task(std::move(task)), m_total(total), m_start(std::chrono::steady_clock::now()),
      m_last_report(m_start) {
    report(false);
}

Progress::~Progress() { finish(); }

void Progress::advance(std::size_t n) {
    m_done.fetch_add(n, std::memory_order_relaxed);
    const auto now = std::chrono::steady_clock::now();
    std::unique_lock lock(m_mutex, std::try_to_lock);
    if (!lock.owns_lock() || m_finished) return;
    if (now - m_last_report < std::chrono::milliseconds(100)) return;
    m_last_report = now;
    lock.unlock();
    report(false);
}

void Progress::finish() {
    {
        std::lock_guard lock(m_mutex);
        if (m_finished) return;
        m_finished = true;
    }
    report(true);
}

void Progress::report(bool finished) {
    auto sink = log_sink();
    if (!sink) return;
    ProgressUpdate u;
    u.task = m_task;
    u.done = m_done.load(std::memory_order_relaxed);
    u.total = m_total;
    u.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    u.finished = finished;
    sink->progress(u);
}

void MemorySink::message(LogLevel level, std::string_view text) {
    std::lock_guard lock(m_mutex);
    m_messages.push_back({level, std::string(text)});
}

void MemorySink::progress(const ProgressUpdate& update) {
    std::lock_guard lock(m_mutex);
    m_updates.push_back(update);
}

std::vector<MemorySink::Entry> MemorySink::messages() const {
    std::lock_guard lock(m_mutex);
    return m_messages;
}

std::vector<ProgressUpdate> MemorySink::updates() const {
    std::lock_guard lock(m_mutex);
    return m_updates;
}

}  // namespace avsi
