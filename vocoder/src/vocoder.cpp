// The channel vocoder of Shannon et al. (1995) with the options reviewed by
// Cychosz, Winn & Goupell (2024). Processing per channel:
//   1. analysis: the input through each band's Butterworth band-pass (a
//      bank of cascades run side by side, one lane per band);
//   2. envelope: rectification (or Hilbert magnitude), then a Butterworth
//      low-pass, negative values set to zero;
//   3. carrier: seeded noise, a sine at the band centre, or low-noise noise;
//   4. modulation, then the modulated carrier back through its band-pass;
//   5. level matching per band and overall, and the sum.
#include "avsi/vocoder/vocoder.h"

#include <algorithm>
#include <atomic>
#include <complex>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>
#include <exception>
#include <functional>
#include <utility>
#include <thread>
#include <chrono>

#include <fmt/format.h>
#include <sys/mman.h>

#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/vocoder/filters.h"
#include "avsi/vocoder/hilbert.h"
#include "fused_pipeline.h"

namespace avsi::vocoder {

namespace {

double to_db(double ratio) { return 20.0 * std::log10(ratio); }

std::string format_hz(double hz) { return fmt::format("{:.1f}", hz); }

std::string join_hz(const std::vector<double>& values) {
    std::string out;
    for (std::size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + format_hz(values[i]);
    return out;
}

std::string ordinal(int n) {
    const char* suffix = "th";
    if (n % 100 < 11 || n % 100 > 13) {
        if (n % 10 == 1) suffix = "st";
        if (n % 10 == 2) suffix = "nd";
        if (n % 10 == 3) suffix = "rd";
    }
    return fmt::format("{}{}", n, suffix);
}

// Runs a bank over interleaved data, forward and (zero-phase) backward.
void run_bank(const SosBank& bank, std::vector<double>& data, std::size_t frames, bool zero_phase) {
    bank.process(data.data(), frames, false);
    if (zero_phase) bank.process(data.data(), frames, true);
}

std::vector<double> column(const std::vector<double>& data, std::size_t frames, std::size_t stride,
                           std::size_t lane) {
    std::vector<double> out(frames);
    for (std::size_t n = 0; n < frames; ++n) out[n] = data[n * stride + lane];
    return out;
}

// acc[j] += Σ_n data[n·stride + j]², four lanes at a time.
void add_squares(const double* data, std::size_t frames, std::size_t stride, double* acc) {
    for (std::size_t chunk = 0; chunk < stride; chunk += 4) {
        // Each lane sums in sample order starting from its running total, so
        // the result does not depend on how the signal was split into blocks.
        double a[4] = {acc[chunk], acc[chunk + 1], acc[chunk + 2], acc[chunk + 3]};
        for (std::size_t n = 0; n < frames; ++n)
            for (std::size_t j = 0; j < 4; ++j) a[j] += data[n * stride + chunk + j] * data[n * stride + chunk + j];
        for (std::size_t j = 0; j < 4; ++j) acc[chunk + j] = a[j];
    }
}

void set_column(std::vector<double>& data, std::size_t stride, std::size_t lane,
                const std::vector<double>& values) {
    for (std::size_t n = 0; n < values.size(); ++n) data[n * stride + lane] = values[n];
}

// Low-noise noise (Pumplin 1985; Kohlrausch, Fassel, van der Heijden et al.
// 1997): band-limited noise divided by its own Hilbert envelope, then
// band-limited again, repeated; each round flattens the envelope further.
void make_low_noise(const SosBank& bank, std::vector<double>& carrier, std::size_t frames,
                    std::size_t lanes, int iterations, bool zero_phase) {
    const std::size_t stride = bank.stride();
    run_bank(bank, carrier, frames, zero_phase);
    for (int it = 0; it < iterations; ++it) {
        for (std::size_t l = 0; l < lanes; ++l) {
            std::vector<double> band = column(carrier, frames, stride, l);
            const std::vector<double> envelope = hilbert_envelope(band);
            double mean = 0.0;
            for (double e : envelope) mean += e;
            mean /= static_cast<double>(std::max<std::size_t>(frames, 1));
            const double floor = 1e-9 * std::max(mean, 1e-300);
            for (std::size_t n = 0; n < frames; ++n) band[n] /= std::max(envelope[n], floor);
            set_column(carrier, stride, l, band);
        }
        run_bank(bank, carrier, frames, zero_phase);
    }
}

}  // namespace

// ------------------------------------------------------------- names

std::string to_string(BandSpacing spacing) {
    switch (spacing) {
        case BandSpacing::Greenwood: return "greenwood";
        case BandSpacing::Log: return "log";
        case BandSpacing::Linear: return "linear";
        case BandSpacing::Explicit: return "explicit";
    }
    return "?";
}

std::string to_string(EnvelopeMethod method) {
    switch (method) {
        case EnvelopeMethod::HalfWaveRectify: return "rectify";
        case EnvelopeMethod::FullWaveRectify: return "full-wave";
        case EnvelopeMethod::Hilbert: return "hilbert";
    }
    return "?";
}

std::string to_string(CarrierType carrier) {
    switch (carrier) {
        case CarrierType::Noise: return "noise";
        case CarrierType::Sine: return "sine";
        case CarrierType::LowNoise: return "low-noise";
    }
    return "?";
}

namespace {
template <typename Enum>
Enum parse_enum(const std::string& text, const std::string& field, std::initializer_list<Enum> values) {
    std::vector<std::string> names;
    for (Enum v : values) {
        if (to_string(v) == text) return v;
        names.push_back(to_string(v));
    }
    std::string message = fmt::format("expected one of {}, got \"{}\"", fmt::join(names, ", "), text);
    const std::string hint = closest_match(text, names);
    if (!hint.empty()) message += fmt::format(" (did you mean \"{}\"?)", hint);
    throw InputError(Diagnostic{"", 0, 0, field, message});
}
}  // namespace

BandSpacing parse_band_spacing(const std::string& text, const std::string& field) {
    return parse_enum(text, field,
                      {BandSpacing::Greenwood, BandSpacing::Log, BandSpacing::Linear, BandSpacing::Explicit});
}

EnvelopeMethod parse_envelope_method(const std::string& text, const std::string& field) {
    return parse_enum(text, field,
                      {EnvelopeMethod::HalfWaveRectify, EnvelopeMethod::FullWaveRectify, EnvelopeMethod::Hilbert});
}

CarrierType parse_carrier_type(const std::string& text, const std::string& field) {
    return parse_enum(text, field, {CarrierType::Noise, CarrierType::Sine, CarrierType::LowNoise});
}

// ------------------------------------------------------------- settings

void validate_settings(const VocoderSettings& s, double rate, const std::string& source) {
    DiagnosticList problems;
    auto add = [&](const std::string& field, std::string message) {
        problems.add(source, 0, 0, "vocoder." + field, std::move(message));
    };
    const double nyquist = rate / 2.0;
    const std::string rate_note = fmt::format("the Nyquist frequency ({} Hz) of the {} Hz input",
                                              format_hz(nyquist), format_hz(rate));
    if (s.bands < 1 || s.bands > 64) add("bands", fmt::format("expected an integer in [1, 64], got {}", s.bands));
    if (!std::isfinite(s.low_hz) || s.low_hz <= 0.0)
        add("low_hz", fmt::format("expected a frequency above 0 Hz, got {}", s.low_hz));
    if (!std::isfinite(s.high_hz) || !(s.high_hz > s.low_hz))
        add("high_hz", fmt::format("expected a frequency above low_hz ({} Hz), got {}", s.low_hz, s.high_hz));
    if (rate > 0.0 && std::isfinite(s.high_hz) && s.high_hz >= nyquist)
        add("high_hz", fmt::format("expected a frequency below {}, got {} Hz; lower high_hz or "
                                   "resample the input to at least {} Hz",
                                   rate_note, format_hz(s.high_hz), format_hz(2.0 * s.high_hz + 1.0)));
    if (s.spacing == BandSpacing::Explicit) {
        const auto& e = s.edges_hz;
        if (e.size() != static_cast<std::size_t>(std::max(s.bands, 0)) + 1)
            add("edges_hz", fmt::format("expected bands + 1 = {} edges, got {}", s.bands + 1, e.size()));
        for (std::size_t i = 0; i < e.size(); ++i) {
            if (!std::isfinite(e[i]) || e[i] <= 0.0)
                add(fmt::format("edges_hz[{}]", i), fmt::format("expected a frequency above 0 Hz, got {}", e[i]));
            else if (i > 0 && !(e[i] > e[i - 1]))
                add(fmt::format("edges_hz[{}]", i),
                    fmt::format("expected increasing edges, above {} Hz, got {}", e[i - 1], e[i]));
        }
        if (!e.empty() && (e.front() != s.low_hz || e.back() != s.high_hz))
            add("edges_hz", fmt::format("expected the first and last edge to equal low_hz and high_hz "
                                        "({} and {} Hz), got {} and {} Hz",
                                        s.low_hz, s.high_hz, e.front(), e.back()));
    } else if (!s.edges_hz.empty()) {
        add("edges_hz", fmt::format("expected no explicit edges with {} spacing (set spacing to "
                                    "explicit to use them), got {} edges",
                                    to_string(s.spacing), s.edges_hz.size()));
    }
    if (s.filter_order < 1 || s.filter_order > 16)
        add("filter_order", fmt::format("expected an integer in [1, 16], got {}", s.filter_order));
    if (!std::isfinite(s.envelope_cutoff_hz) || s.envelope_cutoff_hz <= 0.0)
        add("envelope_cutoff_hz", fmt::format("expected a frequency above 0 Hz, got {}", s.envelope_cutoff_hz));
    else if (rate > 0.0 && s.envelope_cutoff_hz >= nyquist)
        add("envelope_cutoff_hz",
            fmt::format("expected a frequency below {}, got {} Hz", rate_note, format_hz(s.envelope_cutoff_hz)));
    if (s.envelope_filter_order < 1 || s.envelope_filter_order > 16)
        add("envelope_filter_order", fmt::format("expected an integer in [1, 16], got {}", s.envelope_filter_order));
    if (s.low_noise_iterations < 0 || s.low_noise_iterations > 100)
        add("low_noise_iterations", fmt::format("expected an integer in [0, 100], got {}", s.low_noise_iterations));
    if (!(rate > 0.0) && rate != 0.0)
        add("sample_rate_hz", fmt::format("expected a positive sample rate, got {}", rate));
    problems.throw_if_any();
}

double greenwood_hz(double x) { return 165.4 * (std::pow(10.0, 2.1 * x) - 0.88); }

double greenwood_position(double frequency_hz) { return std::log10(frequency_hz / 165.4 + 0.88) / 2.1; }

std::vector<double> band_edges_hz(const VocoderSettings& s) {
    validate_settings(s, 0.0);
    if (s.spacing == BandSpacing::Explicit) return s.edges_hz;
    std::vector<double> edges(static_cast<std::size_t>(s.bands) + 1);
    const double b = s.bands;
    for (int k = 0; k <= s.bands; ++k) {
        const double t = k / b;
        switch (s.spacing) {
            case BandSpacing::Greenwood: {
                const double x0 = greenwood_position(s.low_hz);
                const double x1 = greenwood_position(s.high_hz);
                edges[k] = greenwood_hz(x0 + (x1 - x0) * t);
                break;
            }
            case BandSpacing::Log: edges[k] = s.low_hz * std::pow(s.high_hz / s.low_hz, t); break;
            case BandSpacing::Linear: edges[k] = s.low_hz + (s.high_hz - s.low_hz) * t; break;
            case BandSpacing::Explicit: break;
        }
    }
    edges.front() = s.low_hz;  // exact, whatever the rounding of the inverse map
    edges.back() = s.high_hz;
    return edges;
}

// ------------------------------------------------------------- processing

namespace {

// The memory of ChannelEngine's store: large ones in 2 MiB-aligned memory
// that the kernel may back with huge pages (a tenth of the time of a
// 96 MiB store went to faulting in its 4 KiB pages one by one), made
// resident ahead of its first writes: by make_ready on the thread that runs
// the fronts, and by populate_ahead on the worker, which writes the store,
// while it waits for a front (a third of pass 1 went to those waits when
// the fronts' thread made it all resident), both taking the next part from
// one cursor.
//
// On a virtual machine that hands free memory back to its host (free page
// reporting, as on the project's machine), the first touch of a huge page
// the host took back costs the host's page faults as well: about 5 ms for
// 2 MiB instead of 0.2 ms, and a 96 MiB store then cost 87–235 ms instead
// of 8 (whole 2 MiB free blocks are what the guest hands back, while 4 KiB
// pages come first from smaller free blocks, which it keeps: 27–58 ms for
// 96 MiB, in every run). So each huge page's fault is timed, and after a
// slow one the rest of the store takes 4 KiB pages.
class StoreBuffer {
public:
    explicit StoreBuffer(std::size_t bytes) : m_bytes(bytes) {
        if (bytes >= kHuge) {
            const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
            m_data = static_cast<unsigned char*>(std::aligned_alloc(kHuge, rounded));
#ifdef MADV_HUGEPAGE
            // Advice only: failure changes nothing.
            if (m_data) m_huge = ::madvise(m_data, rounded, MADV_HUGEPAGE) == 0;
#endif
        } else {
            m_data = static_cast<unsigned char*>(std::malloc(std::max<std::size_t>(bytes, 1)));
            m_claimed = bytes;  // less than a huge page: faulted in as it is written
        }
        if (!m_data) throw std::bad_alloc();
    }
    ~StoreBuffer() { std::free(m_data); }
    StoreBuffer(const StoreBuffer&) = delete;
    StoreBuffer& operator=(const StoreBuffer&) = delete;
    unsigned char* get() const { return m_data; }

