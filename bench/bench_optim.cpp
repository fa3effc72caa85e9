// Costs and quality of the cloth-fitting building blocks.
//
//   flowvid_bench_optim                 Google Benchmark timings: stripe render,
//                                       angle map and metric of one 480x360
//                                       frame (the per-frame cost of a fit), and
//                                       annealing runs on test functions.
//   flowvid_bench_optim --report        tables for docs/cloth_fitting.md:
//                                       annealing vs plain simplex success rates
//                                       and evaluation counts (20 shifted
//                                       instances), grid vs Halton starts.

#include "flowvid/optim/annealing.hpp"
#include "flowvid/optim/test_functions.hpp"
#include "flowvid/video/angle_map.hpp"
#include "flowvid/video/angle_map_metric.hpp"
#include "flowvid/video/cloth_footage.hpp"
#include "flowvid/video/stripe_render.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>

using namespace flowvid;

namespace {

// One frame of the static cotton capture and its truth mesh, loaded once.
struct FrameFixture {
    formats::Capture capture;
    video::ReferenceFrame real;
    std::vector<Eigen::Vector3d> vertices;
    std::vector<std::array<int, 3>> triangles;
    video::AngleMapSettings settings;

    FrameFixture() {
        capture = formats::read_capture(std::string(FLOWVID_SHARED_DIR) + "/captures/cloth-cotton-static-1");
        video::ClothFootage footage(capture);
        const video::ClothFrame frame = footage.frame(1);
        settings = video::AngleMapSettings::for_stripe_period(video::expected_stripe_period_px(capture));
        video::AngleMapper mapper(settings);
        real.silhouette = frame.silhouette;
        mapper.compute(frame.gray, frame.silhouette, real.angles);
        video::prepare_reference(real);
        const auto truth = formats::read_capture_truth_positions(capture);  // a mesh to render; not a fit
        vertices = video::vertices_of_frame(*truth, 0);
        triangles = video::grid_triangles(24, 24);
    }
};

FrameFixture& fixture() {
    static FrameFixture f;
    return f;
}

void BM_StripeRender(benchmark::State& state) {
    FrameFixture& f = fixture();
    video::StripeRenderer renderer(*f.capture.camera, *f.capture.projector);
    video::StripeImage out;
    for (auto _ : state) {
        renderer.render(f.vertices, f.triangles, out);
        benchmark::DoNotOptimize(out.image.pixels.data());
    }
}
BENCHMARK(BM_StripeRender)->Unit(benchmark::kMillisecond);

void BM_AngleMap(benchmark::State& state) {
    FrameFixture& f = fixture();
    video::StripeRenderer renderer(*f.capture.camera, *f.capture.projector);
    const video::StripeImage rendered = renderer.render(f.vertices, f.triangles);
    video::AngleMapper mapper(f.settings);
    video::AngleMap map;
    for (auto _ : state) {
        mapper.compute(rendered.image, rendered.silhouette, map);
        benchmark::DoNotOptimize(map.angle_rad.data());
    }
}
BENCHMARK(BM_AngleMap)->Unit(benchmark::kMillisecond);

void BM_Metric(benchmark::State& state) {
    FrameFixture& f = fixture();
    video::StripeRenderer renderer(*f.capture.camera, *f.capture.projector);
    const video::StripeImage rendered = renderer.render(f.vertices, f.triangles);
    video::AngleMapper mapper(f.settings);
    const video::AngleMap map = mapper.compute(rendered.image, rendered.silhouette);
    video::AngleMapMetricSettings settings;
    settings.silhouette_term = state.range(0) ? video::SilhouetteTerm::edge_distance : video::SilhouetteTerm::pixel_xor;
    for (auto _ : state) benchmark::DoNotOptimize(video::angle_map_frame_error(f.real, map, rendered.silhouette, settings));
}
BENCHMARK(BM_Metric)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Everything one simulated frame costs in a fit.
void BM_FrameError(benchmark::State& state) {
    FrameFixture& f = fixture();
    video::StripeRenderer renderer(*f.capture.camera, *f.capture.projector);
    video::AngleMapper mapper(f.settings);
    video::StripeImage rendered;
    video::AngleMap map;
    for (auto _ : state) {
        renderer.render(f.vertices, f.triangles, rendered);
        mapper.compute(rendered.image, rendered.silhouette, map);
        benchmark::DoNotOptimize(video::angle_map_frame_error(f.real, map, rendered.silhouette));
    }
}
BENCHMARK(BM_FrameError)->Unit(benchmark::kMillisecond);

void BM_AnnealAckley(benchmark::State& state) {
    const int n = static_cast<int>(state.range(0));
    const optim::TestFunction f = optim::ackley(n, 1);
    optim::MinimizeSettings s;
    s.threads = 1;
    long long evaluations = 0;
    for (auto _ : state) {
        const optim::MinimizeResult r =
            optim::minimize([&](const Eigen::VectorXd& x, const optim::EvaluationContext&) { return f.f(x); }, f.space, s);
        evaluations = r.evaluations;
    }
    state.counters["evaluations"] = static_cast<double>(evaluations);
}
BENCHMARK(BM_AnnealAckley)->Arg(2)->Arg(6)->Arg(9)->Unit(benchmark::kMillisecond);

// ---- --report ---------------------------------------------------------------

struct Tally {
    int successes = 0;
    double value = 0.0;
    double evaluations = 0.0;
};

void report_annealing() {
    const int instances = 20;
    std::printf("\nAnnealing vs plain downhill simplex, same Halton start (16 n points), %d shifted instances,\n"
                "at most 30000 evaluations; success = global minimum's basin (f < 0.5)\n\n", instances);
    std::printf("| function | n | annealing: found | mean f | evaluations | simplex: found | mean f | evaluations |\n");
    std::printf("|---|---|---|---|---|---|---|---|\n");
    struct Case {
        optim::TestFunction (*make)(int, std::uint64_t);
        const char* name;
    };
    for (const Case c : {Case{optim::ackley, "Ackley"}, Case{optim::rastrigin, "Rastrigin"}}) {
        for (int n : {2, 4, 6, 9}) {
            Tally tally[2];
            for (int i = 1; i <= instances; ++i) {
                const optim::TestFunction f = c.make(n, static_cast<std::uint64_t>(i));
                for (int k = 0; k < 2; ++k) {
                    optim::MinimizeSettings s;
                    s.threads = 1;
                    s.annealing.seed = static_cast<std::uint64_t>(i);
                    s.annealing.max_evaluations = 30000;
                    s.annealing.initial_temperature = k == 0 ? -1.0 : 0.0;
                    const optim::MinimizeResult r = optim::minimize(
                        [&](const Eigen::VectorXd& x, const optim::EvaluationContext&) { return f.f(x); }, f.space, s);
                    tally[k].successes += r.annealing.best_value < f.success_threshold;
                    tally[k].value += r.annealing.best_value / instances;
                    tally[k].evaluations += static_cast<double>(r.evaluations) / instances;
                }
            }
            std::printf("| %s | %d | %d/%d | %.3f | %.0f | %d/%d | %.3f | %.0f |\n", c.name, n, tally[0].successes,
                        instances, tally[0].value, tally[0].evaluations, tally[1].successes, instances, tally[1].value,
                        tally[1].evaluations);
        }
    }
}

void report_designs() {
    const int instances = 20;
    std::printf("\nStarts: 4^n grid vs scrambled Halton, then annealing from the best point (%d instances)\n\n",
                instances);
    std::printf("| function | n | design | design evaluations | mean best start | annealing found | total evaluations |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    struct Case {
        const char* name;
        int n;
        int active;  // 0: isotropic Rastrigin
    };
    for (const Case c : {Case{"Rastrigin", 4, 0}, Case{"Rastrigin 2 active", 6, 2}, Case{"Rastrigin 2 active", 8, 2},
                         Case{"Rastrigin 3 active", 9, 3}}) {
        const int grid_points = static_cast<int>(std::pow(4, c.n));
        for (int variant = 0; variant < 3; ++variant) {
            const bool grid = variant == 0;
            const int points = grid ? grid_points : grid_points / (variant == 1 ? 16 : 64);
            Tally tally;
            double start = 0.0;
            for (int i = 1; i <= instances; ++i) {
                const optim::TestFunction f = c.active ? optim::rastrigin_low_dimensional(c.n, c.active, i)
                                                       : optim::rastrigin(c.n, i);
                optim::MinimizeSettings s;
                s.threads = 0;
                s.design = grid ? optim::DesignKind::grid : optim::DesignKind::halton;
                s.design_points = points;
                s.annealing.seed = static_cast<std::uint64_t>(i);
                s.annealing.max_evaluations = 400000;
                const optim::MinimizeResult r = optim::minimize(
                    [&](const Eigen::VectorXd& x, const optim::EvaluationContext&) { return f.f(x); }, f.space, s);
                start += r.design.best_value() / instances;
                tally.successes += r.annealing.best_value < f.success_threshold;
                tally.evaluations += static_cast<double>(r.evaluations) / instances;
            }
            std::printf("| %s | %d | %s | %d | %.2f | %d/%d | %.0f |\n", c.name, c.n, grid ? "grid 4^n" : "Halton", points,
                        start, tally.successes, instances, tally.evaluations);
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
    for (int i = 1; i < argc; ++i)
        if (std::strcmp(argv[i], "--report") == 0) {
            report_annealing();
            report_designs();
            return 0;
        }
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
