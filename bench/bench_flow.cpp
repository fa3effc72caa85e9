// Flow-based video: speed of synthesis, editing, tracking and the editing
// correspondence, and measured quality on the real clips against two
// baselines (naive looping; the flow-map method games use). Speeds are also
// given as ratios against the flow-map baseline measured in the same run.
//
//   flowvid_bench_flow                         # everything (a few minutes: it tracks both real clips)
//   flowvid_bench_flow --benchmark_filter=xx   # only the micro benchmarks matching xx, then the tables
//   FLOWVID_BENCH_FLOW_QUICK=1 flowvid_bench_flow   # skip the real-clip quality table

#include "flowvid/flow/editing.hpp"
#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/quality.hpp"
#include "flowvid/flow/stabilise.hpp"
#include "flowvid/flow/synthesis_job.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/flow/synthetic.hpp"
#include "flowvid/flow/tracking.hpp"
#include "flowvid/flow/tracking_job.hpp"
#include "flowvid/formats/particle_bank.hpp"
#include "flowvid/random.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// ---- the speed scenes ---------------------------------------------------------------------------
// 53 vertical lines one patch apart across the frame, particles entering
// every frame at half a patch per frame and living 60 frames (crossing the
// frame's height): 3180 patches on screen per frame. Textures are random
// (tracking is not what is measured here). 1280 x 720 uses 24 px patches;
// 1920 x 1080 scales lines, patches and speeds with the frame (36 px). The
// scene is held in memory and goes through the same prepare_synthesis as
// `flowvid synth` and `edit` (SynthesisSources): a still grey clip whose
// median plate is the background, the drawing's input lines and, for edits,
// every input line bent into a sine.
struct Scene {
    int width = 0, height = 0, patch = 0;
    std::shared_ptr<formats::ParticleBank> bank;
    formats::FlowLineSet drawing;                 // input lines and the bent output lines
    std::shared_ptr<const ClipFrames> grey_clip;  // median plate: grey 0.2
    PreparedSynthesis synthesis;                  // defaults, plain synthesis
};

// Output lines for the edit benchmark: every input line bent into a sine.
std::vector<formats::FlowLine> bent_lines(const formats::FlowLineSet& drawing, int patch, int height) {
    const double scale = patch / 24.0;
    std::vector<formats::FlowLine> out;
    for (const formats::FlowLine& in : drawing.inputs) {
        formats::FlowLine o;
        o.id = "out-" + in.id.substr(3);
        o.from = in.id;
        for (int y = 0; y <= height; y += 20) o.points.emplace_back(in.points[0].x() + 20.0 * scale * std::sin(y / (90.0 * scale)), y);
        out.push_back(o);
    }
    return out;
}

// The scene through prepare_synthesis: plain synthesis or the edit (drawn
// output lines, as `flowvid edit --no-interpolate`), over `clip` (the grey
// clip when null) with the background asked for.
PreparedSynthesis prepare_scene(const Scene& s, const SynthesisSettings& settings, bool edit = false,
                                const std::string& background = "median",
                                std::shared_ptr<const ClipFrames> clip = nullptr) {
    SynthesisSources sources;
    sources.bank = s.bank;
    sources.drawing = s.drawing;
    sources.drawing_name = "bench scene";
    sources.clip = clip ? std::move(clip) : s.grey_clip;
    SynthesisJob job;
    job.settings = settings;
    job.background = background;
    job.edit = edit;
    job.interpolate = false;
    return prepare_synthesis(std::move(sources), job);
}