    // Sees that bytes [0, upto) are resident, or being faulted in by the
    // other thread, before they are first written (called ahead of the
    // thread that writes them; touches no byte it has written), and lets
    // populate_ahead go on to kAhead bytes further.
    void make_ready(std::size_t upto) {
        upto = std::min(upto, m_bytes);
        m_limit.store(std::min(m_bytes, upto + kAhead), std::memory_order_relaxed);
        while (m_claimed.load(std::memory_order_relaxed) < upto) populate_next(upto);
    }
    // Gives the memory of bytes [0, upto) back to the system, in whole huge
    // pages (those left go with the store): for a pass that has read them for
    // the last time, so that freeing them runs beside its work rather than at
    // the end.
    void release(std::size_t upto) {
        if (m_bytes < kHuge) return;  // malloc'd
        upto = std::min(upto, m_bytes) / kHuge * kHuge;
        if (upto <= m_released) return;
        ::madvise(m_data + m_released, upto - m_released, MADV_DONTNEED);  // advice only: failure keeps them
        m_released = upto;
    }
    // Faults in the next part of the store below the limit make_ready set,
    // if any: whether there was one.
    bool populate_ahead() { return populate_next(m_limit.load(std::memory_order_relaxed)); }

private:
    static constexpr std::size_t kHuge = std::size_t{2} << 20;
    static constexpr std::size_t kPage = 4096;
    // 4 KiB pages are faulted in this many bytes at a time (tens of µs).
    static constexpr std::size_t kSmallStep = std::size_t{64} << 10;
    static constexpr std::size_t kAhead = std::size_t{1} << 20;
    // A huge page's fault takes 0.2 ms when its memory is at hand.
    static constexpr std::chrono::microseconds kSlowHugeFault{1000};

    // Claims and faults in the next part below `limit`: a huge page (the
    // kernel faults it in whole), else up to kSmallStep bytes.
    bool populate_next(std::size_t limit) {
        std::size_t at = m_claimed.load(std::memory_order_relaxed);
        for (;;) {
            if (at >= limit) return false;
            const bool huge = m_huge.load(std::memory_order_relaxed);
            const std::size_t huge_end = std::min(m_bytes, (at / kHuge + 1) * kHuge);
            const std::size_t end =
                huge ? huge_end : std::min({huge_end, (at / kSmallStep + 1) * kSmallStep, (limit + kPage - 1) / kPage * kPage});
            if (!m_claimed.compare_exchange_weak(at, end, std::memory_order_relaxed)) continue;
            const auto start = std::chrono::steady_clock::now();
            populate(at, end);
            if (huge && end < m_bytes && std::chrono::steady_clock::now() - start > kSlowHugeFault &&
                m_huge.exchange(false, std::memory_order_relaxed)) {
#ifdef MADV_NOHUGEPAGE
                const std::size_t rounded = (m_bytes + kHuge - 1) / kHuge * kHuge;
                ::madvise(m_data + end, rounded - end, MADV_NOHUGEPAGE);  // advice only, as above
#endif
            }
            return true;
        }
    }

    // Faults in bytes [from, to) for writing (MADV_POPULATE_WRITE, Linux
    // 5.14; else a write to each page, of a byte not yet written).
    void populate(std::size_t from, std::size_t to) {
#ifdef MADV_POPULATE_WRITE
        const std::size_t page_from = from / kPage * kPage;
        if (::madvise(m_data + page_from, to - page_from, MADV_POPULATE_WRITE) == 0) return;
#endif
        for (std::size_t at = from; at < to; at = (at / kPage + 1) * kPage)
            reinterpret_cast<volatile unsigned char*>(m_data)[at] = 0;
    }

    unsigned char* m_data = nullptr;
    std::size_t m_bytes = 0;
    std::atomic<std::size_t> m_claimed{0};  // bytes [0, m_claimed) are resident or being faulted in
    std::atomic<std::size_t> m_limit{0};    // populate_ahead's bound
    std::atomic<bool> m_huge{false};        // the rest takes huge pages
    std::size_t m_released = 0;             // bytes [0, m_released) given back
};

// Waiting for the other of two threads, which hand over work thousands of
// times a second (pieces of tens of microseconds): first spin on its
// counter (with `pause`), and only then sleep on it: on the 2-core VM a
// futex sleep and wake cost more than a piece, and a pass whose hand-overs
// sleep ran slower on two threads than on one. The spin is bounded in
// time, not in pauses (a pause takes 25 ns on the Zen 4 machine): up to
// 200 µs, several pieces' length, so that the other side's piece taking
// longer than this one's does not send this side to sleep. The bound
// adapts: it halves when a wait lasts longer than the longest spin (a busy
// machine, where the other thread waits for a core: there spinning wastes
// a core others could use; or the other side idle for a while), and
// doubles when the other side arrives within the longest spin, whether
// within the bound or in the sleep that followed it (so that a bound halved
// by a few long waits comes back when waits are short again).
// (std::binary_semaphore spins 16 times, yields and sleeps.)
class HandOver {
public:
    using Clock = std::chrono::steady_clock;
    static constexpr std::chrono::nanoseconds kMinSpin{5'000}, kMaxSpin{200'000};

