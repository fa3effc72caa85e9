#include "flowvid/gap/cloth_model.hpp"

#include "flowvid/optim/annealing.hpp"
#include "flowvid/thread_pool.hpp"
#include "flowvid/video/stripe_render.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace flowvid::gap {

namespace {

bool is_neutral(const Effect& effect, const Eigen::VectorXd& values) {
    for (std::size_t i = 0; i < effect.parameters.size(); ++i) {
        // The gust frequency means nothing without a gust: neutral whatever it is.
        if (effect.name == "wind" && effect.parameters[i].key == "gust_frequency_hz") continue;
        if (values(static_cast<Eigen::Index>(i)) != effect.parameters[i].neutral) return false;
    }
    return true;
}

// Positions of a pin at fractional frame index `f` (linear between the
// recorded frames, held at the ends).
Eigen::Vector3d pin_at(const std::vector<Eigen::Vector3d>& positions, double f) {
    if (positions.empty()) return Eigen::Vector3d::Zero();
    const double last = static_cast<double>(positions.size() - 1);
    f = std::clamp(f, 0.0, last);
    const std::size_t i = static_cast<std::size_t>(std::floor(f));
    const double t = f - static_cast<double>(i);
    if (t == 0.0 || i + 1 >= positions.size()) return positions[i];
    return (1.0 - t) * positions[i] + t * positions[i + 1];
}

// A run's 3*#V positions at fractional frame index `f` (linear between frames).
Eigen::VectorXd positions_at(const cloth::SwatchRun& run, int usable, double f) {
    f = std::clamp(f, 0.0, static_cast<double>(std::max(0, usable - 1)));
    const std::size_t i = static_cast<std::size_t>(std::floor(f));
    const double t = f - static_cast<double>(i);
    if (t == 0.0 || static_cast<int>(i) + 1 >= usable) return run.simulation.frames[i];
    return (1.0 - t) * run.simulation.frames[i] + t * run.simulation.frames[i + 1];
}

// The run's vertices at frame `index` as a rolling shutter sees them: a
// vertex imaged on row y was exposed readout * (y / H - 1/2) after the frame
// time (one fixed-point pass: the row of the frame-time position).
std::vector<Eigen::Vector3d> rolling_vertices(const ClothScenario& scenario, const cloth::SwatchRun& run, int usable,
                                              double frame_index) {
    const Eigen::VectorXd centre = positions_at(run, usable, frame_index);
    const std::vector<Eigen::Vector3d> at_frame = video::vertices_from_vector(centre);
    if (scenario.readout_s == 0.0) return at_frame;
    const double fps = scenario.experiment.fps;
    const double height = static_cast<double>(scenario.camera.height);
    std::vector<Eigen::Vector3d> out(at_frame.size());
    const Eigen::VectorXd earlier = positions_at(run, usable, frame_index - 1.0);
    const Eigen::VectorXd later = positions_at(run, usable, frame_index + 1.0);
    for (std::size_t v = 0; v < at_frame.size(); ++v) {
        const Eigen::Vector2d pixel = scenario.camera.project(at_frame[v]);
        const double row = std::isfinite(pixel.y()) ? pixel.y() : 0.5 * height;
        const double offset_frames = scenario.readout_s * (row / height - 0.5) * fps;
        // Linear in time through the neighbouring frames.
        const Eigen::Index k = static_cast<Eigen::Index>(3 * v);
        const Eigen::Vector3d p = at_frame[v];
        const Eigen::Vector3d q = offset_frames >= 0.0 ? Eigen::Vector3d(later.segment<3>(k)) : Eigen::Vector3d(earlier.segment<3>(k));
        out[v] = p + std::abs(offset_frames) * (q - p);
    }
    return out;
}

}  // namespace

// rho_air C_d / 2 for a flat plate across the flow: 1.2 kg/m^3 x 1.2 / 2.
constexpr double kWindPlatePressure_kg_per_m3 = 0.72;

