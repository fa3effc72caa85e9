#pragma once
// A small portable random generator (xoshiro256** seeded by splitmix64):
// the same numbers on every platform and standard library, which
// std::uniform_*_distribution does not promise. Private to optim.

#include <cmath>
#include <cstdint>

namespace flowvid::optim::detail {

inline std::uint64_t splitmix64(std::uint64_t& state) {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// A seed for stream `index` of `seed` (independent runs of one analysis).
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t index) {
    std::uint64_t state = seed ^ (0xD1B54A32D192ED03ull * (index + 1));
    return splitmix64(state);
}

class Random {
public:
    explicit Random(std::uint64_t seed) {
        std::uint64_t state = seed;
        for (auto& word : m_s) word = splitmix64(state);
    }

    std::uint64_t next() {
        const std::uint64_t result = rotl(m_s[1] * 5, 7) * 9;
        const std::uint64_t t = m_s[1] << 17;
        m_s[2] ^= m_s[0];
        m_s[3] ^= m_s[1];
        m_s[1] ^= m_s[2];
        m_s[0] ^= m_s[3];
        m_s[2] ^= t;
        m_s[3] = rotl(m_s[3], 45);
        return result;
    }

    // Uniform in (0, 1]: never 0, so log() of it is finite.
    double open_unit() { return static_cast<double>((next() >> 11) + 1) * 0x1.0p-53; }
    // Uniform in [-1, 1).
    double symmetric() { return static_cast<double>(next() >> 11) * 0x1.0p-52 - 1.0; }
    // Uniform integer in [0, n), unbiased.
    std::uint64_t below(std::uint64_t n) {
        const std::uint64_t limit = (~std::uint64_t{0}) - (~std::uint64_t{0}) % n;
        std::uint64_t x;
        do x = next();
        while (x >= limit);
        return x % n;
    }

private:
    static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
    std::uint64_t m_s[4];
};

}  // namespace flowvid::optim::detail