    // Returns once `counter` has reached `target` (acquire; counted modulo
    // 2^32, the two less than 2^31 apart).
    void await(const std::atomic<unsigned>& counter, unsigned target) {
        auto reached = [&](unsigned value) { return static_cast<int>(value - target) >= 0; };
        if (reached(counter.load(std::memory_order_acquire))) return;
        const Clock::time_point begin = Clock::now();
        for (unsigned n = 1;; ++n) {
#if defined(__x86_64__) || defined(__i386__)
            __builtin_ia32_pause();
#endif
            if (reached(counter.load(std::memory_order_acquire))) {
                m_spin = std::min(2 * m_spin, kMaxSpin);
                return;
            }
            if (n % 32 == 0 && Clock::now() - begin >= m_spin) break;  // a clock read costs about a pause
        }
        for (unsigned seen; !reached(seen = counter.load(std::memory_order_acquire));) counter.wait(seen);
        m_spin = Clock::now() - begin <= kMaxSpin ? std::min(2 * m_spin, kMaxSpin) : std::max(m_spin / 2, kMinSpin);
    }
    // Adds one to `counter` (release) and wakes its waiter.
    static void bump(std::atomic<unsigned>& counter) {
        counter.fetch_add(1, std::memory_order_release);
        counter.notify_one();
    }

private:
    std::chrono::nanoseconds m_spin = kMaxSpin;  // the current bound
};

// A second thread that runs one job at a time beside the caller (see
// HandOver for how each side waits for the other).
class PairWorker {
public:
    PairWorker() : m_thread([this] { loop(); }) {}
    ~PairWorker() {
        m_stop.store(true, std::memory_order_relaxed);
        HandOver::bump(m_started);
        m_thread.join();
    }
    PairWorker(const PairWorker&) = delete;
    PairWorker& operator=(const PairWorker&) = delete;

    // Starts `job` on the worker, after the job started before it; `owner`
    // tags it (see running_for).
    void start(std::function<void()> job, const void* owner = nullptr) {
        wait();
        m_job = std::move(job);
        m_owner = owner;
        m_outstanding = true;
        HandOver::bump(m_started);
    }
    // Waits for the job started last, if it has not been waited for;
    // rethrows what it threw.
    void wait() {
        if (!m_outstanding) return;
        m_outstanding = false;
        m_caller.await(m_finished, m_started.load(std::memory_order_relaxed));
        if (m_error) std::rethrow_exception(std::exchange(m_error, nullptr));
    }
    // Whether the job started last, tagged `owner`, has not been waited for.
    bool running_for(const void* owner) const { return m_outstanding && m_owner == owner; }
    // Each side's hand-overs, for a job and its caller that wait on each
    // other's counters.
    HandOver& caller_side() { return m_caller; }
    HandOver& worker_side() { return m_worker; }

private:
    void loop() {
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
    std::function<void()> m_job;
    std::exception_ptr m_error;
    HandOver m_caller, m_worker;  // each side's spin bound
    const void* m_owner = nullptr;
    bool m_outstanding = false;  // a job started and not yet waited for (caller's side)
    std::atomic<bool> m_stop{false};
    std::atomic<unsigned> m_started{0}, m_finished{0};
    std::thread m_thread;
};

// The band-pass and envelope filters of one channel and their memory, so the
// signal can run through the pipeline block by block.
struct Pipeline {
    const VocoderSettings& settings;
    double rate;
    std::size_t lanes;
    SosBank bands;
    SosBank envelope_lowpass;
    SosBank::State analysis_state, envelope_state, prefilter_state, refilter_state;
    // One noise stream per band (Rng(seed).derive("channel<c>/band<b>")),
    // run four side by side: xoshiro256** states [chunk][word][4] (padding
    // lanes all zero), and the current 64-bit draw per lane.
    std::vector<std::uint64_t> noise_state;
    std::vector<std::uint64_t> noise_draw;
    std::vector<double> analysis_sum_sq;
    bool fused;  // steps 1–4 in one loop (fused_pipeline.h)
    // With the fused loop: a block of more than one piece runs on two
    // threads (by chunks of bands, run_split; with one chunk, the front and
    // the back a piece behind); null: one thread.
    PairWorker* worker = nullptr;
    // With one chunk of bands on two threads: the store the worker faults in
    // ahead while it waits for a front (StoreBuffer::populate_ahead; null:
    // none).
    StoreBuffer* ahead = nullptr;
    static constexpr std::size_t kPieceFrames = 4096;
    // With one chunk of bands on two threads: the pieces of the block whose
    // front this thread has done and whose back the worker has (a copy of
    // the pipeline, taken settled, starts afresh).
    struct PieceCounts {
        std::atomic<unsigned> fronts{0}, backs{0};
        std::atomic<bool> abandoned{false};  // this thread stopped at an exception
        PieceCounts() = default;
        PieceCounts(const PieceCounts&) {}
        PieceCounts& operator=(const PieceCounts&) { return *this; }
    } piece_counts;
    // Makes x[offset, offset + count) ready (x as run gets it). With the
    // worker, run calls it piece by piece, in order, just before the piece
    // is read, so that this thread reads the input while the worker runs
    // the back of the piece before; otherwise once for the whole block.
    // Empty: x is ready.
    using Fill = std::function<void(std::size_t offset, std::size_t count)>;
    // Given to run with sums asked for: called with the sums of each piece
    // of the block (where they are, and how many), in order, once they are
    // there: on the worker when it makes them (and then run does not wait
    // for them), else on this thread before run returns.
    using Then = std::function<void(const double* sums, std::size_t count)>;
    // run_split's scratch per side (work, then carrier).
    std::vector<double> split_scratch[2];

    Pipeline(const VocoderSettings& s, double rate_hz, const std::vector<Sos>& band_filters, int channel)
        : settings(s), rate(rate_hz), lanes(band_filters.size()), bands(band_filters),
          envelope_lowpass(std::vector<Sos>(lanes, butterworth_lowpass(s.envelope_filter_order,
                                                                       s.envelope_cutoff_hz, rate_hz))),
          analysis_state(bands.initial_state()), envelope_state(envelope_lowpass.initial_state()),
          prefilter_state(bands.initial_state()), refilter_state(bands.initial_state()),
          noise_state(bands.stride() * 4, 0), noise_draw(bands.stride(), 0), analysis_sum_sq(bands.stride(), 0.0),
          fused(!s.zero_phase && s.envelope != EnvelopeMethod::Hilbert && s.carrier != CarrierType::LowNoise &&
                detail::fused_supported(bands, envelope_lowpass)) {
        constexpr std::size_t chunk = SosBank::chunk_lanes;
        for (std::size_t b = 0; b < lanes; ++b) {
            const Rng stream = Rng(s.seed).derive(fmt::format("channel{}/band{}", channel, b));
            for (std::size_t word = 0; word < 4; ++word)
                noise_state[(b / chunk * 4 + word) * chunk + b % chunk] = stream.state()[word];
        }
    }

    // Waits for what the worker may still be running (see run).
    void settle() {
        if (worker) worker->wait();
    }

    // Runs a bank over `frames` rows: forward with carried state when the
    // signal comes in blocks, forward and backward over the whole signal
    // for zero phase.
    void filter(const SosBank& bank, SosBank::State& state, double* data, std::size_t frames) {
        if (settings.zero_phase) {
            bank.process(data, frames, false);
            bank.process(data, frames, true);
        } else {
            bank.process(data, frames, state);
        }
    }

    // Fills `carrier` (frames × stride) for the frames from `first` on.
    void make_carrier(double* carrier, std::size_t first, std::size_t frames,
                      const std::vector<double>& centres_hz) {
        make_carrier(carrier, first, frames, centres_hz, 0, bands.stride() / SosBank::chunk_lanes, bands.stride());
    }
    // The same for the lanes of chunks [chunk_begin, chunk_end) only, into
    // rows of `out_stride` whose column 0 is lane 0 of chunk_begin (padding
    // lanes are left as they are, or get 0).
    void make_carrier(double* carrier, std::size_t first, std::size_t frames, const std::vector<double>& centres_hz,
                      std::size_t chunk_begin, std::size_t chunk_end, std::size_t out_stride) {
        const std::size_t stride = out_stride;
        const std::size_t lane_begin = chunk_begin * SosBank::chunk_lanes;
        const std::size_t lane_end = std::min(lanes, chunk_end * SosBank::chunk_lanes);
        switch (settings.carrier) {
            case CarrierType::Noise:
            case CarrierType::LowNoise:
                // Two uniform values in [-1, 1) with 32-bit resolution per
                // 64-bit draw; the stream position is absolute (`first`), so
                // an odd block start uses the second half of a draw.
                detail::noise_carriers(noise_state.data(), noise_draw.data(), lanes, chunk_begin, chunk_end, stride,
                                       first, frames, carrier);
                if (settings.carrier == CarrierType::LowNoise) {
                    AVSI_ASSERT(lane_begin == 0 && stride == bands.stride());
                    // Whole signal only (see vocode_channel): Hilbert envelopes need it.
                    std::vector<double> whole(carrier, carrier + frames * stride);
                    make_low_noise(bands, whole, frames, lanes, settings.low_noise_iterations, settings.zero_phase);
                    std::copy(whole.begin(), whole.end(), carrier);
                }
                break;
            case CarrierType::Sine:
                // A rotating phasor, re-anchored to the exact sin/cos every
                // 1024 samples of absolute time (so blocks do not matter).
                for (std::size_t b = lane_begin; b < lane_end; ++b) {
                    double* column = carrier + (b - lane_begin);
                    const double w = 2.0 * std::numbers::pi * centres_hz[b] / rate;
                    const std::complex<double> step = std::polar(1.0, w);
                    // Start as a whole-signal run would: from the last anchor.
                    const std::size_t anchor = first / 1024 * 1024;
                    std::complex<double> phasor = std::polar(1.0, w * static_cast<double>(anchor));
                    for (std::size_t t = anchor; t < first; ++t) phasor *= step;
                    for (std::size_t n = 0; n < frames; ++n) {
                        const std::size_t t = first + n;
                        if (t % 1024 == 0) phasor = std::polar(1.0, w * static_cast<double>(t));
                        column[n * stride] = phasor.imag();
                        phasor *= step;
                    }
                }
                break;
        }
    }

