#pragma once
// Procedural clips with known motion, the ground truth for tracking tests and
// the benchmark: a smooth random texture flowing along a curve with a known
// speed profile. Pixels within band_px of the curve flow; the rest is a
// static texture. Every particle entering the curve at frame e follows arc
// position S(e, age) exactly (the texture is a function of the particle
// identity and the lateral offset), so tracking can be checked to sub-pixel.
//
// Stationary: speed depends on the arc length only, v(s). Non-stationary:
// each particle's speed is v(s) * g(e), with g varying with its entry frame e
// (flames, smoke: thesis 3.2.2, "Generality").

#include "flowvid/flow/frames.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <vector>

namespace flowvid::flow {

struct SyntheticFlowSpec {
    int width = 160;
    int height = 120;
    int frames = 40;
    double fps = 25.0;
    std::vector<Eigen::Vector2d> curve;  // the flow's centre line (pixels, direction of flow); >= 2 points
    double band_px = 24.0;               // half-width of the flowing band
    std::function<double(double)> speed_px_per_frame;  // v(s) > 0, s = arc length (px)
    // Non-stationary factor g(e) > 0 of the entry frame e; empty = stationary.
    std::function<double(double)> speed_factor;
    // Non-stationary surge h(t) > 0 of the frame t (any real t): the whole
    // flow speeds up and slows down together, so a particle's speed changes
    // during its life (a flame's gusts); empty = 1. Combined with the above, a
    // particle entering at e is where travel_frames(s) = g(e) * (H(e + age) - H(e)),
    // H the integral of h.
    std::function<double(double)> time_factor;
    double feature_px = 3.0;  // texture feature size
    std::uint64_t seed = 1;
};

class SyntheticFlow {
public:
    explicit SyntheticFlow(SyntheticFlowSpec spec);
    const SyntheticFlowSpec& spec() const { return m_spec; }
    // Display RGB of frame `index` (0-based).
    RgbImage frame(int index) const;
    MemoryFrames clip() const;
    // Ground truth: arc position (px) of the particle that enters the curve
    // (s = 0) at frame `entry_frame`, `age` frames later.
    double arc_at(double entry_frame, double age) const;
    // Travel time (frames) from the curve's start to arc s at unit factor.
    double travel_frames(double s) const;

private:
    // H(t), the integral of time_factor from 0 (t itself without one).
    double surge_time(double t) const;
    // The entry frame of the particle at travel time tau in frame `index`.
    double identity_at(double tau, int index) const;

    SyntheticFlowSpec m_spec;
    std::vector<double> m_tau;  // travel time at s = m_s0 + i * kStep
    double m_s0 = 0.0;
    std::vector<double> m_surge;  // H(t) at t = m_t0 + i * kSurgeStep
    double m_t0 = 0.0;
};

// Smooth value noise in [0, 1], deterministic in (x, y, seed): the texture.
float value_noise(double x, double y, std::uint64_t seed);

}  // namespace flowvid::flow
