// The store's memory and its page faults; see store_buffer.h.
#include "store_buffer.h"

#include <algorithm>
#include <cstdlib>
#include <new>

#include <sys/mman.h>

namespace avsi::vocoder::detail {

StoreBuffer::StoreBuffer(std::size_t bytes) : m_bytes(bytes) {
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

StoreBuffer::~StoreBuffer() { std::free(m_data); }

void StoreBuffer::make_ready(std::size_t upto) {
    upto = std::min(upto, m_bytes);
    m_limit.store(std::min(m_bytes, upto + kAhead), std::memory_order_relaxed);
    while (m_claimed.load(std::memory_order_relaxed) < upto) populate_next(upto);
}

void StoreBuffer::release(std::size_t upto) {
    if (m_bytes < kHuge) return;  // malloc'd
    upto = std::min(upto, m_bytes) / kHuge * kHuge;
    if (upto <= m_released) return;
    ::madvise(m_data + m_released, upto - m_released, MADV_DONTNEED);  // advice only: failure keeps them
    m_released = upto;
}

bool StoreBuffer::populate_next(std::size_t limit) {
    std::size_t at = m_claimed.load(std::memory_order_relaxed);
    for (;;) {
        if (at >= limit) return false;
        const bool huge = m_huge.load(std::memory_order_relaxed);
        const std::size_t huge_end = std::min(m_bytes, (at / kHuge + 1) * kHuge);
        const std::size_t end = huge ? huge_end
                                     : std::min({huge_end, (at / kSmallStep + 1) * kSmallStep,
                                                 (limit + kPage - 1) / kPage * kPage});
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

void StoreBuffer::populate(std::size_t from, std::size_t to) {
#ifdef MADV_POPULATE_WRITE
    const std::size_t page_from = from / kPage * kPage;
    if (::madvise(m_data + page_from, to - page_from, MADV_POPULATE_WRITE) == 0) return;
#endif
    for (std::size_t at = from; at < to; at = (at / kPage + 1) * kPage)
        reinterpret_cast<volatile unsigned char*>(m_data)[at] = 0;
}

}  // namespace avsi::vocoder::detail