    // The fused steps with two or more chunks of bands and the worker: the
    // chunks [0, split) here and [split, chunks) on the worker, piece by
    // piece, each side with scratch of its own (so the threads share no
    // cache lines but those of the rows and sums). The replay's sum adds the
    // chunks in order, and the rows kept put both sides' lanes in one cache
    // line: then the worker runs a piece behind (piece i − 1 beside this
    // thread's piece i, whose lines it does not touch); otherwise each side
    // runs the whole block at once.
    void run_split(const detail::FusedBanks& banks, const detail::FusedBlock& rows, std::size_t first,
                   std::size_t frames, const std::vector<double>& centres_hz, const Fill& fill) {
        constexpr std::size_t kLanes = SosBank::chunk_lanes;
        const std::size_t chunks = bands.stride() / kLanes;
        const std::size_t split = (chunks + 1) / 2;
        const bool ordered = rows.sum || rows.rows;
        const std::size_t piece_frames = ordered ? kPieceFrames / 2 : kPieceFrames;
        const std::size_t pieces = (frames + piece_frames - 1) / piece_frames;
        // Work then carrier, per side; zero at first (padding lanes' carriers
        // stay 0 with sine carriers, which fill only the bands).
        for (std::size_t side = 0; side < 2; ++side) {
            const std::size_t lanes_of_side = (side == 0 ? split : chunks - split) * kLanes;
            if (split_scratch[side].size() != 2 * kPieceFrames * lanes_of_side)
                split_scratch[side].assign(2 * kPieceFrames * lanes_of_side, 0.0);
        }
        // Piece i of one side.
        auto run_piece = [this, &banks, &rows, &centres_hz, first, frames, piece_frames, split, chunks](
                             std::size_t i, std::size_t side) {
            detail::FusedBlock p = rows;
            const std::size_t start = i * piece_frames;
            p.frames = std::min(piece_frames, frames - start);
            p.x += start;
            if (p.rows) p.rows += start * p.lanes;
            if (p.sum) p.sum += start;
            if (side == 1) p.in_sum_sq = nullptr;  // chunk 0's
            p.chunk_begin = side == 0 ? 0 : split;
            p.chunk_end = side == 0 ? split : chunks;
            p.stride = (p.chunk_end - p.chunk_begin) * kLanes;
            double* work = split_scratch[side].data();
            double* carrier = work + kPieceFrames * p.stride;
            p.work = work;
            p.carrier = carrier;
            make_carrier(carrier, first + start, p.frames, centres_hz, p.chunk_begin, p.chunk_end, p.stride);
            detail::run_fused(banks, p);
        };
        if (!ordered) {
            if (fill) fill(0, frames);
            worker->start([&run_piece, pieces] {
                for (std::size_t i = 0; i < pieces; ++i) run_piece(i, 1);
            });
            try {
                for (std::size_t i = 0; i < pieces; ++i) run_piece(i, 0);
            } catch (...) {
                worker->wait();
                throw;
            }
            worker->wait();
            return;
        }
        for (std::size_t i = 0; i <= pieces; ++i) {
            if (i > 0) worker->start([&run_piece, i] { run_piece(i - 1, 1); });
            if (i < pieces) {
                try {
                    if (fill) fill(i * piece_frames, std::min(piece_frames, frames - i * piece_frames));
                    run_piece(i, 0);
                } catch (...) {
                    if (i > 0) worker->wait();
                    throw;
                }
            }
            if (i > 0) worker->wait();
        }
    }

    // Steps 1–4 for `frames` rows starting at absolute frame `first` (x[0],
    // made ready by `fill`): `work` gets the input broadcast to every lane
    // on entry and the filtered modulated carriers on exit; `carrier` is
    // scratch. `rows` says what becomes of the band outputs (FusedBlock's
    // fields from out_sum_sq on; x, carrier, work, frames and
    // analysis_sum_sq are filled in here): the same with the fused loop or
    // without.
    // With one chunk of bands on two threads and no sums asked for, the
    // worker may still be running the backs of the last pieces when this
    // returns: beside the next block's reading and first front (which waits
    // until the back is past piece 0, whose part of `work` and `carrier` it
    // rewrites). Their rows and sums of squares are there after settle();
    // every other use of the pipeline's state settles first. So may the
    // backs that make sums, when `then` takes them.
    void run(const double* x, std::size_t first, std::size_t frames, std::vector<double>& work,
             std::vector<double>& carrier, const std::vector<double>& centres_hz, detail::FusedBlock rows,
             const Fill& fill = {}, const Then& then = {}) {
        const std::size_t stride = bands.stride();
        double* w = work.data();
        rows.x = x;
        rows.carrier = carrier.data();
        rows.work = w;
        rows.frames = frames;
        rows.analysis_sum_sq = analysis_sum_sq.data();
        if (fused) {
            detail::FusedBanks banks{&bands, &envelope_lowpass, &analysis_state, &envelope_state,
                                     settings.prefilter_carrier ? &prefilter_state : nullptr,
                                     settings.refilter_carrier ? &refilter_state : nullptr,
                                     settings.envelope == EnvelopeMethod::FullWaveRectify};
            if (!worker || frames <= kPieceFrames) {
                settle();
                if (fill) fill(0, frames);
                make_carrier(carrier.data(), first, frames, centres_hz);
                detail::run_fused(banks, rows);
                if (then) then(rows.sum, frames);
                return;
            }
            if (stride / SosBank::chunk_lanes >= 2) {
                settle();
                run_split(banks, rows, first, frames, centres_hz, fill);
                if (then) then(rows.sum, frames);
                return;
            }
            // One chunk: this thread runs each piece's front and the worker
            // its back (which makes its carriers first), each piece in its own
            // part of work/carrier, as a pipeline: the worker takes piece i
            // once this thread has published its front, so that within the
            // block either side may run ahead of the other, and a long piece
            // on one side (a page fault, the host taking the core for a
            // while) is made up on the next ones instead of holding up the
            // other side at every piece.
            auto piece = [rows, frames, stride](std::size_t i) {
                detail::FusedBlock p = rows;
                const std::size_t start = i * kPieceFrames;
                p.frames = std::min(kPieceFrames, frames - start);
                p.x += start;
                p.carrier += start * stride;
                p.work += start * stride;
                if (p.rows) p.rows += start * p.lanes;
                if (p.sum) p.sum += start;
                return p;
            };
            auto front = [&](std::size_t i) {
                const detail::FusedBlock p = piece(i);
                if (fill) fill(i * kPieceFrames, p.frames);
                detail::run_fused_front(banks, p);
            };
            const std::size_t pieces = (frames + kPieceFrames - 1) / kPieceFrames;
            // Piece 0's front beside the end of the block before, when its
            // back was left running, once that is past piece 0.
            if (worker->running_for(this))
                worker->caller_side().await(piece_counts.backs, 1);
            else
                worker->wait();
            front(0);
            worker->wait();
            piece_counts.fronts.store(1, std::memory_order_relaxed);  // published by start
            piece_counts.backs.store(0, std::memory_order_relaxed);
            piece_counts.abandoned.store(false, std::memory_order_relaxed);
            double* const carriers = carrier.data();
            worker->start(
                [this, banks, piece, pieces, first, carriers, stride, &centres_hz, ahead = ahead, then] {
                    HandOver& side = worker->worker_side();
                    for (std::size_t i = 0; i < pieces; ++i) {
                        const unsigned target = static_cast<unsigned>(i + 1);
                        if (ahead)
                            while (static_cast<int>(piece_counts.fronts.load(std::memory_order_acquire) - target) < 0 &&
                                   ahead->populate_ahead()) {
                            }
                        side.await(piece_counts.fronts, target);
                        if (piece_counts.abandoned.load(std::memory_order_relaxed)) return;
                        const detail::FusedBlock p = piece(i);
                        make_carrier(carriers + i * kPieceFrames * stride, first + i * kPieceFrames, p.frames,
                                     centres_hz);
                        detail::run_fused_back(banks, p);
                        HandOver::bump(piece_counts.backs);
                        if (then) then(p.sum, p.frames);
                    }
                },
                this);
            for (std::size_t i = 1; i < pieces; ++i) {
                try {
                    front(i);
                } catch (...) {
                    piece_counts.abandoned.store(true, std::memory_order_relaxed);
                    HandOver::bump(piece_counts.fronts);
                    worker->wait();
                    throw;
                }
                HandOver::bump(piece_counts.fronts);
            }
            // The sums are read when this returns, unless `then` takes them.
            if (rows.sum && !then) worker->wait();
            return;
        }
        settle();
        if (fill) fill(0, frames);
        if (rows.in_sum_sq)
            for (std::size_t n = 0; n < frames; ++n) *rows.in_sum_sq += x[n] * x[n];
        // Padding lanes get the input too; their filters output zero.
        for (std::size_t n = 0; n < frames; ++n) std::fill_n(w + n * stride, stride, x[n]);
        // 1. Analysis.
        filter(bands, analysis_state, w, frames);
        add_squares(w, frames, stride, analysis_sum_sq.data());
        // 2. Envelope.
        switch (settings.envelope) {
            case EnvelopeMethod::HalfWaveRectify:
                for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::max(w[i], 0.0);
                break;
            case EnvelopeMethod::FullWaveRectify:
                for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::abs(w[i]);
                break;
            case EnvelopeMethod::Hilbert:  // whole signal only
                for (std::size_t b = 0; b < lanes; ++b)
                    set_column(work, stride, b, hilbert_envelope(column(work, frames, stride, b)));
                break;
        }
        filter(envelope_lowpass, envelope_state, w, frames);
        // 3. Carrier.
        double* c = carrier.data();
        make_carrier(c, first, frames, centres_hz);
        if (settings.prefilter_carrier) filter(bands, prefilter_state, c, frames);
        // 4. Modulation (envelope floored at zero), then back through the band.
        for (std::size_t i = 0; i < frames * stride; ++i) w[i] = std::max(w[i], 0.0) * c[i];
        if (settings.refilter_carrier) filter(bands, refilter_state, w, frames);
        // The rows, as the fused loop leaves them.
        if (rows.sum) {
            for (std::size_t n = 0; n < frames; ++n) {
                double s = 0.0;
                for (std::size_t b = 0; b < stride; ++b) s += rows.gains[b] * static_cast<float>(w[n * stride + b]);
                rows.sum[n] = s;
            }
            if (then) then(rows.sum, frames);
            return;
        }
        if (rows.out_sum_sq) add_squares(w, frames, stride, rows.out_sum_sq);
        if (rows.rows)
            for (std::size_t n = 0; n < frames; ++n)
                for (std::size_t b = 0; b < rows.lanes; ++b)
                    rows.rows[n * rows.lanes + b] = static_cast<float>(w[n * stride + b]);
    }
};

// One channel through steps 1–5 in passes over its input, so that a long
// signal needs memory for a block, not for its length (vocode_stream):
//   pass 1 (measure): steps 1–4; sums of squares of each band before and
//     after, and of the input; the band gains follow;
//   pass 2 (replay): the level-matched band sum, its sum of squares and peak;
//     the overall gain and the anti-clipping scale follow;
//   pass 3 (replay again): the output.
// The band outputs of the first `stored` frames are kept from pass 1 in
// single precision (as the sum reads them); later frames are computed again
// by a copy of the pipeline taken at frame `stored`, which gives the same
// values (the pipeline is deterministic and block-length independent). With
// everything stored, the pipeline runs once, as it always did.
// Pass 2 can keep its sums for pass 3 in the same memory (`keep_sums`): a
// frame's sum (8 bytes) takes less room than its band outputs (4 bytes per
// band) from 3 bands on, so the sums of the first `summed` frames fit
// (summed > stored) and pass 3 computes again only the frames past them,
// with a copy of the pipeline taken at frame `summed`.
class ChannelEngine {
public:
    ChannelEngine(const VocoderSettings& s, double rate, const std::vector<Sos>& band_filters,
                  const std::vector<double>& centres, int channel, std::size_t stored_frames, std::size_t frames,
                  bool keep_sums)
        : m_settings(s), m_centres(centres), m_pipeline(s, rate, band_filters, channel),
          m_lanes(band_filters.size()), m_stride(m_pipeline.bands.stride()), m_stored(stored_frames),
          m_summed(m_stored), m_store(stored_frames * m_lanes * sizeof(float)),
          m_out_sum_sq(m_stride, 0.0) {
        const std::size_t sum_room = stored_frames * m_lanes * sizeof(float) / sizeof(double);
        if (keep_sums && m_stored < frames && sum_room > m_stored) m_summed = std::min(frames, sum_room);
    }

