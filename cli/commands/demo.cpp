// flowvid demo: the main job on bundled data, stage by stage. Every stage can
// run alone (--only), prints progress, and writes its results under --out.

#include "command.hpp"
#include "output.hpp"
#include "report_html.hpp"
#include "stage_jobs.hpp"

#include "flowvid/flow/frames.hpp"
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <thread>


namespace flowvid::cli {
namespace {
namespace fs = std::filesystem;

// Where the bundled data lies: beside an installed tool
// (PREFIX/bin/flowvid -> PREFIX/share/flowvid, as `cmake --install` lays it
// out), else the source tree this tool was built from.
std::string default_data_folder() {
    std::error_code error;
    const fs::path tool = fs::canonical("/proc/self/exe", error);
    if (!error) {
        const fs::path installed = tool.parent_path().parent_path() / "share" / "flowvid";
        if (fs::is_directory(installed / "data" / "demo", error)) return installed.string();
    }
    return FLOWVID_BUNDLED_DATA_DIR;
}

struct DemoOptions {
    std::string out = "out/demo";
    std::string data = default_data_folder();
    std::vector<std::string> only;
    int fabric_evaluations = 80;
    int blender_frames = 48;
    // Stages run side by side, at most this many at once (1: one after the
    // other, in this process). One stage alone keeps 1.3-1.7 of 2 cores busy.
    int jobs = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 3);
    // Set by the demo for the stage it runs in a process of its own: print
    // the stage's output only (no header, time or index: the parent does them).
    bool as_stage = false;
};

struct DemoStage {
    const char* name;
    const char* what;
    int (*run)(const DemoOptions&, const GlobalOptions&);
    const char* after = nullptr;  // a stage whose output this one uses, when both run
};

// Runs a program after printing its command line (the demo teaches the
// commands it runs). Its stdout goes to `stdout_file` (a --json summary);
// its progress and logs pass through to stderr. Returns its exit code.
int run_program(const std::vector<std::string>& argv, const std::string& shown, const fs::path& stdout_file) {
    std::cout << "$ " << shown << '\n' << std::flush;
    int error = 0;
    const pid_t child = start_program(argv, stdout_file, {}, &error);
    if (child < 0) {
        log_message("flowvid demo: could not start " + argv[0] + ": " + std::strerror(error));
        return kExitFailure;
    }
    int status = 0;
    while (waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : kExitFailure;
}

std::string flowvid_executable() { return fs::read_symlink("/proc/self/exe").string(); }

// `flowvid ARGS...` with this very executable, as the user would type it.
int run_flowvid(const std::vector<std::string>& args, const fs::path& stdout_file, const GlobalOptions& global) {
    std::vector<std::string> argv = {flowvid_executable(), global.quiet ? "--quiet" : "--progress=" + global.progress};
    argv.insert(argv.end(), args.begin(), args.end());
    std::string shown = "flowvid";
    for (const std::string& a : args) shown += " " + a;
    return run_program(argv, shown, stdout_file);
}

// The last JSON object line of a file (Blender prints its log before it).
nlohmann::json last_json_line(const fs::path& path) {
    std::ifstream in(path);
    nlohmann::json found = nlohmann::json::value_t::discarded;
    for (std::string line; std::getline(in, line);)
        if (!line.empty() && line.front() == '{') {
            nlohmann::json parsed = nlohmann::json::parse(line, nullptr, false);
            if (!parsed.is_discarded()) found = std::move(parsed);
        }
    return found;
}

// scripts/demo_blender.py STAGE ARGS... in headless Blender; the add-on calls
// this flowvid (FLOWVID_CLI). Blender's log goes to FOLDER/blender.log, the
// stage's JSON summary (its last line) to FOLDER/SUMMARY_NAME and `summary`.
int run_blender(const DemoOptions& options, const std::vector<std::string>& args, const fs::path& folder,
                const std::string& summary_name, nlohmann::json& summary) {
    setenv("FLOWVID_CLI", flowvid_executable().c_str(), 1);
    std::vector<std::string> argv = {"blender", "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
                                     "--python", (fs::path(options.data) / "scripts" / "demo_blender.py").string(), "--"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::string shown;
    for (const std::string& a : argv) shown += (shown.empty() ? "" : " ") + a;
    const fs::path log = folder / "blender.log";
    const int status = run_program(argv, shown, log);
    summary = last_json_line(log);
    if (status != kExitOk || summary.is_discarded()) {
        log_message("flowvid demo: Blender failed; its log: " + log.string());
        return status != kExitOk ? status : kExitFailure;
    }
    formats::write_file_atomically((folder / summary_name).string(), [&](std::ostream& s) { s << summary.dump(2) << '\n'; });
    return kExitOk;
}

nlohmann::json read_json_file(const fs::path& path) {
    std::ifstream in(path);
    return nlohmann::json::parse(in, nullptr, false);  // discarded (is_discarded) when not JSON
}

// A number of a JSON summary, or NaN where it is absent or null (JSON's NaN).
double number_or_nan(const nlohmann::json& object, const char* key) {
    return object.is_object() && object.contains(key) && object[key].is_number() ? object[key].get<double>() : NAN;
}

// Which of eval cloth's window fields the demo shows: a scan comparison's
// mean square depths as their roots, in mm; the angle-map metric as it is.
struct EvalWindowFields {
    bool in_mm = false;
    const char* error = "metric_mean";
    const char* floor = "metric_floor";
};
EvalWindowFields eval_window_fields(const nlohmann::json& eval) {
    if (eval.is_object() && eval.value("compared", "") == "scan") return {true, "metric_rms_mm", "metric_floor_rms_mm"};
    return {};
}

// The fitted fabric the later stages use: the fabric stage's, or the bundled example.
fs::path demo_preset(const DemoOptions& options) {
    const fs::path fitted = fs::path(options.out) / "fabric" / "cotton.fabric.json";
    return fs::exists(fitted) ? fitted : fs::path(options.data) / "formats" / "examples" / "cotton.fabric.json";
}

// Stage "fabric": a cotton preset fitted from the bundled static drape and
// the first 24 frames of a waving test (a fixed evaluation count: the same
// preset on every machine), its parameters printed with their uncertainty
// (from three restarts), then evaluated next to the predictability floor.
int run_fabric_stage(const DemoOptions& options, const GlobalOptions& global) {
    const fs::path data = fs::path(options.data) / "data" / "demo";
    const fs::path out = fs::path(options.out) / "fabric";
    fs::create_directories(out);
    const std::string preset = (out / "cotton.fabric.json").string();
    int status = run_flowvid({"fit", "cloth", "--capture", (data / "cotton-static").string(), "--capture",
                              (data / "cotton-waving").string(), "--out", preset, "--frame-count", "24", "--resolution",
                              "16x16", "--evaluations", std::to_string(options.fabric_evaluations), "--variability-runs",
                              "3", "--variability-evaluations", "14", "--json"},
                             out / "fit.json", global);
    if (status != kExitOk) return status;
    const formats::FabricPreset fitted = formats::read_fabric_preset(preset);
    std::cout << "  fitted " << fitted.name << " (" << preset << "):\n";
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table()) {
        const formats::FabricParameter& p = fitted.parameters.*info.member;
        const std::string unit = std::string(info.unit) == "1" ? "" : " " + std::string(info.unit);  // ratios have none
        const bool mass = std::string(info.key) == "areal_density_kg_per_m2";
        std::cout << "    " << info.key << " = " << html::format_compact(p.value) << unit
                  << (p.uncertainty ? "  +- " + html::format_compact(*p.uncertainty, 2)
                      : p.range     ? std::string("  (no uncertainty)")
                      : mass        ? std::string("  (fixed: the capture's declared mass)")
                                    : std::string("  (not fitted: held at its neutral value)"))
                  << '\n';
    }
    status = run_flowvid({"eval", "cloth", "--preset", preset, "--capture", (data / "cotton-waving").string(),
                          "--frame-count", "24", "--resolution", "16x16", "--floor-members", "4", "--out", (out / "eval").string(),
                          "--json"},
                         out / "eval.json", global);
    if (status != kExitOk) return status;
    const nlohmann::json fit = read_json_file(out / "fit.json");
    const nlohmann::json eval = read_json_file(out / "eval.json");
    if (fit.is_discarded() || eval.is_discarded()) return kExitFailure;
    const EvalWindowFields fields = eval_window_fields(eval);
    std::cout << "  weighted " << (fields.in_mm ? "mean square depth error (mm^2) " : "metric error ")
              << html::format_number(fit["start_error"].get<double>()) << " -> "
              << html::format_number(fit["final_error"].get<double>()) << " in " << html::format_number(fit["seconds"].get<double>())
              << " s; per window (" << (fields.in_mm ? "RMS depth error / floor, mm" : "metric / floor") << "):";
    for (const auto& w : eval["captures"][0]["windows"])
        std::cout << "  " << w["frames"].get<std::string>() << ": " << html::format_number(number_or_nan(w, fields.error))
                  << " / " << html::format_number(number_or_nan(w, fields.floor));
    std::cout << "\n  report: " << (out / "eval" / "eval.html").string() << '\n';
    return kExitOk;
}

// Stage "garment": the fabric on a skirt around an animated body, in
// headless Blender through the add-on's preset mapping; frames and a video.
int run_garment_stage(const DemoOptions& options, const GlobalOptions&) {
    const fs::path out = fs::path(options.out) / "garment";
    fs::create_directories(out);
    nlohmann::json summary;
    const int status = run_blender(options, {"garment", "--preset", demo_preset(options).string(), "--out", out.string(),
                                             "--frames", std::to_string(options.blender_frames)},
                                   out, "garment.json", summary);
    if (status != kExitOk) return status;
    std::cout << "  mapping: " << summary.value("mapping", "") << "; video: " << summary.value("video", "") << '\n';
    for (const auto& note : summary["not_represented"]) std::cout << "  note: " << note.get<std::string>() << '\n';
    return kExitOk;
}

// Stage "video": the bundled waterfall clip tracked into a particle bank, an
// infinite loop synthesized and measured against naive looping and the flow
// map, then an edit along a Blender particle system's flow lines seen through
// the (panning) scene camera, rendered through Blender.
// The output frame the index shows beside the clip's (the clip has 120).
const std::string kSideBySideFrame = "50";

int run_video_stage(const DemoOptions& options, const GlobalOptions& global) {
    const fs::path clip = fs::path(options.data) / "data" / "demo" / "waterfall";
    const fs::path out = fs::path(options.out) / "video";
    fs::create_directories(out);
    const std::string bank = (out / "waterfall.bank.exr").string();
    // Defaults only: track chooses the patch and where to add lines from the drawing.
    int status = run_flowvid({"track", "--capture", clip.string(), "--out", bank, "--json"},
                             out / "track.json", global);
    if (status == kExitOk)
        status = run_flowvid({"synth", "--bank", bank, "--loop", "--out", (out / "loop.mp4").string(), "--json"},
                             out / "loop.json", global);
    if (status == kExitOk)
        status = run_flowvid({"quality", "--bank", bank, "--json"}, out / "quality.json", global);
    // One frame of the clip, of the synthesis and of an edit along the
    // capture's drawn output lines, side by side in the index.
    if (status == kExitOk)
        status = run_flowvid({"synth", "--bank", bank, "--frames", kSideBySideFrame + ":" + kSideBySideFrame, "--out",
                              (out / ("frame" + kSideBySideFrame + "_synth.png")).string()},
                             out / "frame_synth.txt", global);
    if (status == kExitOk)
        status = run_flowvid({"edit", "--bank", bank, "--flowlines", (clip / "flowlines.svg").string(), "--frames",
                              kSideBySideFrame + ":" + kSideBySideFrame, "--out",
                              (out / ("frame" + kSideBySideFrame + "_edit.png")).string()},
                             out / "frame_edit.txt", global);
    if (status == kExitOk) {
        flow::CaptureFrames frames(flow::open_clip(clip.string()));
        const int index = std::min(std::stoi(kSideBySideFrame), frames.count()) - 1;
        flow::write_image((out / ("frame" + kSideBySideFrame + "_clip.png")).string(), flow::to_linear(frames.frame(index)));
    }
    if (status != kExitOk) return status;
    nlohmann::json summary;
    status = run_blender(options, {"video", "--bank", bank, "--clip", clip.string(), "--inputs",
                                   (clip / "flowlines.svg").string(), "--out", (out / "edit").string(), "--frames",
                                   std::to_string(options.blender_frames)},
                         out, "edit.json", summary);
    if (status != kExitOk) return status;
    // The particle edit measured as it was rendered (defaults, as the add-on renders it).
    const std::string edit_lines = summary.value("flowlines", "");
    if (!edit_lines.empty())
        status = run_flowvid({"quality", "--bank", bank, "--capture", clip.string(), "--flowlines", edit_lines, "--edit",
                              "--frame-count", std::to_string(options.blender_frames), "--json"},
                             out / "quality_edit.json", global);
    if (status != kExitOk) return status;
    const nlohmann::json quality = read_json_file(out / "quality.json");
    const nlohmann::json quality_edit = read_json_file(out / "quality_edit.json");
    const auto print_region = [](const char* what, const nlohmann::json& measures) {
        std::cout << "  " << what << " over the whole flow region: detail " << html::format_number(measures.value("detail", NAN))
                  << " (of the clip's), patch fidelity " << html::format_number(measures.value("patch_fidelity", NAN))
                  << " (1: as novel as a real frame), share above the clip's 99th "
                  << html::format_percent(measures.value("share_above_clip_p99", NAN)) << ", motion "
                  << html::format_number(measures.value("motion", NAN)) << '\n';
    };
    if (!quality.is_discarded() && quality.contains("region") && quality["region"].contains("ours"))
        print_region("loop", quality["region"]["ours"]);
    if (!quality_edit.is_discarded() && quality_edit.contains("region") && quality_edit["region"].contains("ours")) {
        print_region("particle edit", quality_edit["region"]["ours"]);
        if (quality_edit.contains("tracked_texture_detail"))
            std::cout << "  (the clip's moving texture alone has detail "
                      << html::format_number(quality_edit.value("tracked_texture_detail", NAN))
                      << ": an edit covered by moved texture keeps about that much)\n";
        if (quality_edit.contains("footage_over_region"))
            std::cout << "  (the footage itself over the same region: detail "
                      << html::format_number(quality_edit["footage_over_region"].value("detail", NAN)) << ", patch fidelity "
                      << html::format_number(quality_edit["footage_over_region"].value("patch_fidelity", NAN))
                      << ": what leaving the scene as filmed scores there)\n";
    }
    if (!quality.is_discarded() && quality.contains("methods")) {
        for (const char* method : {"ours", "loop", "flow map"}) {
            if (!quality["methods"].contains(method)) continue;
            const nlohmann::json& measures = quality["methods"][method];
            std::cout << "  " << method << ": loop-seam max " << html::format_number(measures.value("seam_max_ratio", NAN))
                      << " (of the clip's 95th-percentile change), share above the clip's 99th "
                      << html::format_percent(measures.value("share_above_clip_p99", NAN)) << ", motion "
                      << html::format_number(measures.value("motion_ratio", NAN)) << " (of the clip's)\n";
        }
        if (quality.contains("clip_reference"))
            std::cout << "  the clip itself: seam max " << html::format_number(quality["clip_reference"].value("seam_max_ratio", NAN))
                      << ", its calmest change " << html::format_number(quality["clip_reference"].value("smallest_transition_ratio", NAN))
                      << " (an output scoring below that changes less than the clip at every frame)\n";
    }
    std::cout << "  loop: " << (out / "loop.mp4").string() << "; edit along " << summary.value("lines", 0)
              << " particle lines: " << summary.value("video", "") << '\n';
    return kExitOk;
}

// Stage "diagnosis": the gap diagnosis of a cotton fit on a bundled waving
// capture made with one unmodelled effect (which one is not given to the
// diagnoser). The base is the bundled preset fitted to the whole public
// cotton captures (data/demo/cotton-full-fit.fabric.json): the fabric
// stage's quick fit (24 frames, 16 x 16) misses the footage by far more than
// the effect does, more than any single effect can explain, and the
// diagnosis rightly calls such a gap unexplained.
int run_diagnosis_stage(const DemoOptions& options, const GlobalOptions& global) {
    const fs::path out = fs::path(options.out) / "diagnosis";
    fs::create_directories(out);
    const fs::path data = fs::path(options.data) / "data" / "demo";
    // The first 20 waving frames and two candidates refitted per round (the
    // defaults: 30 and 3): on 2 cores 106 s where the defaults take 187,
    // naming the same wind (39 % of the gap closed against 40).
    const int status = run_flowvid({"diagnose", "--preset", (data / "cotton-full-fit.fabric.json").string(), "--capture",
                                    (data / "cotton-waving-effect").string(), "--frame-count", "20", "--candidates", "2",
                                    "--out", (out / "report").string(), "--json"},
                                   out / "diagnose.json", global);
    if (status != kExitOk) return status;
    const nlohmann::json d = read_json_file(out / "diagnose.json");
    if (d.is_discarded()) return kExitFailure;
    std::cout << "  verdict: " << d["verdict"].get<std::string>() << " -- " << d["message"].get<std::string>() << '\n'
              << "  next step: " << d.value("next_step", "") << '\n'
              << "  report: " << (out / "report" / "report.html").string() << '\n';
    return kExitOk;
}

// Stage "formats": every bundled example file validates, is summarised, and
// the flow lines survive JSON -> SVG -> JSON unchanged.
int run_formats_stage(const DemoOptions& options, const GlobalOptions& global) {
    const fs::path examples = fs::path(options.data) / "formats" / "examples";
    const fs::path out = fs::path(options.out) / "formats";
    fs::create_directories(out);
    std::vector<fs::path> files;
    for (const auto& entry : fs::directory_iterator(examples))
        if (entry.is_regular_file()) files.push_back(entry.path());
    std::sort(files.begin(), files.end());

    ProgressBar progress(global, "formats");
    int invalid = 0;
    nlohmann::json summaries = nlohmann::json::array();
    for (std::size_t i = 0; i < files.size(); ++i) {
        progress.update(static_cast<double>(i) / static_cast<double>(files.size()), files[i].filename().string());
        const std::vector<Problem> problems = formats::validate_any_file(files[i].string());
        print_problems(problems);
        const bool valid = std::none_of(problems.begin(), problems.end(),
                                        [](const Problem& p) { return p.severity == Problem::Severity::error; });
        if (!valid) {
            ++invalid;
            continue;
        }
        nlohmann::json summary = formats::summarize_any_file(files[i].string());
        std::cout << "  " << files[i].filename().string() << ": valid " << summary["kind"].get<std::string>() << '\n';
        summaries.push_back(summary);
    }
    progress.done();
    formats::write_file_atomically((out / "summaries.json").string(),
                                   [&](std::ostream& stream) { stream << summaries.dump(2) << '\n'; });

    // An artist's round trip: lines to SVG (to keep drawing) and back.
    const formats::FlowLineSet lines = formats::read_flowline_set((examples / "waterfall.flowlines.json").string());
    const std::string svg = (out / "waterfall.svg").string();
    const std::string back = (out / "waterfall.flowlines.json").string();
    formats::write_flowlines_svg(svg, lines);
    formats::write_flowline_set(back, formats::import_flowlines_svg(svg));
    // SVG holds a time-varying line's first key only: compare what it can hold.
    const formats::FlowLineSet reread = formats::read_flowline_set(back);
    auto same_lines = [](const std::vector<formats::FlowLine>& a, const std::vector<formats::FlowLine>& b) {
        if (a.size() != b.size()) return false;
        for (std::size_t i = 0; i < a.size(); ++i) {
            const auto& expected = a[i].keys.empty() ? a[i].points : a[i].keys.front().points;
            if (a[i].id != b[i].id || a[i].from != b[i].from || expected != b[i].points) return false;
        }
        return true;
    };
    const bool same = same_lines(lines.inputs, reread.inputs) && same_lines(lines.outputs, reread.outputs);
    std::cout << "  flow lines JSON -> SVG -> JSON: " << (same ? "identical" : "DIFFERENT")
              << " (time-varying lines keep their first key in SVG; " << svg << ")\n";
    std::cout << "  summaries: " << (out / "summaries.json").string() << '\n';
    return invalid == 0 && same ? kExitOk : kExitFailure;
}

// A relative link, or the text marked missing when the stage left no such file.
std::string link(const fs::path& target, const fs::path& index_dir, const std::string& text) {
    if (target.empty() || !fs::exists(target)) return html::escape(text) + " (missing)";
    return "<a href=\"" + html::escape(fs::relative(target, index_dir).generic_string()) + "\">" + html::escape(text) + "</a>";
}

// A video the browser plays in the page (H.264: FrameWriter and the
// add-on's encoder write it), with a link for those who would rather download.
std::string video(const fs::path& target, const fs::path& index_dir, const std::string& text, int width_px,
                  const fs::path& poster = {}) {
    if (target.empty() || !fs::exists(target)) return "<p>" + html::escape(text) + " (missing)</p>\n";
    const auto relative = [&](const fs::path& p) { return html::escape(fs::relative(p, index_dir).generic_string()); };
    const std::string poster_attribute =
        !poster.empty() && fs::exists(poster) ? " poster=\"" + relative(poster) + "\"" : std::string();
    return "<figure><video src=\"" + relative(target) + "\" width=\"" + std::to_string(width_px) + "\"" + poster_attribute +
           " controls loop muted playsinline preload=\"auto\"></video><figcaption>" + link(target, index_dir, text) +
           "</figcaption></figure>\n";
}

// One sentence that says how a stage went, boxed: good, warn or bad.
std::string verdict(const std::string& sentence, const std::string& kind) {
    return "<div class=\"verdict " + kind + "\"><p>" + html::escape(sentence) + "</p></div>\n";
}

// index.html beside the stages' folders: every output that exists, linked,
// with the key figures (fit error, time taken, floor, diagnosis verdict).
void write_index(const DemoOptions& options, const std::string& stages_run, double seconds) {
    const fs::path out = options.out;
    std::ostringstream body;
    body << html::element("h1", "flowvid demo")
         << html::element("p", "Every output `flowvid demo` has left in " + out.string() + ". The last run (" + stages_run +
                                   ") took " + html::format_number(seconds) + " s.");
    if (fs::exists(out / "formats" / "summaries.json"))
        body << html::element("h2", "Formats") << "<p>" << link(out / "formats" / "summaries.json", out, "summaries.json")
             << " &middot; " << link(out / "formats" / "waterfall.svg", out, "flow lines as SVG") << "</p>\n";
    const nlohmann::json fit = read_json_file(out / "fabric" / "fit.json");
    const nlohmann::json eval = read_json_file(out / "fabric" / "eval.json");
    if (!fit.is_discarded() && fit.is_object()) {
        body << html::element("h2", "Fabric from footage");
        // The verdict: the first frames (the predictable part of a wave)
        // against what repeated takes of the experiment differ by.
        const nlohmann::json* first_window = nullptr;
        if (!eval.is_discarded() && eval.contains("captures") && !eval["captures"].empty())
            for (const auto& w : eval["captures"][0]["windows"])
                if (first_window == nullptr) first_window = &w;
        const double start = number_or_nan(fit, "start_error"), final = number_or_nan(fit, "final_error");
        const EvalWindowFields fields = eval_window_fields(eval);
        const std::string error_name = fields.in_mm ? "RMS depth error (mm)" : "metric E_k";
        if (first_window != nullptr) {
            const double ratio = number_or_nan(*first_window, fields.error) / number_or_nan(*first_window, fields.floor);
            const double floor_mm = number_or_nan(*first_window, "vertex_floor_mm");
            const double rms_mm = number_or_nan(*first_window, "vertex_rms_mm");
            std::string sentence = "The fit lowered its error by " + html::format_percent(1.0 - final / start) + " in " +
                                   html::format_number(number_or_nan(fit, "seconds")) + " s; over frames " +
                                   first_window->value("frames", "") + " the fitted fabric misses the footage by " +
                                   html::format_number(ratio) + " times the predictability floor";
            if (std::isfinite(floor_mm))
                sentence += " (repeated takes of the experiment differ by " + html::format_number(floor_mm) + " mm RMS)";
            if (std::isfinite(rms_mm)) sentence += "; its vertices lie " + html::format_number(rms_mm) + " mm RMS from the truth";
            sentence += ratio <= 3.0 ? ": it reproduces the fabric about as closely as the footage allows."
                                     : ": this demo-sized fit (" + std::to_string(fit.value("evaluations", 0)) +
                                           " simulations on a 16 x 16 mesh) is a start; the product's setting is a "
                                           "full fit (fit cloth --budget-seconds 600, 24 x 24), docs/cloth_fitting.md.";
            body << verdict(sentence, ratio <= 3.0 ? "good" : "warn");
        }
        body
             << "<p>" << link(out / "fabric" / "cotton.fabric.json", out, "cotton.fabric.json") << ": weighted "
             << (fields.in_mm ? "mean square depth error (mm&sup2;) " : "metric error ")
             << html::format_number(fit.value("start_error", NAN)) << " &rarr; "
             << html::format_number(fit.value("final_error", NAN)) << " (floor "
             << html::format_number(fit.value("final_error_floor", NAN)) << ") in "
             << html::format_number(fit.value("seconds", NAN)) << " s, " << fit.value("evaluations", 0) << " evaluations.";
        if (!eval.is_discarded() && eval.is_object())
            body << " " << link(out / "fabric" / "eval" / "eval.html", out, "evaluation report (plots per frame)");
        body << "</p>\n";
        if (!eval.is_discarded() && eval.contains("captures")) {
            // At a glance: each window's error bar above its floor's (grey);
            // an error bar near its floor is as good as the footage allows.
            html::BarChart chart;
            chart.title = (fields.in_mm ? std::string("RMS depth error against the stripe scan, mm") : error_name) +
                          ": per window (blue), its predictability floor (grey)";
            chart.value_label = fields.in_mm ? "RMS depth error over the window's frames (mm)" : "mean metric E_k per frame";
            for (const auto& w : eval["captures"][0]["windows"]) {
                const std::string frames = w.value("frames", "");
                if (w.contains(fields.error) && w[fields.error].is_number())
                    chart.bars.push_back({"frames " + frames, w[fields.error].get<double>(), "#2e86c1"});
                if (w.contains(fields.floor) && w[fields.floor].is_number())
                    chart.bars.push_back({"floor " + frames, w[fields.floor].get<double>(), "#aab7b8"});
            }
            if (!chart.bars.empty()) body << "<figure>" << html::bar_chart_svg(chart) << "</figure>\n";
            html::Table table;
            table.caption = (fields.in_mm ? std::string("RMS depth error against the footage's stripe scan") : error_name) +
                            " per window next to its predictability floor";
            table.header = {"frames", error_name, "floor"};
            for (const auto& w : eval["captures"][0]["windows"])
                table.rows.push_back({w.value("frames", ""), html::format_number(number_or_nan(w, fields.error)),
                                      html::format_number(number_or_nan(w, fields.floor))});
            body << html::table(table);
        }
    }
    // A video's poster: its middle rendered frame (what a thumbnail showed before).
    const auto middle_frame = [](const nlohmann::json& frames) {
        return frames.is_array() && !frames.empty() ? fs::path(frames[frames.size() / 2].get<std::string>()) : fs::path();
    };
    const nlohmann::json garment = read_json_file(out / "garment" / "garment.json");
    if (!garment.is_discarded() && garment.is_object()) {
        const std::size_t frame_count = garment["frames"].is_array() ? garment["frames"].size() : 0;
        body << html::element("h2", "Onto a garment (Blender)")
             << verdict("The fitted fabric went onto a skirt through the add-on's " + garment.value("mapping", std::string()) +
                            " mapping; Blender simulated and rendered its " + std::to_string(frame_count) + " frames (" +
                            html::format_number(frame_count / 24.0) + " s of animation) in " +
                            html::format_number(garment.value("render_seconds", NAN)) + " s.",
                        "good")
             << video(garment.value("video", ""), out, "garment.mp4", 640, middle_frame(garment["frames"]));
    }
    const nlohmann::json edit = read_json_file(out / "video" / "edit.json");
    const nlohmann::json quality = read_json_file(out / "video" / "quality.json");
    const bool have_edit = !edit.is_discarded() && edit.is_object();
    const bool have_quality = !quality.is_discarded() && quality.contains("methods");
    if (have_edit || have_quality) {
        body << html::element("h2", "Video editing");
        if (have_quality && quality["methods"].contains("ours") && quality["methods"].contains("loop")) {
            const double ours = number_or_nan(quality["methods"]["ours"], "seam_max_ratio");
            const double naive = number_or_nan(quality["methods"]["loop"], "seam_max_ratio");
            const double clip = quality.contains("clip_reference") ? number_or_nan(quality["clip_reference"], "seam_max_ratio")
                                                                   : NAN;
            // Within half a percent of the clip's own largest change is as large
            // as it: a loop that replays the clip's background shows that very
            // change, measured again to within rounding, and the page's three
            // digits could not tell them apart anyway.
            const double reference = std::isfinite(clip) ? clip : 1.0;
            const bool below = ours <= reference;
            const bool as_large = !below && ours <= reference * 1.005;
            body << verdict("The loop's largest frame-to-frame change is " + html::format_number(ours) +
                                " times the clip's 95th-percentile change (the clip's own largest: " +
                                html::format_number(clip) + "; naive looping: " + html::format_number(naive) + ")" +
                                (below      ? ": no seam stands out from the footage's own changes."
                                 : as_large ? ": as large as the footage's own largest change (within 0.5 %), so no seam "
                                              "stands out from it."
                                            : ": its worst seam changes more than the footage ever does."),
                            below || as_large ? "good" : "warn");
        }
        if (fs::exists(out / "video" / "loop.mp4"))
            body << video(out / "video" / "loop.mp4", out, "loop.mp4: the seamless infinite loop (one period)", 640);
        if (have_edit)
            body << video(edit.value("video", ""), out,
                          "edit.mp4: along " + std::to_string(edit.value("lines", 0)) +
                              " lines of a Blender particle system seen through the panning camera",
                          640, middle_frame(edit["frames"]))
                 << "<p>" << link(edit.value("flowlines", ""), out, "the edit's flow lines") << "</p>\n";
        const std::string stem = "video/frame" + kSideBySideFrame;
        if (fs::exists(out / (stem + "_clip.png")) && fs::exists(out / (stem + "_synth.png")) &&
            fs::exists(out / (stem + "_edit.png"))) {
            body << "<p>Frame " << kSideBySideFrame
                 << ": the clip as filmed &middot; the synthesis (a still camera in the clip's central view) &middot; "
                    "an edit along the capture's drawn output lines (a new channel on the left)</p>\n<p>";
            for (const auto& [file, what] : {std::pair<const char*, const char*>{"_clip.png", "the clip"},
                                              {"_synth.png", "the synthesis"}, {"_edit.png", "the edit"}})
                body << "<img src=\"" << html::escape(stem + file) << "\" alt=\"frame " << kSideBySideFrame << " of "
                     << what << "\" width=\"320\"> ";
            body << "</p>\n";
        }
        if (have_quality) {
            html::Table table;
            table.caption = "loop seams: largest frame-to-frame change / the clip's 95th percentile; motion: median change / "
                            "the clip's (an output that barely moves, motion well below 1, scores a low seam max without "
                            "hiding any seam)";
            table.header = {"method", "seam max", "share above the clip's 99th percentile", "motion"};
            for (const char* method : {"ours", "loop", "flow map"}) {
                if (!quality["methods"].contains(method)) continue;
                const nlohmann::json& measures = quality["methods"][method];
                table.rows.push_back({method, html::format_number(measures.value("seam_max_ratio", NAN)),
                                      html::format_percent(measures.value("share_above_clip_p99", NAN)),
                                      html::format_number(measures.value("motion_ratio", NAN))});
            }
            if (quality.contains("clip_reference"))
                table.rows.push_back({"the clip itself", html::format_number(quality["clip_reference"].value("seam_max_ratio", NAN)),
                                      "", "1"});
            body << html::table(table);
        }
        const nlohmann::json quality_edit = read_json_file(out / "video" / "quality_edit.json");
        html::Table region;
        region.caption = "what a viewer sees: every pixel within 20 px of the drawn lines (the edit's moving lines at "
                         "each frame). detail: fine detail kept, 1 = the clip's; patch fidelity: distance to the nearest "
                         "clip patch over a real frame's own, 1 = as novel as footage";
        region.header = {"sequence", "detail", "patch fidelity", "share above the clip's 99th percentile", "motion"};
        const auto add_region = [&region](const std::string& name, const nlohmann::json& report) {
            if (report.is_discarded() || !report.contains("region") || !report["region"].contains("ours")) return;
            const nlohmann::json& m = report["region"]["ours"];
            region.rows.push_back({name, html::format_number(m.value("detail", NAN)),
                                   html::format_number(m.value("patch_fidelity", NAN)),
                                   html::format_percent(m.value("share_above_clip_p99", NAN)),
                                   html::format_number(m.value("motion", NAN))});
        };
        add_region("loop", quality);
        add_region("particle edit", quality_edit);
        if (!quality_edit.is_discarded() && quality_edit.contains("footage_over_region")) {
            // The reference for the edit: its region left as filmed.
            const nlohmann::json& f = quality_edit["footage_over_region"];
            region.rows.push_back({"the footage itself over the particle edit's region",
                                   html::format_number(f.value("detail", NAN)),
                                   html::format_number(f.value("patch_fidelity", NAN)), "", ""});
        }
        if (!region.rows.empty()) body << html::table(region);
    }
    const nlohmann::json diagnosis = read_json_file(out / "diagnosis" / "diagnose.json");
    if (!diagnosis.is_discarded() && diagnosis.is_object()) {
        const std::string verdict_name = diagnosis.value("verdict", "");
        const double over_floor = number_or_nan(diagnosis, "held_out_over_floor");
        const double closed = number_or_nan(diagnosis, "gap_closed");
        std::string sentence = "On footage with an effect it was not told about, the fitted model misses held-out frames by " +
                               html::format_number(over_floor) + " times the predictability floor";
        if (verdict_name == "named" && std::isfinite(closed))
            sentence += "; modelling the named effect closes " + html::format_percent(closed) + " of that gap.";
        else
            sentence += ".";
        body << html::element("h2", "Diagnosis")
             << verdict(sentence, verdict_name == "named" || verdict_name == "no_gap" ? "good" : "warn")
             << html::element("p", "verdict: " + verdict_name) << html::element("p", diagnosis.value("message", ""))
             << (diagnosis.value("next_step", "").empty() ? std::string()
                                                          : html::element("p", "Next step: " + diagnosis.value("next_step", "") + "."))
             << "<p>Diagnosed in " << html::format_number(diagnosis.value("seconds", NAN)) << " s. "
             << link(out / "diagnosis" / "report" / "report.html", out, "full report (heat maps, ablation table)") << "</p>\n";
    }
    formats::write_file_atomically((out / "index.html").string(),
                                   [&](std::ostream& stream) { stream << html::page("flowvid demo", body.str()); });
}

const std::vector<DemoStage>& demo_stages() {
    static const std::vector<DemoStage> stages = {
        {"formats", "validate and summarise the bundled example files; flow lines to SVG and back", run_formats_stage},
        {"fabric", "fit a cotton preset to bundled swatch footage (static + waving); errors next to their floor",
         run_fabric_stage},
        {"garment", "the fitted fabric on a skirt around an animated body, rendered by headless Blender", run_garment_stage,
         "fabric"},
        {"video", "track a waterfall clip, loop it seamlessly, edit it along a Blender particle system's lines",
         run_video_stage},
        {"diagnosis", "diagnose a bundled full cotton fit on footage with a hidden unmodelled effect", run_diagnosis_stage},
    };
    return stages;
}

// The stages this run asked for, in the demo's order.
std::vector<const DemoStage*> chosen_stages(const DemoOptions& options) {
    std::vector<const DemoStage*> chosen;
    for (const DemoStage& stage : demo_stages())
        if (options.only.empty() || std::find(options.only.begin(), options.only.end(), stage.name) != options.only.end())
            chosen.push_back(&stage);
    return chosen;
}

std::string minutes_seconds(double seconds) {
    const int whole = static_cast<int>(seconds);
    std::ostringstream text;
    text << whole / 60 << ':' << std::setw(2) << std::setfill('0') << whole % 60;
    return text.str();
}

// One line on a terminal's stderr naming the stages that run and how far
// each is, redrawn in place; cleared before anything else is printed.
class StatusLine {
public:
    explicit StatusLine(bool shown) : m_shown(shown) {}
    void draw(const std::string& text) {
        if (!m_shown || (m_drawn && text == m_text)) return;
        m_text = text;
        std::cerr << "\r\033[K" << text.substr(0, 110) << std::flush;
        m_drawn = true;
    }
    void clear() {
        if (m_drawn) std::cerr << "\r\033[K" << std::flush;
        m_drawn = false;
    }

private:
    bool m_shown;
    bool m_drawn = false;
    std::string m_text;
};

// Every stage in a process of its own (`flowvid demo --only STAGE`), side by
// side as far as --jobs and the stages' order allow. A stage's printed output
// shows when it ends; its messages show as they come, marked with its name;
// its progress shows on one status line (or, with --progress json, passes
// through with a "demo_stage" field). Everything is kept under OUT/logs.
int run_stages_side_by_side(const DemoOptions& options, const GlobalOptions& global,
                            const std::vector<const DemoStage*>& stages) {
    const fs::path logs = fs::path(options.out) / "logs";
    fs::create_directories(logs);
    std::vector<StageJob> jobs;
    for (const DemoStage* stage : stages) {
        StageJob job;
        job.name = stage->name;
        job.argv = {flowvid_executable(), global.quiet ? "--quiet" : "--progress=json", "demo", "--as-stage", "--only",
                    stage->name, "--out", options.out, "--data", options.data, "--blender-frames",
                    std::to_string(options.blender_frames), "--fabric-evaluations", std::to_string(options.fabric_evaluations)};
        if (stage->after && std::any_of(stages.begin(), stages.end(), [&](const DemoStage* s) { return std::string(s->name) == stage->after; }))
            job.after = {stage->after};
        job.stdout_file = logs / (job.name + ".txt");
        job.stderr_file = logs / (job.name + ".log");
        jobs.push_back(std::move(job));
    }
    const bool json = !global.quiet && global.progress == "json";
    StatusLine status_line(!global.quiet &&
                           global.progress == "auto" && ::isatty(STDERR_FILENO));
    struct Running {
        std::unique_ptr<FileFollower> messages;
        std::chrono::steady_clock::time_point began;
        std::string progress;  // the latest progress event, as "task: stage 45%"
    };
    std::map<std::string, Running> running;
    const auto take_messages = [&](const std::string& name, Running& r) {
        for (const std::string& line : r.messages->new_lines()) {
            nlohmann::json event = line.empty() || line.front() != '{' ? nlohmann::json()
                                                                       : nlohmann::json::parse(line, nullptr, false);
            if (event.is_object() && event.contains("event")) {
                if (json) {
                    event["demo_stage"] = name;
                    std::cerr << event.dump() << std::endl;
                } else if (event["event"] == "progress") {
                    r.progress = event.value("task", "") +
                                 (event.contains("stage") ? ": " + event.value("stage", "") : std::string()) + " " +
                                 std::to_string(static_cast<int>(event.value("fraction", 0.0) * 100.0 + 0.5)) + "%";
                }
                continue;
            }
            status_line.clear();
            std::cerr << "[" << name << "] " << line << '\n';
        }
    };
    StageJobEvents events;
    events.started = [&](const StageJob& job) {
        running[job.name] = {std::make_unique<FileFollower>(job.stderr_file), std::chrono::steady_clock::now(), {}};
        status_line.clear();
        std::cout << "-> " << job.name << " started (its output follows when it ends; messages: "
                  << job.stderr_file.string() << ")\n"
                  << std::flush;
    };
    events.tick = [&] {
        std::string text = "running:";
        for (auto& [name, r] : running) {
            take_messages(name, r);
            text += "  " + name + " " +
                    minutes_seconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - r.began).count()) +
                    (r.progress.empty() ? "" : " (" + r.progress + ")");
        }
        if (!running.empty()) status_line.draw(text);
    };
    int status = kExitOk;
    events.ended = [&](const StageJob& job, const StageJobEnd& end) {
        take_messages(job.name, running[job.name]);
        running.erase(job.name);
        status_line.clear();
        const auto stage = std::find_if(stages.begin(), stages.end(), [&](const DemoStage* s) { return job.name == s->name; });
        std::cout << "== " << job.name << ": " << (*stage)->what << '\n';
        std::ifstream printed(job.stdout_file);
        std::cout << printed.rdbuf();
        std::cout.clear();  // an empty file sets failbit on the stream it went to
        std::cout << "   " << job.name << (end.exit_code == kExitOk ? " done" : " FAILED") << " in "
                  << html::format_number(end.seconds) << " s"
                  << (end.exit_code == kExitOk ? std::string() : "; its messages: " + job.stderr_file.string()) << '\n'
                  << std::flush;
        if (end.exit_code != kExitOk) status = end.exit_code == 127 ? kExitFailure : end.exit_code;
    };
    run_stage_jobs(jobs, options.jobs, events);
    return status;
}

