#include "flowvid/gap/diagnose.hpp"
#include "flowvid/random.hpp"
#include "flowvid/thread_pool.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
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
// quadratic through them predicts within twice the farthest step, or the
// best sampled one. An effect's score is its best parameter's.
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
                // Trusted no further than twice the farthest step: beyond
                // the points it passes through, a parabola is a guess.
                const double reach = 2.0 * std::max(std::abs(x1), std::abs(x2));
                const double x = std::clamp(-b / (2.0 * a), std::max(p.lower - p.neutral, -reach), std::min(p.upper - p.neutral, reach));
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

std::string join(const std::vector<std::string>& names, const std::string& separator) {
    std::string out;
    for (const std::string& n : names) out += (out.empty() ? "" : separator) + n;
    return out;
}

std::string percent(double share) { return std::to_string(static_cast<int>(std::lround(100.0 * share))) + " %"; }
std::string times(double ratio) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f", ratio);
    return text;
}

std::string plain_list(const std::vector<std::string>& names) {
    std::vector<std::string> out;
    for (const std::string& n : names) out.push_back(labelled_name(n));
    return join(out, " and ");
}

// The state a round of naming starts from: the effects named so far at their
// fitted values and the model they make.
struct Named {
    std::vector<std::string> names;
    EffectValues values;
    RefitResult refit;  // the named effects refitted jointly with the base (the null refit when none)
};

// Greedy naming over `names`, from `start`: each round screens every
// candidate not yet named, refits the most promising jointly with the base
// parameters, and names the held-out best when it passes every test
// (`terms_compete`: its bootstrap stability counts the resamples in which it
// beats the other refitted candidates too, not only the model before it).
// `round_zero` receives the first round's evidence.
Named name_greedily(const GapModel& model, const DiagnoseSettings& settings, const std::vector<std::string>& names,
                    Named start, int max_rounds, bool terms_compete, double base_held_out, double gap,
                    const std::vector<std::vector<std::size_t>>& blocks, std::uint64_t seed, const Stages& stages, ThreadPool& pool,
                    double progress_start, double progress_span, long long& evaluations,
                    std::vector<CandidateEvidence>& round_zero) {
    Named current = std::move(start);
    std::uint64_t round_seed = seed;
    for (int round = 0; round < max_rounds; ++round) {
        const double round_start = progress_start + progress_span * round / max_rounds;
        const double round_span = progress_span / max_rounds;
        std::vector<CandidateEvidence> evidence;
        // Screening steps away from the model an effect must beat: the null
        // refit in the first round (the base parameters refitted alone absorb
        // what they can, e.g. a different discretisation's damping, so that
        // what is left shows the effect's own signature), the named effects
        // at their fitted values after.
        const double current_score = training_score(current.refit.residuals);
        for (const std::string& name : names) {
            if (current.values.count(name)) continue;
            CandidateEvidence c;
            c.name = name;
            const Effect& effect = find_effect(name);
            c.domain = domain_name(effect.domain);
            c.equivalence_class = effect.equivalence_class;
            c.gap_closed = kNaN;
            c.delta_bic = kNaN;
            evidence.push_back(std::move(c));
        }
        // Candidates are screened, then refitted, side by side (each result
        // depends only on its inputs: the verdict does not depend on threads).
        std::vector<long long> spent(evidence.size(), 0);
        stages.report("screening " + std::to_string(evidence.size()) + " candidates", round_start);
        pool.run(evidence.size(), [&](std::size_t i, int) {
            const Screened s = screen(model, evidence[i].name, current.values, current.refit.base, current_score, spent[i]);
            evidence[i].screen_score = s.score;
            evidence[i].screened = s.best;
        });
        std::stable_sort(evidence.begin(), evidence.end(),
                         [](const CandidateEvidence& a, const CandidateEvidence& b) { return a.screen_score > b.screen_score; });
        int refits = 0;  // the most promising, while there is something to gain
        while (refits < std::min<int>(settings.refitted_candidates, static_cast<int>(evidence.size())) &&
               evidence[static_cast<std::size_t>(refits)].screen_score > 0.0)
            ++refits;
        std::string refitting;
        for (int i = 0; i < refits; ++i) refitting += (i ? ", " : "") + evidence[static_cast<std::size_t>(i)].name;
        if (refits > 0) stages.report("refitting " + refitting, round_start + 0.3 * round_span);
        // After a name, the model it made is refitted once more beside the
        // candidates, with their budget, and the better of the two (on
        // training frames) is what they must beat: a candidate's refit also
        // goes on optimising the named effect, and a first effect's refit,
        // started from its screened point, is often far from converged (a
        // sealed case's pin slip: the continuation alone took the held-out
        // score from 51.5 to 38.0 floors, as much as a camera roll "named"
        // on top of it). The null refit needs no continuation: on
        // cotton-waving-1 one gains 3 % on training frames and loses on
        // held-out ones. Nothing to judge, nothing continued.
        const bool continue_current = round > 0 && refits > 0;
        std::optional<RefitResult> continued;
        pool.run(static_cast<std::size_t>(refits) + (continue_current ? 1 : 0), [&](std::size_t i, int) {
            if (i == static_cast<std::size_t>(refits)) {
                continued = model.refit(current.values, settings.refit_evaluations, current.refit.base);
                return;
            }
            CandidateEvidence& c = evidence[i];
            // The named effects at their values, this one at its screened best,
            // from the base as the previous model left it: the effect must
            // earn its keep beyond it.
            c.refit = model.refit(c.screened, settings.refit_evaluations, current.refit.base);
            spent[i] += c.refit.evaluations;
            c.refitted = true;
        });
        for (long long n : spent) evaluations += n;
        if (continued) evaluations += continued->evaluations;
        if (continued && continued->residuals.ok && training_score(continued->residuals) < current_score) {
            current.values = continued->effects;
            current.refit = std::move(*continued);
        }
        const Residuals& reference = current.refit.residuals;
        // What that model leaves of the gap (held-out, above the floor): an
        // effect must explain a share of it. Measured against the whole gap
        // instead, an effect whose signature the base parameters partly
        // mimic (a lag the null refit half absorbs by stiffening) could never
        // be named, however much of the rest it explains.
        const double reference_held_out = held_out_score(reference);
        const double remaining = std::max(reference_held_out - (base_held_out - gap), 1e-12 * gap);
        for (CandidateEvidence& c : evidence) {
            if (!c.refitted) continue;
            c.held_out_score = held_out_score(c.refit.residuals);
            c.gap_closed = (base_held_out - c.held_out_score) / gap;
            c.effect_share = (reference_held_out - c.held_out_score) / gap;
            c.share_of_remaining = (reference_held_out - c.held_out_score) / remaining;
            c.delta_bic = delta_bic(c.refit.residuals, reference, parameter_count(find_effect(c.name)));
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
            // The world's effects compete: footage usually hides one, and the
            // one named must beat the others in most resamples. The model's
            // own terms do not: a preset fitted without several may miss
            // them all (soft compression and diagonal fibres both shape
            // folds), so each need only beat the model before it; the
            // greedy rounds then add the others on top.
            c.bootstrap_stability =
                terms_compete ? bootstrap_stability(refitted, r, reference, blocks, settings.bootstrap_resamples, round_seed + r)
                              : bootstrap_stability({refitted[r]}, 0, reference, blocks, settings.bootstrap_resamples, round_seed + r);
            c.passes = c.refit.residuals.ok && c.share_of_remaining >= settings.min_effect_share &&
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
        if (round == 0) round_zero = evidence;
        // No candidate passes, or the held-out best does not (a passing
        // runner-up is not evidence enough): stop.
        if (winner == evidence.end() || winner != evidence.begin()) break;
        current.names.push_back(winner->name);
        current.values = winner->refit.effects;
        current.refit = winner->refit;
    }
    return current;
}

double held_out_ratio(const Residuals& r) {
    const int n = count_frames(r, true);
    return n > 0 ? held_out_score(r) / n : kNaN;
}

}  // namespace

