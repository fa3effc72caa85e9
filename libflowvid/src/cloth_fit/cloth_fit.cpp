#include "flowvid/cloth_fit/cloth_fit.hpp"

#include "flowvid/cloth/material.hpp"
#include "flowvid/thread_pool.hpp"
#include "flowvid/version.hpp"
#include "flowvid/video/stripe_render.hpp"
#include "flowvid/video/stripe_scan.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <numbers>
#include <numeric>
#include <optional>
#include <stdexcept>

namespace flowvid::cloth_fit {

namespace {

constexpr const char* kStretchTie = "stretch_stiffness_N_per_m";
constexpr const char* kStretchDampingTie = "stretch_damping_N_s_per_m";

const formats::FabricParameterInfo* preset_entry(const std::string& key) {
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table())
        if (key == info.key) return &info;
    return nullptr;
}

void require_known(const std::string& key) {
    if (key != kStretchTie && key != kStretchDampingTie && !preset_entry(key))
        throw std::invalid_argument("unknown cloth parameter '" + key +
                                    "' (a fabric preset key, stretch_stiffness_N_per_m or stretch_damping_N_s_per_m)");
}

}  // namespace

void set_material_parameter(cloth::ClothMaterial& material, const std::string& key, double value) {
    require_known(key);
    if (key == kStretchTie) {
        material.stretch_warp_N_per_m = material.stretch_weft_N_per_m = value;
        return;
    }
    if (key == kStretchDampingTie) {
        material.stretch_warp_damping_N_s_per_m = material.stretch_weft_damping_N_s_per_m = value;
        return;
    }
    // Through the preset's table, so every preset key is settable; the
    // optional gap-diagnosis terms (not preset keys) are kept.
    const double bias = material.bias_angle_rad, memory = material.bend_memory_rate_per_s;
    formats::FabricParameters parameters = cloth::fabric_from_material(material);
    (parameters.*(preset_entry(key)->member)).value = value;
    material = cloth::material_from_fabric(parameters);
    material.bias_angle_rad = bias;
    material.bend_memory_rate_per_s = memory;
}

double material_parameter(const cloth::ClothMaterial& material, const std::string& key) {
    require_known(key);
    if (key == kStretchTie) return material.stretch_warp_N_per_m;
    if (key == kStretchDampingTie) return material.stretch_warp_damping_N_s_per_m;
    const formats::FabricParameters parameters = cloth::fabric_from_material(material);
    return (parameters.*(preset_entry(key)->member)).value;
}

bool parameter_allows_zero(const std::string& key) {
    require_known(key);
    const formats::FabricParameterInfo* entry = preset_entry(key);
    return entry != nullptr && entry->zero_allowed;
}

std::vector<FittedParameter> static_test_parameters() {
    return {
        {kStretchTie, 10.0, 1e4, true},
        {"shear_stiffness_N_per_m", 5.0, 1e4, true},
        {"bend_stiffness_N_m", 1e-9, 1e-4, true},
        {kStretchDampingTie, 1e-5, 1.0, true},
        {"shear_damping_N_s_per_m", 1e-5, 1.0, true},
        {"bend_damping_N_m_s", 1e-11, 1e-5, true},
    };
}

std::vector<FittedParameter> waving_test_parameters() {
    std::vector<FittedParameter> p = static_test_parameters();
    p.push_back({"drag_normal_kg_per_m3", 1e-3, 10.0, true});
    p.push_back({"drag_degradation_s2_per_m2", 1e-3, 10.0, true});
    p.push_back({"drag_tangential_kg_per_m2_s", 1e-3, 10.0, true});
    return p;
}

std::vector<FittedParameter> with_bending_floor(std::vector<FittedParameter> parameters, double min_bending_N_m) {
    if (min_bending_N_m <= 0.0) return parameters;
    for (FittedParameter& p : parameters)
        if (p.key == "bend_stiffness_N_m") {
            p.lower = std::max(p.lower, min_bending_N_m);
            p.upper = std::max(p.upper, 10.0 * p.lower);
        }
    return parameters;
}

const char* fit_target_name(FitTarget target) {
    switch (target) {
    case FitTarget::tracks: return "tracks";
    case FitTarget::scan: return "scan";
    case FitTarget::footage: break;
    }
    return "footage";
}

std::optional<FitTarget> fit_target_from_name(std::string_view name) {
    for (const FitTarget target : {FitTarget::footage, FitTarget::scan, FitTarget::tracks})
        if (name == fit_target_name(target)) return target;
    return std::nullopt;
}

