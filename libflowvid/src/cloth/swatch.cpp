#include "flowvid/cloth/swatch.hpp"

#include "flowvid/error.hpp"
#include "flowvid/random.hpp"
#include "flowvid/threads.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace flowvid::cloth {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string pin_field(size_t k, const char* member) {
    return "/swatch/pins/" + std::to_string(k) + "/" + member;
}

// Amplitude A of y = A sin(pi t), t in [0, 1], whose arc length over a chord
// of `span` equals `length` (the slack of a row taken up out of plane).
double bow_amplitude(double span, double length) {
    if (span >= length) return 0.0;
    auto arc = [&](double A) {
        const int samples = 64;
        double sum = 0.0;
        for (int k = 0; k < samples; ++k) {
            const double t = (k + 0.5) / samples;
            const double dy = A * kPi * std::cos(kPi * t);
            sum += std::sqrt(span * span + dy * dy);
        }
        return sum / samples;
    };
    double lo = 0.0, hi = length;
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (arc(mid) < length ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

}  // namespace

SwatchExperiment experiment_from_capture(const formats::Capture& capture) {
    if (!capture.swatch) {
        Diagnostics diagnostics(capture.json_path);
        diagnostics.error("/swatch", "this capture (kind " + capture.kind + ") describes no swatch",
                          "use a cloth.static or cloth.waving capture");
        diagnostics.throw_if_errors();
    }
    SwatchExperiment e;
    e.source = capture.json_path;
    e.width_m = capture.swatch->width_m;
    e.height_m = capture.swatch->height_m;
    e.mass_kg = capture.swatch->mass_kg;
    e.fps = capture.fps;
    e.frame_count = capture.frames.count;
    for (const formats::Pin& pin : capture.swatch->pins) e.pins.push_back({pin.uv, pin.positions_m});
    return e;
}

Swatch build_swatch(const SwatchExperiment& experiment, int rows, int cols) {
    Diagnostics diagnostics(experiment.source);
    if (!(experiment.width_m > 0.0) || !std::isfinite(experiment.width_m))
        diagnostics.error("/swatch/width_m", "must be a positive length in metres", "give the swatch width, e.g. 0.30");
    if (!(experiment.height_m > 0.0) || !std::isfinite(experiment.height_m))
        diagnostics.error("/swatch/height_m", "must be a positive length in metres", "give the swatch height, e.g. 0.30");
    if (!(experiment.mass_kg >= 0.0) || !std::isfinite(experiment.mass_kg))
        diagnostics.error("/swatch/mass_kg", "must be >= 0 (0 uses the material's areal density)",
                          "give the swatch mass in kg");
    if (!(experiment.fps > 0.0) || !std::isfinite(experiment.fps))
        diagnostics.error("/fps", "must be positive", "give the capture's frame rate, e.g. 30");
    if (experiment.frame_count < 1) diagnostics.error("/frames/count", "must be at least 1", "give the number of frames");
    if (rows < 2 || cols < 2)
        diagnostics.error("grid", "the simulation grid needs at least 2 x 2 vertices, not " + std::to_string(rows) + " x " +
                                      std::to_string(cols),
                          "use e.g. --grid 24x24");
    if (experiment.pins.empty())
        diagnostics.error("/swatch/pins", "a swatch experiment needs at least one pinned point",
                          "pin the corners the swatch hangs from");
    std::vector<int> used;
    Swatch swatch;
    swatch.rows = rows;
    swatch.cols = cols;
    for (size_t k = 0; k < experiment.pins.size(); ++k) {
        const PinTrajectory& pin = experiment.pins[k];
        const bool uv_ok = pin.uv.allFinite() && (pin.uv.array() >= 0.0).all() && (pin.uv.array() <= 1.0).all();
        if (!uv_ok) diagnostics.error(pin_field(k, "uv"), "must lie in [0, 1] x [0, 1]", "give the pinned point's uv, e.g. [0, 1]");
        if (pin.positions_m.empty())
            diagnostics.error(pin_field(k, "positions"), "has no positions", "give one world position per frame");
        else if (experiment.frame_count >= 1 && static_cast<int>(pin.positions_m.size()) != experiment.frame_count)
            diagnostics.error(pin_field(k, "positions"),
                              "has " + std::to_string(pin.positions_m.size()) + " positions but the experiment has " +
                                  std::to_string(experiment.frame_count) + " frames",
                              "give exactly one world position per frame");
        for (size_t f = 0; f < pin.positions_m.size(); ++f)
            if (!pin.positions_m[f].allFinite()) {
                diagnostics.error(pin_field(k, "positions") + "/" + std::to_string(f), "is not finite",
                                  "give finite coordinates in metres");
                break;
            }
        if (uv_ok && rows >= 2 && cols >= 2) {
            const int c = static_cast<int>(std::lround(pin.uv.x() * (cols - 1)));
            const int r = static_cast<int>(std::lround(pin.uv.y() * (rows - 1)));
            const int vertex = r * cols + c;
            if (std::find(used.begin(), used.end(), vertex) != used.end())
                diagnostics.error(pin_field(k, "uv"), "pins the same grid vertex as another pin", "use distinct pin positions");
            used.push_back(vertex);
            if (!pin.positions_m.empty())
                swatch.pins.push_back({vertex, PinPath(pin.positions_m, experiment.fps > 0.0 ? experiment.fps : 30.0, 0.0)});
        }
    }
    diagnostics.throw_if_errors();
    swatch.mesh = make_swatch_mesh(experiment.width_m, experiment.height_m, rows, cols);
    swatch.pinned.assign(static_cast<size_t>(rows * cols), false);
    for (const PinnedVertex& p : swatch.pins) swatch.pinned[static_cast<size_t>(p.vertex)] = true;
    return swatch;
}

ClothMaterial experiment_material(const SwatchExperiment& experiment, const ClothMaterial& material) {
    ClothMaterial m = material;
    if (experiment.mass_kg > 0.0) {
        // The swatch's mass is what was weighed: a hem takes its share off
        // the area's (capped so that the cloth itself keeps 5 %).
        double cloth_mass = experiment.mass_kg;
        if (m.hem_line_density_kg_per_m != 0.0) {
            const double hem_mass = m.hem_line_density_kg_per_m * 2.0 * (experiment.width_m + experiment.height_m);
            cloth_mass = std::max(experiment.mass_kg - hem_mass, 0.05 * experiment.mass_kg);
        }
        m.areal_density_kg_per_m2 = cloth_mass / (experiment.width_m * experiment.height_m);
    }
    return m;
}

MeshFoldCheck check_mesh_folds(const SwatchExperiment& experiment, const ClothMaterial& material, int rows, int cols,
                               double gravity_m_per_s2) {
    const double edge_m = std::max(experiment.width_m / (cols - 1), experiment.height_m / (rows - 1));
    MeshFoldCheck check;
    static_cast<FoldCheck&>(check) = check_folds(experiment_material(experiment, material), edge_m, gravity_m_per_s2);
    if (check.fold_length_m > 0.0)
        check.rows_needed = static_cast<int>(std::ceil(std::max(experiment.width_m, experiment.height_m) / check.longest_edge_m)) + 1;
    return check;
}

Eigen::VectorXd hanging_start(const Swatch& swatch, const SwatchExperiment& experiment, double bow) {
    const int rows = swatch.rows, cols = swatch.cols;
    const double W = experiment.width_m, H = experiment.height_m;
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    // The two pins furthest apart in u define the hanging frame.
    size_t a = 0, b = 0;
    for (size_t i = 0; i < experiment.pins.size(); ++i)
        for (size_t j = 0; j < experiment.pins.size(); ++j)
            if (experiment.pins[j].uv.x() - experiment.pins[i].uv.x() > experiment.pins[b].uv.x() - experiment.pins[a].uv.x()) {
                a = i;
                b = j;
            }
    const PinTrajectory& pa = experiment.pins[a];
    const PinTrajectory& pb = experiment.pins[b];
    const Eigen::Vector3d Pa = pa.positions_m.front(), Pb = pb.positions_m.front();
    Eigen::Vector3d horizontal = Pb - Pa;
    horizontal -= horizontal.dot(up) * up;
    const double du = pb.uv.x() - pa.uv.x();
    const bool two = a != b && du > 0.0;
    Eigen::Vector3d eh = Eigen::Vector3d::UnitX();
    if (two && horizontal.norm() > 1e-9) eh = horizontal.normalized();
    const Eigen::Vector3d front = eh.cross(up);  // u x v as hung
    const double material_span = du * W;
    const double ratio = two ? std::min(1.0, horizontal.norm() / material_span) : 1.0;
    const double v_pins = two ? 0.5 * (pa.uv.y() + pb.uv.y()) : pa.uv.y();
    const Eigen::Vector3d mid = two ? 0.5 * (Pa + Pb) : Pa;
    const double u_mid = two ? 0.5 * (pa.uv.x() + pb.uv.x()) : pa.uv.x();

    Eigen::VectorXd x(3 * rows * cols);
    for (int r = 0; r < rows; ++r) {
        const double v = static_cast<double>(r) / (rows - 1);
        // Compressed to the pins' separation at their row, full width far below.
        const double below = v_pins > 0.0 ? std::clamp((v_pins - v) / v_pins, 0.0, 1.0) : 1.0;
        const double sigma = ratio + (1.0 - ratio) * below;
        const double amplitude = two ? bow * bow_amplitude(sigma * material_span, material_span) : 0.0;
        for (int c = 0; c < cols; ++c) {
            const double u = static_cast<double>(c) / (cols - 1);
            const double t = two ? (u - pa.uv.x()) / du : 0.0;
            const double height_at_u = two ? Pa.dot(up) + std::clamp(t, 0.0, 1.0) * (Pb - Pa).dot(up) : Pa.dot(up);
            Eigen::Vector3d p = mid + eh * ((u - u_mid) * W * sigma);
            p += up * (height_at_u - (v_pins - v) * H - p.dot(up));
            if (two && t > 0.0 && t < 1.0) p += front * (amplitude * std::sin(kPi * t));
            x.segment<3>(3 * (r * cols + c)) = p;
        }
    }
    for (const PinnedVertex& p : swatch.pins) x.segment<3>(3 * p.vertex) = p.path.position(0.0);
    return x;
}

namespace {

// Gaussian offsets per coordinate of every free vertex, sigma = rms / sqrt(3)
// so the RMS vertex offset is `rms_m`.
Eigen::VectorXd per_vertex_jitter(const Swatch& swatch, double rms_m, std::uint64_t seed) {
    Random random(seed);
    const double sigma = rms_m / std::sqrt(3.0);
    Eigen::VectorXd offset = Eigen::VectorXd::Zero(3 * swatch.mesh.vertex_count());
    for (int i = 0; i < swatch.mesh.vertex_count(); ++i)
        if (!swatch.pinned[static_cast<std::size_t>(i)])
            for (int k = 0; k < 3; ++k) offset(3 * i + k) = random.normal(0.0, sigma);
    return offset;
}

// Offsets along the area-weighted vertex normals of `x`, a sum of the cosine
// modes cos(pi p u) cos(pi q v), p, q in 0..3, with N(0, 1) amplitudes,
// scaled so the RMS over free vertices is `rms_m`. Pinned vertices stay.
Eigen::VectorXd smooth_normal_jitter(const Swatch& swatch, const Eigen::VectorXd& x, double rms_m, std::uint64_t seed) {
    constexpr int kModes = 4;
    Random random(seed);
    double amplitude[kModes][kModes];
    for (auto& row : amplitude)
        for (double& a : row) a = random.normal();
    const int n = swatch.mesh.vertex_count();
    std::vector<Eigen::Vector3d> normals(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
    for (const auto& t : swatch.mesh.triangles) {
        const Eigen::Vector3d a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
        const Eigen::Vector3d area_normal = (b - a).cross(c - a);  // twice the area, along the normal
        for (int v : t) normals[static_cast<std::size_t>(v)] += area_normal;
    }
    Eigen::VectorXd offset = Eigen::VectorXd::Zero(3 * n);
    double sum_squares = 0.0;
    int free_count = 0;
    for (int r = 0; r < swatch.rows; ++r)
        for (int c = 0; c < swatch.cols; ++c) {
            const int i = r * swatch.cols + c;
            if (swatch.pinned[static_cast<std::size_t>(i)] || normals[static_cast<std::size_t>(i)].norm() == 0.0) continue;
            const double u = swatch.cols > 1 ? static_cast<double>(c) / (swatch.cols - 1) : 0.0;
            const double v = swatch.rows > 1 ? static_cast<double>(r) / (swatch.rows - 1) : 0.0;
            double height = 0.0;
            for (int p = 0; p < kModes; ++p)
                for (int q = 0; q < kModes; ++q) height += amplitude[p][q] * std::cos(kPi * p * u) * std::cos(kPi * q * v);
            offset.segment<3>(3 * i) = height * normals[static_cast<std::size_t>(i)].normalized();
            sum_squares += height * height;
            ++free_count;
        }
    if (sum_squares > 0.0) offset *= rms_m / std::sqrt(sum_squares / free_count);
    return offset;
}

}  // namespace

std::optional<std::pair<int, int>> mesh_size_from_text(const std::string& text) {
    int rows = 0, cols = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &rows, &x, &cols, &extra) == 3 && (x == 'x' || x == 'X') && rows >= 2 &&
        cols >= 2 && rows <= 512 && cols <= 512)
        return std::make_pair(rows, cols);
    return std::nullopt;
}