    std::size_t lanes() const { return m_lanes; }
    std::size_t stride() const { return m_stride; }
    bool fused() const { return m_pipeline.fused; }
    // Runs the pipeline (and its copies) with a second thread (see Pipeline::worker).
    void use_worker(PairWorker* worker) { m_pipeline.worker = worker; }
    // The first frame the next replay computes again (and so reads the input from).
    std::size_t replay_from() const { return m_sums_kept ? m_summed : m_stored; }

    // Pass 1 over frames [first, first + count) (x[0] is frame `first`,
    // made ready by `fill`, see Pipeline::Fill); `work` and `carrier` are
    // scratch of count × stride.
    void measure(const double* x, std::size_t first, std::size_t count, std::vector<double>& work,
                 std::vector<double>& carrier, const Pipeline::Fill& fill = {}) {
        // Split at the end of the store and of the sums: replay pipelines start there.
        for (std::size_t edge : {m_stored, m_summed}) {
            if (first < edge && first + count > edge) {
                const std::size_t head = edge - first;
                measure(x, first, head, work, carrier, fill);
                Pipeline::Fill rest;
                if (fill) rest = [&fill, head](std::size_t offset, std::size_t n) { fill(head + offset, n); };
                measure(x + head, edge, count - head, work, carrier, rest);
                return;
            }
        }
        m_pipeline.ahead = nullptr;  // (replay copies start without)
        if (first == m_stored || (first == m_summed && m_summed > m_stored)) m_pipeline.settle();
        if (first == m_stored) m_replay_start.emplace(m_pipeline);
        if (first == m_summed && m_summed > m_stored) m_final_start.emplace(m_pipeline);
        detail::FusedBlock rows;
        rows.out_sum_sq = m_out_sum_sq.data();
        rows.in_sum_sq = &m_in_sq;
        if (first < m_stored) {
            rows.rows = rows_at(first);
            m_store.make_ready((first + count) * m_lanes * sizeof(float));
            m_pipeline.ahead = &m_store;
        }
        rows.lanes = m_lanes;
        m_pipeline.run(x, first, count, work, carrier, m_centres, rows, fill);
    }

    // After pass 1 over all `frames`: the band gains and what was measured.
    void finish_measure(std::size_t frames, std::vector<BandInfo>& bands) {
        m_pipeline.settle();
        m_gains.assign(m_stride, 0.0);  // padding lanes: 0
        const double count = static_cast<double>(frames);
        for (std::size_t b = 0; b < m_lanes; ++b) {
            m_gains[b] = 1.0;
            bands[b].analysis_rms = std::sqrt(m_pipeline.analysis_sum_sq[b] / count);
            const double rms = std::sqrt(m_out_sum_sq[b] / count);
            if (m_settings.match_band_rms && rms > 0.0) m_gains[b] = bands[b].analysis_rms / rms;
            bands[b].output_rms = rms * m_gains[b];
        }
        if (frames == m_stored) m_replay_start.reset();
    }

    // Starts a replay (pass 2 or 3) from frame 0.
    void begin_replay() {
        if (m_summed > m_stored && m_sums_written == m_summed) m_sums_kept = true;
        if (m_sums_kept) {
            if (m_final_start) m_replay.emplace(*m_final_start);
        } else if (m_replay_start) {
            m_replay.emplace(*m_replay_start);
        }
    }

    // The level-matched band sum of frames [first, first + count) (x[0] is
    // frame `first`; read only from replay_from() on), in order from 0:
    // where it is, `sum` or (with `keep`, for a block wholly in the store or
    // wholly between its end and `summed`) its place in the store. With
    // `band_signals`, also each band's level-matched output. With `keep`,
    // the sums of frames before `summed` are kept for the next replay (which
    // then reads them); only in one replay over all frames. With `then` too,
    // the sums made in the store go to `then` instead, in order (see
    // Pipeline::Then; on the worker when there is one), and this returns null.
    const double* replay(const double* x, std::size_t first, std::size_t count, double* sum,
                         std::vector<double>& work, std::vector<double>& carrier,
                         std::vector<std::vector<double>>* band_signals = nullptr, bool keep = false,
                         const Pipeline::Then& then = {}) {
        // Sums kept, of a block wholly in the store or wholly past it:
        // made in their place in the store.
        if (keep && m_summed > m_stored && !m_sums_kept && !band_signals &&
            (first + count <= m_stored || (first >= m_stored && first + count <= m_summed))) {
            AVSI_ASSERT(first == m_sums_written);
            unsigned char* to = m_store.get() + first * sizeof(double);
            const double* sums = reinterpret_cast<const double*>(to);
            m_sums_written += count;
            if (first < m_stored) {
                sum_rows(m_store.get() + first * m_lanes * sizeof(float), count, m_stride > m_lanes, to);
                if (!then) return sums;
                // On the worker while this thread sums the next block's rows.
                if (PairWorker* worker = m_pipeline.worker)
                    worker->start([then, sums, count] { then(sums, count); });
                else
                    then(sums, count);
                return nullptr;
            }
            // (Over rows this replay has read: it is past the store.)
            AVSI_ASSERT(m_replay);
            detail::FusedBlock rows;
            rows.gains = m_gains.data();
            rows.sum = reinterpret_cast<double*>(to);
            m_replay->run(x, first, count, work, carrier, m_centres, rows, {}, then);
            return then ? nullptr : sums;
        }
        replay_into(x, first, count, sum, work, carrier, band_signals, keep);
        return sum;
    }