namespace {

// Simulate only as far as needed, plus two frames so that the pins' spline
// keeps its tangents up to the last compared frame (its ends are at rest).
void truncate_experiment(ClothTrial& trial, int compared_frames) {
    const int simulated = trial.is_static ? 1 : std::min(compared_frames + 2, trial.experiment.frame_count);
    trial.experiment.frame_count = simulated;
    for (cloth::PinTrajectory& pin : trial.experiment.pins)
        if (static_cast<int>(pin.positions_m.size()) > simulated) pin.positions_m.resize(static_cast<std::size_t>(simulated));
}

int compared_frame_count(const ClothTrial& trial, const TrialLoadSettings& settings, int available) {
    const int wanted = trial.is_static ? settings.static_frames : settings.waving_frames;
    return std::clamp(wanted, 1, available);
}

std::vector<double> frame_weights(const ClothTrial& trial, const TrialLoadSettings& settings, int count) {
    return trial.is_static ? std::vector<double>(static_cast<std::size_t>(count), settings.static_weight)
                           : video::decaying_frame_weights(count, settings.full_weight_frames, settings.half_life_frames);
}

// A tracks trial: the capture's measured 3D points instead of its footage.
ClothTrial load_tracks_trial(const formats::Capture& capture, const TrialLoadSettings& settings) {
    std::optional<formats::VertexAnimation> tracks = formats::read_capture_tracks(capture);
    if (!tracks) {
        Diagnostics diagnostics(capture.json_path);
        diagnostics.error("/tracks", "this capture has no 3D tracks to fit to",
                          "add a \"tracks\" entry (measured positions of swatch points, see the capture contract), "
                          "or fit to the footage (--fit-to footage, or --fit-to scan for the shape its stripes measure)");
        diagnostics.throw_if_errors();
    }
    ClothTrial trial;
    trial.name = capture.folder;
    trial.is_static = capture.kind == "cloth.static";
    trial.experiment = cloth::experiment_from_capture(capture);
    if (capture.camera) trial.camera = *capture.camera;
    if (capture.projector) trial.projector = *capture.projector;
    const int count = compared_frame_count(trial, settings, tracks->frame_count);
    const std::vector<double> weights = frame_weights(trial, settings, count);
    TrackReference reference;
    reference.rows = *tracks->grid_rows;
    reference.cols = *tracks->grid_cols;
    const double diagonal_mm = 1000.0 * std::hypot(trial.experiment.width_m, trial.experiment.height_m);
    reference.missing_frame_error_mm2 = diagonal_mm * diagonal_mm;
    for (int k = 0; k < count; ++k) {
        video::ReferenceFrame frame;
        frame.number = k + 1;
        frame.weight = weights[static_cast<std::size_t>(k)];
        trial.frames.push_back(std::move(frame));
        Eigen::MatrixX3d positions(tracks->vertex_count, 3);
        for (int v = 0; v < tracks->vertex_count; ++v) positions.row(v) = tracks->position(k, v).cast<double>().transpose();
        reference.positions_m.push_back(std::move(positions));
    }
    trial.tracks = std::move(reference);
    truncate_experiment(trial, count);
    return trial;
}

// What every trial compared with footage shares: name, test, experiment and calibration.
ClothTrial footage_trial(const formats::Capture& capture, const video::ClothFootage& footage) {
    ClothTrial trial;
    trial.name = capture.folder;
    trial.is_static = capture.kind == "cloth.static";
    trial.experiment = cloth::experiment_from_capture(capture);
    trial.camera = footage.camera();
    trial.projector = footage.projector();
    return trial;
}

// A scan trial: the footage's frames scanned in order (each references its
// stripe periods by the one before), sampled every stride pixels.
ClothTrial load_scan_trial(const formats::Capture& capture, const TrialLoadSettings& settings) {
    video::ClothFootage footage(capture, settings.segmentation);
    ClothTrial trial = footage_trial(capture, footage);
    const int count = compared_frame_count(trial, settings, footage.count());
    const std::vector<double> weights = frame_weights(trial, settings, count);
    video::StripeScanner scanner = video::scanner_for(capture);
    ScanReference reference;
    reference.cap_m = settings.scan_cap_m;
    reference.period_units = trial.projector.pattern.period_px;
    const int stride = std::max(1, settings.scan_stride_px);
    reference.stride_px = stride;
    reference.outside_band = settings.scan_outside;
    video::StripeScan previous;
    for (int k = 0; k < count; ++k) {
        const video::ClothFrame frame = footage.frame(footage.first() + k);
        video::StripeScan scan = scanner.scan(frame.gray, frame.silhouette, video::pin_positions_at(capture, k + 1),
                                       previous.width > 0 ? &previous : nullptr);
        std::vector<ScanReference::Sample> samples;
        for (int y = 0; y < scan.height; y += stride)
            for (int x = 0; x < scan.width; x += stride) {
                if (!scan.measured(x, y)) continue;
                const double v = scan.projector_coordinate.at(x, y);
                // Metres of depth along the ray per unit of v_p, by central difference.
                const Eigen::Vector3d ahead = scanner.triangulate({x, y}, v + 0.5), behind = scanner.triangulate({x, y}, v - 0.5);
                const double metres_per_unit = (ahead - behind).norm();
                if (!std::isfinite(metres_per_unit) || metres_per_unit <= 0.0) continue;
                samples.push_back({x, y, v, metres_per_unit});
            }
        reference.samples.push_back(std::move(samples));
        if (settings.scan_outside.max_px > 0.0)
            reference.outside.push_back(scan_outside_pixels(frame.silhouette, stride, settings.scan_outside));
        if (k == 0) {
            reference.width = scan.width;
            reference.height = scan.height;
            reference.first_frame_points_m = scan.points_m;
        }
        video::ReferenceFrame compared;
        compared.number = k + 1;
        compared.weight = weights[static_cast<std::size_t>(k)];
        trial.frames.push_back(std::move(compared));
        previous = std::move(scan);
    }
    trial.scan = std::move(reference);
    truncate_experiment(trial, count);
    return trial;
}

}  // namespace

std::vector<double> scan_residuals_m(const ScanReference& scan, std::size_t frame, const video::StripeImage& rendered) {
    std::vector<double> r;
    r.reserve(scan.samples[frame].size());
    for (const ScanReference::Sample& s : scan.samples[frame]) {
        if (!std::isfinite(s.projector_coordinate)) continue;
        const double simulated = rendered.projector_coordinate.at(s.x, s.y);
        if (!std::isfinite(simulated)) {
            r.push_back(scan.cap_m);  // the simulation does not cover this pixel
            continue;
        }
        double difference = simulated - s.projector_coordinate;
        if (scan.period_units > 0.0) difference -= scan.period_units * std::round(difference / scan.period_units);
        const double depth_m = difference * s.metres_per_unit;
        r.push_back(scan.cap_m * std::tanh(depth_m / scan.cap_m));
    }
    if (frame < scan.outside.size())
        for (const ScanReference::Pixel& p : scan.outside[frame])
            r.push_back(std::isfinite(rendered.projector_coordinate.at(p.x, p.y)) ? scan.cap_m : 0.0);
    return r;
}

long long scan_measured_count(const ScanReference& scan, std::size_t frame) {
    long long measured = 0;
    for (const ScanReference::Sample& s : scan.samples[frame]) measured += std::isfinite(s.projector_coordinate) ? 1 : 0;
    return measured;
}

std::vector<ScanReference::Pixel> scan_outside_pixels(const metrics::Silhouette& silhouette, int stride_px,
                                                      const ScanOutsideBand& band) {
    std::vector<ScanReference::Pixel> pixels;
    if (band.max_px <= 0.0 || silhouette.width <= 0) return pixels;
    const metrics::DistanceField distance = metrics::signed_distance_field(silhouette);
    const int stride = std::max(1, stride_px);
    for (int y = 0; y < silhouette.height; y += stride)
        for (int x = 0; x < silhouette.width; x += stride) {
            const double d = distance.at(x, y);
            if (d >= band.min_px && d <= band.max_px) pixels.push_back({x, y});
        }
    return pixels;
}

