// A minimal binary message format for the TTS engines' child processes
// (tts.cpp, festival_tts.cpp): 64-bit integers, doubles, length-prefixed
// strings and raw bytes, in the machine's byte order (both ends are the same
// executable). Private to avsi_core.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

namespace avsi::detail {

class WireWriter {
public:
    void i64(std::int64_t v) { bytes(&v, sizeof v); }
    void f64(double v) { bytes(&v, sizeof v); }
    void str(const std::string& v) {
        i64(static_cast<std::int64_t>(v.size()));
        bytes(v.data(), v.size());
    }
    void bytes(const void* data, std::size_t n) { m_out.append(static_cast<const char*>(data), n); }
    const std::string& data() const { return m_out; }
    void clear() { m_out.clear(); }

private:
    std::string m_out;
};

// Reads what a WireWriter wrote; throws std::runtime_error naming `what` on a
// truncated or malformed message.
class WireReader {
public:
    WireReader(const std::string& in, const char* what) : m_in(in), m_what(what) {}
    std::int64_t i64() {
        std::int64_t v = 0;
        bytes(&v, sizeof v);
        return v;
    }
    double f64() {
        double v = 0;
        bytes(&v, sizeof v);
        return v;
    }
    // A count of items each at least `min_item_bytes` long, checked against what is left.
    std::size_t count(std::size_t min_item_bytes) {
        const std::int64_t n = i64();
        if (n < 0 || static_cast<std::uint64_t>(n) > (m_in.size() - m_pos) / std::max<std::size_t>(1, min_item_bytes))
            throw std::runtime_error(std::string(m_what) + ": malformed message");
        return static_cast<std::size_t>(n);
    }
    std::string str() {
        const std::size_t n = count(1);
        std::string v = m_in.substr(m_pos, n);
        m_pos += n;
        return v;
    }
    void bytes(void* data, std::size_t n) {
        if (n > m_in.size() - m_pos) throw std::runtime_error(std::string(m_what) + ": truncated message");
        std::memcpy(data, m_in.data() + m_pos, n);
        m_pos += n;
    }

private:
    const std::string& m_in;
    const char* m_what;
    std::size_t m_pos = 0;
};

}  // namespace avsi::detail
