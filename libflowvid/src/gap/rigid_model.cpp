// The rigid side of the gap diagnosis: flight-parameter re-fits with the
// catalogue's rigid effects, the quantisation floor and residual maps (the
// synthetic bench cases are in rigid_bench.cpp). Design notes in docs/rigid.md ("Gap diagnosis").

#include "flowvid/gap/rigid_model.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/rigid/optimize.hpp"
#include "flowvid/rigid/rectify.hpp"
#include "flowvid/threads.hpp"

#include "rigid_model_parts.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace flowvid::gap {

using rigid::FlightEffects;
using rigid::FlightParameters;
using rigid::FrameObservation;
using rigid::RigidBody;
using rigid::RigidState;
using Scratch = rigid::SilhouetteModel::Scratch;
using namespace rigid_parts;

namespace {

// Error given to frames of a simulation that diverged (px^2): far above any
// real misfit, finite so sums stay comparable.
constexpr double kFailedErrorPx2 = 1e6;
// Smallest floor reported (px^2): the interface wants it positive.
constexpr double kMinimumFloorPx2 = 1e-3;
// Outline length (px) per independent observation of a frame's E_k
// (FrameResidual::observations, for the diagnosis's BIC): quantisation
// errors along an edge repeat with its pixel staircase and a pose error moves
// whole edges, so neighbouring outline pixels are far from independent.
constexpr double kObservationSpacingPx = 8.0;

std::string format(const char* pattern, double a, double b = 0.0, double c = 0.0) {
    char buffer[256];
    std::snprintf(buffer, sizeof buffer, pattern, a, b, c);
    return buffer;
}

Eigen::Vector3d rotation_vector(const Eigen::Quaterniond& q) {
    const Eigen::AngleAxisd aa(q.normalized());
    double angle = aa.angle();
    Eigen::Vector3d axis = aa.axis();
    if (angle > M_PI) angle -= 2.0 * M_PI;
    return angle * axis;
}

std::string folder_name(const std::string& folder) {
    std::filesystem::path p(folder);
    if (p.filename().empty()) p = p.parent_path();
    return p.filename().string();
}

}  // namespace

// ---- Effects ---------------------------------------------------------------------------

FlightEffects flight_effects(const EffectValues& effects) {
    FlightEffects out;
    for (const auto& [name, values] : effects) {
        const Effect& effect = find_effect(name);  // throws for unknown names
        if (effect.domain != EffectDomain::rigid)
            throw std::invalid_argument("effect '" + name + "' is not a rigid-body effect (rigid: air_drag, inertia_error" +
                                        (name == "camera_roll" ? "; a rolled camera is absorbed by the fit's free gravity direction)" : ")"));
        if (values.size() != static_cast<Eigen::Index>(effect.parameters.size()))
            throw std::invalid_argument("effect '" + name + "' takes " + std::to_string(effect.parameters.size()) + " values, got " +
                                        std::to_string(values.size()));
        if (!values.allFinite()) throw std::invalid_argument("effect '" + name + "' has a value that is not finite");
        if (name == "air_drag") {
            out.quadratic_drag_per_m = values[0];
            out.angular_damping_per_s = values[1];
        } else if (name == "inertia_error") {
            out.log_inertia_scale_xy = Eigen::Vector2d(values[0], values[1]);
        }
    }
    return out;
}

// ---- Rendering --------------------------------------------------------------------------

metrics::Silhouette render_rigid_mask(const RigidBody& body, const formats::CameraModel& camera, const RigidState& state,
                                      int supersampling) {
    const std::vector<Eigen::Vector3d> points = camera_points(body, state);
    render::RasterSettings settings;
    settings.supersampling = std::clamp(supersampling, 1, 8);
    settings.region = projected_region(camera, points);
    settings.attributes = false;
    metrics::Silhouette mask(camera.width, camera.height);
    if (settings.region->empty()) return mask;
    const render::Framebuffer fb = render::rasterize(points, body.mesh.triangles, render::VertexSpace::camera, camera, settings);
    mask.pixels = fb.silhouette(0.5f);
    return mask;
}

// ---- The model --------------------------------------------------------------------------

struct RigidGapModel::Trial {
    std::string name;
    formats::Capture capture;
    RigidBody body;
    std::unique_ptr<rigid::SilhouetteModel> model;  // FlightProblem keeps its address
    rigid::FitResult fit;
    int first_frame = 1;
    double fps = 30.0;
    std::vector<FrameObservation> train;  // time_s relative to fit.reference_frame
    std::vector<FrameObservation> held;
    struct Slot {
        bool train = true;
        std::size_t index = 0;
    };
    std::vector<Slot> order;  // every frame, in frame order
    std::vector<double> floors;
    std::vector<double> train_floors;  // floors of `train`, in its order