Scene make_scene(int width, int height, int patch) {
    Scene s;
    s.width = width;
    s.height = height;
    s.patch = patch;
    auto bank = std::make_shared<formats::ParticleBank>();
    const int life = 61, count = 8;
    const double spacing = patch, speed = 0.5 * patch;
    bank->patch_size_px = patch;
    bank->clip_width_px = width;
    bank->clip_height_px = height;
    bank->clip_frame_count = count + life;
    s.drawing.width = width;
    s.drawing.height = height;
    Random random(1);
    for (int l = 0; l < 53; ++l) {
        const double x = 2.0 * patch / 3.0 + spacing * l;
        const std::string id = "in-" + std::to_string(l);
        bank->lines.push_back({id, static_cast<float>(height)});
        s.drawing.inputs.push_back({id, {{x, 0.0}, {x, static_cast<double>(height)}}});
        for (int p = 0; p < count; ++p) {
            formats::TrackedParticle particle;
            particle.line_id = id;
            particle.start_frame = p;
            for (int a = 0; a < life; ++a) {
                particle.arc_length_px.push_back(static_cast<float>(speed * a));
                for (int t = 0; t < patch * patch; ++t) {
                    const float r = static_cast<float>(random.uniform(0.05, 0.95));
                    const float g = static_cast<float>(random.uniform(0.05, 0.95));
                    const float b = static_cast<float>(random.uniform(0.05, 0.95));
                    particle.texture_rgba.insert(particle.texture_rgba.end(), {r, g, b, 1.0f});
                }
            }
            bank->particles.push_back(std::move(particle));
        }
    }
    s.drawing.outputs = bent_lines(s.drawing, patch, height);
    s.bank = bank;
    auto grey = std::make_shared<ClipFrames>(width, height, 25.0, "grey");
    for (int i = 0; i < 3; ++i) grey->append(RgbImage(width, height, 0.2f));
    s.grey_clip = grey;
    s.synthesis = prepare_scene(s, SynthesisSettings{});
    return s;
}

const Scene& scene() {
    static const Scene s = make_scene(1280, 720, 24);
    return s;
}

const Scene& scene_1080p() {
    static const Scene s = make_scene(1920, 1080, 36);
    return s;
}

FlowMapBaseline make_flow_map(const Scene& s) {
    const RgbImage plate = s.grey_clip->display(0);
    return FlowMapBaseline(velocity_field(*s.synthesis.streams, s.width, s.height, 0.5 * s.patch), plate, plate, 32);
}

const FlowMapBaseline& flow_map() {
    static const FlowMapBaseline baseline = make_flow_map(scene());
    return baseline;
}

void BM_SynthesisFrame1280x720(benchmark::State& state) {
    const Synthesizer& synth = *scene().synthesis.synthesizer;
    int frame = 1;
    for (auto _ : state) benchmark::DoNotOptimize(synth.render(frame++).rgb.data());
    state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SynthesisFrame1280x720)->Unit(benchmark::kMillisecond);

void BM_SynthesisFrame1920x1080(benchmark::State& state) {
    const Synthesizer& synth = *scene_1080p().synthesis.synthesizer;
    int frame = 1;
    for (auto _ : state) benchmark::DoNotOptimize(synth.render(frame++).rgb.data());
    state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SynthesisFrame1920x1080)->Unit(benchmark::kMillisecond);

void BM_EditFrame1280x720(benchmark::State& state) {
    const PreparedSynthesis edit = prepare_scene(scene(), SynthesisSettings{}, true);
    int frame = 1;
    for (auto _ : state) benchmark::DoNotOptimize(edit.synthesizer->render(frame++).rgb.data());
    state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EditFrame1280x720)->Unit(benchmark::kMillisecond);

void BM_FlowMapBaselineFrame1280x720(benchmark::State& state) {
    int frame = 1;
    for (auto _ : state) benchmark::DoNotOptimize(flow_map().render(frame++).rgb.data());
    state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FlowMapBaselineFrame1280x720)->Unit(benchmark::kMillisecond);

