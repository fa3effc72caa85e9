#include "flowvid/gap/diagnose.hpp"
#include "flowvid/random.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <limits>
#include <map>
#include <numbers>

namespace flowvid::gap {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int count_frames(const Residuals& r, bool held_out) {
    int n = 0;
    for (const FrameResidual& f : r.frames) n += f.held_out == held_out ? 1 : 0;
    return n;
}

// Held-out blocks (trial, block index) and each block's frames' indices into
// Residuals::frames (the same layout for every evaluation of one model).
std::vector<std::vector<std::size_t>> held_out_blocks(const Residuals& r) {
    std::map<std::pair<int, int>, std::vector<std::size_t>> blocks;
    for (std::size_t i = 0; i < r.frames.size(); ++i)
        if (r.frames[i].held_out) blocks[{r.frames[i].trial, (r.frames[i].frame - 1) / kHeldOutBlockFrames}].push_back(i);
    std::vector<std::vector<std::size_t>> out;
    for (auto& [key, frames] : blocks) out.push_back(std::move(frames));
    return out;
}

// Parameters an effect adds to a model (those screening can move: a gust's
// frequency means nothing without a gust).
double parameter_count(const Effect& effect) {
    double k = 0.0;
    for (const EffectParameter& p : effect.parameters) k += p.screen_step > 0.0 ? 1.0 : 0.0;
    return k;
}

// BIC difference of a model against a reference on training frames, the
// frames' error/floor taken as scaled chi-squares with their observations as
// degrees of freedom: N ln(S / S_ref) + dk ln N, N = the observations.
double delta_bic(const Residuals& model, const Residuals& reference, double extra_parameters) {
    double n = 0.0;
    for (const FrameResidual& f : model.frames)
        if (!f.held_out) n += f.observations;
    const double s = training_score(model), s_ref = training_score(reference);
    if (!(s > 0.0) || !(s_ref > 0.0) || n < 1.0) return kNaN;
    return n * std::log(s / s_ref) + extra_parameters * std::log(n);
}

Spectrum residual_spectrum(const Residuals& base) {
    Spectrum out;
    // The first trial's frames (all trials' would mix lengths and rates).
    std::vector<double> residual, floor;
    double dt = 0.0;
    for (const FrameResidual& f : base.frames) {
        if (f.trial != 0) continue;
        if (residual.size() == 1) dt = f.time_s - base.frames.front().time_s;
        residual.push_back(f.error - f.floor);
        floor.push_back(f.floor);
    }
    const std::size_t n = residual.size();
    if (n < 4 || !(dt > 0.0)) return out;
    const auto mean_removed = [](std::vector<double> v) {
        double m = 0.0;
        for (double x : v) m += x;
        m /= static_cast<double>(v.size());
        for (double& x : v) x -= m;
        return v;
    };
    residual = mean_removed(residual);
    floor = mean_removed(floor);
    for (std::size_t j = 0; j <= n / 2; ++j) {
        std::complex<double> a = 0.0, b = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            const std::complex<double> w = std::polar(1.0, -2.0 * std::numbers::pi * double(j) * double(k) / double(n));
            a += residual[k] * w;
            b += floor[k] * w;
        }
        out.frequency_hz.push_back(static_cast<double>(j) / (static_cast<double>(n) * dt));
        out.residual_power.push_back(std::norm(a) / static_cast<double>(n));
        out.floor_power.push_back(std::norm(b) / static_cast<double>(n));
    }
    return out;
}

class Stages {
public:
    explicit Stages(const DiagnoseSettings& settings) : m_settings(settings) {}
    void report(const std::string& stage, double fraction) const {
        report_progress(m_settings.progress, stage, fraction);
    }

private:
    const DiagnoseSettings& m_settings;
};

struct Screened {
    double score = 0.0;
    EffectValues best;
};