int run_demo(const DemoOptions& options, const GlobalOptions& global) {
    for (const std::string& name : options.only) {
        const bool known = std::any_of(demo_stages().begin(), demo_stages().end(),
                                       [&](const DemoStage& stage) { return name == stage.name; });
        if (!known) {
            log_message("flowvid demo: no stage '" + name + "' (see 'flowvid help demo')");
            return kExitUsage;
        }
    }
    const std::vector<const DemoStage*> stages = chosen_stages(options);
    if (options.as_stage) {  // the parent prints the header, the time and the index
        int status = kExitOk;
        for (const DemoStage* stage : stages)
            if (const int result = stage->run(options, global); result != kExitOk) status = result;
        return status;
    }
    const auto start = std::chrono::steady_clock::now();
    int status = kExitOk;
    std::string stages_run;
    for (const DemoStage* stage : stages) stages_run += (stages_run.empty() ? "" : ", ") + std::string(stage->name);
    if (options.jobs > 1 && stages.size() > 1) {
        status = run_stages_side_by_side(options, global, stages);
    } else {
        for (const DemoStage* stage : stages) {
            std::cout << "== " << stage->name << ": " << stage->what << '\n';
            const auto stage_start = std::chrono::steady_clock::now();
            const int result = stage->run(options, global);
            std::cout << "   " << stage->name << (result == kExitOk ? " done" : " FAILED") << " in "
                      << html::format_number(std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start).count())
                      << " s\n";
            if (result != kExitOk) status = result;
        }
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    write_index(options, stages_run, seconds);
    std::cout << "index: " << (fs::path(options.out) / "index.html").string() << '\n';
    std::cout << "demo " << (status == kExitOk ? "finished" : "FAILED") << " in " << seconds << " s; outputs in "
              << options.out << '\n';
    return status;
}