// DP of eq. 3.1 alone: 100 dense lines x 20 candidate input lines.
void BM_DynamicProgramme100x20(benchmark::State& state) {
    Random random(3);
    std::vector<Eigen::MatrixXd> e(99, Eigen::MatrixXd(20, 20));
    for (auto& m : e)
        for (int i = 0; i < 20; ++i)
            for (int j = 0; j < 20; ++j) m(i, j) = random.uniform();
    std::vector<std::vector<int>> allowed(100);
    allowed.front() = {0};
    allowed.back() = {19};
    for (auto _ : state) benchmark::DoNotOptimize(solve_chain(e, allowed, 20).cost);
}
BENCHMARK(BM_DynamicProgramme100x20)->Unit(benchmark::kMicrosecond);

// ---- tables -------------------------------------------------------------------------------------------

// Rows of a speed table: wall-clock frames/s over `frames` frames, as a
// ratio to the first row (the flow map), and the process's CPU time per frame
// (all threads: on a loaded machine it shows whether the threads got their cores).
struct SpeedRows {
    int frames = 60;
    double flow_map_fps = 0.0;  // the first row's
    double row(const std::string& name, const std::function<void(int)>& render_range) {
        const std::clock_t cpu_start = std::clock();
        const auto start = std::chrono::steady_clock::now();
        render_range(frames);
        const double fps = frames / seconds_since(start);
        const double cpu_ms = 1000.0 * static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC / frames;
        if (flow_map_fps == 0.0) flow_map_fps = fps;
        std::printf("%-58s %8.1f %10.2f %12.1f\n", name.c_str(), fps, fps / flow_map_fps, cpu_ms);
        return fps;
    }
};

void speed_table() {
    std::printf("\n== Speed at 1280 x 720, 24 x 24 patches (53 lines, 3180 patches per frame) ==\n");
    const Synthesizer& synth = *scene().synthesis.synthesizer;
    const PreparedSynthesis edit = prepare_scene(scene(), SynthesisSettings{}, true);
    SpeedRows rows{60};
    const auto row = [&](const std::string& name, const std::function<void(int)>& render_range) { rows.row(name, render_range); };
    const auto frames_of = [](const Synthesizer& synthesizer, int threads) {
        return [&synthesizer, threads](int frames) {
            synthesizer.render_frames(1, frames, threads, [](int, const RgbImage&) { return true; });
        };
    };
    // The default: the detail gain with overlap sharpness 4; the others for comparison.
    SynthesisSettings plain;
    plain.preserve_detail = false;
    const PreparedSynthesis plain_synth = prepare_scene(scene(), plain);
    SynthesisSettings before;  // the default before overlap sharpening
    before.overlap_sharpness = 1.0;
    const PreparedSynthesis before_synth = prepare_scene(scene(), before);
    SynthesisSettings mixed = plain;  // the weighted mean alone
    mixed.overlap_sharpness = 1.0;
    const PreparedSynthesis mixed_synth = prepare_scene(scene(), mixed);
    SynthesisSettings whole_frame;
    whole_frame.reference_rendering = true;
    const PreparedSynthesis whole_frame_synth = prepare_scene(scene(), whole_frame);
    const Synthesizer& reference = *whole_frame_synth.synthesizer;
    std::printf("%-58s %8s %10s %12s\n", "", "fps", "vs flow map", "CPU ms/frame");
    row("flow-map baseline (1 thread)", [](int frames) {
        for (int f = 1; f <= frames; ++f) benchmark::DoNotOptimize(flow_map().render(f).rgb.data());
    });
    for (int threads : {1, 2})
        row("synthesis (default: detail gain, overlap sharpness 4), " + std::to_string(threads) + " thread(s)",
            frames_of(synth, threads));
    for (int threads : {1, 2})
        row("  same, whole-frame pass (reference_rendering), " + std::to_string(threads) + " thread(s)",
            frames_of(reference, threads));
    for (int threads : {1, 2})
        row("  plain blending (--blend plain), " + std::to_string(threads) + " thread(s)", frames_of(*plain_synth.synthesizer, threads));
    for (int threads : {1, 2})
        row("  detail gain, sharpness 1 (before), " + std::to_string(threads) + " thread(s)", frames_of(*before_synth.synthesizer, threads));
    for (int threads : {1, 2})
        row("  weighted mean (plain, sharpness 1), " + std::to_string(threads) + " thread(s)",
            frames_of(*mixed_synth.synthesizer, threads));
    // --background relit: the plate darkened frame by frame as a replayed
    // clip is lit (a short random clip, replayed modulo its length).
    auto relit_clip = std::make_shared<ClipFrames>(1280, 720, 25.0, "bench");
    {
        Random random(2);
        RgbImage frame(1280, 720);
        for (int i = 0; i < 8; ++i) {
            for (float& v : frame.rgb) v = static_cast<float>(random.uniform());
            relit_clip->append(frame);
        }
    }
    const PreparedSynthesis relit_synth = prepare_scene(scene(), SynthesisSettings{}, false, "relit", relit_clip);
    for (int threads : {1, 2})
        row("  relit background (--background relit), " + std::to_string(threads) + " thread(s)",
            frames_of(*relit_synth.synthesizer, threads));
    SynthesisSettings carry;
    carry.carry_background = true;
    const PreparedSynthesis edit_carry = prepare_scene(scene(), carry, true);
    for (int threads : {1, 2})
        row("edit (warped, bent lines), " + std::to_string(threads) + " thread(s)", frames_of(*edit.synthesizer, threads));
    for (int threads : {1, 2})
        row("  same, --carry-background, " + std::to_string(threads) + " thread(s)", frames_of(*edit_carry.synthesizer, threads));
    float worst = 0.0f;
    for (int f : {1, 17, 40}) {
        const RgbImage a = synth.render(f), b = reference.render(f);
        for (std::size_t i = 0; i < a.rgb.size(); ++i) worst = std::max(worst, std::abs(a.rgb[i] - b.rgb[i]));
    }
    std::printf("banded vs whole-frame pass, frames 1, 17, 40: largest difference %.2g\n", worst);
    std::printf("goal: synthesis >= 30 frames/s on 2 cores (the thesis: 320 x 240 at 20 s/frame)\n");
}