ClothScenario apply_cloth_effects(const cloth_fit::ClothTrial& trial, const cloth::ClothMaterial& material,
                                  const cloth::SwatchOptions& options, const EffectValues& effects) {
    ClothScenario s{trial.experiment, material, options, trial.camera, 0.0, 0.0};
    for (const auto& [name, values] : effects) {
        const Effect& effect = find_effect(name);
        if (values.size() != static_cast<Eigen::Index>(effect.parameters.size()))
            throw std::invalid_argument("effect '" + name + "' needs " + std::to_string(effect.parameters.size()) +
                                        " values, got " + std::to_string(values.size()));
        if (is_neutral(effect, values)) continue;
        if (name == "compression_softness") {
            const double ratio = std::exp(-values(0));
            s.material.stretch_warp_compression_ratio *= ratio;
            s.material.stretch_weft_compression_ratio *= ratio;
        } else if (name == "hem_mass") {
            s.material.hem_line_density_kg_per_m = values(0);  // the swatch keeps its declared mass
        } else if (name == "diagonal_fibres") {
            // Relative to the stretch stiffness, so that one range suits every fabric.
            s.material.diagonal_tension_N_per_m =
                values(0) * std::sqrt(s.material.stretch_warp_N_per_m * s.material.stretch_weft_N_per_m);
        } else if (name == "drag_linear") {
            s.material.drag_linear_normal_kg_per_m2_s = values(0);
        } else if (name == "drag_nonlinear") {
            s.material.drag_normal_kg_per_m3 = values(0);
            s.material.drag_degradation_s2_per_m2 = values(1);
        } else if (name == "wind") {
            const Eigen::Vector3d steady = values.head<3>();
            const double amplitude = values(3), frequency = values(4);
            s.options.environment.wind_m_per_s = steady;
            // A draught pushes the swatch as air pushes a flat plate
            // (cloth::Environment::wind_pressure_kg_per_m3), whatever drag
            // the preset was fitted with.
            s.options.environment.wind_pressure_kg_per_m3 = kWindPlatePressure_kg_per_m3;
            if (amplitude != 0.0) {
                const Eigen::Vector3d along = steady.norm() > 0.0 ? Eigen::Vector3d(steady.normalized()) : Eigen::Vector3d::UnitX();
                s.options.environment.wind_field = [steady, amplitude, frequency, along](const Eigen::Vector3d&, double t) {
                    return Eigen::Vector3d(steady + amplitude * std::sin(2.0 * std::numbers::pi * frequency * t) * along);
                };
            }
        } else if (name == "anisotropy") {
            // Warp and weft apart by the ratio, their geometric mean kept.
            const double half = 0.5 * values(0);
            s.material.stretch_warp_N_per_m *= std::exp(-half);
            s.material.stretch_weft_N_per_m *= std::exp(half);
            s.material.bias_angle_rad = values(1);
        } else if (name == "hysteresis") {
            s.material.bend_memory_rate_per_s = values(0);
        } else if (name == "pin_lag") {
            // The footage at time t shows the pins where the record has them at t - lag.
            const double lag_frames = values(0) * s.experiment.fps;
            for (cloth::PinTrajectory& pin : s.experiment.pins) {
                const std::vector<Eigen::Vector3d> recorded = pin.positions_m;
                for (std::size_t k = 0; k < pin.positions_m.size(); ++k)
                    pin.positions_m[k] = pin_at(recorded, static_cast<double>(k) - lag_frames);
            }
        } else if (name == "pin_slip") {
            const Eigen::Vector3d down = s.options.environment.gravity_m_per_s2.normalized();
            for (cloth::PinTrajectory& pin : s.experiment.pins)
                for (std::size_t k = 0; k < pin.positions_m.size(); ++k)
                    pin.positions_m[k] += values(0) * (static_cast<double>(k) / s.experiment.fps) * down;
        } else if (name == "camera_roll") {
            Eigen::Matrix4d roll = Eigen::Matrix4d::Identity();
            roll.topLeftCorner<3, 3>() = Eigen::AngleAxisd(values(0), Eigen::Vector3d::UnitZ()).toRotationMatrix();
            s.camera.camera_from_world = roll * s.camera.camera_from_world;
        } else if (name == "lens_distortion") {
            s.camera.dist[0] += values(0);
            s.camera.dist[1] += values(1);
        } else if (name == "rolling_shutter") {
            s.readout_s = values(0);
        } else if (name == "motion_blur") {
            s.exposure_s = values(0);
        } else {
            throw std::invalid_argument("effect '" + name + "' is not a cloth or camera effect");
        }
    }
    return s;
}