// Screening: per parameter, the training score at neutral and two steps
// (both sides when the range allows, else two steps out); the reduction a
// quadratic through them predicts, or the best sampled one. An effect's
// score is its best parameter's.
Screened screen(const GapModel& model, const std::string& name, const EffectValues& fixed,
                const std::vector<BaseParameterChange>& base, double base_score, long long& evaluations) {
    const Effect& effect = find_effect(name);
    Screened out;
    out.best = fixed;
    out.best[name] = neutral_values(effect);
    for (std::size_t i = 0; i < effect.parameters.size(); ++i) {
        const EffectParameter& p = effect.parameters[i];
        if (!(p.screen_step > 0.0)) continue;
        const bool two_sided = p.neutral - p.screen_step >= p.lower;
        const double h = p.screen_step;
        const std::array<double, 2> offsets = two_sided ? std::array<double, 2>{-h, h} : std::array<double, 2>{h, 2.0 * h};
        std::array<double, 2> scores{};
        for (int s = 0; s < 2; ++s) {
            EffectValues trial = fixed;
            trial[name] = neutral_values(effect);
            trial[name](static_cast<Eigen::Index>(i)) = p.neutral + offsets[static_cast<std::size_t>(s)];
            const Residuals r = model.evaluate(trial, base);
            ++evaluations;
            scores[static_cast<std::size_t>(s)] = r.ok ? training_score(r) : std::numeric_limits<double>::infinity();
        }
        // Quadratic through (0, base), (o1, s1), (o2, s2): its minimum within the range.
        const double x1 = offsets[0], x2 = offsets[1], y0 = base_score, y1 = scores[0], y2 = scores[1];
        double best_x = 0.0, best_y = y0;
        if (y1 < best_y) best_x = x1, best_y = y1;
        if (y2 < best_y) best_x = x2, best_y = y2;
        if (std::isfinite(y1) && std::isfinite(y2)) {
            // y = a x^2 + b x + y0
            const double det = x1 * x2 * (x1 - x2);
            const double a = ((y1 - y0) * x2 - (y2 - y0) * x1) / det;
            const double b = ((y2 - y0) * x1 * x1 - (y1 - y0) * x2 * x2) / det;
            if (a > 0.0) {
                const double x = std::clamp(-b / (2.0 * a), p.lower - p.neutral, p.upper - p.neutral);
                const double y = a * x * x + b * x + y0;
                if (y < best_y) best_x = x, best_y = std::max(y, 0.0);
            }
        }
        const double reduction = base_score - best_y;
        if (reduction > out.score) {
            out.score = reduction;
            out.best[name] = neutral_values(effect);
            out.best[name](static_cast<Eigen::Index>(i)) = p.neutral + best_x;
        }
    }
    return out;
}

// Share of bootstrap resamples of the held-out blocks in which candidate
// `which` has the lowest held-out score of all `candidates` and beats `null`.
double bootstrap_stability(const std::vector<const Residuals*>& candidates, std::size_t which, const Residuals& null,
                           const std::vector<std::vector<std::size_t>>& blocks, int resamples, std::uint64_t seed) {
    if (blocks.empty() || resamples < 1) return 0.0;
    Random random(seed);
    const auto block_score = [](const Residuals& r, const std::vector<std::size_t>& block) {
        double s = 0.0;
        for (std::size_t i : block) s += r.frames[i].error / r.frames[i].floor;
        return s;
    };
    int wins = 0;
    std::vector<double> totals(candidates.size());
    for (int b = 0; b < resamples; ++b) {
        std::fill(totals.begin(), totals.end(), 0.0);
        double null_total = 0.0;
        for (std::size_t k = 0; k < blocks.size(); ++k) {
            const std::vector<std::size_t>& block = blocks[random.below(blocks.size())];
            for (std::size_t c = 0; c < candidates.size(); ++c) totals[c] += block_score(*candidates[c], block);
            null_total += block_score(null, block);
        }
        bool best = totals[which] < null_total;
        for (std::size_t c = 0; c < candidates.size() && best; ++c)
            if (c != which && totals[c] <= totals[which]) best = false;
        wins += best ? 1 : 0;
    }
    return static_cast<double>(wins) / static_cast<double>(resamples);
}

std::string join(const std::vector<std::string>& names, const std::string& separator) {
    std::string out;
    for (const std::string& n : names) out += (out.empty() ? "" : separator) + n;
    return out;
}

}  // namespace