    double in_sq() const { return m_in_sq; }

private:
    // replay's work, into `sum`.
    void replay_into(const double* x, std::size_t first, std::size_t count, double* sum, std::vector<double>& work,
                     std::vector<double>& carrier, std::vector<std::vector<double>>* band_signals, bool keep) {
        const std::size_t from = replay_from();
        if (first < from && first + count > from) {
            const std::size_t head = from - first;
            replay_into(x, first, head, sum, work, carrier, band_signals, keep);
            replay_into(x + head, from, count - head, sum + head, work, carrier, band_signals, keep);
            return;
        }
        if (keep && m_summed > m_stored && first < m_summed && first + count > m_summed) {
            const std::size_t head = m_summed - first;
            replay_into(x, first, head, sum, work, carrier, band_signals, keep);
            replay_into(x + head, m_summed, count - head, sum + head, work, carrier, band_signals, keep);
            return;
        }
        if (m_sums_kept && first < m_summed) {
            std::memcpy(sum, m_store.get() + first * sizeof(double), count * sizeof(double));
            return;
        }
        if (first < m_stored) {
            // The sum as the pipeline's rows give it: over the stride's
            // lanes, whose padding lanes hold +0 with gain 0 and so add
            // +0.0 (which turns a -0 sum into +0).
            const float* rows = rows_at(first);
            sum_rows(reinterpret_cast<const unsigned char*>(rows), count, m_stride > m_lanes,
                     reinterpret_cast<unsigned char*>(sum));
            if (band_signals)
                for (std::size_t b = 0; b < m_lanes; ++b)
                    for (std::size_t n = 0; n < count; ++n)
                        (*band_signals)[b][first + n] = m_gains[b] * rows[n * m_lanes + b];
        } else {
            AVSI_ASSERT(m_replay && !band_signals);
            detail::FusedBlock rows;
            rows.gains = m_gains.data();
            rows.sum = sum;
            m_replay->run(x, first, count, work, carrier, m_centres, rows);
        }
        // Frame n's sum goes to bytes [8n, 8n + 8), which hold band outputs
        // of frames before n·8/(4·lanes) ≤ n only: read already.
        if (keep && m_summed > m_stored && first < m_summed) {
            AVSI_ASSERT(first == m_sums_written);
            std::memcpy(m_store.get() + first * sizeof(double), sum, count * sizeof(double));
            m_sums_written += count;
        }
    }

public:
    // The kept sums of frames [first, first + count) when the next replay
    // reads them all from the store, else null.
    const double* kept_sums(std::size_t first, std::size_t count) const {
        if (!m_sums_kept || first + count > m_summed) return nullptr;
        return reinterpret_cast<const double*>(m_store.get()) + first;
    }

    // In the last replay, once the sums of frames before `frame` are read
    // for the last time: their part of the store is given back (when the
    // replay reads kept sums; otherwise the store goes at the end).
    void done_with(std::size_t frame) {
        if (m_sums_kept) m_store.release(std::min(frame, m_summed) * sizeof(double));
    }

private:
    float* rows_at(std::size_t frame) {
        return reinterpret_cast<float*>(m_store.get()) + frame * m_lanes;
    }
    // sum[n] = Σ_b gains[b]·rows[n][b] in band order from 0.0 (+ 0.0 when
    // padded); four frames at a time, each frame's operations in that order.
    // Through bytes (memcpy, which the compiler keeps in order with every
    // access that may overlap), so that `sum` may be the store over the rows
    // themselves: frame n's sum (bytes [8n, 8n + 8)) overwrites only rows of
    // frames f < 2(n + 1) / lanes ≤ n (sums are kept there from 3 bands
    // on), read in n's group of four or before it.
    void sum_rows(const unsigned char* rows, std::size_t count, bool padded, unsigned char* sum) const {
        auto row = [rows](std::size_t at) {
            float v;
            std::memcpy(&v, rows + at * sizeof(float), sizeof v);
            return static_cast<double>(v);
        };
        auto put = [sum](std::size_t n, double v) { std::memcpy(sum + n * sizeof(double), &v, sizeof v); };
        auto run = [&](auto lanes_constant) {
            constexpr std::size_t L = decltype(lanes_constant)::value;
            const std::size_t lanes = L ? L : m_lanes;
            std::size_t n = 0;
            for (; n + 4 <= count; n += 4) {
                double s[4] = {0.0, 0.0, 0.0, 0.0};
                for (std::size_t b = 0; b < lanes; ++b)
                    for (std::size_t j = 0; j < 4; ++j) s[j] += m_gains[b] * row((n + j) * lanes + b);
                for (std::size_t j = 0; j < 4; ++j) put(n + j, padded ? s[j] + 0.0 : s[j]);
            }
            for (; n < count; ++n) {
                double s = 0.0;
                for (std::size_t b = 0; b < lanes; ++b) s += m_gains[b] * row(n * lanes + b);
                put(n, padded ? s + 0.0 : s);
            }
        };
        switch (m_lanes) {
            case 1: run(std::integral_constant<std::size_t, 1>{}); break;
            case 2: run(std::integral_constant<std::size_t, 2>{}); break;
            case 3: run(std::integral_constant<std::size_t, 3>{}); break;
            case 4: run(std::integral_constant<std::size_t, 4>{}); break;
            default: run(std::integral_constant<std::size_t, 0>{}); break;
        }
    }