video::StripeImage film_frame(const ClothScenario& scenario, const cloth::SwatchRun& run, int index,
                              video::StripeRenderer& renderer) {
    const int usable = cloth_fit::usable_frames(run);
    const auto& triangles = run.swatch.mesh.triangles;
    if (scenario.exposure_s <= 0.0)
        return renderer.render(rolling_vertices(scenario, run, usable, index), triangles);
    // Motion blur: the mean of renders spread evenly over the open shutter.
    constexpr int kSamples = 5;
    video::StripeImage sum;
    std::vector<int> coverage;
    for (int s = 0; s < kSamples; ++s) {
        const double offset_s = scenario.exposure_s * ((s + 0.5) / kSamples - 0.5);
        video::StripeImage one =
            renderer.render(rolling_vertices(scenario, run, usable, index + offset_s * scenario.experiment.fps), triangles);
        if (s == 0) {
            sum = one;
            coverage.assign(one.silhouette.pixels.size(), 0);
            std::fill(sum.image.pixels.begin(), sum.image.pixels.end(), 0.0f);
        }
        for (std::size_t i = 0; i < one.image.pixels.size(); ++i) sum.image.pixels[i] += one.image.pixels[i] / kSamples;
        for (std::size_t i = 0; i < coverage.size(); ++i) coverage[i] += one.silhouette.pixels[i] ? 1 : 0;
        sum.region = sum.region.united(one.region);
    }
    for (std::size_t i = 0; i < coverage.size(); ++i) sum.silhouette.pixels[i] = 2 * coverage[i] >= kSamples ? 1 : 0;
    return sum;
}

std::vector<float> residual_image(const video::ReferenceFrame& reference, const video::AngleMap& simulated,
                                  const metrics::Silhouette& simulated_silhouette,
                                  const video::AngleMapMetricSettings& metric) {
    const std::size_t n = reference.silhouette.pixels.size();
    std::vector<float> out(n, 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
        if (reference.silhouette.pixels[i] != simulated_silhouette.pixels[i]) out[i] += static_cast<float>(metric.alpha);
        if (i < reference.angles.valid.size() && i < simulated.valid.size() && reference.angles.valid[i] &&
            simulated.valid[i] && reference.angles.gradient_mask[i]) {
            const float d = video::orientation_difference(reference.angles.angle_rad[i], simulated.angle_rad[i]);
            out[i] += d * d;
        }
    }
    return out;
}

ClothGapModel::ClothGapModel(std::vector<cloth_fit::ClothTrial> trials, cloth::ClothMaterial base, ClothGapSettings settings)
    : m_trials(std::move(trials)), m_base(std::move(base)), m_settings(std::move(settings)) {
    if (m_trials.empty()) throw std::invalid_argument("ClothGapModel: no trials");
    // A linear-drag base refits its linear drag; the nonlinear one is the effect.
    if (m_base.drag_normal_kg_per_m3 == 0.0)
        for (std::string& key : m_settings.refit_base)
            if (key == "drag_normal_kg_per_m3")
                key = m_base.drag_linear_normal_kg_per_m2_s > 0.0 ? "drag_linear_normal_kg_per_m2_s" : "drag_tangential_kg_per_m2_s";
    const int threads = std::max(1, m_settings.threads);
    m_warm_starts.resize(m_trials.size());
    m_floors.resize(m_trials.size());
    m_pin_speeds.resize(m_trials.size());
    cloth_fit::ClothFitSettings fit = m_settings.fit;
    fit.base = m_base;
    for (std::size_t t = 0; t < m_trials.size(); ++t) {
        const cloth_fit::ClothTrial& trial = m_trials[t];
        m_warm_starts[t] = cloth_fit::matching_equilibrium(trial, m_base, fit);
        // From the equilibrium just found: no second search over the bows.
        cloth_fit::ClothFitSettings floor_fit = fit;
        floor_fit.swatch.initial_positions = m_warm_starts[t];
        const cloth_fit::PredictabilityFloor ensemble = cloth_fit::estimate_floor(trial, m_base, floor_fit, m_settings.floor, threads);
        std::vector<double> floor = ensemble.metric;
        if (m_settings.floor_resolution_step > 0) {
            // The same fabric on a finer mesh, filmed as footage: what the
            // model's own discretisation leaves unexplained.
            const cloth::SwatchRun nominal = run_scenario(t, apply_cloth_effects(trial, m_base, fit.swatch, {}), threads);
            if (cloth_fit::usable_frames(nominal) >= static_cast<int>(trial.frames.size())) {
                const cloth_fit::ClothTrial as_footage = cloth_fit::simulated_trial(
                    trial, nominal, fit.metric.silhouette_term == video::SilhouetteTerm::edge_distance);
                cloth::SwatchOptions finer = fit.swatch;
                finer.rows += m_settings.floor_resolution_step;
                finer.cols += m_settings.floor_resolution_step;
                finer.simulation.threads = threads;
                cloth_fit::ClothFitSettings finer_fit = fit;
                finer_fit.swatch = finer;
                const Eigen::VectorXd start = cloth_fit::matching_equilibrium(trial, m_base, finer_fit);
                if (start.size() > 0) finer.initial_positions = start;
                const cloth::SwatchRun fine = cloth::simulate_swatch(trial.experiment, m_base, finer);
                const std::vector<video::FrameError> errors = cloth_fit::compare_run(as_footage, fine, fit.metric);
                for (std::size_t k = 0; k < floor.size() && k < errors.size(); ++k) floor[k] = std::max(floor[k], errors[k].total);
            }
        }
        // A floor of zero would make any frame infinitely significant.
        double largest = 0.0;
        for (double f : floor) largest = std::max(largest, f);
        for (double& f : floor) f = std::max(f, std::max(1e-3 * largest, 1e-6));
        m_floors[t] = floor;
        for (const video::ReferenceFrame& frame : trial.frames) {
            double speed = 0.0;
            for (const cloth::PinTrajectory& pin : trial.experiment.pins) {
                const int k = frame.number - 1;
                const double f = static_cast<double>(k);
                const Eigen::Vector3d a = pin_at(pin.positions_m, f - 1.0), b = pin_at(pin.positions_m, f + 1.0);
                speed = std::max(speed, (b - a).norm() * 0.5 * trial.experiment.fps);
            }
            m_pin_speeds[t].push_back(speed);
        }
    }
}