// The speed goal at full HD: the 1280 x 720 scene scaled with the
// frame (36 px patches one patch apart, 18 px per frame), synthesis against
// the flow map in the same run.
void speed_table_1080p() {
    const Scene& s = scene_1080p();
    std::printf("\n== Speed at 1920 x 1080, 36 x 36 patches (53 lines, 3180 patches per frame) ==\n");
    const FlowMapBaseline flow_map_1080p = make_flow_map(s);
    const Synthesizer& synth = *s.synthesis.synthesizer;
    const PreparedSynthesis edit = prepare_scene(s, SynthesisSettings{}, true);
    SpeedRows rows{40};
    double synthesis_fps = 0.0;
    std::printf("%-58s %8s %10s %12s\n", "", "fps", "vs flow map", "CPU ms/frame");
    const auto row = [&](const std::string& name, const std::function<void(int)>& render_range) {
        return rows.row(name, render_range);
    };
    row("flow-map baseline (1 thread)", [&](int frames) {
        for (int f = 1; f <= frames; ++f) benchmark::DoNotOptimize(flow_map_1080p.render(f).rgb.data());
    });
    for (int threads : {1, 2}) {
        const double fps = row("synthesis (defaults), " + std::to_string(threads) + " thread(s)", [&](int frames) {
            synth.render_frames(1, frames, threads, [](int, const RgbImage&) { return true; });
        });
        if (threads == 2) synthesis_fps = fps;
    }
    row("edit (warped, bent lines), 2 thread(s)",
        [&](int frames) { edit.synthesizer->render_frames(1, frames, 2, [](int, const RgbImage&) { return true; }); });
    std::printf("goal (issue #30): synthesis >= 40 frames/s on 2 cores and >= 2x the flow map: %.1f frames/s, %.2fx -> %s\n",
                synthesis_fps, synthesis_fps / rows.flow_map_fps,
                synthesis_fps >= 40.0 && synthesis_fps >= 2.0 * rows.flow_map_fps ? "met" : "NOT met");
}

