#include "flowvid/flow/synthetic.hpp"

#include "flowvid/flow/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace flowvid::flow {

namespace {

constexpr double kStep = 0.25;       // px of arc per travel-time table entry
constexpr double kSurgeStep = 0.05;  // frames per surge-time table entry

std::uint64_t mix(std::uint64_t x) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    x ^= x >> 33;
    return x;
}

float lattice(std::int64_t i, std::int64_t j, std::uint64_t seed) {
    const std::uint64_t h = mix(static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ULL ^
                                mix(static_cast<std::uint64_t>(j) + 0x632BE59BD9B4E019ULL) ^ mix(seed));
    return static_cast<float>(h >> 40) / static_cast<float>(1ULL << 24);
}

double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

}  // namespace

float value_noise(double x, double y, std::uint64_t seed) {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto i = static_cast<std::int64_t>(fx), j = static_cast<std::int64_t>(fy);
    const double u = fade(x - fx), v = fade(y - fy);
    const double a = lattice(i, j, seed), b = lattice(i + 1, j, seed);
    const double c = lattice(i, j + 1, seed), d = lattice(i + 1, j + 1, seed);
    return static_cast<float>((a + u * (b - a)) * (1.0 - v) + (c + u * (d - c)) * v);
}

SyntheticFlow::SyntheticFlow(SyntheticFlowSpec spec) : m_spec(std::move(spec)) {
    if (m_spec.curve.size() < 2 || !m_spec.speed_px_per_frame)
        throw std::invalid_argument("a synthetic flow needs a curve and a speed profile");
    const double length = formats::polyline_length(m_spec.curve);
    const double margin = m_spec.band_px + 64.0;
    m_s0 = -margin;
    const int n = static_cast<int>(std::ceil((length + 2.0 * margin) / kStep)) + 1;
    m_tau.assign(static_cast<std::size_t>(n), 0.0);
    // tau(s) = integral of 1/v from 0 to s (trapezoids), then shifted so tau(0) = 0.
    for (int i = 1; i < n; ++i) {
        const double s_prev = m_s0 + (i - 1) * kStep, s = m_s0 + i * kStep;
        const double v0 = m_spec.speed_px_per_frame(std::max(0.0, s_prev));
        const double v1 = m_spec.speed_px_per_frame(std::max(0.0, s));
        m_tau[static_cast<std::size_t>(i)] = m_tau[static_cast<std::size_t>(i - 1)] + 0.5 * kStep * (1.0 / v0 + 1.0 / v1);
    }
    const double at_zero = travel_frames(0.0);
    for (double& t : m_tau) t -= at_zero;
    if (m_spec.time_factor) {
        // Far enough before and after the clip for every particle on the curve
        // (travel times at the slowest surge stay within this span).
        const double span = 4.0 * (m_spec.frames + std::fabs(m_tau.front()) + std::fabs(m_tau.back())) + 64.0;
        m_t0 = -span;
        const int count = static_cast<int>(std::ceil((m_spec.frames + 2.0 * span) / kSurgeStep)) + 1;
        m_surge.assign(static_cast<std::size_t>(count), 0.0);
        for (int i = 1; i < count; ++i) {
            const double t = m_t0 + i * kSurgeStep;
            m_surge[static_cast<std::size_t>(i)] = m_surge[static_cast<std::size_t>(i - 1)] +
                                                   0.5 * kSurgeStep * (m_spec.time_factor(t - kSurgeStep) + m_spec.time_factor(t));
        }
        const double offset = surge_time(0.0);
        for (double& h : m_surge) h -= offset;
    }
}

double SyntheticFlow::surge_time(double t) const {
    if (m_surge.empty()) return t;
    const double r = std::clamp((t - m_t0) / kSurgeStep, 0.0, static_cast<double>(m_surge.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(r), m_surge.size() - 2);
    const double f = r - static_cast<double>(i);
    return m_surge[i] + f * (m_surge[i + 1] - m_surge[i]);
}

double SyntheticFlow::identity_at(double tau, int index) const {
    if (!m_spec.speed_factor && m_surge.empty()) return index - tau;
    // Solve g(e) * (H(index) - H(e)) = tau for e: the left side falls as e
    // grows (for slowly varying g), so bisect.
    const double h_index = surge_time(index);
    const auto factor = [&](double e) { return m_spec.speed_factor ? m_spec.speed_factor(e) : 1.0; };
    double lo = index - std::fabs(tau) * 10.0 - 10.0, hi = index + std::fabs(tau) * 10.0 + 10.0;
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (factor(mid) * (h_index - surge_time(mid)) > tau) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

double SyntheticFlow::travel_frames(double s) const {
    const double r = std::clamp((s - m_s0) / kStep, 0.0, static_cast<double>(m_tau.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(r), m_tau.size() - 2);
    const double f = r - static_cast<double>(i);
    return m_tau[i] + f * (m_tau[i + 1] - m_tau[i]);
}

double SyntheticFlow::arc_at(double entry_frame, double age) const {
    const double factor = m_spec.speed_factor ? m_spec.speed_factor(entry_frame) : 1.0;
    const double target = (surge_time(entry_frame + age) - surge_time(entry_frame)) * factor;
    const auto it = std::lower_bound(m_tau.begin(), m_tau.end(), target);
    if (it == m_tau.begin()) return m_s0;
    if (it == m_tau.end()) return m_s0 + (m_tau.size() - 1) * kStep;
    const std::size_t i = static_cast<std::size_t>(it - m_tau.begin());
    const double f = (target - m_tau[i - 1]) / (m_tau[i] - m_tau[i - 1]);
    return m_s0 + (static_cast<double>(i - 1) + f) * kStep;
}

RgbImage SyntheticFlow::frame(int index) const {
    const SyntheticFlowSpec& s = m_spec;
    const LineGeometry curve(s.curve, 0.0);
    const double v_ref = s.speed_px_per_frame(0.0);
    const double extension = s.band_px + 64.0;
    RgbImage out(s.width, s.height);
    for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) {
            const LineGeometry::Projection p = curve.project(Eigen::Vector2d(x, y), extension);
            double u, w;
            std::uint64_t seed = s.seed;
            if (std::fabs(p.n) > s.band_px) {
                u = x / s.feature_px;
                w = y / s.feature_px;
                seed += 7777;
            } else {
                const double identity = identity_at(travel_frames(p.s), index);  // which particle is here: its entry frame
                u = p.n / s.feature_px + 1000.0;
                w = -identity * v_ref / s.feature_px;
            }
            const float a = value_noise(u, w, seed);
            const float b = value_noise(u + 31.7, w + 17.3, seed + 1);
            const float c = value_noise(u - 53.1, w + 91.9, seed + 2);
            float* px = out.pixel(x, y);
            px[0] = 0.12f + 0.76f * a;
            px[1] = 0.12f + 0.76f * (0.5f * a + 0.5f * b);
            px[2] = 0.12f + 0.76f * c;
        }
    return out;
}

MemoryFrames SyntheticFlow::clip() const {
    std::vector<RgbImage> frames;
    for (int i = 0; i < m_spec.frames; ++i) frames.push_back(frame(i));
    return MemoryFrames(std::move(frames), m_spec.fps, "synthetic");
}

}  // namespace flowvid::flow