std::vector<std::string> ClothGapModel::trial_names() const {
    std::vector<std::string> names;
    for (const cloth_fit::ClothTrial& t : m_trials) names.push_back(t.name);
    return names;
}

std::vector<std::string> ClothGapModel::candidate_effects() const {
    std::vector<std::string> names;
    const bool waving = std::any_of(m_trials.begin(), m_trials.end(), [](const cloth_fit::ClothTrial& t) { return !t.is_static; });
    for (const Effect& e : effect_catalogue()) {
        if (e.domain == EffectDomain::rigid) continue;
        if (e.name == "drag_nonlinear" && m_base.drag_normal_kg_per_m3 > 0.0) continue;  // already modelled
        // The model's own terms: offered only where the preset holds them at
        // their neutral value (a preset fitted without them).
        if (e.name == "compression_softness" &&
            (m_base.stretch_warp_compression_ratio != 1.0 || m_base.stretch_weft_compression_ratio != 1.0))
            continue;
        if (e.name == "hem_mass" && m_base.hem_line_density_kg_per_m != 0.0) continue;
        if (e.name == "diagonal_fibres" && m_base.diagonal_tension_N_per_m != 0.0) continue;
        if (e.name == "drag_linear" && m_base.drag_linear_normal_kg_per_m2_s != 0.0) continue;
        // Effects of motion need motion to show.
        if (!waving && (e.name == "drag_nonlinear" || e.name == "drag_linear" || e.name == "hysteresis" || e.name == "pin_lag" ||
                        e.name == "rolling_shutter" || e.name == "motion_blur"))
            continue;
        names.push_back(e.name);
    }
    return names;
}

cloth::SwatchRun ClothGapModel::run_scenario(std::size_t trial, const ClothScenario& scenario, int threads) const {
    return run_scenario(scenario, m_warm_starts[trial], threads);
}

cloth::SwatchRun ClothGapModel::run_scenario(const ClothScenario& scenario, const Eigen::VectorXd& warm_start, int threads) const {
    cloth::SwatchOptions options = scenario.options;
    options.simulation.threads = std::max(1, threads);
    if (warm_start.size() > 0) options.initial_positions = warm_start;
    return cloth::simulate_swatch(scenario.experiment, scenario.material, options);
}