void correspondence_table() {
    std::printf("\n== Editing correspondence: 100 dense lines x 20 input lines, 30 frames ==\n");
    // 20 input lines 30 px apart; the artist draws 2 output lines 600 px apart:
    // 98 lines are interpolated between them (spacing 6 px).
    auto bank = std::make_shared<formats::ParticleBank>();
    bank->patch_size_px = 24;
    bank->clip_width_px = 1280;
    bank->clip_height_px = 720;
    formats::FlowLineSet drawing;
    drawing.width = 1280;
    drawing.height = 720;
    Random random(5);
    const int life = 31, count = 6;
    bank->clip_frame_count = count + life;
    for (int l = 0; l < 20; ++l) {
        const std::string id = "in-" + std::to_string(l);
        const double x = 40.0 + 30.0 * l;
        bank->lines.push_back({id, 300.0f});
        formats::FlowLine line;
        line.id = id;
        line.points = {{x, 0.0}, {x, 300.0}};
        drawing.inputs.push_back(line);
        const float grey = static_cast<float>(random.uniform(0.05, 0.95));
        for (int p = 0; p < count; ++p) {
            formats::TrackedParticle particle;
            particle.line_id = id;
            particle.start_frame = p;
            for (int a = 0; a < life; ++a) {
                particle.arc_length_px.push_back(10.0f * a);
                for (int t = 0; t < 24 * 24; ++t) particle.texture_rgba.insert(particle.texture_rgba.end(), {grey, static_cast<float>(random.uniform(0.05, 0.95)) * 0.1f + grey, grey, 1.0f});
            }
            bank->particles.push_back(std::move(particle));
        }
    }
    for (int k = 0; k < 2; ++k) {
        formats::FlowLine out;
        out.id = k ? "right" : "left";
        out.from = k ? "in-19" : "in-0";
        out.points = {{50.0 + 594.0 * k, 0.0}, {60.0 + 594.0 * k, 300.0}};
        drawing.outputs.push_back(out);
    }
    // Through prepare_synthesis, as `flowvid edit --background none`: the
    // schedule and the Synthesizer cost little beside the correspondence.
    SynthesisJob job;
    job.background = "none";
    job.edit = true;
    EditSettings& settings = job.edit_settings;
    settings.spacing_px = 6.0;
    settings.max_gap_px = 1000.0;
    // Baseline: every interpolated line at the input's own time (as before
    // time offsets); then the default, where each line's error needs its own frames.
    double baseline = 0.0;
    for (const auto& [threads, offsets] : std::vector<std::pair<int, bool>>{{1, false}, {1, true}, {2, true}, {1, true}}) {
        settings.threads = threads;
        settings.offset_interpolated_lines = offsets;
        const auto start = std::chrono::steady_clock::now();
        SynthesisSources sources;
        sources.bank = bank;
        sources.drawing = drawing;
        sources.drawing_name = "correspondence scene";
        const PreparedSynthesis prepared = prepare_synthesis(std::move(sources), job);
        const double total = seconds_since(start);
        const EditPlan& plan = *prepared.plan;
        if (baseline == 0.0) baseline = total;
        std::printf("%zu dense lines, %zu candidates, %d thread(s), time offsets %s: overlap errors + DP %.2f s (%.2f x)\n",
                    plan.lines.size(), prepared.streams->input_lines().size(), threads, offsets ? "on " : "off", total, total / baseline);
    }
    std::printf("(the DP alone, eq. 3.1, takes the time of BM_DynamicProgramme100x20 above)\n");
}

