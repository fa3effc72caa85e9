// flowvid demo: the main job on bundled data, stage by stage. Every stage can
// run alone (--only), prints progress, and writes its results under --out.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {
namespace fs = std::filesystem;

struct DemoOptions {
    std::string out = "out/demo";
    std::string data = FLOWVID_BUNDLED_DATA_DIR;
    std::vector<std::string> only;
};

struct DemoStage {
    const char* name;
    const char* what;
    int (*run)(const DemoOptions&, const GlobalOptions&);
};

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

    Progress progress(global, "formats");
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

const std::vector<DemoStage>& demo_stages() {
    static const std::vector<DemoStage> stages = {
        {"formats", "validate and summarise the bundled example files; flow lines to SVG and back", run_formats_stage},
    };
    return stages;
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
    const auto start = std::chrono::steady_clock::now();
    int status = kExitOk;
    for (const DemoStage& stage : demo_stages()) {
        if (!options.only.empty() && std::find(options.only.begin(), options.only.end(), stage.name) == options.only.end())
            continue;
        std::cout << "== " << stage.name << ": " << stage.what << '\n';
        const int result = stage.run(options, global);
        if (result != kExitOk) status = result;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
                   "\nExamples:\n"
                   "  flowvid demo\n"
                   "  flowvid demo --only formats --out /tmp/demo");
        app.add_option("--out", options->out, "folder for every output")->capture_default_str();
        app.add_option("--data", options->data, "flowvid source tree holding the bundled data")->capture_default_str();
        app.add_option("--only", options->only, "run only these stages");
        return [options](const GlobalOptions& global) { return run_demo(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