std::optional<DiscretisationControl> ClothGapModel::discretisation_control(const std::vector<BaseParameterChange>& base,
                                                                           const EffectValues& effects) const {
    if (m_settings.control_resolution_step <= 0) return std::nullopt;
    cloth::ClothMaterial material = m_base;
    for (const BaseParameterChange& change : base) cloth_fit::set_material_parameter(material, change.key, change.after);
    cloth_fit::ClothFitSettings finer = m_settings.fit;
    finer.swatch.rows += m_settings.control_resolution_step;
    finer.swatch.cols += m_settings.control_resolution_step;
    finer.swatch.simulation.threads = std::max(1, m_settings.threads);
    // The finer mesh's own equilibrium (the model's warm starts are its mesh's),
    // of the material as the effects (the model's own terms) change it.
    std::vector<Eigen::VectorXd> starts;
    for (const cloth_fit::ClothTrial& trial : m_trials) {
        finer.base = apply_cloth_effects(trial, material, finer.swatch, effects).material;
        starts.push_back(cloth_fit::matching_equilibrium(trial, finer.base, finer));
    }
    DiscretisationControl control;
    control.description = "a " + std::to_string(finer.swatch.rows) + "x" + std::to_string(finer.swatch.cols) + " mesh";
    control.residuals = evaluate_on(material, effects, finer.swatch, starts);
    return control;
}

Residuals ClothGapModel::evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>& base) const {
    cloth::ClothMaterial material = m_base;
    for (const BaseParameterChange& change : base) cloth_fit::set_material_parameter(material, change.key, change.after);
    return evaluate_material(material, effects);
}

Residuals ClothGapModel::evaluate_material(const cloth::ClothMaterial& material, const EffectValues& effects) const {
    return evaluate_on(material, effects, m_settings.fit.swatch, m_warm_starts);
}

Residuals ClothGapModel::evaluate_on(const cloth::ClothMaterial& material, const EffectValues& effects,
                                     const cloth::SwatchOptions& swatch, const std::vector<Eigen::VectorXd>& warm_starts) const {
    Residuals out;
    std::vector<std::vector<FrameResidual>> per_trial(m_trials.size());
    std::vector<std::string> failures(m_trials.size());
    // The threads are shared among the evaluations running at once (the
    // diagnosis runs up to concurrency() of them side by side).
    struct Running {
        std::atomic<int>& count;
        int now;
        explicit Running(std::atomic<int>& c) : count(c), now(++c) {}
        ~Running() { --count; }
    } running(m_running);
    const int threads = std::max(1, m_settings.threads / std::max(1, running.now));
    const int workers = std::min<int>(threads, static_cast<int>(m_trials.size()));
    const int per_simulation = std::max(1, threads / std::max(1, workers));
    auto one = [&](std::size_t t) {
        const cloth_fit::ClothTrial& trial = m_trials[t];
        const ClothScenario scenario = apply_cloth_effects(trial, material, swatch, effects);
        const cloth::SwatchRun run = run_scenario(scenario, t < warm_starts.size() ? warm_starts[t] : Eigen::VectorXd(), per_simulation);
        const int usable = cloth_fit::usable_frames(run);
        if (!run.simulation.report.ok()) failures[t] = trial.name + ": " + run.simulation.report.reason;
        video::StripeRenderer renderer(scenario.camera, trial.projector);
        video::AngleMapper mapper(trial.angle_map);
        video::AngleMap angles;
        for (std::size_t k = 0; k < trial.frames.size(); ++k) {
            const video::ReferenceFrame& reference = trial.frames[k];
            FrameResidual r;
            r.trial = static_cast<int>(t);
            r.frame = reference.number;
            r.time_s = (reference.number - 1) / trial.experiment.fps;
            r.floor = m_floors[t][k];
            r.held_out = is_held_out(reference.number);
            r.driver = m_pin_speeds[t][k];
            const int index = reference.number - 1;
            if (index >= 0 && index < usable) {
                const video::StripeImage filmed = film_frame(scenario, run, index, renderer);
                mapper.compute(filmed.image, filmed.silhouette, angles);
                const video::FrameError fe = video::angle_map_frame_error(reference, angles, filmed.silhouette, m_settings.fit.metric);
                r.error = fe.total;
                // One orientation estimate spans a blur disc of radius 2 sigma.
                const double sigma = trial.angle_map.blur_sigma_px;
                r.observations = std::max(1.0, static_cast<double>(fe.overlap_px) / (std::numbers::pi * 4.0 * sigma * sigma));
            } else {
                r.error = cloth_fit::missing_frame_error(reference, m_settings.fit.metric);
            }
            per_trial[t].push_back(r);
        }
    };
    if (workers <= 1) {
        for (std::size_t t = 0; t < m_trials.size(); ++t) one(t);
    } else {
        ThreadPool pool(workers);
        pool.run(m_trials.size(), [&](std::size_t t, int) { one(t); });
    }
    for (std::size_t t = 0; t < m_trials.size(); ++t) {
        out.frames.insert(out.frames.end(), per_trial[t].begin(), per_trial[t].end());
        if (!failures[t].empty()) {
            out.ok = false;
            out.reason += (out.reason.empty() ? "" : "; ") + failures[t];
        }
    }
    return out;
}