// Bayesian bootstrap: each resample weighs the blocks by flat Dirichlet weights
// (independent unit exponentials) instead of drawing them with replacement:
// with the few blocks a diagnosis has (three in 30 frames) a drawn resample
// leaves any one block out with probability (2/3)^3 = 0.30, so a candidate
// that closes a gap concentrated in one block (the first held-out block of a
// waving cloth, where the chaos floor is smallest) and is slightly worse
// elsewhere could never reach a stability above 0.70. Weights keep every
// block in every resample and still ask the win to hold when the blocks'
// shares shift.
double bootstrap_stability(const std::vector<const Residuals*>& candidates, std::size_t which, const Residuals& null,
                           const std::vector<std::vector<std::size_t>>& blocks, int resamples, std::uint64_t seed) {
    if (blocks.empty() || resamples < 1) return 0.0;
    const auto block_score = [](const Residuals& r, const std::vector<std::size_t>& block) {
        double s = 0.0;
        for (std::size_t i : block) s += r.frames[i].error / r.frames[i].floor;
        return s;
    };
    // Scores per block: [candidate][block], then the null model's.
    std::vector<std::vector<double>> scores(candidates.size(), std::vector<double>(blocks.size()));
    std::vector<double> null_scores(blocks.size());
    for (std::size_t k = 0; k < blocks.size(); ++k) {
        for (std::size_t c = 0; c < candidates.size(); ++c) scores[c][k] = block_score(*candidates[c], blocks[k]);
        null_scores[k] = block_score(null, blocks[k]);
    }
    Random random(seed);
    std::vector<double> weights(blocks.size());
    int wins = 0;
    for (int b = 0; b < resamples; ++b) {
        for (double& w : weights) w = -std::log(random.open_unit());
        const auto weighted = [&](const std::vector<double>& per_block) {
            double total = 0.0;
            for (std::size_t k = 0; k < per_block.size(); ++k) total += weights[k] * per_block[k];
            return total;
        };
        const double mine = weighted(scores[which]);
        bool best = mine < weighted(null_scores);
        for (std::size_t c = 0; c < candidates.size() && best; ++c)
            if (c != which && weighted(scores[c]) <= mine) best = false;
        wins += best ? 1 : 0;
    }
    return static_cast<double>(wins) / static_cast<double>(resamples);
}

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

    const std::string how_far = "over the held-out frames the model misses the footage by " + times(d.ratio) +
                                " times what repeated takes of the experiment differ by";
    if (!d.gap_detected) {
        d.status = "no_gap";
        d.message = "No structural gap: " + how_far + ", within the threshold of " + times(settings.gap_threshold) +
                    " (chaos, noise and discretisation explain it).";
        d.next_step = "nothing to fix: the preset reproduces this footage as well as the experiment repeats";
        d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return d;
    }

    // 3. Which: the model's own terms first, then the world's effects.
    std::vector<std::string> names = settings.effects.empty() ? model.candidate_effects() : settings.effects;
    const std::vector<std::string> offered = model.candidate_effects();
    names.erase(std::remove_if(names.begin(), names.end(),
                               [&](const std::string& n) { return std::find(offered.begin(), offered.end(), n) == offered.end(); }),
                names.end());
    std::vector<std::string> model_names, effect_names;
    for (const std::string& n : names) (find_effect(n).domain == EffectDomain::model ? model_names : effect_names).push_back(n);
    const std::vector<std::vector<std::size_t>> blocks = held_out_blocks(d.base);
    const double base_held_out = held_out_score(d.base);
    const double floor_level = static_cast<double>(count_frames(d.base, true));  // error = floor in every held-out frame
    const double gap = std::max(base_held_out - floor_level, 1e-12);
    const auto closed = [&](const Residuals& r) { return (base_held_out - held_out_score(r)) / gap; };

    ThreadPool pool(settings.concurrent_evaluations > 0 ? std::min(settings.concurrent_evaluations, model.concurrency())
                                                        : model.concurrency());
    stages.report("null refit", 0.1);
    d.null_refit = model.refit({}, settings.refit_evaluations);
    d.evaluations += d.null_refit.evaluations;

    // The discretisation control: the base (as the null refit left it, with
    // the model terms named so far) on a finer discretisation. What it
    // closes, the model's own discretisation accounts for; named terms and
    // effects have to close clearly more.
    std::map<std::string, std::optional<double>> controls;  // by the model terms it holds
    const auto control_closes = [&](const EffectValues& terms) -> std::optional<double> {
        if (!settings.discretisation_control) return std::nullopt;
        std::string key;
        for (const auto& [name, values] : terms) key += name + ";";
        if (const auto it = controls.find(key); it != controls.end()) return it->second;
        stages.report("discretisation control", 0.93);
        std::optional<double> share;
        if (const std::optional<DiscretisationControl> control = model.discretisation_control(d.null_refit.base, terms)) {
            ++d.evaluations;
            d.control_description = control->description;
            if (control->residuals.ok) share = closed(control->residuals);
            else d.control_failure = control->residuals.reason.empty() ? "the simulation failed" : control->residuals.reason;
        }
        controls[key] = share;
        return share;
    };

    // 3a. The model's own physics: a term the preset holds at its neutral
    // value (fitted without it) that closes the gap is the first thing to fix.
    Named after_model{{}, {}, d.null_refit};
    double discounted_closed = 0.0;  // what the discounted terms or effects closed
    if (!model_names.empty()) {
        after_model = name_greedily(model, settings, model_names, after_model, settings.max_model_terms, false, base_held_out, gap,
                                    blocks, settings.seed + 7919, stages, pool, 0.15, 0.3, d.evaluations, d.model_candidates);
        if (!after_model.names.empty()) {
            const double share = closed(after_model.refit.residuals);
            const std::optional<double> control = control_closes({});
            if (control && !(share >= *control + settings.min_share_beyond_discretisation)) {
                d.discounted = after_model.names;
                discounted_closed = share;
                after_model = Named{{}, {}, d.null_refit};
            } else {
                d.model_terms = after_model.names;
                d.model_gap_closed = share;
                d.model_refit = after_model.refit;
            }
        }
    }
    const bool model_named = !d.model_terms.empty();
    d.ratio_with_model_terms = held_out_ratio(after_model.refit.residuals);

    // 3b. The world's effects, on top of the model terms named.
    EffectValues model_values = after_model.values;
    Named after_effects = after_model;
    const bool gap_left = !model_named || d.ratio_with_model_terms > settings.gap_threshold;
    if (gap_left && !effect_names.empty()) {
        after_effects = name_greedily(model, settings, effect_names, after_model, settings.max_effects, true, base_held_out, gap,
                                      blocks, settings.seed, stages, pool, model_names.empty() ? 0.15 : 0.45,
                                      model_names.empty() ? 0.78 : 0.48, d.evaluations, d.candidates);
    }
    std::vector<std::string> effects_named(after_effects.names.begin() + static_cast<std::ptrdiff_t>(after_model.names.size()),
                                           after_effects.names.end());
    const double effects_closed = closed(after_effects.refit.residuals) - closed(after_model.refit.residuals);
    if (!effects_named.empty()) {
        const std::optional<double> control = control_closes(model_values);
        if (control && !(closed(after_effects.refit.residuals) >= *control + settings.min_share_beyond_discretisation)) {
            d.control_gap_closed = control;
            d.discounted.insert(d.discounted.end(), effects_named.begin(), effects_named.end());
            discounted_closed = closed(after_effects.refit.residuals);
            effects_named.clear();
        }
    }
    if (!d.control_gap_closed && settings.discretisation_control && (model_named || !effects_named.empty() || !d.discounted.empty()))
        d.control_gap_closed = control_closes(model_values);

    // 4. The verdict, in words an artist can act on.
    const std::string model_sentence =
        model_named ? "The fabric model itself lacks " + plain_list(d.model_terms) + ": adding " +
                          (d.model_terms.size() > 1 ? "them" : "it") + " closes " +
                          percent(*d.model_gap_closed) + " of the gap (" + times(d.ratio) + " -> " +
                          times(d.ratio_with_model_terms) + " times the floor)."
                    : "";
    if (!effects_named.empty()) {
        d.status = "named";
        d.named = effects_named;
        d.named_class = find_effect(effects_named.front()).equivalence_class;
        d.named_refit = after_effects.refit;
        d.gap_closed = effects_closed;
        const std::string what = d.named_class.empty()
                                     ? plain_list(d.named)
                                     : plain_list(d.named) + ", reported as the class " + d.named_class + " (one camera cannot tell its members apart)";
        const std::string verb = d.named.size() > 1 ? " account" : " accounts";
        d.message = "Gap explained: " + how_far + "; " + what + verb + " for it, closing " + percent(*d.gap_closed) + " of that gap." +
                    (model_sentence.empty() ? "" : " " + model_sentence);
        d.next_step = find_effect(d.named.front()).next_step;
        if (model_named) d.next_step += "; and " + find_effect(d.model_terms.front()).next_step;
    } else if (model_named && !gap_left) {
        d.status = "no_gap";
        d.message = model_sentence + " With it, no structural gap is left: no effect of the world (wind, pins, camera) "
                                     "is needed to explain the footage.";
        d.next_step = find_effect(d.model_terms.front()).next_step;
    } else if (!d.discounted.empty() && d.control_gap_closed) {
        d.status = "unexplained";
        d.message = "Unexplained gap: " + how_far + ". The model's own discretisation may account for it: the base on " +
                    d.control_description + " closes " + percent(*d.control_gap_closed) + " of it, " + join(d.discounted, " + ") +
                    " " + percent(discounted_closed) + "." + (model_sentence.empty() ? "" : " " + model_sentence);
        d.next_step = "diagnose on a finer mesh (--resolution) to tell them apart";
    } else {
        d.status = "unexplained";
        const std::vector<CandidateEvidence>& ranked = d.candidates.empty() ? d.model_candidates : d.candidates;
        std::vector<std::string> best;
        for (std::size_t i = 0; i < ranked.size() && i < 3; ++i) best.push_back(labelled_name(ranked[i].name));
        const std::string closest = best.empty() ? std::string(".") : "; closest: " + join(best, ", ") + ".";
        // A named model term is the finding to act on: it leads, and what it
        // leaves is the unexplained part.
        d.message = model_named ? model_sentence + " The rest is unexplained: no effect of the world (wind, pins, camera) "
                                                   "explains it with enough evidence" + closest
                                : "Unexplained gap: " + how_far + ", and no effect explains it with enough evidence" + closest;
        d.next_step = model_named ? find_effect(d.model_terms.front()).next_step
                                  : "look at where the residual lies (the heat maps) and check the capture's calibration and pin record";
    }
    stages.report("done", 1.0);
    d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return d;
}

}  // namespace flowvid::gap
