// The second thread of the fast path and how the two threads wait for each
// other. Threads change when work runs, never what it computes: the fast
// path's output is the same on one thread or two.
//
// The two threads hand over short pieces of work (a 4096-frame piece of the
// filter loop) many times a second. A futex sleep and wake can cost more
// than such a piece, and two threads whose every hand-over sleeps run slower
// than one; so a waiting side first spins on the other's counter (with
// `pause`) for a bound of clock time, and only then sleeps on it. The bound
// adapts within [kMinSpin, kMaxSpin]: it halves after a wait longer than
// kMaxSpin (a busy machine, where spinning takes a core others could use, or
// a partner idle for a while), and doubles when the partner arrives within
// kMaxSpin, while spinning or asleep (so that a bound halved by a few long
// waits comes back when waits are short again). kMaxSpin is several pieces'
// length, so that a partner's piece running a little longer than this
// side's does not send this side to sleep. (std::binary_semaphore spins 16
// times, yields and sleeps: too short for this.) docs/performance.md ("The
// vocoder's fast path") gives the measurements.
#pragma once

#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <thread>

namespace avsi::vocoder::detail {

// One side's waiting, with its adaptive spin bound.
class HandOver {
public:
    using Clock = std::chrono::steady_clock;
    static constexpr std::chrono::nanoseconds kMinSpin{5'000}, kMaxSpin{200'000};

    // Returns once `counter` has reached `target` (acquire; counted modulo
    // 2^32, the two less than 2^31 apart).
    void await(const std::atomic<unsigned>& counter, unsigned target);

    // Adds one to `counter` (release) and wakes its waiter.
    static void bump(std::atomic<unsigned>& counter) {
        counter.fetch_add(1, std::memory_order_release);
        counter.notify_one();
    }

private:
    std::chrono::nanoseconds m_spin = kMaxSpin;  // the current bound
};

// A second thread that runs one job at a time beside the caller.
class PairWorker {
public:
    PairWorker();
    // Stops once the job running, if any, has returned (a job started and
    // not yet begun may not run; an error not waited for is dropped).
    ~PairWorker();
    PairWorker(const PairWorker&) = delete;
    PairWorker& operator=(const PairWorker&) = delete;

    // Starts `job` on the worker, after the job started before it; `owner`
    // tags it (see running_for).
    void start(std::function<void()> job, const void* owner = nullptr);
    // Waits for the job started last, if it has not been waited for;
    // rethrows what it threw.
    void wait();
    // Whether the job started last, tagged `owner`, has not been waited for.
    bool running_for(const void* owner) const { return m_outstanding && m_owner == owner; }
    // Each side's hand-overs, for a job and its caller that wait on each
    // other's counters.
    HandOver& caller_side() { return m_caller; }
    HandOver& worker_side() { return m_worker; }

private:
    void loop();

    std::function<void()> m_job;
    std::exception_ptr m_error;
    HandOver m_caller, m_worker;  // each side's spin bound
    const void* m_owner = nullptr;
    bool m_outstanding = false;  // a job started and not yet waited for (caller's side)
    std::atomic<bool> m_stop{false};
    std::atomic<unsigned> m_started{0}, m_finished{0};
    std::thread m_thread;
};

}  // namespace avsi::vocoder::detail
