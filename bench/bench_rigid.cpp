// Rigid-body inverse simulation: speed of the pieces (Google Benchmark), the
// whole fit of a 40-frame toss on 1 and 2 threads, and the thesis's hybrid
// gradient optimizer against our Levenberg-Marquardt from identical starts.
// Ratios are against the baseline measured in the same run (LM, 1 thread).
//
//   flowvid_bench_rigid                      # everything
//   flowvid_bench_rigid --benchmark_filter=xx  # only the micro benchmarks matching xx, then the tables

#include "flowvid/render/rasterizer.hpp"
#include "flowvid/rigid/fit.hpp"

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

using namespace flowvid;
using namespace flowvid::rigid;

namespace {

const std::string kCapture = std::string(FLOWVID_SHARED_DIR) + "/captures/rigid-toss-major";

Eigen::Vector3d vec3(const nlohmann::json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

struct Setup {
    formats::Capture capture;
    RigidBody body;
    FlightParameters truth;  // evaluation only
    std::vector<FrameObservation> real_half;   // frames 1-18
    std::vector<FrameObservation> synthetic40;  // 40 frames rendered from the truth
};

const Setup& setup() {
    static const Setup s = [] {
        Setup s;
        s.capture = formats::read_capture(kCapture);
        s.body = RigidBody::from_capture(*s.capture.rigid);
        std::ifstream file(kCapture + "/truth/truth.json");
        std::stringstream text;
        text << file.rdbuf();
        const nlohmann::json t = nlohmann::json::parse(text.str());
        s.truth.com_m = vec3(t["initial"]["com_cam"]);
        const nlohmann::json& q = t["initial"]["orientation_cam_wxyz"];
        s.truth.orientation = Eigen::Quaterniond(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(), q[3].get<double>());
        s.truth.com_velocity_m_per_s = vec3(t["initial"]["com_velocity_cam"]);
        s.truth.angular_velocity_rad_per_s = vec3(t["initial"]["angular_velocity_cam"]);
        s.truth.gravity = GravityAngles::from_vector(vec3(t["gravity_cam"]));
        s.real_half = load_observations(s.capture, 1, 18, 1);
        // A 40-frame toss: the same throw simulated longer, masks = coverage (5x5 samples) >= 0.5.
        std::vector<double> times;
        for (int i = 0; i < 40; ++i) times.push_back(i / s.capture.fps);
        const Trajectory trajectory = simulate(s.body, s.truth, times);
        for (std::size_t i = 0; i < times.size(); ++i) {
            std::vector<Eigen::Vector3d> vertices;
            for (const Eigen::Vector3d& v : s.body.mesh.vertices_m) vertices.push_back(trajectory.states[i].to_camera(s.body, v));
            render::RasterSettings raster;
            raster.supersampling = 5;
            const render::Framebuffer fb =
                render::rasterize(vertices, s.body.mesh.triangles, render::VertexSpace::camera, *s.capture.camera, raster);
            metrics::Silhouette mask(s.capture.camera->width, s.capture.camera->height);
            mask.pixels = fb.silhouette(0.5f);
            s.synthetic40.push_back(make_frame_observation(std::move(mask), static_cast<int>(i) + 1, times[i]));
        }
        return s;
    }();
    return s;
}

double deg(double rad) { return rad * 180.0 / M_PI; }

struct Errors {
    double gravity_deg, orientation_deg, spin_percent;
};
Errors errors(const FlightParameters& p, const FlightParameters& truth, const RigidBody& body) {
    return {deg(std::acos(std::clamp(p.gravity.direction().dot(truth.gravity.direction()), -1.0, 1.0))),
            deg(orientation_distance_rad(p.orientation, truth.orientation, body.symmetries)),
            100.0 * (p.angular_velocity_rad_per_s - truth.angular_velocity_rad_per_s).norm() / truth.angular_velocity_rad_per_s.norm()};
}

// ---- Micro benchmarks ------------------------------------------------------------------

void BM_Simulate36Frames(benchmark::State& state) {
    const Setup& s = setup();
    SimulationSettings settings;
    settings.sensitivities = state.range(0) != 0;
    std::vector<double> times;
    for (int i = 0; i < 36; ++i) times.push_back(i / 30.0);
    for (auto _ : state) benchmark::DoNotOptimize(simulate(s.body, s.truth, times, settings));
}
BENCHMARK(BM_Simulate36Frames)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_EdgeCostOneFrame(benchmark::State& state) {
    const Setup& s = setup();
    const SilhouetteModel model(s.body, *s.capture.camera);
    SilhouetteModel::Scratch scratch;
    const Pose pose = Pose::of(s.truth.initial_state());
    PoseNormalEquations normal;
    for (auto _ : state)
        benchmark::DoNotOptimize(model.edge_cost(pose, s.real_half[0], scratch, state.range(0) ? &normal : nullptr));
}
BENCHMARK(BM_EdgeCostOneFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_XorOneFrame(benchmark::State& state) {
    const Setup& s = setup();
    const SilhouetteModel model(s.body, *s.capture.camera);
    SilhouetteModel::Scratch scratch;
    const Pose pose = Pose::of(s.truth.initial_state());
    for (auto _ : state) benchmark::DoNotOptimize(model.overlap(pose, s.real_half[0], scratch));
}
BENCHMARK(BM_XorOneFrame)->Unit(benchmark::kMicrosecond);

void BM_RasterizeFullImage(benchmark::State& state) {
    const Setup& s = setup();
    std::vector<Eigen::Vector3d> vertices;
    for (const Eigen::Vector3d& v : s.body.mesh.vertices_m) vertices.push_back(s.truth.initial_state().to_camera(s.body, v));
    render::RasterSettings raster;
    raster.supersampling = static_cast<int>(state.range(0));
    render::Framebuffer fb;
    for (auto _ : state)
        render::rasterize(render::MeshView{&vertices, &s.body.mesh.triangles}, render::VertexSpace::camera, *s.capture.camera,
                          raster, fb);
}
BENCHMARK(BM_RasterizeFullImage)->Arg(1)->Arg(4)->Unit(benchmark::kMicrosecond);

void BM_NormalEquations18Frames(benchmark::State& state) {
    const Setup& s = setup();
    const SilhouetteModel model(s.body, *s.capture.camera);
    const FlightProblem problem(model, s.real_half, 0, s.real_half.size());
    SilhouetteModel::Scratch scratch;
    ParameterMatrix H;
    ParameterVector g;
    for (auto _ : state) benchmark::DoNotOptimize(problem.normal_equations(s.truth, scratch, H, g));
}
BENCHMARK(BM_NormalEquations18Frames)->Unit(benchmark::kMillisecond);

// ---- Tables ------------------------------------------------------------------------------

template <typename F>
double seconds_of(F&& f) {
    const auto start = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The silhouette cost's nearest-piece search for every observed outline point
// of a real frame at the true pose and 2 cm beside it: the scan (baseline) against
// the grid (what edge_cost uses), the grid's build included.
void nearest_piece_table() {
    const Setup& s = setup();
    const SilhouetteModel model(s.body, *s.capture.camera);
    SilhouetteModel::Scratch scratch;
    std::printf("\nNearest contour piece for every outline point (real frame 1), 200 repeats:\n");
    std::printf("%-16s %8s %8s %12s %12s %8s %10s\n", "pose", "pieces", "points", "scan ms", "grid ms", "ratio", "same");
    for (double offset_m : {0.0, 0.02}) {
        Pose pose = Pose::of(s.truth.initial_state());
        pose.com_m.x() += offset_m;
        model.contour(pose, scratch);
        std::vector<Segment2> segments;
        for (const ContourPiece& p : scratch.pieces) segments.push_back({p.pixel_a, p.pixel_b});
        const std::vector<Eigen::Vector2d>& points = s.real_half[0].edge_points_px;
        constexpr int kRepeats = 200;
        double checksum_scan = 0.0, checksum_grid = 0.0;
        const double scan_s = seconds_of([&] {
            for (int r = 0; r < kRepeats; ++r)
                for (const Eigen::Vector2d& q : points) checksum_scan += nearest_segment_by_scan(segments, q).distance2_px2;
        });
        NearestSegmentGrid grid;
        const double grid_s = seconds_of([&] {
            for (int r = 0; r < kRepeats; ++r) {
                grid.build(segments);
                for (const Eigen::Vector2d& q : points) checksum_grid += grid.nearest(q).distance2_px2;
            }
        });
        std::printf("%-16s %8zu %8zu %12.3f %12.3f %8.3f %10s\n", offset_m == 0.0 ? "true" : "2 cm off", segments.size(),
                    points.size(), 1e3 * scan_s / kRepeats, 1e3 * grid_s / kRepeats, grid_s / scan_s,
                    checksum_scan == checksum_grid ? "yes" : "NO");
    }
}

void whole_fit_table() {
    const Setup& s = setup();
    std::printf("\nWhole fit, no guess, 40-frame synthetic toss (major axis), 480x360:\n");
    std::printf("%-10s %10s %8s %10s %10s %10s %10s\n", "threads", "seconds", "ratio", "E px^2", "gravity", "orient", "spin");
    double baseline = 0.0;
    FlightParameters first;
    for (int threads : {1, 2}) {
        FitSettings settings;
        settings.threads = threads;
        FitResult fit;
        const double t = seconds_of([&] { fit = fit_rigid(s.body, *s.capture.camera, s.capture.fps, s.synthetic40, settings); });
        if (threads == 1) {
            baseline = t;
            first = fit.parameters;
        }
        const Errors e = errors(fit.parameters, s.truth, s.body);
        std::printf("%-10d %10.2f %8.2f %10.4f %8.3f d %8.3f d %8.3f %%\n", threads, t, t / baseline, fit.final_cost_px2,
                    e.gravity_deg, e.orientation_deg, e.spin_percent);
        if (threads == 2) {
            const bool same = (fit.parameters.com_m - first.com_m).norm() == 0.0 &&
                              fit.parameters.orientation.coeffs() == first.orientation.coeffs() &&
                              (fit.parameters.angular_velocity_rad_per_s - first.angular_velocity_rad_per_s).norm() == 0.0;
            std::printf("result identical on 1 and 2 threads: %s\n", same ? "yes" : "NO");
        }
    }
}

void optimizer_table() {
    const Setup& s = setup();
    const SilhouetteModel model(s.body, *s.capture.camera);
    const FlightProblem problem(model, s.real_half, 0, s.real_half.size());
    SilhouetteModel::Scratch scratch;
    // The same start for every optimizer: the truth moved by a typical initialisation error.
    ParameterVector offset;
    offset << 0.01, -0.01, 0.03, 0.06, -0.08, 0.05, 0.05, -0.05, 0.05, 0.6, -0.5, 0.8, 0.02, -0.015;
    const FlightParameters start = s.truth.perturbed(offset);
    const Errors e0 = errors(start, s.truth, s.body);
    std::printf("\nOptimizers from the same start (real capture frames 1-18, one thread); start: E %.3f px^2, "
                "gravity %.2f deg, orientation %.2f deg, spin %.1f %%\n",
                problem.cost(start, scratch), e0.gravity_deg, e0.orientation_deg, e0.spin_percent);
    std::printf("%-28s %9s %8s %10s %8s %10s %10s %10s %8s\n", "optimizer", "seconds", "ratio", "E px^2", "ratio", "gravity",
                "orient", "spin", "evals");
    double base_time = 0.0, base_cost = 0.0;
    auto row = [&](const char* name, const std::function<OptimizerResult()>& run) {
        OptimizerResult r;
        const double t = seconds_of([&] { r = run(); });
        const double cost = problem.cost(r.parameters, scratch);
        if (base_time == 0.0) {
            base_time = t;
            base_cost = cost;
        }
        const Errors e = errors(r.parameters, s.truth, s.body);
        std::printf("%-28s %9.2f %8.2f %10.4f %8.2f %8.3f d %8.3f d %8.3f %% %8d\n", name, t, t / base_time, cost, cost / base_cost,
                    e.gravity_deg, e.orientation_deg, e.spin_percent, r.report.cost_evaluations);
    };
    row("levenberg_marquardt", [&] {
        LmSettings lm;
        lm.max_iterations = 60;
        lm.relative_tolerance = 1e-6;
        return levenberg_marquardt(problem, start, lm, scratch);
    });
    for (int iterations : {20, 100}) {
        for (HybridMetric metric : {HybridMetric::edge_distance, HybridMetric::xor_pixels}) {
            HybridSettings h;
            h.max_iterations = iterations;
            h.metric = metric;
            if (metric == HybridMetric::xor_pixels) {
                h.position_step_m = 0.005;
                h.rotation_step_rad = 0.03;
                h.gravity_step_rad = 0.005;
            }
            char name[64];
            std::snprintf(name, sizeof name, "hybrid %s, %d iterations", metric == HybridMetric::xor_pixels ? "xor" : "edge", iterations);
            row(name, [&] { return hybrid_gradient(problem, start, h, scratch); });
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    nearest_piece_table();
    whole_fit_table();
    optimizer_table();
    return 0;
}