void tracking_table() {
    const std::string capture_dir = std::string(FLOWVID_SHARED_DIR) + "/captures/video-waterfall-cascade";
    std::printf("\n== Tracking a 120-frame 640 x 360 clip with 10 lines ==\n");
    if (!std::filesystem::exists(capture_dir)) {
        std::printf("(skipped: %s not found)\n", capture_dir.c_str());
        return;
    }
    const formats::Capture capture = open_clip(capture_dir);
    const formats::FlowLineSet drawing = formats::import_flowlines_svg(capture.resolve(capture.flowlines));
    std::vector<formats::FlowLine> lines = densify_input_lines(drawing, 25.0, 144.0);
    lines.resize(std::min<std::size_t>(lines.size(), 10));
    for (int threads : {1, 2}) {
        CaptureFrames frames(capture);
        TrackingSettings settings;
        settings.threads = threads;
        const auto start = std::chrono::steady_clock::now();
        const TrackingResult result = track_particles(frames, lines, settings);
        std::printf("waterfall, %zu drawn lines (%zu tracked segments), %d thread(s): %.1f s, %zu particles\n", lines.size(),
                    result.report.lines.size(), threads, seconds_since(start), result.bank.particles.size());
    }
    std::printf("goal: under a minute\n");
}

// ---- quality on the real clips -------------------------------------------------------------------------

struct QualityRow {
    const char* name;
    QualityReport report;
};

void print_quality(const char* clip, const std::vector<QualityRow>& rows) {
    std::printf("\n%s\n", clip);
    std::printf("%-9s %9s %9s %7s | %8s %8s | %9s %9s %8s | %7s\n", "method", "seam max", "share>p99", "spike", "pulsing",
                "(clip)", "patch d", "(self d)", "HF ratio", "motion");
    for (const QualityRow& r : rows)
        std::printf("%-9s %9.2f %9.3f %7.2f | %8.3f %8.3f | %9.4f %9.4f %8.2f | %7.2f\n", r.name, r.report.max_transition_ratio,
                    r.report.share_above_p99, r.report.seam_spike, r.report.pulsing, r.report.clip_pulsing,
                    r.report.patch_distance, r.report.clip_self_distance, r.report.hf_power_ratio, r.report.motion_ratio);
    if (rows.empty()) return;
    const QualityReport& clip_itself = rows.front().report;
    std::printf("%-9s %9.2f %9s %7.2f | %8.3f %8s | %9s %9.4f %8.2f | %7.2f\n", "clip", clip_itself.clip_max_ratio, "-",
                clip_itself.clip_seam_spike, clip_itself.clip_pulsing, "", "-", clip_itself.clip_self_distance, 1.0, 1.0);
    std::printf("clip's transitions span %.2f..%.2f x its p95\n", clip_itself.clip_min_ratio, clip_itself.clip_max_ratio);
}