SwatchOptions run_swatch_options(int rows, int cols, Integrator integrator, double initial_bow, int threads) {
    SwatchOptions swatch;
    swatch.rows = rows;
    swatch.cols = cols;
    swatch.simulation.integrator = integrator;
    swatch.simulation.threads = resolve_thread_count(threads);
    swatch.initial_bow = initial_bow;
    if (integrator == Integrator::rk4_adaptive || integrator == Integrator::dopri54 ||
        integrator == Integrator::bogacki_shampine32)
        swatch.simulation.position_tolerance_m = 1e-4;
    return swatch;
}

SwatchRun simulate_swatch(const SwatchExperiment& experiment, const ClothMaterial& material, const SwatchOptions& options,
                          const Progress& progress) {
    SwatchRun run;
    run.swatch = build_swatch(experiment, options.rows, options.cols);
    ClothModel model(run.swatch.mesh, experiment_material(experiment, material), options.environment);
    Eigen::VectorXd x = options.initial_positions.size() == 3 * model.vertex_count()
                            ? options.initial_positions
                            : hanging_start(run.swatch, experiment, options.initial_bow);
    for (const PinnedVertex& p : run.swatch.pins) x.segment<3>(3 * p.vertex) = p.path.position(0.0);
    run.equilibrium = solve_static_equilibrium(model, run.swatch.pinned, x, options.equilibrium);
    if (run.equilibrium.cancelled) {
        run.simulation.report.status = SimulationReport::Status::cancelled;
        run.simulation.report.frame = 0;
        run.simulation.report.reason = "cancelled while solving the static equilibrium";
        run.simulation.frames.push_back(x);
        return run;
    }
    if (!run.equilibrium.converged) {
        run.simulation.report.status = SimulationReport::Status::blew_up;
        run.simulation.report.frame = 1;
        run.simulation.report.reason = "the static equilibrium under the first pin positions was not found: " +
                                       run.equilibrium.reason;
        run.simulation.frames.push_back(x);
        return run;
    }
    if (options.initial_jitter_m > 0.0) {
        if (options.jitter_shape == SwatchOptions::JitterShape::smooth_normal)
            x += smooth_normal_jitter(run.swatch, x, options.initial_jitter_m, options.jitter_seed);
        else
            x += per_vertex_jitter(run.swatch, options.initial_jitter_m, options.jitter_seed);
    }
    run.simulation = simulate(model, run.swatch.pins, x, Eigen::VectorXd::Zero(x.size()), 0.0, experiment.fps,
                              experiment.frame_count, options.simulation, progress);
    return run;
}

std::vector<Eigen::MatrixX3d> sample_frames(const ClothMesh& mesh, const std::vector<Eigen::VectorXd>& frames, int rows,
                                            int cols) {
    const UvSampler sampler(mesh, rows, cols);
    std::vector<Eigen::MatrixX3d> out;
    out.reserve(frames.size());
    for (const Eigen::VectorXd& f : frames) out.push_back(sampler.sample(f));
    return out;
}

}  // namespace flowvid::cloth
