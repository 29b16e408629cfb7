// Seeded random numbers whose streams are identical on every platform and
// compiler: xoshiro256** seeded through SplitMix64, with our own uniform and
// normal transforms (std:: distributions are not specified bit-for-bit).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

namespace avsi {

class Rng {
public:
    explicit Rng(std::uint64_t seed);

    // A generator for a named sub-stream, independent of this one's state:
    // Rng(seed).derive("carrier/band2") is the same wherever it is called.
    Rng derive(std::string_view stream) const;

    std::uint64_t next_u64();
    // Uniform in [0, 1).
    double uniform();
    // Uniform in [lo, hi).
    double uniform(double lo, double hi);
    // Uniform integer in [0, n), unbiased; n > 0.
    std::uint64_t uniform_int(std::uint64_t n);
    // Standard normal (Box-Muller, cached pair).
    double normal();
    double normal(double mean, double sd) { return mean + sd * normal(); }

    std::uint64_t seed() const { return m_seed; }
    // The xoshiro256** state, for code that runs several streams side by
    // side in vector registers (the vocoder's carriers) and must draw the
    // same numbers as next_u64().
    const std::array<std::uint64_t, 4>& state() const { return m_state; }

private:
    std::uint64_t m_seed;
    std::array<std::uint64_t, 4> m_state{};
    bool m_has_spare = false;
    double m_spare = 0.0;
};

// A 64-bit seed derived from a base seed and a name (FNV-1a mixed by SplitMix64).
std::uint64_t derive_seed(std::uint64_t seed, std::string_view name);

}  // namespace avsi