    // training_score of this trial's flight parameters under `problem`.
    double score(const rigid::FlightProblem& problem, const FlightParameters& p, Scratch& scratch) const {
        std::vector<rigid::FrameCost> costs;
        problem.cost(p, scratch, &costs);
        double sum = 0.0;
        for (std::size_t j = 0; j < costs.size(); ++j) sum += costs[j].cost_px2 / train_floors[j];
        return std::isfinite(sum) ? sum : std::numeric_limits<double>::infinity();
    }

    const FrameObservation& frame(std::size_t k) const {
        const Slot& s = order[k];
        return s.train ? train[s.index] : held[s.index];
    }
    std::vector<double> times() const {
        std::vector<double> out;
        for (std::size_t k = 0; k < order.size(); ++k) out.push_back(frame(k).time_s);
        return out;
    }
};

struct RigidGapModel::Profile {
    // Sum over trials and training frames of E_k / floor_k (training_score):
    // what refits minimise. LM itself minimises the sum of E_k; floors vary
    // little from frame to frame, so the two optima nearly coincide.
    double score = 0.0;
    bool ok = true;
    std::string reason;
    std::vector<FlightParameters> parameters;  // per trial
};

RigidGapModel::~RigidGapModel() = default;
RigidGapModel::RigidGapModel(RigidGapModel&&) noexcept = default;
RigidGapModel& RigidGapModel::operator=(RigidGapModel&&) noexcept = default;

namespace {

// The floor of one trial (see the header): per frame, the mean over copies
// of the E_k a fit to masks rendered from the fitted motion leaves.
std::vector<double> estimate_floors(const rigid::SilhouetteModel& model, const RigidBody& body, const FlightParameters& fitted,
                                    const std::vector<FrameObservation>& frames_in_order,
                                    const std::vector<bool>& training, const RigidGapSettings& settings,
                                    std::uint64_t seed) {
    const formats::CameraModel& camera = model.camera();
    const int repeats = std::max(1, settings.floor_repeats);
    std::vector<double> times;
    for (const FrameObservation& o : frames_in_order) times.push_back(o.time_s);
    // Sub-pixel offsets of the copies (the first one unshifted).
    Random random(seed);
    std::vector<Eigen::Vector2d> offsets_px(static_cast<std::size_t>(repeats), Eigen::Vector2d::Zero());
    for (std::size_t r = 1; r < offsets_px.size(); ++r) offsets_px[r] = {random.uniform(-0.5, 0.5), random.uniform(-0.5, 0.5)};

    rigid::SimulationSettings simulation;
    simulation.max_step_s = settings.max_step_s;
    std::vector<std::vector<double>> per_copy(offsets_px.size());
    const int threads = resolve_thread_count(settings.threads);
    std::vector<Scratch> scratches(static_cast<std::size_t>(threads));
    rigid::parallel_for(offsets_px.size(), threads, [&](std::size_t r, int t) {
        Scratch& scratch = scratches[static_cast<std::size_t>(t)];
        FlightParameters truth = fitted;
        const double z = std::max(truth.com_m.z(), 1e-3);
        truth.com_m += Eigen::Vector3d(offsets_px[r].x() * z / camera.K(0, 0), offsets_px[r].y() * z / camera.K(1, 1), 0.0);
        const rigid::Trajectory motion = rigid::simulate(body, truth, times, simulation);
        std::vector<FrameObservation> all, train;
        for (std::size_t k = 0; k < times.size(); ++k) {
            FrameObservation o = rigid::make_frame_observation(
                render_rigid_mask(body, camera, motion.states[k], settings.floor_supersampling), frames_in_order[k].frame, times[k]);
            if (training[k]) train.push_back(o);
            all.push_back(std::move(o));
        }
        const rigid::FlightProblem problem(model, train, 0, train.size(), simulation);
        rigid::LmSettings lm;
        lm.max_iterations = settings.lm_iterations;
        lm.relative_tolerance = 1e-6;
        const rigid::OptimizerResult fit = rigid::levenberg_marquardt(problem, truth, lm, scratch);
        const rigid::Trajectory refitted = rigid::simulate(body, fit.parameters, times, simulation);
        per_copy[r].resize(times.size());
        for (std::size_t k = 0; k < times.size(); ++k)
            per_copy[r][k] = model.edge_cost(rigid::Pose::of(refitted.states[k]), all[k], scratch).cost_px2;
    });
    std::vector<double> floors(times.size(), 0.0);
    for (std::size_t k = 0; k < times.size(); ++k) {
        for (const std::vector<double>& copy : per_copy) floors[k] += copy[k];
        floors[k] = std::max(floors[k] / static_cast<double>(per_copy.size()), kMinimumFloorPx2);
    }
    return floors;
}

}  // namespace

