// The diagnosis's discretisation control, and the model's own terms named
// before the world's effects, on models whose residual is known
// in closed form: a gap made of an effect's part and a discretisation part
// that only a finer mesh removes. The effect is named when it closes clearly
// more of the gap than the finer mesh; when the finer mesh closes about as
// much, the verdict is "unexplained" and the effect is listed as discounted.

#include "flowvid/gap/diagnose.hpp"
#include "flowvid/gap/effects.hpp"
#include "flowvid/gap/open_model.hpp"
#include "flowvid/formats/diagnosis.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

namespace flowvid::gap {
namespace {

constexpr double kTrueLag_s = 0.1;

// Frame `frame` of the known models' 60: 30 fps, a floor that varies, its error still to set.
FrameResidual known_frame(int frame) {
    FrameResidual f;
    f.frame = frame;
    f.time_s = (frame - 1) / 30.0;
    f.held_out = is_held_out(frame);
    f.floor = 2.0 + std::sin(0.7 * frame);
    f.observations = 50.0;
    return f;
}

// The known models' 60 frames, error_k = floor_k * factor(k).
Residuals frames_scaled_by(const std::function<double(int)>& factor) {
    Residuals out;
    for (int frame = 1; frame <= 60; ++frame) {
        FrameResidual f = known_frame(frame);
        f.error = f.floor * factor(frame);
        out.frames.push_back(f);
    }
    return out;
}

// An effect's first parameter, 0 when the effect is absent.
double first_value(const EffectValues& effects, const char* name) {
    const auto it = effects.find(name);
    return it == effects.end() ? 0.0 : it->second(0);
}

// What the closed-form models share: one cloth trial, no base parameters, no maps.
class ClosedFormModel : public GapModel {
public:
    std::string kind() const override { return "cloth"; }
    std::vector<std::string> trial_names() const override { return {"known"}; }
    std::vector<std::string> base_parameter_keys() const override { return {}; }
    std::vector<RegionMap> localise(const EffectValues&) const override { return {}; }
};

// error_k = floor_k (1 + effect_weight * w_k * (1 - lag / true lag)^2 + discretisation_weight * v_k):
// the effect's part vanishes at the true lag, the discretisation part on the finer mesh.
class KnownGapModel : public ClosedFormModel {
public:
    KnownGapModel(double effect_weight, double discretisation_weight, bool control_fails = false)
        : m_effect(effect_weight), m_discretisation(discretisation_weight), m_control_fails(control_fails) {}