double track_frame_error_mm2(const Eigen::MatrixX3d& measured_m, const Eigen::MatrixX3d& simulated_m) {
    double sum = 0.0;
    long long seen = 0;
    for (Eigen::Index i = 0; i < measured_m.rows() && i < simulated_m.rows(); ++i) {
        if (!measured_m.row(i).allFinite()) continue;
        sum += (measured_m.row(i) - simulated_m.row(i)).squaredNorm();
        ++seen;
    }
    return seen > 0 ? 1e6 * sum / static_cast<double>(seen) : 0.0;
}

double tracks_rms_mm(const ClothTrial& trial, double weighted_error) {
    double weights = 0.0;
    for (const video::ReferenceFrame& f : trial.frames) weights += f.weight;
    return weights > 0.0 ? std::sqrt(std::max(0.0, weighted_error) / weights) : 0.0;
}

double balanced_static_weight(const TrialLoadSettings& load) {
    const std::vector<double> weights =
        video::decaying_frame_weights(std::max(load.waving_frames, 1), load.full_weight_frames, load.half_life_frames);
    return std::accumulate(weights.begin(), weights.end(), 0.0);
}

double default_static_weight(const TrialLoadSettings& load, const std::vector<formats::Capture>& captures) {
    const auto is_static = [](const formats::Capture& c) { return c.kind == "cloth.static"; };
    const bool mixed = std::any_of(captures.begin(), captures.end(), is_static) && !std::all_of(captures.begin(), captures.end(), is_static);
    return load.target == FitTarget::tracks && mixed ? balanced_static_weight(load) : 1.0;
}

double default_shear_cell_fraction(FitTarget target) { return target == FitTarget::tracks ? 1.0 : 0.0; }

ClothTrial load_trial(const formats::Capture& capture, const TrialLoadSettings& settings) {
    if (settings.target == FitTarget::tracks) return load_tracks_trial(capture, settings);
    if (settings.target == FitTarget::scan) return load_scan_trial(capture, settings);
    video::ClothFootage footage(capture, settings.segmentation);
    ClothTrial trial = footage_trial(capture, footage);
    const double period = settings.stripe_period_px.value_or(video::expected_stripe_period_px(capture));
    trial.angle_map = video::AngleMapSettings::for_stripe_period(period);
    const int count = compared_frame_count(trial, settings, footage.count());
    const std::vector<double> weights = frame_weights(trial, settings, count);
    video::AngleMapper mapper(trial.angle_map);
    for (int k = 0; k < count; ++k) {
        const video::ClothFrame frame = footage.frame(footage.first() + k);
        video::ReferenceFrame reference;
        reference.number = k + 1;
        reference.weight = weights[static_cast<std::size_t>(k)];
        reference.silhouette = frame.silhouette;
        mapper.compute(frame.gray, frame.silhouette, reference.angles);
        if (settings.silhouette_term == video::SilhouetteTerm::edge_distance) video::prepare_reference(reference);
        trial.frames.push_back(std::move(reference));
    }
    truncate_experiment(trial, count);
    return trial;
}

int usable_frames(const cloth::SwatchRun& run) {
    // After a failure only the frames before the failing one are good (an
    // equilibrium that did not converge leaves none).
    int usable = static_cast<int>(run.simulation.frames.size());
    if (!run.simulation.report.ok()) usable = std::min(usable, std::max(0, run.simulation.report.frame - 1));
    return usable;
}

namespace {

std::vector<video::FrameError> compare_tracks(const ClothTrial& trial, const cloth::SwatchRun& run) {
    const TrackReference& tracks = *trial.tracks;
    const int usable = usable_frames(run);
    const cloth::UvSampler sampler(run.swatch.mesh, tracks.rows, tracks.cols);
    std::vector<video::FrameError> errors;
    for (std::size_t k = 0; k < trial.frames.size(); ++k) {
        const int index = trial.frames[k].number - 1;
        video::FrameError fe;
        fe.total = index >= 0 && index < usable
                       ? track_frame_error_mm2(tracks.positions_m[k], sampler.sample(run.simulation.frames[static_cast<std::size_t>(index)]))
                       : tracks.missing_frame_error_mm2;
        errors.push_back(fe);
    }
    return errors;
}

// A renderer of the simulation's projector coordinates for a scan trial.
video::StripeRenderer scan_renderer(const ClothTrial& trial) {
    video::StripeRenderSettings settings;
    settings.projector_coordinates = true;
    return video::StripeRenderer(trial.camera, trial.projector, settings);
}

std::vector<video::FrameError> compare_scan(const ClothTrial& trial, const cloth::SwatchRun& run) {
    const ScanReference& scan = *trial.scan;
    const int usable = usable_frames(run);
    video::StripeRenderer renderer = scan_renderer(trial);
    video::StripeImage rendered;
    std::vector<video::FrameError> errors;
    for (std::size_t k = 0; k < trial.frames.size(); ++k) {
        const int index = trial.frames[k].number - 1;
        video::FrameError fe;
        if (index >= 0 && index < usable) {
            renderer.render(video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]),
                            run.swatch.mesh.triangles, rendered);
            const std::vector<double> r = scan_residuals_m(scan, k, rendered);
            double sum = 0.0;
            for (const double v : r) sum += v * v;
            const long long measured = scan_measured_count(scan, k);
            fe.total = measured == 0 ? 0.0 : 1e6 * sum / static_cast<double>(measured);
        } else {
            fe.total = scan.missing_frame_error_mm2();
        }
        errors.push_back(fe);
    }
    return errors;
}

}  // namespace

std::vector<video::FrameError> compare_run(const ClothTrial& trial, const cloth::SwatchRun& run,
                                             const video::AngleMapMetricSettings& metric) {
    if (trial.tracks) return compare_tracks(trial, run);
    if (trial.frames.empty()) return {};  // nothing compared (no camera needed)
    if (trial.scan) return compare_scan(trial, run);
    const int usable = usable_frames(run);
    video::StripeRenderer renderer(trial.camera, trial.projector);
    video::AngleMapper mapper(trial.angle_map);
    video::StripeImage rendered;
    video::AngleMap angles;
    std::vector<video::FrameError> errors;
    for (const video::ReferenceFrame& reference : trial.frames) {
        const int index = reference.number - 1;
        video::FrameError fe;
        if (index >= 0 && index < usable) {
            renderer.render(video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]),
                            run.swatch.mesh.triangles, rendered);
            mapper.compute(rendered.image, rendered.silhouette, angles);
            fe = video::angle_map_frame_error(reference, angles, rendered.silhouette, metric);
        } else {
            fe.total = missing_frame_error(reference, metric);
        }
        errors.push_back(fe);
    }
    return errors;
}