RigidGapModel::RigidGapModel(std::vector<RigidTrial> trials, RigidGapSettings settings) : m_settings(std::move(settings)) {
    if (trials.empty()) throw std::invalid_argument("the rigid gap model needs at least one capture");
    auto log = [&](const std::string& line) {
        if (m_settings.log) m_settings.log(line);
    };
    const int threads = resolve_thread_count(m_settings.threads);
    for (std::size_t index = 0; index < trials.size(); ++index) {
        RigidTrial& given = trials[index];
        auto trial = std::make_unique<Trial>();
        formats::Capture& capture = given.capture;
        trial->name = !given.name.empty() ? given.name : folder_name(capture.folder);
        if (trial->name.empty()) trial->name = "trial " + std::to_string(index + 1);

        // Everything that makes the capture unusable, at once.
        Diagnostics diagnostics(capture.json_path.empty() ? capture.folder : capture.json_path);
        if (!capture.is_rigid())
            diagnostics.error("/kind", "the rigid gap diagnosis needs a rigid.toss capture, this one is '" + capture.kind + "'",
                              "diagnose cloth captures with the cloth model");
        if (!capture.rigid)
            diagnostics.error("/rigid", "no rigid block: the body's mesh and mass properties are needed",
                              "add \"rigid\": {\"mesh\", \"mass_kg\", \"center_of_mass\", \"inertia_body\"}");
        else if (!given.body && capture.rigid->body_mesh.vertices_m.empty())
            diagnostics.error("/rigid/mesh", "the body's mesh was not loaded", "read the capture with formats::read_capture");
        if (!capture.camera) diagnostics.error("/camera", "no camera: silhouettes cannot be predicted", "add the camera block");
        if (capture.masks.empty() && capture.background.empty())
            diagnostics.error("/masks", "neither masks nor a background image: no silhouettes to compare with",
                              "add \"masks\": \"masks/%06d.png\" (255 = object) or a \"background\" image");
        const int first = given.first_frame > 0 ? given.first_frame : capture.frames.first;
        const int last = given.last_frame > 0 ? given.last_frame : capture.frames.last();
        if (first < capture.frames.first || last > capture.frames.last() || first > last)
            diagnostics.error("/frames", "frames " + std::to_string(first) + ".." + std::to_string(last) +
                                             " are not within the capture's " + std::to_string(capture.frames.first) + ".." +
                                             std::to_string(capture.frames.last()),
                              "choose a frame range inside the capture");
        int training_count = 0, first_training = 0;
        for (int f = first; f <= last; ++f)
            if (!is_held_out(f)) {
                if (training_count++ == 0) first_training = f;
            }
        if (first <= last && training_count < 3)
            diagnostics.error("/frames/count", "only " + std::to_string(training_count) +
                                                   " training frames (held-out blocks of " + std::to_string(kHeldOutBlockFrames) +
                                                   " frames alternate with training blocks): at least 3 are needed",
                              "use a longer frame range");
        diagnostics.throw_if_errors();

        trial->capture = capture;
        trial->body = given.body ? *given.body : RigidBody::from_capture(*capture.rigid);
        trial->model = std::make_unique<rigid::SilhouetteModel>(trial->body, *capture.camera);
        trial->model->set_corner_radius(m_settings.fit.corner_radius_px);
        trial->first_frame = first;
        const int reference = given.fit ? given.fit->reference_frame : first_training;
        trial->fps = given.fit && given.fit->fps > 0.0 ? given.fit->fps : capture.fps;

        std::vector<FrameObservation> observations = rigid::load_observations(capture, first, last, reference, threads);
        if (trial->fps != capture.fps)
            for (FrameObservation& o : observations) o.time_s = (o.frame - reference) / trial->fps;
        for (FrameObservation& o : observations) {
            const bool train = !is_held_out(o.frame);
            std::vector<FrameObservation>& target = train ? trial->train : trial->held;
            trial->order.push_back({train, target.size()});
            target.push_back(std::move(o));
        }

        if (given.fit) {
            trial->fit = *given.fit;
        } else {
            rigid::FitSettings fit_settings = m_settings.fit;
            fit_settings.threads = m_settings.threads;
            fit_settings.simulation = rigid::SimulationSettings{};
            fit_settings.simulation.max_step_s = m_settings.max_step_s;
            fit_settings.log = m_settings.log;
            trial->fit = rigid::fit_rigid(trial->body, *capture.camera, trial->fps, trial->train, fit_settings);
            log(trial->name + ": base fit on " + std::to_string(trial->train.size()) + " training frames: " +
                rigid::status_name(trial->fit.report.status) +
                format(", E = %.4g px^2 (%.3g per frame)", trial->fit.final_cost_px2,
                       trial->fit.final_cost_px2 / static_cast<double>(std::max<std::size_t>(trial->train.size(), 1))));
        }

        std::vector<FrameObservation> in_order;
        std::vector<bool> training;
        for (std::size_t k = 0; k < trial->order.size(); ++k) {
            // The floor needs frame numbers and times only: copy those, not the images.
            FrameObservation o;
            o.frame = trial->frame(k).frame;
            o.time_s = trial->frame(k).time_s;
            in_order.push_back(std::move(o));
            training.push_back(trial->order[k].train);
        }
        trial->floors = estimate_floors(*trial->model, trial->body, trial->fit.parameters, in_order, training, m_settings,
                                        m_settings.floor_seed + 7919u * index);
        double mean_floor = 0.0;
        trial->train_floors.resize(trial->train.size());
        for (std::size_t k = 0; k < trial->floors.size(); ++k) {
            mean_floor += trial->floors[k];
            if (trial->order[k].train) trial->train_floors[trial->order[k].index] = trial->floors[k];
        }
        log(trial->name + format(": floor %.3g px^2 per frame on average", mean_floor / static_cast<double>(trial->floors.size())));
        m_trials.push_back(std::move(trial));
    }
}

