// The memory of the fast path's store (channel_engine.h): pass 1's band
// outputs, then pass 2's sums, written once from the start onwards and read
// in order by the replays. Nothing here changes a value; it decides only
// where the page faults of a large store happen.
//
// A store of 2 MiB or more is 2 MiB-aligned and advised for huge pages, and
// is made resident ahead of its first writes, so that its page faults run
// beside the filters rather than inside them: make_ready on the thread that
// writes it, populate_ahead on the worker while it waits for that thread;
// both take the next part from one cursor. Each huge page's fault is timed:
// after one slower than kSlowHugeFault (memory that the host must back
// again, as on a virtual machine that hands free memory back to it) the
// rest of the store takes 4 KiB pages. docs/performance.md ("The vocoder's
// fast path") gives the measurements behind these choices.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>

namespace avsi::vocoder::detail {

class StoreBuffer {
public:
    // `bytes` of uninitialised memory; throws std::bad_alloc.
    explicit StoreBuffer(std::size_t bytes);
    ~StoreBuffer();
    StoreBuffer(const StoreBuffer&) = delete;
    StoreBuffer& operator=(const StoreBuffer&) = delete;

    unsigned char* get() const { return m_data; }

    // Sees that bytes [0, upto) are resident, or being faulted in by the
    // other thread, before they are first written (called ahead of the
    // thread that writes them; touches no byte it has written), and lets
    // populate_ahead go on to kAhead bytes further.
    void make_ready(std::size_t upto);

    // Gives the memory of bytes [0, upto) back to the system, in whole huge
    // pages (those left go with the store): for a pass that has read them for
    // the last time, so that freeing them runs beside its work rather than at
    // the end.
    void release(std::size_t upto);

    // Faults in the next part of the store below the limit make_ready set,
    // if any: whether there was one.
    bool populate_ahead() { return populate_next(m_limit.load(std::memory_order_relaxed)); }

private:
    static constexpr std::size_t kHuge = std::size_t{2} << 20;
    static constexpr std::size_t kPage = 4096;
    // 4 KiB pages are faulted in this many bytes at a time.
    static constexpr std::size_t kSmallStep = std::size_t{64} << 10;
    static constexpr std::size_t kAhead = std::size_t{1} << 20;
    // A huge page whose fault takes longer than this had to be backed by the
    // host: several times what one from memory at hand takes.
    static constexpr std::chrono::microseconds kSlowHugeFault{1000};

    // Claims and faults in the next part below `limit`: a huge page (the
    // kernel faults it in whole), else up to kSmallStep bytes.
    bool populate_next(std::size_t limit);

    // Faults in bytes [from, to) for writing (MADV_POPULATE_WRITE, Linux
    // 5.14; else a write to each page, of a byte not yet written).
    void populate(std::size_t from, std::size_t to);

    unsigned char* m_data = nullptr;
    std::size_t m_bytes = 0;
    std::atomic<std::size_t> m_claimed{0};  // bytes [0, m_claimed) are resident or being faulted in
    std::atomic<std::size_t> m_limit{0};    // populate_ahead's bound
    std::atomic<bool> m_huge{false};        // the rest takes huge pages
    std::size_t m_released = 0;             // bytes [0, m_released) given back
};

}  // namespace avsi::vocoder::detail
