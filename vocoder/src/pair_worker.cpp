// The second thread and the spin-then-sleep hand-over; see pair_worker.h.
#include "pair_worker.h"

#include <algorithm>
#include <utility>

namespace avsi::vocoder::detail {

void HandOver::await(const std::atomic<unsigned>& counter, unsigned target) {
    auto reached = [&](unsigned value) { return static_cast<int>(value - target) >= 0; };
    if (reached(counter.load(std::memory_order_acquire))) return;
    const Clock::time_point begin = Clock::now();
    // Spin, reading the clock every 32 pauses (a read costs about a pause).
    for (unsigned n = 1;; ++n) {
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#endif
        if (reached(counter.load(std::memory_order_acquire))) {
            m_spin = std::min(2 * m_spin, kMaxSpin);
            return;
        }
        if (n % 32 == 0 && Clock::now() - begin >= m_spin) break;
    }
    // Then sleep on the counter.
    for (unsigned seen; !reached(seen = counter.load(std::memory_order_acquire));) counter.wait(seen);
    m_spin = Clock::now() - begin <= kMaxSpin ? std::min(2 * m_spin, kMaxSpin) : std::max(m_spin / 2, kMinSpin);
}

PairWorker::PairWorker() : m_thread([this] { loop(); }) {}

PairWorker::~PairWorker() {
    m_stop.store(true, std::memory_order_relaxed);
    HandOver::bump(m_started);
    m_thread.join();
}

void PairWorker::start(std::function<void()> job, const void* owner) {
    wait();
    m_job = std::move(job);
    m_owner = owner;
    m_outstanding = true;
    HandOver::bump(m_started);
}

void PairWorker::wait() {
    if (!m_outstanding) return;
    m_outstanding = false;
    m_caller.await(m_finished, m_started.load(std::memory_order_relaxed));
    if (m_error) std::rethrow_exception(std::exchange(m_error, nullptr));
}

void PairWorker::loop() {
    for (unsigned jobs = 1;; ++jobs) {
        m_worker.await(m_started, jobs);
        if (m_stop.load(std::memory_order_relaxed)) return;
        try {
            m_job();
        } catch (...) {
            m_error = std::current_exception();
        }
        HandOver::bump(m_finished);
    }
}

}  // namespace avsi::vocoder::detail