ClothTrial simulated_trial(const ClothTrial& trial, const cloth::SwatchRun& run, bool edge_distance) {
    ClothTrial out = trial;
    if (trial.tracks) {
        const int usable = usable_frames(run);
        const cloth::UvSampler sampler(run.swatch.mesh, trial.tracks->rows, trial.tracks->cols);
        for (std::size_t k = 0; k < out.frames.size(); ++k) {
            const int index = out.frames[k].number - 1;
            if (index < 0 || index >= usable)
                throw std::invalid_argument("simulated_trial: the run has no frame " + std::to_string(out.frames[k].number));
            out.tracks->positions_m[k] = sampler.sample(run.simulation.frames[static_cast<std::size_t>(index)]);
        }
        return out;
    }
    if (trial.scan) {
        // The simulation's own projector coordinates at the samples (NaN where it does not cover).
        const int usable = usable_frames(run);
        video::StripeRenderer renderer = scan_renderer(trial);
        video::StripeImage rendered;
        for (std::size_t k = 0; k < out.frames.size(); ++k) {
            const int index = out.frames[k].number - 1;
            if (index < 0 || index >= usable)
                throw std::invalid_argument("simulated_trial: the run has no frame " + std::to_string(out.frames[k].number));
            renderer.render(video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]),
                            run.swatch.mesh.triangles, rendered);
            for (ScanReference::Sample& sample : out.scan->samples[k])
                sample.projector_coordinate = rendered.projector_coordinate.at(sample.x, sample.y);
            if (k < out.scan->outside.size())
                out.scan->outside[k] = scan_outside_pixels(rendered.silhouette, out.scan->stride_px, out.scan->outside_band);
        }
        return out;
    }
    video::StripeRenderer renderer(trial.camera, trial.projector);
    video::AngleMapper mapper(trial.angle_map);
    video::StripeImage rendered;
    const int usable = usable_frames(run);
    for (video::ReferenceFrame& reference : out.frames) {
        const int index = reference.number - 1;
        if (index < 0 || index >= usable) throw std::invalid_argument("simulated_trial: the run has no frame " + std::to_string(reference.number));
        renderer.render(video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]),
                        run.swatch.mesh.triangles, rendered);
        mapper.compute(rendered.image, rendered.silhouette, reference.angles);
        reference.silhouette = rendered.silhouette;
        reference.edge_distance = {};
        if (edge_distance) video::prepare_reference(reference);
    }
    return out;
}