namespace {

const cloth_fit::FittedParameter* waving_range(const std::string& key) {
    static const std::vector<cloth_fit::FittedParameter> table = [] {
        std::vector<cloth_fit::FittedParameter> t = cloth_fit::waving_test_parameters();
        t.push_back({"drag_linear_normal_kg_per_m2_s", 0.01, 10.0, true});
        return t;
    }();
    for (const cloth_fit::FittedParameter& p : table)
        if (p.key == key) return &p;
    return nullptr;
}

}  // namespace

RefitResult ClothGapModel::refit(const EffectValues& start, int max_evaluations,
                                 const std::vector<BaseParameterChange>& base_start) const {
    // The space: every parameter of the effects (linear, catalogue ranges)
    // then the base parameters (log scale, the fit's ranges).
    std::vector<optim::Parameter> parameters;
    std::vector<std::pair<std::string, int>> layout;  // effect name, parameter count
    for (const auto& [name, values] : start) {
        const Effect& effect = find_effect(name);
        layout.emplace_back(name, static_cast<int>(effect.parameters.size()));
        for (const EffectParameter& p : effect.parameters) parameters.push_back({name + "." + p.key, p.lower, p.upper, false});
    }
    std::vector<std::string> base_keys;
    for (const std::string& key : m_settings.refit_base) {
        const cloth_fit::FittedParameter* range = waving_range(key);
        const double value = cloth_fit::material_parameter(m_base, key);
        if (!range || !(value > 0.0)) continue;  // a term the base does not use stays off
        base_keys.push_back(key);
        parameters.push_back({"base." + key, std::min(range->lower, value), std::max(range->upper, value), true});
    }
    const optim::ParameterSpace space(parameters);
    const auto unpack = [&](const Eigen::VectorXd& values, EffectValues& effects, cloth::ClothMaterial& material) {
        Eigen::Index i = 0;
        effects.clear();
        for (const auto& [name, count] : layout) {
            effects[name] = values.segment(i, count);
            i += count;
        }
        material = m_base;
        for (const std::string& key : base_keys) cloth_fit::set_material_parameter(material, key, values(i++));
    };
    Eigen::VectorXd start_values(space.size());
    {
        Eigen::Index i = 0;
        for (const auto& [name, count] : layout) {
            start_values.segment(i, count) = start.at(name);
            i += count;
        }
        for (const std::string& key : base_keys) {
            double value = cloth_fit::material_parameter(m_base, key);
            for (const BaseParameterChange& c : base_start)
                if (c.key == key) value = c.after;
            start_values(i++) = value;
        }
    }
    const optim::Objective objective = [&](const Eigen::VectorXd& values, const optim::EvaluationContext&) {
        EffectValues effects;
        cloth::ClothMaterial material;
        unpack(values, effects, material);
        const Residuals r = evaluate_material(material, effects);
        return r.ok ? training_score(r) : std::numeric_limits<double>::infinity();
    };
    optim::Evaluator evaluator(objective, space, nullptr);
    optim::AnnealingSettings annealing;
    annealing.initial_temperature = 0.0;  // a local refit from the base fit
    annealing.initial_step = 0.15;
    annealing.max_evaluations = std::max(space.size() + 2, max_evaluations);
    annealing.tolerance = 1e-4;
    const optim::AnnealingResult result = optim::anneal(evaluator, space.to_unit(space.clamp_values(start_values)), annealing);

    RefitResult out;
    cloth::ClothMaterial material;
    unpack(result.best_values, out.effects, material);
    for (const std::string& key : base_keys)
        out.base.push_back({key, cloth_fit::material_parameter(m_base, key), cloth_fit::material_parameter(material, key)});
    out.residuals = evaluate_material(material, out.effects);
    out.evaluations = result.evaluations + 1;
    return out;
}