    const VocoderSettings& m_settings;
    const std::vector<double>& m_centres;
    Pipeline m_pipeline;
    std::size_t m_lanes, m_stride, m_stored, m_summed;
    // [frame][band] floats of the first m_stored frames; after a replay
    // with `keep`, the doubles of the first m_summed frames' sums.
    StoreBuffer m_store;
    std::size_t m_sums_written = 0;  // by the replay with `keep`
    bool m_sums_kept = false;         // the next replays read them
    std::vector<double> m_out_sum_sq;
    double m_in_sq = 0.0;
    std::vector<double> m_gains;
    std::optional<Pipeline> m_replay_start, m_final_start, m_replay;
};

// Zero-phase filtering, Hilbert envelopes and low-noise carriers need the
// whole signal at once.
bool whole_signal_only(const VocoderSettings& s) {
    return s.zero_phase || s.envelope == EnvelopeMethod::Hilbert || s.carrier == CarrierType::LowNoise;
}

struct BandSetup {
    std::vector<Sos> filters;
    std::vector<double> centres;
    std::vector<BandInfo> bands;
};

BandSetup band_setup(const VocoderSettings& s, double rate) {
    const std::vector<double> edges = band_edges_hz(s);
    BandSetup setup;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        setup.filters.push_back(butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate));
        BandInfo info;
        info.low_hz = edges[b];
        info.high_hz = edges[b + 1];
        info.centre_hz = std::sqrt(edges[b] * edges[b + 1]);
        setup.centres.push_back(info.centre_hz);
        setup.bands.push_back(info);
    }
    return setup;
}

}  // namespace

namespace detail {

ChannelResult vocode_channel_in_blocks(std::span<const double> x, double rate, const VocoderSettings& s,
                                       int channel, bool keep_band_signals, std::size_t block_frames) {
    validate_settings(s, rate);
    const std::size_t frames = x.size();
    BandSetup setup = band_setup(s, rate);
    ChannelResult result;
    result.bands = setup.bands;
    result.samples.assign(frames, 0.0);
    if (frames == 0) return result;
    const std::size_t block =
        whole_signal_only(s) ? frames : std::max<std::size_t>(1, std::min(block_frames, frames));
    ChannelEngine engine(s, rate, setup.filters, setup.centres, channel, frames, frames, false);
    std::vector<double> work(block * engine.stride()), carrier(block * engine.stride());
    for (std::size_t first = 0; first < frames; first += block)
        engine.measure(x.data() + first, first, std::min(block, frames - first), work, carrier);
    engine.finish_measure(frames, result.bands);
    std::vector<std::vector<double>> band_signals;
    if (keep_band_signals) band_signals.assign(engine.lanes(), std::vector<double>(frames));
    engine.begin_replay();
    double out_sq = 0.0;
    for (std::size_t first = 0; first < frames; first += block) {
        const std::size_t count = std::min(block, frames - first);
        engine.replay(x.data() + first, first, count, result.samples.data() + first, work, carrier,
                      keep_band_signals ? &band_signals : nullptr);
    }
    for (double v : result.samples) out_sq += v * v;
    result.band_signals = std::move(band_signals);
    if (s.match_output_rms && out_sq > 0.0) {
        const double in_sq = engine.in_sq();
        const double gain = std::sqrt(in_sq / out_sq);
        for (double& v : result.samples) v *= gain;
        result.output_gain_db = in_sq > 0.0 ? to_db(gain) : -INFINITY;
    }
    return result;
}

VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& s,
                            const StreamLimits& limits) {
    const int channels = input.channels();
    const double rate = input.sample_rate_hz();
    if (channels < 1 || rate <= 0)
        throw InputError(Diagnostic{"", 0, 0, "audio",
                                    fmt::format("expected at least one channel and a positive sample "
                                                "rate, got {} channels at {} Hz",
                                                channels, input.sample_rate_hz())});
    validate_settings(s, rate);
    const std::size_t frames = input.frames();
    const std::size_t nc = static_cast<std::size_t>(channels);
    BandSetup setup = band_setup(s, rate);
    VocoderReport report;
    report.bands = setup.bands;
    if (frames == 0) return report;

    // Block length; what is stored from pass 1 (everything when it fits in
    // the budget, or when the settings need the whole signal at once).
    const bool whole = whole_signal_only(s);
    const std::size_t block = whole ? frames : std::max<std::size_t>(1, std::min(limits.block_frames, frames));
    const std::size_t per_frame = setup.filters.size() * nc * sizeof(float);
    const std::size_t stored = whole ? frames : std::min(frames, limits.store_bytes / per_frame);

    std::vector<std::unique_ptr<ChannelEngine>> engines;
    // Every channel gets channel 0's noise carrier: a dual-mono input stays
    // dual-mono (independent carriers would make it dichotic).
    for (int c = 0; c < channels; ++c)
        engines.push_back(std::make_unique<ChannelEngine>(s, rate, setup.filters, setup.centres, 0, stored, frames, true));
    const std::size_t stride = engines.front()->stride();
    // Pass 3's output blocks, two so that the worker writes one while the
    // next is filled (declared before the worker, which may still be
    // writing one when an exception unwinds: it finishes before they go).
    std::vector<float> out[2] = {std::vector<float>(block * nc), std::vector<float>(block * nc)};
    // The same as 16-bit samples, when the output takes them (converted
    // here, so that the worker only writes).
    const bool pcm16 = output.takes_pcm16();
    std::vector<std::int16_t> out16[2];
    if (pcm16) out16[0].resize(block * nc), out16[1].resize(block * nc);
    // So are the pipeline's buffers (the worker may be running the back of
    // a block's last piece when the next block's reading throws) and pass
    // 2's energies and peaks (which it may be adding to).
    // The input's frames as read: its 16-bit samples when it gives them
    // (libsndfile's floats of those are s·2^-15, exact, and so is s·2^-15
    // as a double: the same x, without a conversion inside libsndfile and
    // an 8 KiB read per 4096 samples), else floats.
    const bool pcm16_in = input.gives_pcm16();
    std::vector<float> interleaved(pcm16_in ? 0 : block * nc);
    std::vector<std::int16_t> interleaved16(pcm16_in ? block * nc : 0);
    std::vector<double> x(block), work(block * stride), carrier(block * stride), sum(block);
    std::vector<double> out_sq(nc, 0.0), max_abs(nc, 0.0);
    // Declared after the engines so it stops before they go.
    std::optional<PairWorker> worker;
    if (limits.threads >= 2 && engines.front()->fused() && block > Pipeline::kPieceFrames &&
        frames > Pipeline::kPieceFrames) {
        worker.emplace();
        for (auto& engine : engines) engine->use_worker(&*worker);
    }
    // Reads frames [offset, offset + count) of channel c into x.
    auto deinterleave = [&](std::size_t offset, std::size_t count, std::size_t c) {
        if (pcm16_in)
            for (std::size_t n = offset; n < offset + count; ++n) x[n] = interleaved16[n * nc + c] * (1.0 / 32768.0);
        else
            for (std::size_t n = offset; n < offset + count; ++n) x[n] = interleaved[n * nc + c];
    };
    // Reads the next `count` frames of the input into the block from `offset`.
    auto read_frames = [&](std::size_t offset, std::size_t count) {
        std::size_t got = 0;
        while (got < count) {
            const std::size_t n = pcm16_in ? input.read_pcm16(interleaved16.data() + (offset + got) * nc, count - got)
                                           : input.read(interleaved.data() + (offset + got) * nc, count - got);
            if (n == 0)
                throw InputError(Diagnostic{"", 0, 0, "audio",
                                            fmt::format("expected {} frames, the input ended after fewer", frames)});
            got += n;
        }
    };

    // Pass 1: measure. Channel 0's pipeline reads the block piece by piece
    // as it goes (see Pipeline::Fill); the other channels' find it read.
    input.seek(0);
    for (std::size_t first = 0; first < frames; first += block) {
        const std::size_t count = std::min(block, frames - first);
        for (std::size_t c = 0; c < nc; ++c)
            engines[c]->measure(x.data(), first, count, work, carrier, [&, c](std::size_t offset, std::size_t n) {
                if (c == 0) read_frames(offset, n);
                deinterleave(offset, n, c);
            });
    }
    std::vector<std::vector<BandInfo>> bands(nc, setup.bands);
    for (std::size_t c = 0; c < nc; ++c) engines[c]->finish_measure(frames, bands[c]);
    report.bands = bands[0];

    // Replays (passes 2 and 3): the input is read only past the store.
    // With `keep`, the engines keep what sums fit for the next replay.
    // `sums`: the block's sums for `consume` (`sum`, or the engine's store).
    const double* sums = nullptr;
    // Pass 3 writes its blocks on the worker, when there is one (a
    // pipeline that needs the worker waits for the write first).
    // `then_of(c)`: channel c's Pipeline::Then for the sums made in the store
    // (which then skip `consume`).
    auto replay = [&](auto&& consume, bool keep, auto&& then_of) {
        for (auto& engine : engines) engine->begin_replay();
        const std::size_t stored = engines.front()->replay_from();  // the same for every channel
        if (stored < frames) input.seek(stored);
        for (std::size_t first = 0; first < frames; first += block) {
            const std::size_t count = std::min(block, frames - first);
            const std::size_t from_input = first + count > stored ? first + count - std::max(first, stored) : 0;
            // Read the frames past the store into their place in the block.
            if (from_input > 0) read_frames(count - from_input, from_input);
            for (std::size_t c = 0; c < nc; ++c) {
                if (from_input > 0) deinterleave(0, count, c);
                sums = engines[c]->kept_sums(first, count);
                if (!sums) {
                    sums = engines[c]->replay(x.data(), first, count, sum.data(), work, carrier, nullptr, keep,
                                              then_of(c));
                    if (!sums) continue;
                }
                consume(c, first, count);
            }
        }
    };

    // Pass 2: the sum's energy and peak per channel, then the gains. The
    // energy is one chain of additions in frame order (4 cycles each), as
    // long as the sums of the stored rows take to make: so with the worker,
    // the sums made in the store are added up there, by the worker: a stored
    // block's while this thread sums the next block's rows, and a block past
    // the store piece by piece after each piece's back, so that this thread
    // goes on to the next block's input and fronts without waiting for the
    // last back (the worker's jobs run one at a time, in order; a block
    // added up here waits for the worker first).
    auto add_up = [](const double* sums_of_block, std::size_t count, double* sq_sum, double* top_abs) {
        double sq = *sq_sum, top = *top_abs;
        for (std::size_t n = 0; n < count; ++n) {
            sq += sums_of_block[n] * sums_of_block[n];
            top = std::max(top, std::abs(sums_of_block[n]));
        }
        *sq_sum = sq;
        *top_abs = top;
    };
    replay(
        [&](std::size_t c, std::size_t, std::size_t count) {
            if (worker) worker->wait();
            add_up(sums, count, &out_sq[c], &max_abs[c]);
        },
        true,
        [&](std::size_t c) -> Pipeline::Then {
            if (!worker) return {};
            return [add_up, sq = &out_sq[c], top = &max_abs[c]](const double* s, std::size_t n) { add_up(s, n, sq, top); };
        });
    if (worker) worker->wait();
    std::vector<double> gain(nc, 1.0);
    std::vector<bool> apply_gain(nc, false);
    double peak = 0.0;
    for (std::size_t c = 0; c < nc; ++c) {
        if (s.match_output_rms && out_sq[c] > 0.0) {
            const double in_sq = engines[c]->in_sq();
            gain[c] = std::sqrt(in_sq / out_sq[c]);
            apply_gain[c] = true;
            if (c == 0) report.output_gain_db = in_sq > 0.0 ? to_db(gain[c]) : -INFINITY;
        }
        // Rounding is monotonic, so the peak of the scaled samples is the
        // scaled peak.
        peak = std::max(peak, apply_gain[c] ? max_abs[c] * gain[c] : max_abs[c]);
    }
    // No clipping: scale the whole output down when its peak exceeds full scale.
    report.peak_before_limit = peak;
    double scale = 1.0;
    constexpr double kMaxPeak = 0.999;
    if (peak > 1.0) {
        scale = kMaxPeak / peak;
        report.limit_gain_db = to_db(scale);
        log_warning("vocoder: output peak {:.3f} exceeds full scale; scaled the whole output by {:.2f} dB "
                    "to avoid clipping",
                    peak, report.limit_gain_db);
    }

    // Pass 3: the output (block k written on the worker while block k + 1
    // is filled, into the other buffer).
    std::size_t current = 0;
    // Every so many frames, this thread starts the disk writes of what the
    // worker wrote (while it writes the next block), so that the output's
    // fsync at the end waits for the last few only.
    constexpr std::size_t kWritebackFrames = std::size_t{1} << 21;
    std::size_t unflushed = 0;
    replay(
        [&](std::size_t c, std::size_t first, std::size_t count) {
            float* o = out[current].data();
            const double g = gain[c];
            if (apply_gain[c])
                for (std::size_t n = 0; n < count; ++n) o[n * nc + c] = static_cast<float>(sums[n] * g * scale);
            else
                for (std::size_t n = 0; n < count; ++n) o[n * nc + c] = static_cast<float>(sums[n] * scale);
            if (c + 1 < nc) return;
            std::int16_t* o16 = out16[current].data();
            if (pcm16) float_to_pcm16(o, count * nc, o16);
            if (!worker) {
                pcm16 ? output.write_pcm16(o16, count) : output.write(o, count);
                return;
            }
            if (unflushed >= kWritebackFrames) {
                unflushed = 0;
                output.start_writeback();
            }
            // (start waits for the block before's write.) The worker then
            // gives back the store's memory of the sums read so far.
            auto done_with = [&engines, end = first + count] {
                for (auto& engine : engines) engine->done_with(end);
            };
            if (pcm16)
                worker->start([&output, o16, count, done_with] {
                    output.write_pcm16(o16, count);
                    done_with();
                });
            else
                worker->start([&output, o, count, done_with] {
                    output.write(o, count);
                    done_with();
                });
            unflushed += count;
            current = 1 - current;
        },
        false, [](std::size_t) { return Pipeline::Then{}; });
    if (worker) worker->wait();
    return report;
}

}  // namespace detail

