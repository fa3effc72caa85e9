#pragma once
// The library's one random source: xoshiro256** seeded by splitmix64, with
// its own distributions, so that a seed gives the same numbers with every
// compiler and standard library ("same input, same output" everywhere; the
// std:: distributions and std::shuffle are not specified to the bit).
// Test unit.core.Random pins the first values.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <utility>

namespace flowvid {

// One splitmix64 step: advances `state` and returns the next output.
inline std::uint64_t splitmix64(std::uint64_t& state) {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

// A seed for stream `index` of `seed`: independent, reproducible streams
// (runs of one analysis, frames of one case).
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t index) {
    std::uint64_t state = seed ^ (0xD1B54A32D192ED03ull * (index + 1));
    return splitmix64(state);
}

// A seed from text (a case id): FNV-1a, the same on every platform, which
// std::hash is not.
inline std::uint64_t seed_from_text(const char* text, std::size_t length) {
    std::uint64_t hash = 0xCBF29CE484222325ull;
    for (std::size_t i = 0; i < length; ++i) {
        hash ^= static_cast<unsigned char>(text[i]);
        hash *= 0x100000001B3ull;
    }
    return hash;
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

    // Uniform in [0, 1).
    double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
    // Uniform in [a, b).
    double uniform(double a, double b) { return a + (b - a) * uniform(); }
    // Uniform in (0, 1]: never 0, so log() of it is finite.
    double open_unit() { return static_cast<double>((next() >> 11) + 1) * 0x1.0p-53; }
    // Uniform in [-1, 1).
    double symmetric() { return static_cast<double>(next() >> 11) * 0x1.0p-52 - 1.0; }
    // Uniform integer in [0, n), unbiased; n > 0.
    std::uint64_t below(std::uint64_t n) {
        const std::uint64_t limit = (~std::uint64_t{0}) - (~std::uint64_t{0}) % n;
        std::uint64_t x;
        do x = next();
        while (x >= limit);
        return x % n;
    }
    // Standard normal (Box-Muller; the second value of each pair is kept for the next call).
    double normal() {
        if (m_has_spare) {
            m_has_spare = false;
            return m_spare;
        }
        const double r = std::sqrt(-2.0 * std::log(open_unit()));
        const double angle = 2.0 * std::numbers::pi * uniform();
        m_spare = r * std::sin(angle);
        m_has_spare = true;
        return r * std::cos(angle);
    }
    double normal(double mean, double sigma) { return mean + sigma * normal(); }

    // Fisher-Yates over [first, last) with below(): the same order everywhere.
    template <class Iterator>
    void shuffle(Iterator first, Iterator last) {
        const auto n = last - first;
        for (auto i = n - 1; i > 0; --i) {
            const auto j = static_cast<decltype(i)>(below(static_cast<std::uint64_t>(i) + 1));
            using std::swap;
            swap(first[i], first[j]);
        }
    }

private:
    static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
    std::uint64_t m_s[4];
    bool m_has_spare = false;
    double m_spare = 0.0;
};

}  // namespace flowvid