std::vector<std::string> RigidGapModel::trial_names() const {
    std::vector<std::string> out;
    for (const auto& t : m_trials) out.push_back(t->name);
    return out;
}

std::vector<std::string> RigidGapModel::candidate_effects() const { return {"air_drag", "inertia_error"}; }

namespace {

const char* const kBaseKeys[rigid::kParameterCount] = {
    "com_x_m",   "com_y_m",   "com_z_m",   "rotation_x_rad", "rotation_y_rad", "rotation_z_rad",
    "com_velocity_x_m_per_s", "com_velocity_y_m_per_s", "com_velocity_z_m_per_s",
    "angular_velocity_x_rad_per_s", "angular_velocity_y_rad_per_s", "angular_velocity_z_rad_per_s",
    "gravity_tilt_rad", "gravity_roll_rad"};

// The 14 values of base_parameter_keys (rotation relative to `reference`).
std::array<double, rigid::kParameterCount> base_values(const FlightParameters& p, const FlightParameters& reference) {
    const Eigen::Vector3d rotation = rotation_vector(p.orientation.normalized() * reference.orientation.normalized().inverse());
    return {p.com_m.x(), p.com_m.y(), p.com_m.z(), rotation.x(), rotation.y(), rotation.z(),
            p.com_velocity_m_per_s.x(), p.com_velocity_m_per_s.y(), p.com_velocity_m_per_s.z(),
            p.angular_velocity_rad_per_s.x(), p.angular_velocity_rad_per_s.y(), p.angular_velocity_rad_per_s.z(),
            p.gravity.tilt_rad, p.gravity.roll_rad};
}

}  // namespace

std::vector<std::string> RigidGapModel::base_parameter_keys() const {
    std::vector<std::string> out;
    for (const auto& t : m_trials)
        for (const char* key : kBaseKeys) out.push_back(m_trials.size() > 1 ? t->name + "/" + key : std::string(key));
    return out;
}

const RigidBody& RigidGapModel::body(int trial) const { return m_trials.at(static_cast<std::size_t>(trial))->body; }
const rigid::FitResult& RigidGapModel::base_fit(int trial) const { return m_trials.at(static_cast<std::size_t>(trial))->fit; }
std::vector<double> RigidGapModel::floors(int trial) const { return m_trials.at(static_cast<std::size_t>(trial))->floors; }

std::vector<FlightParameters> RigidGapModel::base_parameters() const {
    std::vector<FlightParameters> out;
    for (const auto& t : m_trials) out.push_back(t->fit.parameters);
    return out;
}

std::vector<FlightParameters> RigidGapModel::starting_parameters(const std::vector<BaseParameterChange>& base_start) const {
    std::vector<FlightParameters> out = base_parameters();
    if (base_start.empty()) return out;
    const std::vector<std::string> keys = base_parameter_keys();
    std::vector<std::array<double, rigid::kParameterCount>> values;
    for (std::size_t i = 0; i < out.size(); ++i) values.push_back(base_values(out[i], out[i]));
    for (const BaseParameterChange& change : base_start) {
        const auto it = std::find(keys.begin(), keys.end(), change.key);
        if (it == keys.end()) throw std::invalid_argument("'" + change.key + "' is not a base parameter of the rigid model");
        const std::size_t k = static_cast<std::size_t>(it - keys.begin());
        values[k / rigid::kParameterCount][k % rigid::kParameterCount] = change.after;
    }
    for (std::size_t i = 0; i < out.size(); ++i) {
        const std::array<double, rigid::kParameterCount>& v = values[i];
        FlightParameters& p = out[i];
        const Eigen::Vector3d rotation(v[3], v[4], v[5]);
        const double angle = rotation.norm();
        if (angle > 0.0) p.orientation = (Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation / angle)) * p.orientation).normalized();
        p.com_m = {v[0], v[1], v[2]};
        p.com_velocity_m_per_s = {v[6], v[7], v[8]};
        p.angular_velocity_rad_per_s = {v[9], v[10], v[11]};
        p.gravity = rigid::GravityAngles{v[12], v[13]};
    }
    return out;
}