const RegisterCommand registration{Command{
    "demo", "run the bundled end-to-end demo", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<DemoOptions>();
        std::string stage_list;
        for (const DemoStage& stage : demo_stages()) stage_list += std::string("  ") + stage.name + ": " + stage.what + "\n";
        app.footer("Stages (all by default, in this order):\n" + stage_list +
                   "\nEach stage prints the commands it runs (run them yourself: docs/guide/) and writes under\n"
                   "--out; index.html there links every output with thumbnails and key figures. The garment\n"
                   "and video stages need `blender` on PATH. Stages that do not need each other's output run\n"
                   "side by side (--jobs; the garment waits for the fabric), each in a process of its own: its\n"
                   "output shows when it ends, its messages as they come, and OUT/logs keeps both. The whole\n"
                   "demo takes about 5 minutes on 2 cores (about 6 with --jobs 1).\n"
                   "\nExamples:\n"
                   "  flowvid demo\n"
                   "  flowvid demo --only fabric --only garment --out /tmp/demo\n"
                   "  flowvid demo --only formats --out /tmp/demo");
        app.add_option("--out", options->out, "folder for every output")->capture_default_str();
        app.add_option("--data", options->data, "folder holding the bundled data: an installed tool's PREFIX/share/flowvid, else the source tree it was built from")->capture_default_str();
        app.add_option("--only", options->only, "run only these stages");
        app.add_option("--jobs", options->jobs,
                       "stages run side by side, at most this many at once (each in a process of its own; its output "
                       "shows when it ends, everything is kept under OUT/logs); 1 runs them one after the other")
            ->check(CLI::Range(1, 16))
            ->capture_default_str();
        app.add_flag("--as-stage", options->as_stage, "(used by the demo itself) print only the stages' own output")
            ->group("");
        app.add_option("--blender-frames", options->blender_frames, "frames the Blender stages simulate and render")
            ->check(CLI::Range(2, 1000))
            ->capture_default_str();
        app.add_option("--fabric-evaluations", options->fabric_evaluations,
                       "evaluations of the fabric fit's main search (then 3 restarts of 14 for the uncertainty); a "
                       "count, not a time budget, so the demo's preset is the same on every machine")
            ->check(CLI::Range(10, 100000))
            ->capture_default_str();
        return [options](const GlobalOptions& global) { return run_demo(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