ChannelResult vocode_channel(std::span<const double> x, double rate, const VocoderSettings& s, int channel,
                             bool keep_band_signals) {
    return detail::vocode_channel_in_blocks(x, rate, s, channel, keep_band_signals, 512);
}

// One thread: these are called by code that runs several at once (stimulus
// builds, batches); `avsi vocode` of one file asks for two (batch.cpp).
VocoderReport vocode_stream(AudioSource& input, AudioSink& output, const VocoderSettings& settings) {
    detail::StreamLimits limits;
    limits.threads = 1;
    return detail::vocode_stream(input, output, settings, limits);
}

VocoderResult vocode(const Audio& input, const VocoderSettings& settings) {
    AudioBufferSource source(input);
    VocoderResult result;
    result.audio.sample_rate_hz = input.sample_rate_hz;
    result.audio.channels = input.channels;
    result.audio.samples.reserve(input.samples.size());
    AudioBufferSink sink(result.audio);
    detail::StreamLimits limits;
    limits.threads = 1;
    VocoderReport report = detail::vocode_stream(source, sink, settings, limits);
    result.bands = std::move(report.bands);
    result.output_gain_db = report.output_gain_db;
    result.peak_before_limit = report.peak_before_limit;
    result.limit_gain_db = report.limit_gain_db;
    return result;
}

// ------------------------------------------------------------- report

std::string describe(const VocoderSettings& s, double rate) {
    validate_settings(s, rate);
    const std::vector<double> edges = band_edges_hz(s);
    std::vector<double> centres;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) centres.push_back(std::sqrt(edges[b] * edges[b + 1]));
    const int slope_db = 6 * s.filter_order * (s.zero_phase ? 2 : 1);
    const std::string phase = s.zero_phase
                                  ? "zero-phase (applied forward then backward in time, which squares the "
                                    "magnitude response: -6 dB at the edges, slopes doubled)"
                                  : "causal (single forward pass, non-linear phase)";
    std::string spacing;
    switch (s.spacing) {
        case BandSpacing::Greenwood:
            spacing = "Greenwood (1990) spacing: equal steps of relative cochlear place x, "
                      "F = 165.4·(10^(2.1x) − 0.88) Hz";
            break;
        case BandSpacing::Log: spacing = "logarithmic spacing (equal frequency ratios)"; break;
        case BandSpacing::Linear: spacing = "linear spacing (equal widths in Hz)"; break;
        case BandSpacing::Explicit: spacing = "explicit band edges"; break;
    }
    std::string envelope;
    switch (s.envelope) {
        case EnvelopeMethod::HalfWaveRectify: envelope = "half-wave rectification"; break;
        case EnvelopeMethod::FullWaveRectify: envelope = "full-wave rectification"; break;
        case EnvelopeMethod::Hilbert: envelope = "Hilbert transform (magnitude of the analytic signal, by FFT)"; break;
    }
    std::string carrier;
    switch (s.carrier) {
        case CarrierType::Noise:
            carrier = fmt::format("white noise (uniform amplitude distribution, xoshiro256** generator), an "
                                  "independent stream per band, the same on every channel, derived from seed {}",
                                  s.seed);
            break;
        case CarrierType::Sine:
            carrier = "sine at each band's geometric centre frequency (" + join_hz(centres) + " Hz), zero starting phase";
            break;
        case CarrierType::LowNoise:
            carrier = fmt::format("low-noise noise (Pumplin 1985; Kohlrausch et al. 1997): seeded white noise "
                                  "(seed {}) band-pass filtered, then {} times divided by its Hilbert envelope "
                                  "and band-pass filtered again",
                                  s.seed, s.low_noise_iterations);
            break;
    }

    std::string out;
    auto line = [&](std::string_view label, const std::string& text) {
        out += fmt::format("{:<22}{}\n", std::string(label) + ":", text);
    };
    line("Processing", "noise-excited channel vocoder (Shannon et al. 1995); no pre-emphasis");
    line("Sample rate", fmt::format("{} Hz (processing in double precision at the input rate)", format_hz(rate)));
    line("Channels", fmt::format("{} analysis bands, {}–{} Hz, {}", s.bands, format_hz(s.low_hz),
                                 format_hz(s.high_hz), spacing));
    line("Band edges (Hz)", join_hz(edges));
    line("Band centres (Hz)", join_hz(centres) + " (geometric)");
    line("Analysis filters",
         fmt::format("Butterworth band-pass, {}-order low-pass prototype ({} poles, {} second-order "
                     "sections per band), bilinear transform with pre-warped edges, -3 dB at the band "
                     "edges, skirts {} dB/octave; {}",
                     ordinal(s.filter_order), 2 * s.filter_order, s.filter_order, slope_db, phase));
    if (!s.zero_phase) {
        // Group delay at each band centre, -dφ/dω by a central difference of
        // the analysis filter's phase (the re-filter adds as much again).
        std::vector<double> delays_ms;
        for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
            const Sos sos = butterworth_bandpass(s.filter_order, edges[b], edges[b + 1], rate);
            const double df = 1e-3 * (edges[b + 1] - edges[b]);
            const double dphi = std::arg(sos_response(sos, centres[b] + df, rate) /
                                         sos_response(sos, centres[b] - df, rate));
            delays_ms.push_back(-dphi / (2.0 * std::numbers::pi * 2.0 * df) * 1000.0);
        }
        std::string text;
        for (std::size_t b = 0; b < delays_ms.size(); ++b) text += fmt::format("{}{:.2f}", b ? ", " : "", delays_ms[b]);
        line("Group delay (ms)", text + " at the band centres, per analysis filter pass (causal filtering "
                                        "delays narrow bands most; use zero phase to avoid it)");
    }
    line("Envelope", fmt::format("{}, then a {}-order Butterworth low-pass at {} Hz ({} dB/octave, {}); "
                                 "negative values of the smoothed envelope set to 0",
                                 envelope, ordinal(s.envelope_filter_order), format_hz(s.envelope_cutoff_hz),
                                 6 * s.envelope_filter_order * (s.zero_phase ? 2 : 1),
                                 s.zero_phase ? "zero-phase" : "causal"));
    line("Carrier", carrier);
    line("Carrier filtering",
         fmt::format("{} before modulation; {} after modulation",
                     s.prefilter_carrier ? "band-pass filtered through its analysis band" : "not filtered",
                     s.refilter_carrier ? "band-pass filtered through its analysis band (same filter as the analysis)"
                                        : "not filtered"));
    line("Level matching",
         fmt::format("{}; {}; if the output peak would exceed full scale, the whole output is scaled down "
                     "to a peak of 0.999 (logged and reported per file), never clipped",
                     s.match_band_rms ? "each band's output RMS set to its analysis band's RMS (whole signal)"
                                      : "no per-band level matching",
                     s.match_output_rms ? "the summed output's RMS set to the input's RMS (whole signal)"
                                        : "no overall level matching"));
    line("Seed", fmt::format("{} (output is fully determined by the input, these settings and the seed)", s.seed));
    if (s.carrier == CarrierType::Sine) {
        double narrowest = INFINITY;
        for (std::size_t b = 0; b + 1 < edges.size(); ++b) narrowest = std::min(narrowest, edges[b + 1] - edges[b]);
        if (s.envelope_cutoff_hz > narrowest / 2.0)
            line("Note", fmt::format("the envelope cutoff ({} Hz) exceeds half the narrowest band's width "
                                     "({} Hz): with sine carriers, envelope sidebands may be resolved "
                                     "(Cychosz et al. 2024)",
                                     format_hz(s.envelope_cutoff_hz), format_hz(narrowest / 2.0)));
    }
    return out;
}

}  // namespace avsi::vocoder