std::vector<RigidGapModel::Profile> RigidGapModel::profiles(const std::vector<FlightEffects>& effects,
                                                            const std::vector<FlightParameters>& starts,
                                                            bool from_scratch_when_poor) const {
    const std::size_t trials = m_trials.size();
    struct Fit {
        FlightParameters parameters;
        double score = std::numeric_limits<double>::infinity();
        bool failed = false;
        std::string reason;
    };
    std::vector<std::vector<Fit>> fits(effects.size(), std::vector<Fit>(trials));
    const int threads = resolve_thread_count(m_settings.threads);
    std::vector<Scratch> scratches(static_cast<std::size_t>(threads));
    // One task per (effect point, trial): each a pure function of its inputs.
    rigid::parallel_for(effects.size() * trials, threads, [&](std::size_t task, int t) {
        const std::size_t e = task / trials, i = task % trials;
        const Trial& trial = *m_trials[i];
        Scratch& scratch = scratches[static_cast<std::size_t>(t)];
        rigid::SimulationSettings simulation;
        simulation.max_step_s = m_settings.max_step_s;
        simulation.effects = effects[e];
        const rigid::FlightProblem problem(*trial.model, trial.train, 0, trial.train.size(), simulation);
        rigid::LmSettings lm;
        lm.max_iterations = m_settings.lm_iterations;
        lm.relative_tolerance = 1e-6;
        const rigid::OptimizerResult direct = rigid::levenberg_marquardt(problem, starts[i], lm, scratch);
        Fit& fit = fits[e][i];
        fit.parameters = direct.parameters;
        fit.failed = direct.report.status == rigid::OptimizerReport::Status::failed;
        fit.reason = direct.report.reason;
        fit.score = fit.failed ? std::numeric_limits<double>::infinity() : trial.score(problem, direct.parameters, scratch);
        const double poor = m_settings.scratch_refit_above_floor * static_cast<double>(trial.train.size());
        if (from_scratch_when_poor && !(fit.score <= poor)) {
            // A strong effect can put the best initial state in another
            // valley than the start's (a damped spin: the neutral fit's
            // orientation may be 2 rad off): fit from scratch with the effects.
            rigid::FitSettings settings = m_settings.fit;
            settings.threads = 1;  // already one task per thread
            settings.simulation = simulation;
            // The wider pose search only where the base fit needed it (a
            // toss whose silhouette hides its orientation): a poor fit here
            // is mostly the effect's doing, and each wider search costs ~2 s.
            if (!trial.fit.widened) settings.wide_candidates_per_frame = 0;
            settings.log = nullptr;
            settings.progress = nullptr;
            settings.guess.reset();
            const rigid::FitResult fresh = rigid::fit_rigid(trial.body, trial.model->camera(), trial.fps, trial.train, settings);
            const double score = trial.score(problem, fresh.parameters, scratch);
            if (score < fit.score) fit = {fresh.parameters, score, false, {}};
        }
    });
    std::vector<Profile> out(effects.size());
    for (std::size_t e = 0; e < effects.size(); ++e) {
        for (std::size_t i = 0; i < trials; ++i) {
            const Fit& fit = fits[e][i];
            out[e].parameters.push_back(fit.parameters);
            if (fit.failed || !std::isfinite(fit.score)) {
                out[e].ok = false;
                if (out[e].reason.empty())
                    out[e].reason = m_trials[i]->name + ": " + (fit.reason.empty() ? std::string("the re-fit failed") : fit.reason);
            }
            out[e].score += fit.score;
        }
        if (!out[e].ok || !std::isfinite(out[e].score)) out[e].score = std::numeric_limits<double>::infinity();
    }
    return out;
}

Residuals RigidGapModel::residuals_of(const FlightEffects& effects, const std::vector<FlightParameters>& parameters) const {
    Residuals out;
    rigid::SimulationSettings simulation;
    simulation.max_step_s = m_settings.max_step_s;
    simulation.effects = effects;
    struct Task {
        std::size_t trial = 0;
        std::size_t frame = 0;  // index in the trial's order
        RigidState state;
    };
    std::vector<Task> tasks;
    for (std::size_t i = 0; i < m_trials.size(); ++i) {
        const Trial& trial = *m_trials[i];
        const rigid::Trajectory motion = rigid::simulate(trial.body, parameters[i], trial.times(), simulation);
        for (std::size_t k = 0; k < trial.order.size(); ++k) tasks.push_back({i, k, motion.states[k]});
    }
    out.frames.resize(tasks.size());
    const int threads = resolve_thread_count(m_settings.threads);
    std::vector<Scratch> scratches(static_cast<std::size_t>(threads));
    rigid::parallel_for(tasks.size(), threads, [&](std::size_t n, int t) {
        const Task& task = tasks[n];
        const Trial& trial = *m_trials[task.trial];
        const FrameObservation& observed = trial.frame(task.frame);
        FrameResidual& r = out.frames[n];
        r.trial = static_cast<int>(task.trial);
        r.frame = observed.frame;
        r.time_s = (observed.frame - trial.first_frame) / trial.fps;
        r.floor = trial.floors[task.frame];
        r.held_out = !trial.order[task.frame].train;
        // Independent observations in E_k: one per kObservationSpacingPx of
        // observed outline (two outline points per pixel of length).
        r.observations = std::max(1.0, 0.5 * static_cast<double>(observed.edge_points_px.size()) / kObservationSpacingPx);
        if (finite_state(task.state)) {
            r.error = trial.model->edge_cost(rigid::Pose::of(task.state), observed, scratches[static_cast<std::size_t>(t)]).cost_px2;
            r.driver = task.state.com_velocity_m_per_s.norm();
        } else {
            r.error = kFailedErrorPx2;
            r.driver = std::numeric_limits<double>::quiet_NaN();
        }
    });
    for (const FrameResidual& r : out.frames)
        if (!std::isfinite(r.driver) && out.ok) {
            out.ok = false;
            out.reason = m_trials[static_cast<std::size_t>(r.trial)]->name + ": the simulation diverged (state not finite at frame " +
                         std::to_string(r.frame) + ")";
        }
    return out;
}