namespace {

// The first measured frame of a tracks trial on the simulation mesh
// (bilinear in the tracks' uv grid); vertices whose neighbouring points were
// not seen keep `fallback`'s position. Empty when frame 1 is not compared.
Eigen::VectorXd measured_first_frame(const ClothTrial& trial, const cloth::Swatch& swatch, const Eigen::VectorXd& fallback) {
    if (!trial.tracks || trial.frames.empty() || trial.frames.front().number != 1) return {};
    const TrackReference& tracks = *trial.tracks;
    const Eigen::MatrixX3d& measured = tracks.positions_m.front();
    Eigen::VectorXd start = fallback;
    int filled = 0;
    for (int r = 0; r < swatch.rows; ++r)
        for (int c = 0; c < swatch.cols; ++c) {
            const double y = static_cast<double>(r) / (swatch.rows - 1) * (tracks.rows - 1);
            const double x = static_cast<double>(c) / (swatch.cols - 1) * (tracks.cols - 1);
            const int r0 = std::min(static_cast<int>(y), tracks.rows - 2), c0 = std::min(static_cast<int>(x), tracks.cols - 2);
            const double fy = y - r0, fx = x - c0;
            Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
            bool seen = true;
            for (int dr = 0; dr < 2 && seen; ++dr)
                for (int dc = 0; dc < 2 && seen; ++dc) {
                    const double w = (dr ? fy : 1.0 - fy) * (dc ? fx : 1.0 - fx);
                    const Eigen::RowVector3d q = measured.row((r0 + dr) * tracks.cols + c0 + dc);
                    if (w == 0.0) continue;
                    if (!q.allFinite()) seen = false;
                    else p += w * q;
                }
            if (!seen) continue;
            start.segment<3>(3 * (r * swatch.cols + c)) = p.transpose();
            ++filled;
        }
    return filled > 0 ? start : Eigen::VectorXd();
}

// The point frame 1's scan measured at the pixel where the camera sees
// `world_m`; none when that pixel is outside the image or was not measured.
std::optional<Eigen::Vector3d> scanned_point_seen_at(const ScanReference& scan, const formats::CameraModel& camera,
                                                     const Eigen::Vector3d& world_m) {
    const Eigen::Vector2d pixel = camera.project(world_m);
    if (!pixel.allFinite()) return std::nullopt;
    const int px = static_cast<int>(std::lround(pixel.x())), py = static_cast<int>(std::lround(pixel.y()));
    if (px < 0 || py < 0 || px >= scan.width || py >= scan.height) return std::nullopt;
    const Eigen::Vector3f& p =
        scan.first_frame_points_m[static_cast<std::size_t>(py) * static_cast<std::size_t>(scan.width) + static_cast<std::size_t>(px)];
    if (!p.allFinite()) return std::nullopt;
    return p.cast<double>();
}

// A start in the fold state a scan trial's first frame shows: each free
// vertex of `shape` seen by the camera at a scanned pixel moves to the
// scanned point there (on the same camera ray, at the measured depth); the
// others move by the mean of their grid neighbours' moves, spread a few
// times. Empty when frame 1 was not scanned.
Eigen::VectorXd scanned_first_frame(const ClothTrial& trial, const cloth::Swatch& swatch, const Eigen::VectorXd& shape) {
    if (!trial.scan || trial.scan->first_frame_points_m.empty()) return {};
    const ScanReference& scan = *trial.scan;
    const int n = swatch.rows * swatch.cols;
    std::vector<Eigen::Vector3d> move(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
    std::vector<bool> known(static_cast<std::size_t>(n), false);
    int measured = 0;
    for (int i = 0; i < n; ++i) {
        if (swatch.pinned[static_cast<std::size_t>(i)]) {
            known[static_cast<std::size_t>(i)] = true;  // pins stay
            continue;
        }
        const Eigen::Vector3d x = shape.segment<3>(3 * i);
        const std::optional<Eigen::Vector3d> p = scanned_point_seen_at(scan, trial.camera, x);
        if (!p) continue;
        move[static_cast<std::size_t>(i)] = *p - x;
        known[static_cast<std::size_t>(i)] = true;
        ++measured;
    }
    if (measured == 0) return {};
    // Unseen vertices: their known neighbours' mean move, grown outwards.
    for (int pass = 0; pass < swatch.rows + swatch.cols; ++pass) {
        bool changed = false;
        std::vector<bool> next = known;
        std::vector<Eigen::Vector3d> next_move = move;
        for (int r = 0; r < swatch.rows; ++r)
            for (int c = 0; c < swatch.cols; ++c) {
                const int i = r * swatch.cols + c;
                if (known[static_cast<std::size_t>(i)]) continue;
                Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                int count = 0;
                for (const auto& [dr, dc] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
                    const int rr = r + dr, cc = c + dc;
                    if (rr < 0 || cc < 0 || rr >= swatch.rows || cc >= swatch.cols) continue;
                    const int j = rr * swatch.cols + cc;
                    if (!known[static_cast<std::size_t>(j)] || swatch.pinned[static_cast<std::size_t>(j)]) continue;
                    sum += move[static_cast<std::size_t>(j)];
                    ++count;
                }
                if (count == 0) continue;
                next_move[static_cast<std::size_t>(i)] = sum / count;
                next[static_cast<std::size_t>(i)] = true;
                changed = true;
            }
        known = std::move(next);
        move = std::move(next_move);
        if (!changed) break;
    }
    Eigen::VectorXd start = shape;
    for (int i = 0; i < n; ++i) start.segment<3>(3 * i) += move[static_cast<std::size_t>(i)];
    return start;
}

// Frame 1's scanned surface as a drape of `material`, from `start` (a shape
// near it on `swatch`, the mesh of `options`): each round pulls every free
// vertex seen at a scanned pixel towards the plane across its camera ray
// through the scanned point there (its depth; across the ray the fabric's
// energy places it) and solves that equilibrium, then the pixels are looked
// up again. Empty when a solve fails or nothing was seen.
Eigen::VectorXd registered_to_scan(const ClothTrial& trial, const cloth::SwatchExperiment& experiment,
                                   const cloth::Swatch& swatch, const cloth::ClothMaterial& material,
                                   cloth::SwatchOptions options, Eigen::VectorXd start, int rounds, double tolerance_m) {
    const ScanReference& scan = *trial.scan;
    const int n = swatch.rows * swatch.cols;
    const cloth::ClothMaterial weighed = cloth::experiment_material(experiment, material);
    const double vertex_weight_N = weighed.areal_density_kg_per_m2 * experiment.width_m * experiment.height_m / n *
                                   std::max(options.environment.gravity_m_per_s2.norm(), 1e-6);
    const Eigen::Vector3d centre = trial.camera.centre_world();
    Eigen::VectorXd x = std::move(start);
    for (int round = 0; round < rounds; ++round) {
        std::vector<cloth::PlaneAnchor> anchors;
        for (int i = 0; i < n; ++i) {
            if (swatch.pinned[static_cast<std::size_t>(i)]) continue;
            const std::optional<Eigen::Vector3d> point = scanned_point_seen_at(scan, trial.camera, x.segment<3>(3 * i));
            if (!point) continue;
            anchors.push_back({i, *point, (*point - centre).normalized(), vertex_weight_N / tolerance_m});
        }
        if (anchors.empty()) return {};
        options.initial_positions = x;
        options.equilibrium.anchors = std::move(anchors);
        const cloth::SwatchRun run = cloth::simulate_swatch(experiment, material, options);
        if (!run.equilibrium.converged || run.simulation.frames.empty()) return {};
        x = run.simulation.frames.front();
    }
    return x;
}

}  // namespace

Eigen::VectorXd matching_equilibrium(const ClothTrial& trial, const cloth::ClothMaterial& material,
                                     const ClothFitSettings& settings, double* chosen_bow, Eigen::VectorXd* measured_start) {
    if (measured_start) measured_start->resize(0);
    cloth::SwatchExperiment equilibrium_only = trial.experiment;
    equilibrium_only.frame_count = 1;
    for (cloth::PinTrajectory& pin : equilibrium_only.pins) pin.positions_m.resize(std::min<std::size_t>(pin.positions_m.size(), 1));
    ClothTrial first_frame = trial;
    std::vector<std::size_t> kept;
    for (std::size_t k = 0; k < trial.frames.size(); ++k)
        if (trial.frames[k].number == 1) kept.push_back(k);
    first_frame.frames.clear();
    if (first_frame.tracks) first_frame.tracks->positions_m.clear();
    if (first_frame.scan) {
        first_frame.scan->samples.clear();
        first_frame.scan->outside.clear();
    }
    for (const std::size_t k : kept) {
        first_frame.frames.push_back(trial.frames[k]);
        if (first_frame.tracks) first_frame.tracks->positions_m.push_back(trial.tracks->positions_m[k]);
        if (first_frame.scan) {
            first_frame.scan->samples.push_back(trial.scan->samples[k]);
            if (k < trial.scan->outside.size()) first_frame.scan->outside.push_back(trial.scan->outside[k]);
        }
    }
    // Candidate starts: the bows, and for a tracks trial the measured first
    // frame itself (the solve then finds the equilibrium nearest to what was
    // seen, whichever way it folds).
    struct Candidate {
        double bow = 0.0;
        bool measured = false;
    };
    std::vector<Candidate> candidates;
    for (const double bow : settings.candidate_bows) candidates.push_back({bow, false});
    if (candidates.empty()) candidates.push_back({settings.swatch.initial_bow, false});
    const bool choose = !first_frame.frames.empty();
    if (choose && trial.tracks) candidates.push_back({settings.swatch.initial_bow, true});
    // A scan trial: each bow's equilibrium moved onto the scanned first
    // frame, registered to it (settings.scan_registration_rounds), then
    // settled. (Moving a settled shape onto the scan and settling again,
    // without the registration's anchors, moved the captures' starts
    // further from their truth: 3.9-11.1 mm after one round, 4.0-15.9 after
    // two. The settle slides vertices across the rays, which depth alone
    // cannot see; registered, the fabric's energy places them.)
    const bool scanned = choose && trial.scan && !trial.scan->first_frame_points_m.empty();
    const std::size_t bows = candidates.size();
    if (scanned)
        for (std::size_t b = 0; b < bows; ++b) candidates.push_back({candidates[b].bow, true});
    std::vector<Eigen::VectorXd> bow_equilibria(bows);
    Eigen::VectorXd best;
    double best_error = std::numeric_limits<double>::infinity();
    for (std::size_t index = 0; index < candidates.size(); ++index) {
        const Candidate& candidate = candidates[index];
        cloth::SwatchOptions options = settings.swatch;
        options.simulation.threads = 1;
        options.initial_bow = candidate.bow;
        options.initial_positions.resize(0);
        cloth::SwatchRun run;
        if (candidate.measured && trial.scan) {
            const Eigen::VectorXd& from = bow_equilibria[index - bows];
            if (from.size() == 0) continue;
            const cloth::Swatch swatch = cloth::build_swatch(equilibrium_only, options.rows, options.cols);
            options.initial_positions = scanned_first_frame(trial, swatch, from);
            if (options.initial_positions.size() == 0) continue;
            if (settings.scan_registration_rounds > 0) {
                options.initial_positions =
                    registered_to_scan(trial, equilibrium_only, swatch, material, options, options.initial_positions,
                                       settings.scan_registration_rounds, settings.scan_registration_tolerance_m);
                if (options.initial_positions.size() == 0) continue;
            }
            run = cloth::simulate_swatch(equilibrium_only, material, options);
        } else {
            if (candidate.measured) {
                const cloth::Swatch swatch = cloth::build_swatch(equilibrium_only, options.rows, options.cols);
                options.initial_positions =
                    measured_first_frame(trial, swatch, cloth::hanging_start(swatch, equilibrium_only, candidate.bow));
                if (options.initial_positions.size() == 0) continue;
            }
            run = cloth::simulate_swatch(equilibrium_only, material, options);
        }
        if (!run.equilibrium.converged || run.simulation.frames.empty()) continue;
        if (index < bows) bow_equilibria[index] = run.simulation.frames.front();
        double error = 0.0;
        for (const video::FrameError& e : compare_run(first_frame, run, settings.metric)) error += e.total;
        if (!choose || candidates.size() == 1) error = 0.0;  // nothing to choose by
        if (error < best_error) {
            best_error = error;
            best = run.simulation.frames.front();
            if (chosen_bow) *chosen_bow = candidate.bow;
            if (measured_start) {
                if (candidate.measured && !trial.scan) *measured_start = options.initial_positions;
                else measured_start->resize(0);
            }
        }
    }
    return best;
}

double missing_frame_error(const video::ReferenceFrame& reference, const video::AngleMapMetricSettings& settings) {
    const double quarter_turn = 0.5 * std::numbers::pi;
    const double fold = static_cast<double>(reference.angles.mask_count()) * quarter_turn * quarter_turn;
    double silhouette = 0.0;
    if (settings.silhouette_term == video::SilhouetteTerm::pixel_xor) {
        silhouette = static_cast<double>(reference.silhouette.area_px());
    } else {
        const double far = static_cast<double>(reference.silhouette.width + reference.silhouette.height);
        silhouette = static_cast<double>(metrics::silhouette_edge_pixels(reference.silhouette).size()) * far * far;
    }
    return fold + settings.alpha * silhouette;
}

ClothFitProblem::ClothFitProblem(std::vector<ClothTrial> trials, std::vector<FittedParameter> parameters,
                                 ClothFitSettings settings)
    : m_trials(std::move(trials)), m_parameters(std::move(parameters)), m_settings(std::move(settings)) {
    if (m_trials.empty()) throw std::invalid_argument("ClothFitProblem: no trials");
    std::vector<optim::Parameter> space;
    for (const FittedParameter& p : m_parameters) {
        require_known(p.key);
        space.push_back({p.key, p.lower, p.upper, p.log_scale});
    }
    m_space = optim::ParameterSpace(space);
    // A trial whose first frame was measured in 3D starts every simulation's
    // equilibrium solve there, so that each fabric settles into the
    // equilibrium nearest what was seen -- the one its prediction starts
    // from. The base fabric's own equilibrium from there is a different fold
    // (silk static-1: the fitted fabric settled from it 8.6 mm from the
    // truth, from the measured shape 5.5 mm), and the fit would tune the
    // wrong drape.
    auto warm_start_of = [this](std::size_t trial, const ClothFitSettings& settings) {
        Eigen::VectorXd measured;
        Eigen::VectorXd start = matching_equilibrium(m_trials[trial], settings.base, settings, nullptr, &measured);
        return settings.warm_start_from_measurement && measured.size() > 0 ? measured : start;
    };
    ClothFitSettings on_second_mesh = m_settings;
    on_second_mesh.swatch.rows = m_settings.second_drape_rows;
    on_second_mesh.swatch.cols = m_settings.second_drape_cols;
    m_warm_starts.resize(m_trials.size());
    m_second_mesh_warm_starts.resize(m_trials.size());
    if (m_settings.warm_start)
        for (std::size_t i = 0; i < m_trials.size(); ++i) {
            const auto began = std::chrono::steady_clock::now();
            m_warm_starts[i] = warm_start_of(i, m_settings);
            m_warm_start_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
            if (has_second_mesh(i)) m_second_mesh_warm_starts[i] = warm_start_of(i, on_second_mesh);
        }
}

cloth::ClothMaterial ClothFitProblem::material(const Eigen::VectorXd& values) const {
    cloth::ClothMaterial m = m_settings.base;
    for (std::size_t i = 0; i < m_parameters.size(); ++i)
        set_material_parameter(m, m_parameters[i].key, values(static_cast<Eigen::Index>(i)));
    return m;
}

Eigen::VectorXd ClothFitProblem::values_of(const cloth::ClothMaterial& material) const {
    Eigen::VectorXd values(static_cast<Eigen::Index>(m_parameters.size()));
    for (std::size_t i = 0; i < m_parameters.size(); ++i)
        values(static_cast<Eigen::Index>(i)) = material_parameter(material, m_parameters[i].key);
    return values;
}

cloth::SwatchRun ClothFitProblem::simulate(std::size_t trial, const cloth::ClothMaterial& material, int threads) const {
    return simulate_candidate(trial, material, threads, false);
}

bool ClothFitProblem::has_second_mesh(std::size_t trial) const {
    return m_settings.has_second_drape_mesh() && m_trials.at(trial).is_static;
}

cloth::SwatchRun ClothFitProblem::simulate_second_mesh(std::size_t trial, const cloth::ClothMaterial& material,
                                                       int threads) const {
    if (!has_second_mesh(trial)) throw std::logic_error("ClothFitProblem::simulate_second_mesh: the trial has no second mesh");
    return simulate_candidate(trial, material, threads, true);
}

cloth::SwatchRun ClothFitProblem::simulate_candidate(std::size_t trial, const cloth::ClothMaterial& material, int threads,
                                                     bool second_mesh) const {
    cloth::SwatchOptions options = m_settings.swatch;
    if (m_settings.evaluation_equilibrium_iterations > 0)
        options.equilibrium.max_iterations =
            std::min(options.equilibrium.max_iterations, m_settings.evaluation_equilibrium_iterations);
    if (second_mesh) {
        options.rows = m_settings.second_drape_rows;
        options.cols = m_settings.second_drape_cols;
    }
    options.simulation.threads = std::max(1, threads);
    const Eigen::VectorXd& warm = second_mesh ? m_second_mesh_warm_starts[trial] : m_warm_starts[trial];
    if (warm.size() > 0) options.initial_positions = warm;
    return cloth::simulate_swatch(m_trials[trial].experiment, material, options);
}

void ClothFitProblem::for_each_trial(int threads, const std::function<void(std::size_t, int)>& run_trial) const {
    // Static drapes cost a fraction of a waving test: run side by side they
    // leave a thread idle, so then the trials run one after the other, each
    // simulation with every thread (results do not depend on the count).
    const bool mixed = std::any_of(m_trials.begin(), m_trials.end(), [](const ClothTrial& t) { return t.is_static; }) &&
                       std::any_of(m_trials.begin(), m_trials.end(), [](const ClothTrial& t) { return !t.is_static; });
    const int available = std::max(threads, 1);
    const int workers = mixed ? 1 : std::min<int>(available, static_cast<int>(m_trials.size()));
    const int per_simulation = std::max(1, available / workers);
    if (workers <= 1) {
        for (std::size_t t = 0; t < m_trials.size(); ++t) run_trial(t, per_simulation);
    } else {
        ThreadPool pool(workers);
        pool.run(m_trials.size(), [&](std::size_t t, int) { run_trial(t, per_simulation); });
    }
}

ClothEvaluation ClothFitProblem::evaluate(const cloth::ClothMaterial& material, int threads) const {
    ClothEvaluation out;
    out.trials.resize(m_trials.size());
    auto one = [&](std::size_t t, int simulation_threads) {
        TrialEvaluation& e = out.trials[t];
        e.name = m_trials[t].name;
        const cloth::SwatchRun run = simulate(t, material, simulation_threads);
        e.report = run.simulation.report;
        e.simulated_frames = usable_frames(run);
        e.frames = compare_run(m_trials[t], run, m_settings.metric);
        for (std::size_t k = 0; k < e.frames.size(); ++k) e.error += m_trials[t].frames[k].weight * e.frames[k].total;
        if (!has_second_mesh(t)) return;
        const cloth::SwatchRun second = simulate_second_mesh(t, material, simulation_threads);
        const std::vector<video::FrameError> frames = compare_run(m_trials[t], second, m_settings.metric);
        for (std::size_t k = 0; k < frames.size(); ++k) e.second_mesh_error += m_trials[t].frames[k].weight * frames[k].total;
    };
    for_each_trial(threads, one);
    // In trial order: thread-independent.
    for (const TrialEvaluation& e : out.trials) out.total += e.error + e.second_mesh_error;
    return out;
}

bool ClothFitProblem::all_measure_shape() const {
    return std::all_of(m_trials.begin(), m_trials.end(), [](const ClothTrial& t) { return t.measures_shape(); });
}

namespace {

// sqrt(w_k / n_k) r for each of a scan trial's samples, r in mm.
void append_scan_residuals(const ClothTrial& trial, const cloth::SwatchRun& run, std::vector<double>& out) {
    const ScanReference& scan = *trial.scan;
    const int usable = usable_frames(run);
    video::StripeRenderer renderer = scan_renderer(trial);
    video::StripeImage rendered;
    for (std::size_t k = 0; k < trial.frames.size(); ++k) {
        const long long measured = scan_measured_count(scan, k);
        if (measured == 0) continue;
        const std::size_t outside = k < scan.outside.size() ? scan.outside[k].size() : 0;
        const double weight = trial.frames[k].weight;
        const int index = trial.frames[k].number - 1;
        if (index < 0 || index >= usable) {
            const double entry = std::sqrt(weight * scan.missing_frame_error_mm2() / static_cast<double>(measured));
            out.insert(out.end(), static_cast<std::size_t>(measured), entry);
            out.insert(out.end(), outside, 0.0);  // same length as a simulated frame's
            continue;
        }
        renderer.render(video::vertices_from_vector(run.simulation.frames[static_cast<std::size_t>(index)]), run.swatch.mesh.triangles,
                        rendered);
        const double scale = 1000.0 * std::sqrt(weight / static_cast<double>(measured));
        for (const double r : scan_residuals_m(scan, k, rendered)) out.push_back(scale * r);
    }
}

// sqrt(w_k / n_k) (simulated - measured) per seen point and axis of a tracks
// trial, in mm (see ClothFitProblem::residuals).
void append_track_residuals(const ClothTrial& trial, const cloth::SwatchRun& run, std::vector<double>& out) {
    const TrackReference& tracks = *trial.tracks;
    const int usable = usable_frames(run);
    const cloth::UvSampler sampler(run.swatch.mesh, tracks.rows, tracks.cols);
    for (std::size_t k = 0; k < trial.frames.size(); ++k) {
        const Eigen::MatrixX3d& measured = tracks.positions_m[k];
        long long seen = 0;
        for (Eigen::Index i = 0; i < measured.rows(); ++i) seen += measured.row(i).allFinite() ? 1 : 0;
        if (seen == 0) continue;
        const double weight = trial.frames[k].weight;
        const int index = trial.frames[k].number - 1;
        if (index < 0 || index >= usable) {
            const double entry = std::sqrt(weight * tracks.missing_frame_error_mm2 / (3.0 * static_cast<double>(seen)));
            out.insert(out.end(), static_cast<std::size_t>(3 * seen), entry);
            continue;
        }
        const Eigen::MatrixX3d simulated = sampler.sample(run.simulation.frames[static_cast<std::size_t>(index)]);
        const double scale = 1000.0 * std::sqrt(weight / static_cast<double>(seen));
        for (Eigen::Index i = 0; i < measured.rows(); ++i) {
            if (!measured.row(i).allFinite()) continue;
            for (int c = 0; c < 3; ++c) out.push_back(scale * (simulated(i, c) - measured(i, c)));
        }
    }
}

void append_shape_residuals(const ClothTrial& trial, const cloth::SwatchRun& run, std::vector<double>& out) {
    if (trial.scan) append_scan_residuals(trial, run, out);
    else append_track_residuals(trial, run, out);
}

}  // namespace

Eigen::VectorXd ClothFitProblem::residuals(const cloth::ClothMaterial& material, int threads) const {
    if (!all_measure_shape())
        throw std::logic_error("ClothFitProblem::residuals: only tracks and scan trials have residuals");
    std::vector<std::vector<double>> per_trial(m_trials.size());
    auto one = [&](std::size_t t, int simulation_threads) {
        append_shape_residuals(m_trials[t], simulate(t, material, simulation_threads), per_trial[t]);
        if (has_second_mesh(t))
            append_shape_residuals(m_trials[t], simulate_second_mesh(t, material, simulation_threads), per_trial[t]);
    };
    for_each_trial(threads, one);
    std::size_t length = 0;
    for (const std::vector<double>& r : per_trial) length += r.size();
    Eigen::VectorXd all(static_cast<Eigen::Index>(length));
    Eigen::Index at = 0;
    for (const std::vector<double>& r : per_trial)
        for (const double v : r) all(at++) = v;
    return all;
}

optim::Objective ClothFitProblem::objective() const {
    return [this](const Eigen::VectorXd& values, const optim::EvaluationContext& context) {
        return evaluate(material(values), context.spare_threads).total;
    };
}

formats::FabricPreset fitted_preset(const std::string& name, const ClothFitProblem& problem,
                                    const std::vector<formats::Capture>& captures, const cloth::ClothMaterial& material,
                                    const ClothEvaluation& final, std::uint64_t seed,
                                    const optim::VariabilityReport* variability, const std::string& optimizer) {
    if (captures.size() != problem.trials().size())
        throw std::invalid_argument("fitted_preset: " + std::to_string(captures.size()) + " captures for " +
                                    std::to_string(problem.trials().size()) + " trials");
    formats::FabricPreset preset;
    preset.name = name;
    preset.description = "fitted by flowvid from " + std::to_string(captures.size()) + " capture(s)";
    // The trials' swatch mass sets the density the fit saw (experiment_material).
    preset.parameters = cloth::fabric_from_material(cloth::experiment_material(problem.trials().front().experiment, material));
    const optim::ParameterSpace& space = problem.space();
    for (int i = 0; i < space.size(); ++i) {
        const std::string& key = space[i].name;
        std::vector<std::string> members = {key};
        if (key == kStretchTie) members = {"stretch_warp_stiffness_N_per_m", "stretch_weft_stiffness_N_per_m"};
        if (key == kStretchDampingTie) members = {"stretch_warp_damping_N_s_per_m", "stretch_weft_damping_N_s_per_m"};
        for (const std::string& member : members) {
            formats::FabricParameter& p = preset.parameters.*(preset_entry(member)->member);
            p.range = std::array<double, 2>{space[i].lower, space[i].upper};
            if (variability && static_cast<std::size_t>(i) < variability->parameters.size())
                p.uncertainty = variability->parameters[static_cast<std::size_t>(i)].stddev;
        }
    }
    formats::FabricProvenance& prov = preset.provenance;
    prov.method = "fit";
    const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    std::tm utc{};
    gmtime_r(&now, &utc);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", &utc);
    prov.created_utc = stamp;
    for (const formats::Capture& c : captures)
        prov.captures.push_back({c.folder, c.capture_json_sha256, c.kind == "cloth.static" ? "static" : "waving"});
    const video::AngleMapMetricSettings& metric = problem.settings().metric;
    if (problem.trials().front().tracks) {
        // E_k in mm^2: the mean squared distance of the seen track points.
        prov.metric = "tracks_mean_square_mm2";
    } else if (const std::optional<ScanReference>& scan = problem.trials().front().scan) {
        // E_k in mm^2: the mean squared, softly capped depth error at the scan's samples.
        prov.metric = "scan_depth_mean_square_mm2";
        prov.metric_weights["cap_m"] = scan->cap_m;
        if (!scan->outside.empty()) {
            prov.metric_weights["outside_min_px"] = scan->outside_band.min_px;
            prov.metric_weights["outside_max_px"] = scan->outside_band.max_px;
        }
    } else {
        prov.metric = metric.silhouette_term == video::SilhouetteTerm::pixel_xor ? "angle_map+silhouette_xor"
                                                                                     : "angle_map+silhouette_edge_distance";
        prov.metric_weights["alpha"] = metric.alpha;
        if (metric.planar_weight > 0.0) prov.metric_weights["planar_weight"] = metric.planar_weight;
    }
    if (problem.settings().has_second_drape_mesh()) {
        // Each drape also compared on this mesh, at the same weight.
        prov.metric_weights["second_drape_mesh_rows"] = problem.settings().second_drape_rows;
        prov.metric_weights["second_drape_mesh_cols"] = problem.settings().second_drape_cols;
    }
    prov.optimizer = optimizer;
    prov.seed = seed;
    for (std::size_t i = 0; i < final.trials.size() && i < captures.size(); ++i)
        prov.final_errors.push_back({captures[i].folder, final.trials[i].error});
    prov.simulator = "flowvid " + flowvid::version();
    prov.integrator = cloth::integrator_name(problem.settings().swatch.simulation.integrator);
    const cloth::SwatchExperiment& e = problem.trials().front().experiment;
    const int cols = problem.settings().swatch.cols;
    if (cols > 1) prov.swatch_edge_length_m = e.width_m / (cols - 1);
    return preset;
}

}  // namespace flowvid::cloth_fit