std::vector<RegionMap> ClothGapModel::localise(const EffectValues& effects) const {
    constexpr int kImageCellPx = 20;
    constexpr int kUvCells = 12;
    const cloth_fit::ClothTrial& first = m_trials.front();
    const int width = first.camera.width, height = first.camera.height;
    RegionMap image{"image", "E_k per pixel, summed over frames", (height + kImageCellPx - 1) / kImageCellPx,
                    (width + kImageCellPx - 1) / kImageCellPx, {}};
    image.values.assign(static_cast<std::size_t>(image.rows * image.cols), 0.0);
    RegionMap uv{"swatch uv", "mean E_k per pixel near the surface point (row 0 at v = 0)", kUvCells, kUvCells, {}};
    std::vector<double> uv_sum(static_cast<std::size_t>(kUvCells * kUvCells), 0.0), uv_count(uv_sum.size(), 0.0);
    for (std::size_t t = 0; t < m_trials.size(); ++t) {
        const cloth_fit::ClothTrial& trial = m_trials[t];
        if (trial.camera.width != width || trial.camera.height != height) continue;  // one image grid per map
        const ClothScenario scenario = apply_cloth_effects(trial, m_base, m_settings.fit.swatch, effects);
        const cloth::SwatchRun run = run_scenario(t, scenario, std::max(1, m_settings.threads));
        const int usable = cloth_fit::usable_frames(run);
        video::StripeRenderer renderer(scenario.camera, trial.projector);
        video::AngleMapper mapper(trial.angle_map);
        video::AngleMap angles;
        const auto& uv_m = run.swatch.mesh.material_uv_m;
        Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
        for (const Eigen::Vector2d& p : uv_m) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
        for (const video::ReferenceFrame& reference : trial.frames) {
            const int index = reference.number - 1;
            if (index < 0 || index >= usable) continue;
            const video::StripeImage filmed = film_frame(scenario, run, index, renderer);
            mapper.compute(filmed.image, filmed.silhouette, angles);
            const std::vector<float> residual = residual_image(reference, angles, filmed.silhouette, m_settings.fit.metric);
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x)
                    image.values[static_cast<std::size_t>((y / kImageCellPx) * image.cols + x / kImageCellPx)] +=
                        residual[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
            // Each vertex takes the mean residual of the 5x5 pixels it is imaged on.
            const std::vector<Eigen::Vector3d> vertices = video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]);
            for (std::size_t v = 0; v < vertices.size(); ++v) {
                const Eigen::Vector2d pixel = scenario.camera.project(vertices[v]);
                if (!pixel.allFinite()) continue;
                const int px = static_cast<int>(std::lround(pixel.x())), py = static_cast<int>(std::lround(pixel.y()));
                double sum = 0.0;
                int n = 0;
                for (int dy = -2; dy <= 2; ++dy)
                    for (int dx = -2; dx <= 2; ++dx) {
                        const int x = px + dx, y = py + dy;
                        if (x < 0 || y < 0 || x >= width || y >= height) continue;
                        sum += residual[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)];
                        ++n;
                    }
                if (n == 0) continue;
                const Eigen::Vector2d s = (uv_m[v] - lo).cwiseQuotient((hi - lo).cwiseMax(1e-12));
                const int cu = std::clamp(static_cast<int>(s.x() * kUvCells), 0, kUvCells - 1);
                const int cv = std::clamp(static_cast<int>(s.y() * kUvCells), 0, kUvCells - 1);
                uv_sum[static_cast<std::size_t>(cv * kUvCells + cu)] += sum / n;
                uv_count[static_cast<std::size_t>(cv * kUvCells + cu)] += 1.0;
            }
        }
    }
    uv.values.resize(uv_sum.size());
    for (std::size_t i = 0; i < uv_sum.size(); ++i)
        uv.values[i] = uv_count[i] > 0.0 ? uv_sum[i] / uv_count[i] : std::numeric_limits<double>::quiet_NaN();
    return {uv, image};
}

}  // namespace flowvid::gap