Residuals RigidGapModel::evaluate(const EffectValues& effects, const std::vector<BaseParameterChange>& base) const {
    const FlightEffects terms = flight_effects(effects);
    std::vector<FlightParameters> parameters = starting_parameters(base);
    std::string reason;
    if (m_settings.refit_initial_state) {
        const Profile p = profiles({terms}, parameters, true).front();
        parameters = p.parameters;
        reason = p.reason;
    }
    Residuals out = residuals_of(terms, parameters);
    if (out.ok && !reason.empty()) {
        out.ok = false;
        out.reason = reason;
    }
    return out;
}

RefitResult RigidGapModel::refit(const EffectValues& start, int max_evaluations,
                                 const std::vector<BaseParameterChange>& base_start) const {
    // The effect parameters searched, in the order of `start` and the catalogue.
    struct Free {
        std::string effect;
        Eigen::Index index = 0;
        double lower = 0.0, upper = 0.0, step = 0.0, neutral = 0.0;
    };
    std::vector<Free> free;
    flight_effects(start);  // validates names, sizes and values
    std::vector<double> x;
    for (const auto& [name, values] : start) {
        const Effect& effect = find_effect(name);
        for (std::size_t k = 0; k < effect.parameters.size(); ++k) {
            const EffectParameter& p = effect.parameters[k];
            free.push_back({name, static_cast<Eigen::Index>(k), p.lower, p.upper, p.screen_step, p.neutral});
            x.push_back(std::clamp(values[static_cast<Eigen::Index>(k)], p.lower, p.upper));
        }
    }
    auto values_of = [&](const std::vector<double>& point) {
        EffectValues out = start;
        for (std::size_t k = 0; k < free.size(); ++k) out[free[k].effect][free[k].index] = point[k];
        return out;
    };
    const int budget = max_evaluations > 0 ? max_evaluations : 80;

    const std::vector<FlightParameters> base = base_parameters();
    Profile best = profiles({flight_effects(values_of(x))}, starting_parameters(base_start), true).front();
    long long evaluations = 1;
    int scratch_fits = 0;
    std::size_t training_frames = 0;
    for (const auto& t : m_trials) training_frames += t->train.size();

    // A parameter that can go either way from neutral (an inertia scale) can
    // have a profile with a valley on each side, and the compass search stays
    // in the start's: first a coarse grid over such parameters (neutral and
    // two thirds of the way to either bound), each point fitted from the base.
    // On the bench's strong inertia errors the search alone closed 9 % and
    // made another case worse; the true values close all of it.
    std::vector<std::size_t> two_sided;
    for (std::size_t k = 0; k < free.size(); ++k)
        if (free[k].lower < free[k].neutral && free[k].neutral < free[k].upper) two_sided.push_back(k);
    if (!two_sided.empty() && two_sided.size() <= 2) {
        std::vector<std::vector<double>> grid = {x};
        for (std::size_t k : two_sided) {
            std::vector<std::vector<double>> wider;
            const double levels[3] = {free[k].neutral + 2.0 / 3.0 * (free[k].lower - free[k].neutral), free[k].neutral,
                                      free[k].neutral + 2.0 / 3.0 * (free[k].upper - free[k].neutral)};
            for (const std::vector<double>& p : grid)
                for (double level : levels) {
                    std::vector<double> q = p;
                    q[k] = level;
                    wider.push_back(q);
                }
            grid = std::move(wider);
        }
        grid.erase(std::remove(grid.begin(), grid.end(), x), grid.end());
        if (!grid.empty() && evaluations + static_cast<long long>(grid.size()) < budget) {
            std::vector<FlightEffects> terms;
            for (const std::vector<double>& p : grid) terms.push_back(flight_effects(values_of(p)));
            const std::vector<Profile> tried = profiles(terms, starting_parameters(base_start), true);
            evaluations += static_cast<long long>(grid.size());
            for (std::size_t i = 0; i < grid.size(); ++i)
                if (tried[i].score < best.score) {
                    x = grid[i];
                    best = tried[i];
                }
        }
    }

    // Compass search: per parameter, both neighbours at once (in parallel);
    // move to the better one when it lowers the training cost and widen the
    // step. When the centre stays best, try the minimum of the parabola
    // through the three points (the profile is smooth near its minimum),
    // then halve the step. Done when every step is below 1/16 of its screen
    // step, or the budget is spent.
    std::vector<double> step, min_step;
    for (const Free& f : free) {
        step.push_back(f.step);
        min_step.push_back(f.step / 16.0);
    }
    auto try_points = [&](const std::vector<std::vector<double>>& points) {
        std::vector<FlightEffects> terms;
        for (const std::vector<double>& p : points) terms.push_back(flight_effects(values_of(p)));
        std::vector<Profile> tried = profiles(terms, best.parameters, false);
        evaluations += static_cast<long long>(points.size());
        return tried;
    };
    bool active = !free.empty();
    while (active && evaluations < budget) {
        active = false;
        const std::vector<double> sweep_start = x;
        for (std::size_t k = 0; k < free.size() && evaluations < budget; ++k) {
            if (step[k] < min_step[k]) continue;
            active = true;
            std::vector<std::vector<double>> points;
            for (double sign : {1.0, -1.0}) {
                std::vector<double> p = x;
                p[k] = std::clamp(x[k] + sign * step[k], free[k].lower, free[k].upper);
                if (p[k] != x[k]) points.push_back(p);
            }
            if (points.size() > static_cast<std::size_t>(budget - evaluations)) points.resize(static_cast<std::size_t>(budget - evaluations));
            if (points.empty()) {
                step[k] *= 0.5;
                continue;
            }
            const std::vector<Profile> tried = try_points(points);
            std::size_t winner = points.size();
            for (std::size_t i = 0; i < points.size(); ++i)
                if (tried[i].score < (winner < points.size() ? tried[winner].score : best.score)) winner = i;
            if (winner < points.size()) {
                x = points[winner];
                best = tried[winner];
                step[k] = std::min(1.5 * step[k], 0.5 * (free[k].upper - free[k].lower));
                continue;
            }
            if (points.size() == 2 && evaluations < budget && std::isfinite(tried[0].score) && std::isfinite(tried[1].score)) {
                // y = a d^2 + b d + y0 through (o1, y1), (o2, y2), o the offsets from x.
                const double o1 = points[0][k] - x[k], o2 = points[1][k] - x[k];
                const double y0 = best.score, y1 = tried[0].score, y2 = tried[1].score;
                const double det = o1 * o2 * (o1 - o2);
                const double a = ((y1 - y0) * o2 - (y2 - y0) * o1) / det;
                const double b = ((y2 - y0) * o1 * o1 - (y1 - y0) * o2 * o2) / det;
                if (a > 0.0) {
                    const double d = -b / (2.0 * a);
                    std::vector<double> p = x;
                    p[k] = std::clamp(x[k] + d, free[k].lower, free[k].upper);
                    if (std::abs(p[k] - x[k]) >= min_step[k]) {
                        const std::vector<Profile> vertex = try_points({p});
                        if (vertex.front().score < best.score) {
                            x = p;
                            best = vertex.front();
                        }
                    }
                }
            }
            step[k] *= 0.5;
        }
        // Pattern move (Hooke-Jeeves): repeat the sweep's displacement, which
        // follows valleys that run across the parameter axes.
        if (free.size() > 1 && x != sweep_start && evaluations < budget) {
            std::vector<double> p = x;
            for (std::size_t k = 0; k < free.size(); ++k) p[k] = std::clamp(2.0 * x[k] - sweep_start[k], free[k].lower, free[k].upper);
            if (p != x) {
                const std::vector<Profile> moved = try_points({p});
                if (moved.front().score < best.score) {
                    x = p;
                    best = moved.front();
                }
            }
        }
        // Still far above the floor after moving: the flight parameters may
        // sit in the wrong valley for these effect values; a fit from scratch
        // can switch valleys (counted as one evaluation), then search again.
        if (x != sweep_start && scratch_fits < m_settings.refit_scratch_fits && evaluations < budget &&
            !(best.score <= m_settings.scratch_refit_above_floor * static_cast<double>(training_frames))) {
            ++scratch_fits;
            ++evaluations;
            const Profile fresh = profiles({flight_effects(values_of(x))}, best.parameters, true).front();
            if (fresh.score < best.score) {
                best = fresh;
                active = true;
                for (std::size_t k = 0; k < free.size(); ++k) step[k] = std::max(step[k], free[k].step);
            }
        }
    }

    RefitResult result;
    const EffectValues fitted = values_of(x);
    result.effects = fitted;
    for (std::size_t i = 0; i < m_trials.size(); ++i) {
        const std::array<double, rigid::kParameterCount> before = base_values(base[i], base[i]);
        const std::array<double, rigid::kParameterCount> after = base_values(best.parameters[i], base[i]);
        for (int k = 0; k < rigid::kParameterCount; ++k)
            result.base.push_back({m_trials.size() > 1 ? m_trials[i]->name + "/" + kBaseKeys[k] : std::string(kBaseKeys[k]),
                                   before[static_cast<std::size_t>(k)], after[static_cast<std::size_t>(k)]});
    }
    result.residuals = residuals_of(flight_effects(fitted), best.parameters);
    if (result.residuals.ok && !best.ok) {
        result.residuals.ok = false;
        result.residuals.reason = best.reason;
    }
    result.evaluations = evaluations;
    return result;
}

