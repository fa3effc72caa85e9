// How the sealed benchmark draws its cases: the strength knob scales every
// effect magnitude and nothing else, within the catalogue's ranges.

#include "flowvid/gap/bench.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace flowvid;
using namespace flowvid::gap;

namespace {

std::vector<BenchCase> draw(double strength) {
    BenchSettings settings;
    settings.strength = strength;
    return draw_bench_cases(60, 31, 2, 2, settings);
}

}  // namespace

TEST(BenchDraw, StrengthScalesEveryMagnitudeButNotRatesWithinTheCatalogueRanges) {
    const std::vector<BenchCase> single = draw(1.0), double_strength = draw(2.0);
    ASSERT_EQ(single.size(), double_strength.size());
    int scaled = 0, clamped = 0, none = 0;
    for (std::size_t i = 0; i < single.size(); ++i) {
        const BenchCase &a = single[i], &b = double_strength[i];
        // Same seed: the same effects, scenes and fabrics in the same order.
        ASSERT_EQ(a.effect, b.effect) << a.id;
        EXPECT_EQ(a.scene, b.scene);
        EXPECT_EQ(a.fabric, b.fabric);
        if (a.effect == "none") {
            ++none;
            continue;
        }
        if (a.effect == "drag_nonlinear") continue;  // the fabric's own drag: no magnitude drawn
        const Effect& effect = find_effect(a.effect);
        const Eigen::VectorXd &va = a.values.at(a.effect), &vb = b.values.at(b.effect);
        for (std::size_t p = 0; p < effect.parameters.size(); ++p) {
            const EffectParameter& parameter = effect.parameters[p];
            const double x = va(static_cast<Eigen::Index>(p)), y = vb(static_cast<Eigen::Index>(p));
            EXPECT_GE(y, parameter.lower) << a.id << " " << parameter.key;
            EXPECT_LE(y, parameter.upper) << a.id << " " << parameter.key;
            if (parameter.key == "gust_frequency_hz") {
                EXPECT_EQ(x, y) << a.id << ": a rate is not a magnitude";
                continue;
            }
            const double expected = 2.0 * x;
            if (expected > parameter.upper || expected < parameter.lower) {
                EXPECT_DOUBLE_EQ(y, std::clamp(expected, parameter.lower, parameter.upper)) << a.id << " " << parameter.key;
                ++clamped;
            } else {
                EXPECT_NEAR(y, expected, 1e-12 * std::max(1.0, std::abs(expected))) << a.id << " " << parameter.key;
                scaled += x != 0.0 ? 1 : 0;
            }
        }
    }
    // About a quarter effect-free, and both branches exercised.
    EXPECT_NEAR(none, 15, 1);
    EXPECT_GT(scaled, 40);
    EXPECT_GT(clamped, 0);
}