// Tracks the clip as `flowvid track` does by default (the patch side from the
// drawing, lines added two patches apart), then measures the synthesis that
// flow::prepare_synthesis assembles, as `synth` and `quality` render it.
void quality_on(const std::string& name, formats::ParticleDynamics dynamics) {
    const std::string capture_dir = std::string(FLOWVID_SHARED_DIR) + "/captures/" + name;
    if (!std::filesystem::exists(capture_dir)) {
        std::printf("(skipped: %s not found)\n", capture_dir.c_str());
        return;
    }
    const formats::Capture capture = open_clip(capture_dir);
    const formats::FlowLineSet drawing = formats::import_flowlines_svg(capture.resolve(capture.flowlines));
    CaptureFrames frames(capture);
    TrackingJob tracking;
    tracking.drawing = drawing;
    tracking.settings.dynamics = dynamics;
    tracking.settings.patch_size_px = 0;  // from the drawing, as `flowvid track`
    const auto start = std::chrono::steady_clock::now();  // the camera's drift included
    const TrackingOutcome outcome = track_clip(frames, tracking);
    const TrackingResult& tracked = outcome.result;
    const int patch_px = outcome.patch_px;
    const double track_seconds = seconds_since(start);
    const std::string bank_path =
        (std::filesystem::temp_directory_path() / ("flowvid_bench_" + name + ".bank.exr")).string();
    formats::ParticleBank bank = tracked.bank;
    bank.source_clip = formats::source_clip_for_bank(bank_path, capture_dir);
    formats::write_particle_bank(bank_path, bank);

    SynthesisJob job;
    job.bank_path = bank_path;
    job.clip_path = capture_dir;
    job.keep_clip = true;
    const PreparedSynthesis prepared = prepare_synthesis(job);
    const ClipFrames& clip = *prepared.clip;
    const RgbImage plate = median_plate(clip);
    const Comparison comparison = compare_with_baselines(clip, *prepared.streams, *prepared.synthesizer, plate);
    const int frames_out = comparison.output_frames;
    const Schedule& schedule = prepared.streams->schedule();
    std::size_t substituted = 0, borrowed = 0;
    for (const auto& l : schedule.lines) {
        substituted += static_cast<std::size_t>(l.substituted);
        borrowed += static_cast<std::size_t>(l.borrowed);
    }
    char title[640];
    std::snprintf(title, sizeof title,
                  "%s (%s, defaults: patch %d px, lines added %.0f px apart, background %s): tracked %zu segments in %.1f s, "
                  "%zu particles; K = %d, step %d, period %d frames, %zu of %zu slots without a particle (%zu borrowing a "
                  "near one); %d output frames",
                  name.c_str(), formats::to_string(dynamics), patch_px, outcome.densify_px, to_string(prepared.background),
                  tracked.report.lines.size(), track_seconds, bank.particles.size(), schedule.particles_per_line,
                  schedule.start_every, schedule.period_frames, substituted,
                  schedule.lines.size() * static_cast<std::size_t>(schedule.particles_per_line), borrowed, frames_out);
    std::vector<QualityRow> rows;
    for (const MethodQuality& m : comparison.methods) rows.push_back({m.method.c_str(), m.report});
    print_quality(title, rows);
    // The banded renderer against the whole-frame pass on this bank.
    SynthesisSettings whole_frame = prepared.settings;
    whole_frame.reference_rendering = true;
    job.settings = whole_frame;
    job.keep_clip = false;
    const PreparedSynthesis reference = prepare_synthesis(job);
    std::filesystem::remove(bank_path);
    float worst = 0.0f;
    for (int f = 1; f <= frames_out; f += 7) {
        const RgbImage a = prepared.synthesizer->render(f), b = reference.synthesizer->render(f);
        for (std::size_t i = 0; i < a.rgb.size(); ++i) worst = std::max(worst, std::abs(a.rgb[i] - b.rgb[i]));
    }
    std::printf("banded vs whole-frame pass, every 7th output frame: largest difference %.2g\n", worst);
}

void quality_table() {
    if (std::getenv("FLOWVID_BENCH_FLOW_QUICK")) return;
    std::printf("\n== Quality on the real clips (luma in the band within a quarter patch of the tracked lines) ==\n");
    std::printf("seam max = largest frame-to-frame difference / clip's 95th percentile; share>p99 = output\n"
                "transitions above the clip's 99th percentile; pulsing = coefficient of variation of per-frame\n"
                "high-frequency energy; patch d = RMS distance of 16x16 output patches to their nearest clip patch\n"
                "(self d: the clip's patches to other frames >= 5 apart); HF ratio = output / clip HF energy;\n"
                "complementary: spike = largest / own median transition, motion = output / clip median transition\n"
                "(the same table as `flowvid quality --bank BANK`)\n");
    // Defaults only, as a user runs them (flames: --dynamics non-stationary).
    quality_on("video-waterfall-cascade", formats::ParticleDynamics::stationary);
    quality_on("video-fire-pot", formats::ParticleDynamics::non_stationary);
}

}  // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    speed_table();
    speed_table_1080p();
    correspondence_table();
    tracking_table();
    quality_table();
    return 0;
}