std::vector<RegionMap> RigidGapModel::localise(const EffectValues& effects) const {
    const FlightEffects terms = flight_effects(effects);
    std::vector<FlightParameters> parameters = base_parameters();
    if (m_settings.refit_initial_state) parameters = profiles({terms}, parameters, true).front().parameters;
    rigid::SimulationSettings simulation;
    simulation.max_step_s = m_settings.max_step_s;
    simulation.effects = terms;

    const int image_rows = std::max(1, m_settings.image_rows), image_cols = std::max(1, m_settings.image_cols);
    const int body_rows = std::max(1, m_settings.body_rows), body_cols = std::max(1, m_settings.body_cols);
    struct FrameMaps {
        std::vector<double> image, body;
        std::vector<char> image_seen, body_seen;
    };
    struct Task {
        std::size_t trial = 0, frame = 0;
        RigidState state;
    };
    std::vector<Task> tasks;
    for (std::size_t i = 0; i < m_trials.size(); ++i) {
        const rigid::Trajectory motion = rigid::simulate(m_trials[i]->body, parameters[i], m_trials[i]->times(), simulation);
        for (std::size_t k = 0; k < m_trials[i]->order.size(); ++k) tasks.push_back({i, k, motion.states[k]});
    }
    std::vector<FrameMaps> maps(tasks.size());
    const int threads = resolve_thread_count(m_settings.threads);
    std::vector<Scratch> scratches(static_cast<std::size_t>(threads));
    rigid::parallel_for(tasks.size(), threads, [&](std::size_t n, int t) {
        Scratch& scratch = scratches[static_cast<std::size_t>(t)];
        const Trial& trial = *m_trials[tasks[n].trial];
        const FrameObservation& observed = trial.frame(tasks[n].frame);
        FrameMaps& m = maps[n];
        m.image.assign(static_cast<std::size_t>(image_rows * image_cols), 0.0);
        m.image_seen.assign(m.image.size(), 0);
        m.body.assign(static_cast<std::size_t>(body_rows * body_cols), 0.0);
        m.body_seen.assign(m.body.size(), 0);
        if (!finite_state(tasks[n].state)) return;
        const rigid::Pose pose = rigid::Pose::of(tasks[n].state);

        // Image: where the silhouettes differ.
        const metrics::Silhouette predicted = trial.model->render(pose, scratch);
        const int width = observed.mask.width, height = observed.mask.height;
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const bool a = predicted.at(x, y), b = observed.mask.at(x, y);
                if (!a && !b) continue;
                const std::size_t cell = static_cast<std::size_t>((y * image_rows / height) * image_cols + x * image_cols / width);
                m.image_seen[cell] = 1;
                if (a != b) m.image[cell] += 1.0;
            }

        // Body: each visible outline piece's squared distance to the observed outline.
        trial.model->contour(pose, scratch);
        for (const rigid::ContourPiece& piece : scratch.pieces) {
            const Eigen::Vector3d d = 0.5 * (piece.body_a + piece.body_b);
            const double norm = d.norm();
            if (!(norm > 0.0)) continue;
            const double elevation = std::asin(std::clamp(d.z() / norm, -1.0, 1.0));
            const double azimuth = std::atan2(d.y(), d.x());
            const int row = std::clamp(static_cast<int>((elevation + 0.5 * M_PI) / M_PI * body_rows), 0, body_rows - 1);
            const int col = std::clamp(static_cast<int>((azimuth + M_PI) / (2.0 * M_PI) * body_cols), 0, body_cols - 1);
            const double phi = observed.signed_distance.sample(piece.mid_pixel);
            const std::size_t cell = static_cast<std::size_t>(row * body_cols + col);
            m.body[cell] += piece.length_px * phi * phi;
            m.body_seen[cell] = 1;
        }
    });

    auto reduce = [&](const char* name, const char* units, int rows, int cols, bool image) {
        RegionMap map;
        map.name = name;
        map.units = units;
        map.rows = rows;
        map.cols = cols;
        map.values.assign(static_cast<std::size_t>(rows * cols), 0.0);
        std::vector<char> seen(map.values.size(), 0);
        for (const FrameMaps& m : maps)  // in task order: the same sums for any thread count
            for (std::size_t c = 0; c < map.values.size(); ++c) {
                map.values[c] += image ? m.image[c] : m.body[c];
                seen[c] |= image ? m.image_seen[c] : m.body_seen[c];
            }
        for (std::size_t c = 0; c < map.values.size(); ++c)
            if (!seen[c]) map.values[c] = std::numeric_limits<double>::quiet_NaN();
        return map;
    };
    return {reduce("image", "px (silhouette pixels that differ, summed over frames)", image_rows, image_cols, true),
            reduce("body directions", "px^3 (squared outline distance x outline length, summed over frames)", body_rows, body_cols,
                   false)};
}

}  // namespace flowvid::gap
