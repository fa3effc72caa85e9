// The diagnosis's discretisation control, on a model whose residual is known
// in closed form: a gap made of an effect's part and a discretisation part
// that only a finer mesh removes. The effect is named when it closes clearly
// more of the gap than the finer mesh; when the finer mesh closes about as
// much, the verdict is "unexplained" and the effect is listed as discounted.

#include "flowvid/gap/diagnose.hpp"
#include "flowvid/gap/effects.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace flowvid::gap {
namespace {

constexpr double kTrueLag_s = 0.1;

// error_k = floor_k (1 + effect_weight * w_k * (1 - lag / true lag)^2 + discretisation_weight * v_k):
// the effect's part vanishes at the true lag, the discretisation part on the finer mesh.
class KnownGapModel : public GapModel {
public:
    KnownGapModel(double effect_weight, double discretisation_weight, bool control_fails = false)
        : m_effect(effect_weight), m_discretisation(discretisation_weight), m_control_fails(control_fails) {}

    std::string kind() const override { return "cloth"; }
    std::vector<std::string> trial_names() const override { return {"known"}; }
    std::vector<std::string> candidate_effects() const override { return {"pin_lag"}; }
    std::vector<std::string> base_parameter_keys() const override { return {}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>&) const override {
        const auto it = effects.find("pin_lag");
        return residuals(it == effects.end() ? 0.0 : it->second(0), false);
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        RefitResult r;
        r.effects = start;
        if (start.count("pin_lag")) r.effects["pin_lag"] = Eigen::VectorXd::Constant(1, kTrueLag_s);  // the exact optimum
        r.residuals = evaluate(r.effects, {});
        r.evaluations = 1;
        return r;
    }
    std::vector<RegionMap> localise(const EffectValues&) const override { return {}; }
    std::optional<DiscretisationControl> discretisation_control(const std::vector<BaseParameterChange>&) const override {
        DiscretisationControl control{"a finer mesh", residuals(0.0, true)};
        if (m_control_fails) {
            control.residuals.ok = false;
            control.residuals.reason = "the finer mesh went unstable";
        }
        return control;
    }

private:
    Residuals residuals(double lag_s, bool finer) const {
        Residuals out;
        for (int frame = 1; frame <= 60; ++frame) {
            FrameResidual f;
            f.frame = frame;
            f.time_s = (frame - 1) / 30.0;
            f.held_out = is_held_out(frame);
            f.floor = 2.0 + std::sin(0.7 * frame);
            f.observations = 50.0;
            const double w = 1.0 + 0.5 * std::sin(0.3 * frame), v = 1.0 + 0.5 * std::cos(0.45 * frame);
            const double miss = 1.0 - lag_s / kTrueLag_s;
            f.error = f.floor * (1.0 + m_effect * w * miss * miss + (finer ? 0.0 : m_discretisation * v));
            out.frames.push_back(f);
        }
        return out;
    }
    double m_effect, m_discretisation;
    bool m_control_fails;
};

DiagnoseSettings quick() {
    DiagnoseSettings s;
    s.bootstrap_resamples = 100;
    s.max_effects = 1;
    return s;
}

TEST(DiagnoseControl, NamesAnEffectThatClosesClearlyMoreThanAFinerMesh) {
    const KnownGapModel model(9.0, 1.0);
    const Diagnosis d = diagnose(model, quick());
    ASSERT_TRUE(d.gap_detected);
    ASSERT_TRUE(d.control_gap_closed);
    EXPECT_NEAR(*d.control_gap_closed, 0.1, 0.03);
    EXPECT_EQ(d.control_description, "a finer mesh");
    ASSERT_EQ(d.status, "named") << d.message;
    EXPECT_EQ(d.named, std::vector<std::string>{"pin_lag"});
    EXPECT_TRUE(d.discounted.empty());
    ASSERT_TRUE(d.gap_closed);
    EXPECT_NEAR(*d.gap_closed, 0.9, 0.03);
}

TEST(DiagnoseControl, DiscountsAnEffectThatAFinerMeshMatches) {
    const KnownGapModel model(4.0, 6.0);
    const Diagnosis d = diagnose(model, quick());
    ASSERT_TRUE(d.gap_detected);
    // The effect alone passes every test of evidence...
    ASSERT_FALSE(d.candidates.empty());
    EXPECT_EQ(d.candidates.front().name, "pin_lag");
    EXPECT_TRUE(d.candidates.front().passes);
    EXPECT_NEAR(d.candidates.front().gap_closed, 0.4, 0.03);
    // ...but the finer mesh closes more: unexplained, the effect discounted.
    ASSERT_TRUE(d.control_gap_closed);
    EXPECT_NEAR(*d.control_gap_closed, 0.6, 0.03);
    EXPECT_EQ(d.status, "unexplained") << d.message;
    EXPECT_TRUE(d.named.empty());
    EXPECT_EQ(d.discounted, std::vector<std::string>{"pin_lag"});
    EXPECT_FALSE(d.gap_closed);
    EXPECT_NE(d.message.find("a finer mesh"), std::string::npos) << d.message;

    // Without the control the same evidence names the effect.
    DiagnoseSettings off = quick();
    off.discretisation_control = false;
    const Diagnosis named = diagnose(model, off);
    EXPECT_EQ(named.status, "named") << named.message;
    EXPECT_FALSE(named.control_gap_closed);
}

// A control that cannot be measured changes nothing, and says why.
TEST(DiagnoseControl, AFailedControlLeavesTheVerdictAndSaysWhy) {
    const KnownGapModel model(4.0, 6.0, true);
    const Diagnosis d = diagnose(model, quick());
    EXPECT_EQ(d.status, "named") << d.message;
    EXPECT_FALSE(d.control_gap_closed);
    EXPECT_EQ(d.control_failure, "the finer mesh went unstable");
    EXPECT_TRUE(d.discounted.empty());
}

}  // namespace
}  // namespace flowvid::gap