    std::vector<std::string> candidate_effects() const override { return {"pin_lag"}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>&) const override {
        return residuals(first_value(effects, "pin_lag"), false);
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        RefitResult r;
        r.effects = start;
        if (start.count("pin_lag")) r.effects["pin_lag"] = Eigen::VectorXd::Constant(1, kTrueLag_s);  // the exact optimum
        r.residuals = evaluate(r.effects, {});
        r.evaluations = 1;
        return r;
    }
    std::optional<DiscretisationControl> discretisation_control(const std::vector<BaseParameterChange>&, const EffectValues&) const override {
        DiscretisationControl control{"a finer mesh", residuals(0.0, true)};
        if (m_control_fails) {
            control.residuals.ok = false;
            control.residuals.reason = "the finer mesh went unstable";
        }
        return control;
    }

private:
    Residuals residuals(double lag_s, bool finer) const {
        const double miss = 1.0 - lag_s / kTrueLag_s;
        return frames_scaled_by([&](int frame) {
            const double w = 1.0 + 0.5 * std::sin(0.3 * frame), v = 1.0 + 0.5 * std::cos(0.45 * frame);
            return 1.0 + m_effect * w * miss * miss + (finer ? 0.0 : m_discretisation * v);
        });
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

// A gap with three known parts: the model's own term (soft compression, a
// preset fitted without it), an effect of the world (pin lag) and the
// discretisation (gone on the finer mesh). error_k = floor_k (1 + m u_k (1 -
// s / s0)^2 + e w_k (1 - lag / lag0)^2 + c v_k).
constexpr double kTrueSoftness = 2.0;

class ModelAndEffectGap : public ClosedFormModel {
public:
    ModelAndEffectGap(double model_weight, double effect_weight, double discretisation_weight)
        : m_model(model_weight), m_effect(effect_weight), m_discretisation(discretisation_weight) {}

    std::vector<std::string> candidate_effects() const override { return {"compression_softness", "pin_lag"}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>&) const override {
        return residuals(effects, false);
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        RefitResult r;
        r.effects = start;
        if (start.count("pin_lag")) r.effects["pin_lag"] = Eigen::VectorXd::Constant(1, kTrueLag_s);
        if (start.count("compression_softness")) r.effects["compression_softness"] = Eigen::VectorXd::Constant(1, kTrueSoftness);
        r.residuals = evaluate(r.effects, {});
        r.evaluations = 1;
        return r;
    }
    std::optional<DiscretisationControl> discretisation_control(const std::vector<BaseParameterChange>&,
                                                                const EffectValues& effects) const override {
        return DiscretisationControl{"a finer mesh", residuals(effects, true)};
    }

    // Each part's share of the held-out gap, from the formula.
    double share(int part) const {
        double sum = 0.0, total = 0.0;
        for (int frame = 1; frame <= 60; ++frame) {
            if (!is_held_out(frame)) continue;
            const double parts[3] = {m_model * u(frame), m_effect * w(frame), m_discretisation * v(frame)};
            sum += parts[part];
            total += parts[0] + parts[1] + parts[2];
        }
        return sum / total;
    }

private:
    static double u(int frame) { return 1.0 + 0.4 * std::cos(0.2 * frame); }
    static double w(int frame) { return 1.0 + 0.5 * std::sin(0.3 * frame); }
    static double v(int frame) { return 1.0 + 0.5 * std::cos(0.45 * frame); }
    Residuals residuals(const EffectValues& effects, bool finer) const {
        const double soft_miss = 1.0 - first_value(effects, "compression_softness") / kTrueSoftness;
        const double lag_miss = 1.0 - first_value(effects, "pin_lag") / kTrueLag_s;
        return frames_scaled_by([&](int frame) {
            return 1.0 + m_model * u(frame) * soft_miss * soft_miss + m_effect * w(frame) * lag_miss * lag_miss +
                   (finer ? 0.0 : m_discretisation * v(frame));
        });
    }
    double m_model, m_effect, m_discretisation;
};

TEST(DiagnoseModelTerms, NamesThePresetsMissingTermFirstThenTheEffectOnTopOfIt) {
    const ModelAndEffectGap model(6.0, 4.0, 0.5);
    const Diagnosis d = diagnose(model, quick());
    ASSERT_TRUE(d.gap_detected);
    EXPECT_EQ(d.model_terms, std::vector<std::string>{"compression_softness"});
    ASSERT_TRUE(d.model_gap_closed);
    EXPECT_NEAR(*d.model_gap_closed, model.share(0), 1e-9);
    ASSERT_EQ(d.status, "named") << d.message;
    EXPECT_EQ(d.named, std::vector<std::string>{"pin_lag"});
    ASSERT_TRUE(d.gap_closed);
    EXPECT_NEAR(*d.gap_closed, model.share(1), 1e-9);  // beyond the model term
    ASSERT_FALSE(d.model_candidates.empty());
    EXPECT_EQ(d.model_candidates.front().domain, "model");
    for (const CandidateEvidence& c : d.candidates) EXPECT_NE(c.domain, "model") << c.name;
    // Plain names beside the keys, each share once, and what to do next.
    EXPECT_NE(d.message.find("pins out of step with the footage [pin_lag]"), std::string::npos) << d.message;
    EXPECT_NE(d.message.find("soft compression (buckling) [compression_softness]"), std::string::npos) << d.message;
    EXPECT_NE(d.next_step.find("sync"), std::string::npos) << d.next_step;
    EXPECT_NE(d.next_step.find("capacity terms"), std::string::npos) << d.next_step;
    // The document states both and validates.
    const nlohmann::json document = diagnosis_document(d, nlohmann::json::object());
    Diagnostics diagnostics("diagnosis.json");
    const std::optional<formats::Diagnosis> parsed = formats::parse_diagnosis(document, diagnostics, formats::Strictness::strict);
    ASSERT_TRUE(parsed) << diagnostics.problems().front().to_string();
    EXPECT_EQ(parsed->verdict.model_terms, std::vector<std::string>{"compression_softness"});
    EXPECT_EQ(parsed->verdict.effects, std::vector<std::string>{"pin_lag"});
}

TEST(DiagnoseModelTerms, AGapTheMissingTermClosesEndsWithNoEffectNamed) {
    const ModelAndEffectGap model(8.0, 0.0, 0.2);
    const Diagnosis d = diagnose(model, quick());
    ASSERT_TRUE(d.gap_detected);
    EXPECT_EQ(d.model_terms, std::vector<std::string>{"compression_softness"});
    EXPECT_LT(d.ratio_with_model_terms, d.threshold);
    EXPECT_EQ(d.status, "no_gap") << d.message;
    EXPECT_TRUE(d.named.empty());
    EXPECT_TRUE(d.candidates.empty());  // no effect was needed
    const nlohmann::json document = diagnosis_document(d, nlohmann::json::object());
    Diagnostics diagnostics("diagnosis.json");
    EXPECT_TRUE(formats::parse_diagnosis(document, diagnostics, formats::Strictness::strict));
    // Without the model term the same file would contradict itself.
    nlohmann::json broken = document;
    broken["verdict"]["model_terms"] = nlohmann::json::array();
    Diagnostics refused("diagnosis.json");
    EXPECT_FALSE(formats::parse_diagnosis(broken, refused, formats::Strictness::strict));
}

TEST(DiagnoseModelTerms, AModelTermAFinerMeshMatchesIsDiscounted) {
    const ModelAndEffectGap model(3.0, 0.0, 5.0);
    const Diagnosis d = diagnose(model, quick());
    EXPECT_TRUE(d.model_terms.empty());
    EXPECT_EQ(d.discounted, std::vector<std::string>{"compression_softness"});
    EXPECT_EQ(d.status, "unexplained") << d.message;
}

TEST(DiagnoseModelTerms, ATermThatLeavesAGapLeadsTheVerdict) {
    // The term closes two thirds of the gap; what is left (a part only a
    // finer mesh removes, a third) no effect explains: 4 floors.
    const ModelAndEffectGap model(6.0, 0.0, 3.0);
    const Diagnosis d = diagnose(model, quick());
    ASSERT_TRUE(d.gap_detected);
    EXPECT_EQ(d.model_terms, std::vector<std::string>{"compression_softness"});
    ASSERT_TRUE(d.model_gap_closed);
    EXPECT_NEAR(*d.model_gap_closed, model.share(0), 1e-9);
    EXPECT_GT(d.ratio_with_model_terms, d.threshold);
    EXPECT_EQ(d.status, "unexplained") << d.message;
    EXPECT_EQ(d.message.rfind("The fabric model itself lacks soft compression (buckling) [compression_softness]", 0), 0u) << d.message;
    EXPECT_NE(d.message.find("The rest is unexplained"), std::string::npos) << d.message;
    EXPECT_NE(d.next_step.find("capacity terms"), std::string::npos) << d.next_step;
}

// Screening's parabola on a nearly flat score: error_k = floor_k (4 + g(r)),
// g(r) = -e r/h + d (r/h)^2 + K max(0, |r|/h - 2)^2 for a camera roll r, h its
// screening step. Through neutral and +-h the parabola's minimum lies at
// r/h = e/(2d) = 10, the range's end, where the score is far worse: the
// screened point stays within two steps, and the refit starts there.
class FlatNearNeutral : public ClosedFormModel {
public:
    static constexpr double kSlope = 0.2, kCurvature = 0.01, kWall = 5.0;
    static double g(double r) {
        const double x = r / find_effect("camera_roll").parameters[0].screen_step;
        const double beyond = std::max(0.0, std::abs(x) - 2.0);
        return -kSlope * x + kCurvature * x * x + kWall * beyond * beyond;
    }
    std::vector<std::string> candidate_effects() const override { return {"camera_roll"}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>&) const override {
        const double excess = g(first_value(effects, "camera_roll"));
        return frames_scaled_by([&](int) { return 4.0 + excess; });
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        started_at = start;  // no search: the refit stays where screening put it
        RefitResult r;
        r.effects = start;
        r.residuals = evaluate(start, {});
        r.evaluations = 1;
        return r;
    }
    mutable EffectValues started_at;
};

TEST(DiagnoseScreening, TrustsItsParabolaOnlyNearItsSteps) {
    const FlatNearNeutral model;
    DiagnoseSettings settings = quick();
    settings.discretisation_control = false;
    const Diagnosis d = diagnose(model, settings);
    ASSERT_TRUE(d.gap_detected);
    ASSERT_EQ(d.candidates.size(), 1u);
    const double step = find_effect("camera_roll").parameters[0].screen_step;
    const CandidateEvidence& roll = d.candidates.front();
    // The parabola's own minimum (10 steps) is clamped to two steps out.
    EXPECT_NEAR(roll.screened.at("camera_roll")(0), 2.0 * step, 1e-12);
    int training_frames = 0;
    for (int frame = 1; frame <= 60; ++frame) training_frames += is_held_out(frame) ? 0 : 1;
    // Predicted reduction at two steps, in floors: -(g(2h) - g(0)) per training frame.
    EXPECT_NEAR(roll.screen_score, -training_frames * (2.0 * (-FlatNearNeutral::kSlope) + 4.0 * FlatNearNeutral::kCurvature), 1e-9);
    ASSERT_TRUE(model.started_at.count("camera_roll"));
    EXPECT_NEAR(model.started_at.at("camera_roll")(0), 2.0 * step, 1e-12);
    // At the range's end the model is far worse than at neutral: what the
    // unclamped parabola would have started the refit from.
    EXPECT_GT(FlatNearNeutral::g(find_effect("camera_roll").parameters[0].upper), 10.0);
}

// A gap of three parts: what the base parameters mimic (the null refit
// removes it), a pin lag, and a rest nothing removes: error_k = floor_k (1 +
// w_k (A [not refitted] + B (1 - lag / lag0)^2 + C)). The lag closes B / (A +
// B + C) of the gap beyond the null refit but B / (B + C) of what it leaves.
class PartlyMimicked : public ClosedFormModel {
public:
    static constexpr double kMimicked = 4.0, kLag = 2.0, kRest = 4.0;
    std::vector<std::string> candidate_effects() const override { return {"pin_lag"}; }
    std::vector<std::string> base_parameter_keys() const override { return {"stiffness"}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>& base) const override {
        const double miss = 1.0 - first_value(effects, "pin_lag") / kTrueLag_s;
        return frames_scaled_by([&](int frame) {
            const double w = 1.0 + 0.5 * std::sin(0.3 * frame);
            return 1.0 + w * ((base.empty() ? kMimicked : 0.0) + kLag * miss * miss + kRest);
        });
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        RefitResult r;
        r.effects = start;
        if (start.count("pin_lag")) r.effects["pin_lag"] = Eigen::VectorXd::Constant(1, kTrueLag_s);
        r.base = {{"stiffness", 1.0, 2.0}};  // the base parameters remove their part
        r.residuals = evaluate(r.effects, r.base);
        r.evaluations = 1;
        return r;
    }
};

TEST(DiagnoseEvidence, AnEffectMustExplainAShareOfWhatTheNullRefitLeaves) {
    const PartlyMimicked model;
    DiagnoseSettings settings = quick();
    settings.discretisation_control = false;
    const Diagnosis d = diagnose(model, settings);
    ASSERT_TRUE(d.gap_detected);
    ASSERT_FALSE(d.candidates.empty());
    const CandidateEvidence& lag = d.candidates.front();
    constexpr double kTotal = PartlyMimicked::kMimicked + PartlyMimicked::kLag + PartlyMimicked::kRest;
    // Below the bar as a share of the whole gap, above it as a share of the rest.
    EXPECT_NEAR(lag.effect_share, PartlyMimicked::kLag / kTotal, 1e-9);
    EXPECT_NEAR(lag.share_of_remaining, PartlyMimicked::kLag / (PartlyMimicked::kLag + PartlyMimicked::kRest), 1e-9);
    EXPECT_LT(lag.effect_share, settings.min_effect_share);
    EXPECT_EQ(d.status, "named") << d.message;
    EXPECT_EQ(d.named, std::vector<std::string>{"pin_lag"});
    // A bar above what it explains of the rest refuses it.
    settings.min_effect_share = 0.4;
    EXPECT_EQ(diagnose(model, settings).status, "unexplained");
}


// An optimiser that gets halfway: each refit moves the pin lag half the
// way from where it starts to the true lag (and a camera roll all the way to
// its true value). error_k = floor_k (1 + w_k (E (1 - lag / lag0)^2 +
// R (1 - roll / roll0)^2 + D)), the lag four screening steps out (screening
// starts its refit at two), a small roll part and a rest D nothing removes.
class HalfwayRefits : public ClosedFormModel {
public:
    static constexpr double kLagPart = 16.0, kRollPart = 0.3, kRest = 2.0;
    static double true_lag() { return 4.0 * find_effect("pin_lag").parameters[0].screen_step; }
    static double true_roll() { return find_effect("camera_roll").parameters[0].screen_step; }
    std::vector<std::string> candidate_effects() const override { return {"pin_lag", "camera_roll"}; }
    Residuals evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>&) const override {
        const double lag_miss = 1.0 - first_value(effects, "pin_lag") / true_lag();
        const double roll_miss = 1.0 - first_value(effects, "camera_roll") / true_roll();
        return frames_scaled_by([&](int frame) {
            const double w = 1.0 + 0.3 * std::sin(0.5 * frame);
            return 1.0 + w * (kLagPart * lag_miss * lag_miss + kRollPart * roll_miss * roll_miss + kRest);
        });
    }
    RefitResult refit(const EffectValues& start, int, const std::vector<BaseParameterChange>&) const override {
        RefitResult r;
        r.effects = start;
        if (start.count("pin_lag")) r.effects["pin_lag"](0) += 0.5 * (true_lag() - start.at("pin_lag")(0));
        if (start.count("camera_roll")) r.effects["camera_roll"](0) = true_roll();
        r.residuals = evaluate(r.effects, {});
        r.evaluations = 1;
        return r;
    }
};

TEST(DiagnoseEvidence, ALaterEffectMustBeatTheNamedOnesRefittedAsLong) {
    // The lag is named at three quarters of the way (screened at 2 steps,
    // refitted to 3). A roll refitted on top also takes the lag on to 3.5
    // steps: credited with that, it would close (1 + 0.3 - 0.25) / 3.3 =
    // 32 % of what the lag left. Against the lag refitted once more alone
    // it closes its own 0.3 / 2.55 = 12 %: not named.
    const HalfwayRefits model;
    DiagnoseSettings settings = quick();
    settings.max_effects = 2;
    settings.discretisation_control = false;
    const Diagnosis d = diagnose(model, settings);
    ASSERT_TRUE(d.gap_detected);
    EXPECT_EQ(d.status, "named") << d.message;
    EXPECT_EQ(d.named, std::vector<std::string>{"pin_lag"});
    // The named lag is the continued one, and the gap closed is measured there.
    ASSERT_TRUE(d.named_refit);
    EXPECT_NEAR(first_value(d.named_refit->effects, "pin_lag"), 3.5 / 4.0 * HalfwayRefits::true_lag(), 1e-12);
    ASSERT_TRUE(d.gap_closed);
    const double base = HalfwayRefits::kLagPart + HalfwayRefits::kRollPart + HalfwayRefits::kRest;
    EXPECT_NEAR(*d.gap_closed, (HalfwayRefits::kLagPart * (1.0 - 1.0 / 64.0)) / base, 1e-9);
}

// Residuals of one frame per block with error/floor = `scores`, and the blocks.
Residuals one_frame_per_block(const std::vector<double>& scores) {
    Residuals out;
    for (std::size_t k = 0; k < scores.size(); ++k) {
        FrameResidual f = known_frame(static_cast<int>(k) + 1);
        f.held_out = true;
        f.error = f.floor * scores[k];
        out.frames.push_back(f);
    }
    return out;
}

TEST(DiagnoseEvidence, StabilityWeighsTheBlocksAndNeverLeavesOneOut) {
    const std::vector<std::vector<std::size_t>> two_blocks{{0}, {1}}, three_blocks{{0}, {1}, {2}};
    constexpr int kResamples = 40000;  // the share's sampling error: about 0.002
    // Two blocks, the candidate 3 better in one and 1 worse in the other: with
    // flat weights (w, 1 - w) it wins when 3 w > 1 - w, in 3 / 4 of them.
    const Residuals null2 = one_frame_per_block({10.0, 10.0}), wins_and_loses = one_frame_per_block({7.0, 11.0});
    EXPECT_NEAR(bootstrap_stability({&wins_and_loses}, 0, null2, two_blocks, kResamples, 3), 0.75, 0.01);
    // Three blocks shaped as the first held-out block of a waving cloth (the
    // gap nearly all there: the candidate gains 18.6 in it, loses 1.81 in
    // the second, gains 0.41 in the third). Over the weight simplex the
    // candidate loses only in the corner by the second block's vertex, cut
    // at 1.81 / (18.6 + 1.81) and 1.81 / (1.81 + 0.41) along its edges: it
    // wins in 1 - 0.0887 x 0.8153 = 0.928 of resamples. Resampling the
    // blocks with replacement leaves the first out in (2/3)^3 of them and
    // could not pass 0.74.
    const Residuals null3 = one_frame_per_block({51.17, 10.02, 5.29}), term = one_frame_per_block({32.57, 11.83, 4.88});
    const double expected = 1.0 - (1.81 / (18.6 + 1.81)) * (1.81 / (1.81 + 0.41));
    const double stability = bootstrap_stability({&term}, 0, null3, three_blocks, kResamples, 3);
    EXPECT_NEAR(stability, expected, 0.01);
    EXPECT_GT(stability, DiagnoseSettings{}.min_stability);
    // Seeded: the same share again; a rival better in every block leaves none.
    EXPECT_EQ(bootstrap_stability({&term}, 0, null3, three_blocks, kResamples, 3), stability);
    const Residuals rival = one_frame_per_block({30.0, 9.0, 4.0});
    EXPECT_EQ(bootstrap_stability({&term, &rival}, 0, null3, three_blocks, 400, 3), 0.0);
    EXPECT_EQ(bootstrap_stability({&term, &rival}, 1, null3, three_blocks, 400, 3), 1.0);
}

}  // namespace
}  // namespace flowvid::gap
