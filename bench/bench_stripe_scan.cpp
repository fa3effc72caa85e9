// Accuracy of the single-shot structured-light scan (video/stripe_scan.hpp)
// on cloth captures, against their truth/ (read here for evaluation only,
// never by the scan). Per capture and frame: the scanned pixels' distance to
// the true surface along the same camera ray (the truth mesh rendered through
// the calibrated camera gives the true v_p per pixel, triangulated exactly as
// the scan is), in mm, the coverage of the silhouette, and how many pixels
// took the wrong whole number of stripe periods (|v_p error| > half a period).
//
//   flowvid_bench_stripe_scan [--captures DIR] [--names a,b] [--frames N] [--json FILE] [--figures DIR]
//
// Figures per chosen frame: the frame, the error (0-10 mm), the modulation,
// and v_p modulo 8 periods (where it jumps, the periods slipped).

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/video/cloth_footage.hpp"
#include "flowvid/video/stripe_render.hpp"
#include "flowvid/video/stripe_scan.hpp"

#include "option_value.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace fs = std::filesystem;
namespace ff = flowvid::formats;
namespace fv = flowvid::video;

namespace {

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return std::nan("");
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
}

}  // namespace

int main(int argc, char** argv) {
    std::string captures = std::string(FLOWVID_SHARED_DIR) + "/captures";
    std::vector<std::string> names;
    int max_frames = 0;
    std::string json_path, figures;
    fv::StripeScanSettings settings;
    bool temporal = true;
    std::vector<int> figure_frames = {1, 25};
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : std::string(); };
        if (a == "--captures") captures = value();
        else if (a == "--names") names = flowvid::bench::comma_list(value());
        else if (a == "--frames") max_frames = std::atoi(value().c_str());
        else if (a == "--json") json_path = value();
        else if (a == "--figures") figures = value();
        else if (a == "--figure-frames") {
            figure_frames.clear();
            for (const std::string& f : flowvid::bench::comma_list(value())) figure_frames.push_back(std::atoi(f.c_str()));
        }
        else if (a == "--max-step") settings.max_step_rad = std::atof(value().c_str());
        else if (a == "--min-modulation") settings.min_modulation = std::atof(value().c_str());
        else if (a == "--each-frame-alone") temporal = false;
        else if (a == "--margin") settings.edge_margin_px = std::atoi(value().c_str());
        else {
            std::printf("flowvid_bench_stripe_scan [--captures DIR] [--names cloth-cotton-waving-1,...] [--frames N] [--json FILE] [--figures DIR [--figure-frames 1,25]]\n"
                        "  [--max-step RAD] [--min-modulation M] [--margin PX] [--each-frame-alone] (scan settings)\n"
                        "Scans every frame of each cloth capture with truth/ and scores the scan against the truth (mm).\n");
            return a == "--help" || a == "-h" ? 0 : 2;
        }
    }
    if (names.empty())
        for (const auto& entry : fs::directory_iterator(captures))
            if (entry.path().filename().string().rfind("cloth-", 0) == 0 && fs::exists(entry.path() / "truth" / "positions.exr"))
                names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());

    nlohmann::json record;
    std::printf("| capture | frames | coverage | wrong period | median mm | RMS mm | 95th pct mm | worst frame RMS mm | ms/frame |\n"
                "|---|---|---|---|---|---|---|---|---|\n");
    for (const std::string& name : names) {
        const ff::Capture capture = ff::read_capture((fs::path(captures) / name).string());
        const std::optional<ff::VertexAnimation> truth = ff::read_capture_truth_positions(capture);
        if (!truth) continue;
        fv::StripeScanner scanner = fv::scanner_for(capture, settings);
        fv::StripeRenderSettings render_settings;
        render_settings.projector_coordinates = true;
        fv::StripeRenderer renderer(*capture.camera, *capture.projector, render_settings);
        const auto triangles = fv::grid_triangles(*truth->grid_rows, *truth->grid_cols);
        fv::ClothFootage footage(capture);
        const int frames = max_frames > 0 ? std::min(max_frames, footage.count()) : footage.count();
        fv::StripeScan previous;
        std::vector<double> all_errors;
        long long silhouette = 0, measured = 0, wrong = 0;
        double worst_frame = 0.0, seconds = 0.0;
        nlohmann::json per_frame = nlohmann::json::array();
        for (int f = 0; f < frames; ++f) {
            const fv::ClothFrame frame = footage.frame(footage.first() + f);
            const auto start = std::chrono::steady_clock::now();
            const fv::StripeScan scan = scanner.scan(frame.gray, frame.silhouette, fv::pin_positions_at(capture, f + 1),
                                                     temporal && previous.width > 0 ? &previous : nullptr);
            previous = scan;
            seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            const fv::StripeImage true_image = renderer.render(fv::vertices_of_frame(*truth, f), triangles);
            std::vector<double> errors;
            long long frame_wrong = 0;
            fv::ImageF error_image(scan.width, scan.height, 0.0f);
            for (int y = 0; y < scan.height; ++y)
                for (int x = 0; x < scan.width; ++x) {
                    if (!scan.measured(x, y)) continue;
                    const float v_true = true_image.projector_coordinate.at(x, y);
                    if (!std::isfinite(v_true)) continue;  // scanned outside the true silhouette (edge pixels)
                    const Eigen::Vector3d X_true = scanner.triangulate({x, y}, v_true);
                    const Eigen::Vector3d X = scan.points_m[scan.projector_coordinate.index(x, y)].cast<double>();
                    errors.push_back(1e3 * (X - X_true).norm());
                    error_image.at(x, y) = static_cast<float>(errors.back());
                    if (std::abs(scan.projector_coordinate.at(x, y) - v_true) > 0.5 * capture.projector->pattern.period_px)
                        ++frame_wrong;
                }
            if (!figures.empty() && std::find(figure_frames.begin(), figure_frames.end(), f + 1) != figure_frames.end()) {
                fs::create_directories(figures);
                const std::string stem = figures + "/" + name + "-" + std::to_string(f + 1);
                fv::write_gray_image(stem + "-error-0-10mm.png", error_image, 0.0f, 10.0f);
                fv::write_gray_image(stem + "-modulation.png", scan.modulation, 0.0f, 1.5f);
                fv::write_gray_image(stem + "-frame.png", frame.gray, 0.0f, 1.0f);
                fv::ImageF wrapped(scan.width, scan.height, 0.0f);
                for (std::size_t i = 0; i < wrapped.pixels.size(); ++i)
                    if (std::isfinite(scan.projector_coordinate.pixels[i]))
                        wrapped.pixels[i] = 0.2f + 0.8f * std::fmod(scan.projector_coordinate.pixels[i] / static_cast<float>(8.0 * capture.projector->pattern.period_px), 1.0f);
                fv::write_gray_image(stem + "-vp.png", wrapped, 0.0f, 1.0f);
            }
            double mean_square = 0.0;
            for (const double e : errors) mean_square += e * e;
            const double rms = errors.empty() ? std::nan("") : std::sqrt(mean_square / static_cast<double>(errors.size()));
            worst_frame = std::max(worst_frame, rms);
            silhouette += scan.silhouette_px;
            measured += scan.measured_px;
            wrong += frame_wrong;
            per_frame.push_back({{"frame", f + 1},
                                 {"coverage", scan.silhouette_px ? static_cast<double>(scan.measured_px) / static_cast<double>(scan.silhouette_px) : 0.0},
                                 {"median_mm", percentile(errors, 0.5)},
                                 {"rms_mm", rms},
                                 {"p95_mm", percentile(errors, 0.95)},
                                 {"wrong_period_px", frame_wrong},
                                 {"regions_referenced", scan.regions_referenced},
                                 {"regions_dropped", scan.regions_dropped},
                                 {"regions_inconsistent", scan.regions_inconsistent}});
            all_errors.insert(all_errors.end(), errors.begin(), errors.end());
        }
        double mean_square = 0.0;
        for (const double e : all_errors) mean_square += e * e;
        const double rms = std::sqrt(mean_square / static_cast<double>(std::max<std::size_t>(1, all_errors.size())));
        const double coverage = silhouette ? static_cast<double>(measured) / static_cast<double>(silhouette) : 0.0;
        const double wrong_fraction = measured ? static_cast<double>(wrong) / static_cast<double>(measured) : 0.0;
        std::printf("| %s | %d | %.1f %% | %.2f %% | %.2f | %.2f | %.2f | %.2f | %.1f |\n", name.c_str(), frames, 100.0 * coverage,
                    100.0 * wrong_fraction, percentile(all_errors, 0.5), rms, percentile(all_errors, 0.95), worst_frame,
                    1e3 * seconds / std::max(1, frames));
        std::fflush(stdout);
        record[name] = {{"frames", frames},           {"coverage", coverage},     {"wrong_period_fraction", wrong_fraction},
                        {"median_mm", percentile(all_errors, 0.5)}, {"rms_mm", rms}, {"p95_mm", percentile(all_errors, 0.95)},
                        {"worst_frame_rms_mm", worst_frame}, {"ms_per_frame", 1e3 * seconds / std::max(1, frames)},
                        {"per_frame", per_frame}};
    }
    if (!json_path.empty()) ff::write_file_atomically(json_path, [&](std::ostream& out) { out << record.dump(2) << '\n'; });
    return 0;
}