Diagnosis diagnose(const GapModel& model, const DiagnoseSettings& settings) {
    const auto started = std::chrono::steady_clock::now();
    const Stages stages(settings);
    Diagnosis d;
    d.kind = model.kind();
    d.trials = model.trial_names();
    d.threshold = settings.gap_threshold;

    // 1. The base model and whether its held-out residual is beyond the floor.
    stages.report("base", 0.0);
    d.base = model.evaluate({});
    ++d.evaluations;
    for (const FrameResidual& f : d.base.frames) {
        if (!f.held_out) continue;
        d.held_out_error += f.error;
        d.held_out_floor += f.floor;
        d.held_out_score += f.error / f.floor;
        ++d.held_out_frames;
    }
    d.ratio = d.held_out_frames > 0 ? d.held_out_score / d.held_out_frames : kNaN;
    d.gap_detected = !d.base.ok || d.ratio > settings.gap_threshold;
    d.spectrum = residual_spectrum(d.base);

    // 2. Where.
    stages.report("localise", 0.05);
    d.maps = model.localise({});

    if (!d.gap_detected) {
        d.status = "no_gap";
        d.message = "no structural gap: the held-out residual is " + std::to_string(d.ratio).substr(0, 5) +
                    " times its floor, within the threshold of " + std::to_string(settings.gap_threshold).substr(0, 4) +
                    " (chaos, noise and discretisation explain it)";
        d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return d;
    }

    // 3. Which: screen every candidate, refit the most promising.
    std::vector<std::string> names = settings.effects.empty() ? model.candidate_effects() : settings.effects;
    const std::vector<std::string> offered = model.candidate_effects();
    names.erase(std::remove_if(names.begin(), names.end(),
                               [&](const std::string& n) { return std::find(offered.begin(), offered.end(), n) == offered.end(); }),
                names.end());
    const std::vector<std::vector<std::size_t>> blocks = held_out_blocks(d.base);
    const double base_held_out = held_out_score(d.base);
    const double floor_level = static_cast<double>(count_frames(d.base, true));  // error = floor in every held-out frame
    const double gap = std::max(base_held_out - floor_level, 1e-12);

    stages.report("null refit", 0.1);
    d.null_refit = model.refit({}, settings.refit_evaluations);
    d.evaluations += d.null_refit.evaluations;

    EffectValues named_values;          // effects named so far, at their fitted values
    Residuals current = d.null_refit.residuals;  // the model the next effect must beat
    RefitResult current_refit = d.null_refit;
    std::uint64_t round_seed = settings.seed;
    for (int round = 0; round < settings.max_effects; ++round) {
        const double round_start = 0.15 + 0.8 * round / settings.max_effects;
        const double round_span = 0.8 / settings.max_effects;
        std::vector<CandidateEvidence> evidence;
        // Screening steps away from the model an effect must beat: the null
        // refit in the first round (the base parameters refitted alone absorb
        // what they can, e.g. a different discretisation's damping, so that
        // what is left shows the effect's own signature), the named effects
        // at their fitted values after.
        const double current_score = training_score(current);
        int index = 0;
        for (const std::string& name : names) {
            if (named_values.count(name)) continue;
            stages.report("screening " + name, round_start + 0.3 * round_span * index++ / std::max<std::size_t>(1, names.size()));
            CandidateEvidence c;
            c.name = name;
            const Effect& effect = find_effect(name);
            c.domain = domain_name(effect.domain);
            c.equivalence_class = effect.equivalence_class;
            const Screened s = screen(model, name, named_values, current_refit.base, current_score, d.evaluations);
            c.screen_score = s.score;
            c.screened = s.best;
            c.gap_closed = kNaN;
            c.delta_bic = kNaN;
            evidence.push_back(std::move(c));
        }
        std::stable_sort(evidence.begin(), evidence.end(),
                         [](const CandidateEvidence& a, const CandidateEvidence& b) { return a.screen_score > b.screen_score; });
        const int refits = std::min<int>(settings.refitted_candidates, static_cast<int>(evidence.size()));
        for (int i = 0; i < refits; ++i) {
            CandidateEvidence& c = evidence[static_cast<std::size_t>(i)];
            if (!(c.screen_score > 0.0)) break;  // nothing to gain: not worth a refit
            stages.report("refitting " + c.name, round_start + round_span * (0.3 + 0.6 * i / std::max(1, refits)));
            EffectValues start = c.screened;  // the named effects at their values, this one at its screened best
            // From the base as the previous model left it (the null refit, or
            // the named effects' refit): the effect must earn its keep beyond it.
            c.refit = model.refit(start, settings.refit_evaluations, current_refit.base);
            d.evaluations += c.refit.evaluations;
            c.refitted = true;
            c.held_out_score = held_out_score(c.refit.residuals);
            c.gap_closed = (base_held_out - c.held_out_score) / gap;
            c.effect_share = (held_out_score(current) - c.held_out_score) / gap;
            c.delta_bic = delta_bic(c.refit.residuals, current, parameter_count(find_effect(c.name)));
        }
        std::vector<const Residuals*> refitted;
        std::vector<std::size_t> which;
        for (std::size_t i = 0; i < evidence.size(); ++i)
            if (evidence[i].refitted) {
                refitted.push_back(&evidence[i].refit.residuals);
                which.push_back(i);
            }
        for (std::size_t r = 0; r < refitted.size(); ++r) {
            CandidateEvidence& c = evidence[which[r]];
            c.bootstrap_stability =
                bootstrap_stability(refitted, r, current, blocks, settings.bootstrap_resamples, round_seed + r);
            c.passes = c.refit.residuals.ok && c.effect_share >= settings.min_effect_share &&
                       c.delta_bic <= settings.max_delta_bic && c.bootstrap_stability >= settings.min_stability;
        }
        round_seed += 1000;
        // Rank: refitted by held-out score, then the rest by screening.
        std::stable_sort(evidence.begin(), evidence.end(), [](const CandidateEvidence& a, const CandidateEvidence& b) {
            if (a.refitted != b.refitted) return a.refitted;
            if (a.refitted) return a.held_out_score < b.held_out_score;
            return a.screen_score > b.screen_score;
        });
        const auto winner = std::find_if(evidence.begin(), evidence.end(), [](const CandidateEvidence& c) { return c.passes; });
        if (round == 0) d.candidates = evidence;
        // No candidate passes, or the held-out best does not (a passing
        // runner-up is not evidence enough): stop.
        if (winner == evidence.end() || winner != evidence.begin()) break;
        d.named.push_back(winner->name);
        named_values = winner->refit.effects;
        current = winner->refit.residuals;
        current_refit = winner->refit;
        if (round == 0) d.named_class = winner->equivalence_class;
    }

    // 5. The discretisation control: the base (as the null refit left it) on a
    // finer discretisation. What it closes, the model's own discretisation
    // accounts for; named effects have to close clearly more.
    if (settings.discretisation_control) {
        stages.report("discretisation control", 0.95);
        if (const std::optional<DiscretisationControl> control = model.discretisation_control(d.null_refit.base)) {
            ++d.evaluations;
            d.control_description = control->description;
            if (control->residuals.ok) d.control_gap_closed = (base_held_out - held_out_score(control->residuals)) / gap;
            else d.control_failure = control->residuals.reason.empty() ? "the simulation failed" : control->residuals.reason;
        }
    }
    const double named_closed = (base_held_out - held_out_score(current)) / gap;
    if (!d.named.empty() && d.control_gap_closed &&
        !(named_closed >= *d.control_gap_closed + settings.min_share_beyond_discretisation)) {
        d.status = "unexplained";
        d.message = "a structural gap (held-out residual " + std::to_string(d.ratio).substr(0, 5) +
                    " times its floor) that the model's own discretisation may account for: the base on " + d.control_description +
                    " closes " + std::to_string(static_cast<int>(std::lround(100.0 * *d.control_gap_closed))) + " % of it, " +
                    join(d.named, " + ") + " " + std::to_string(static_cast<int>(std::lround(100.0 * named_closed))) +
                    " %; diagnose on a finer mesh (--resolution) to tell them apart";
        d.discounted = d.named;
        d.named.clear();
        d.named_class.clear();
    } else if (d.named.empty()) {
        d.status = "unexplained";
        std::vector<std::string> best;
        for (std::size_t i = 0; i < d.candidates.size() && i < 3; ++i) best.push_back(d.candidates[i].name);
        d.message = "a structural gap (held-out residual " + std::to_string(d.ratio).substr(0, 5) +
                    " times its floor) that no catalogue effect explains with enough evidence; closest: " + join(best, ", ");
    } else {
        d.status = "named";
        d.named_refit = current_refit;
        d.gap_closed = named_closed;
        const std::string what = d.named_class.empty() ? join(d.named, " + ")
                                                        : "the class " + d.named_class + " (one camera cannot tell its members apart)";
        d.message = "the gap is explained by " + what + ": it closes " +
                    std::to_string(static_cast<int>(std::lround(100.0 * *d.gap_closed))) + " % of the held-out gap";
    }
    stages.report("done", 1.0);
    d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return d;
}

}  // namespace flowvid::gap
