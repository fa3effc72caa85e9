// The video side on a real capture (../shared/captures/cloth-cotton-static-1,
// rendered by Blender, not by us): segmentation, the stripe period predicted
// by the calibration, a well-defined angle map inside the swatch, and the
// stripe renderer applied to the capture's truth mesh reproducing the
// captured stripes (truth is read here for evaluation only, never by a fit).

#include "flowvid/video/angle_map.hpp"
#include "flowvid/video/angle_map_metric.hpp"
#include "flowvid/video/cloth_footage.hpp"
#include "flowvid/video/stripe_render.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>

using namespace flowvid;
using namespace flowvid::video;

namespace {

constexpr double kPi = std::numbers::pi;

const formats::Capture& static_capture() {
    static const formats::Capture capture =
        formats::read_capture(flowvid::testing::shared_path("captures/cloth-cotton-static-1"));
    return capture;
}

double median(std::vector<float> values) {
    if (values.empty()) return 0.0;
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
    return values[values.size() / 2];
}

// Writes figures when FLOWVID_FIGURES names a folder (for docs/cloth_fitting.md).
void figure(const std::string& name, const ImageF& image, float low = 0.0f, float high = 1.0f) {
    if (const char* folder = std::getenv("FLOWVID_FIGURES")) write_gray_image(std::string(folder) + "/" + name, image, low, high);
}

ImageF mask_image(const std::vector<std::uint8_t>& mask, int width, int height) {
    ImageF out(width, height);
    for (std::size_t i = 0; i < mask.size(); ++i) out.pixels[i] = mask[i] ? 1.0f : 0.0f;
    return out;
}

}  // namespace

TEST(ClothFootage, SegmentsAgainstTheBackgroundLikeTheMasks) {
    const formats::Capture& capture = static_capture();
    SegmentationSettings from_plate;
    from_plate.source = SegmentationSettings::Source::background;
    ClothFootage masks(capture), plate(capture, from_plate);
    EXPECT_TRUE(masks.uses_masks());
    EXPECT_FALSE(plate.uses_masks());
    for (int number : {1, 40}) {
        const ClothFrame a = masks.frame(number), b = plate.frame(number);
        const double iou = metrics::silhouette_iou(a.silhouette, b.silhouette);
        std::printf("[measured] frame %d: background segmentation vs mask IoU %.4f, xor %lld px of %lld\n", number, iou,
                    metrics::silhouette_xor(a.silhouette, b.silhouette), a.silhouette.area_px());
        EXPECT_GT(iou, 0.98);
        EXPECT_GT(a.silhouette.area_px(), 10000);
    }
}

TEST(ClothFootage, RefusesCapturesItCannotUse) {
    formats::Capture capture = static_capture();
    capture.kind = "rigid.toss";
    capture.projector.reset();
    const std::string messages = flowvid::testing::validation_messages([&] { ClothFootage footage(capture); });
    EXPECT_NE(messages.find("capture.json"), std::string::npos) << messages;
    EXPECT_NE(messages.find("/kind"), std::string::npos) << messages;
    EXPECT_NE(messages.find("/projector"), std::string::npos) << messages;
}

TEST(ClothFootage, ExpectedStripePeriodMatchesTheFrame) {
    const formats::Capture& capture = static_capture();
    const double period = expected_stripe_period_px(capture);
    std::printf("[measured] expected stripe period %.2f px\n", period);
    // Measured by hand on frame 1: about 12 rows per stripe in the middle of the swatch.
    EXPECT_GT(period, 9.0);
    EXPECT_LT(period, 15.0);
}

// Frame 1 of the static capture: the angle map is defined on most of the
// swatch and its stripes are coherent; the stripe renderer applied to the
// truth mesh of that frame gives nearly the same angle map, far closer than
// a flat swatch hung between the pins.
TEST(ClothFootage, RenderedTruthReproducesTheCapturedStripes) {
    const formats::Capture& capture = static_capture();
    ClothFootage footage(capture);
    const ClothFrame frame = footage.frame(1);
    AngleMapper mapper(AngleMapSettings::for_stripe_period(expected_stripe_period_px(capture)));

    video::ReferenceFrame real;
    real.number = 1;
    real.silhouette = frame.silhouette;
    mapper.compute(frame.gray, frame.silhouette, real.angles);
    video::prepare_reference(real);

    std::vector<float> coherence;
    for (std::size_t i = 0; i < real.angles.valid.size(); ++i)
        if (real.angles.valid[i]) coherence.push_back(real.angles.coherence[i]);
    const double valid_fraction = static_cast<double>(real.angles.valid_count()) / real.silhouette.area_px();
    std::printf("[measured] real frame 1: valid %.3f of the silhouette, median coherence %.3f, fold mask %lld px\n",
                valid_fraction, median(coherence), real.angles.mask_count());
    EXPECT_GT(valid_fraction, 0.85);
    EXPECT_GT(median(coherence), 0.9);

    const auto truth = formats::read_capture_truth_positions(capture);  // evaluation only
    ASSERT_TRUE(truth.has_value());
    const int rows = truth->grid_rows.value_or(24), cols = truth->grid_cols.value_or(24);
    const std::vector<std::array<int, 3>> triangles = grid_triangles(rows, cols);
    StripeRenderer renderer(*capture.camera, *capture.projector);

    auto evaluate = [&](const std::vector<Eigen::Vector3d>& vertices, const char* name, video::FrameError* edge) {
        const StripeImage rendered = renderer.render(vertices, triangles);
        const AngleMap sim = mapper.compute(rendered.image, rendered.silhouette);
        video::AngleMapMetricSettings settings;
        const video::FrameError e = video::angle_map_frame_error(real, sim, rendered.silhouette, settings);
        settings.silhouette_term = video::SilhouetteTerm::edge_distance;
        *edge = video::angle_map_frame_error(real, sim, rendered.silhouette, settings);
        std::printf("[measured] %s: E_k %.1f (fold %.1f rad^2 over %lld masked px, RMS %.2f deg; xor %.0f px; "
                    "edge distance %.0f px^2), IoU %.3f\n",
                    name, e.total, e.fold_rad2, e.masked_px, e.rms_angle_rad * 180 / kPi, e.silhouette, edge->silhouette,
                    metrics::silhouette_iou(real.silhouette, rendered.silhouette));
        figure(std::string("angle_") + name + ".png", angle_map_image(sim));
        figure(std::string("stripes_") + name + ".png", rendered.image);
        return e;
    };
    video::FrameError truth_edge, flat_edge;
    const video::FrameError e_truth = evaluate(vertices_of_frame(*truth, 0), "truth", &truth_edge);

    // A flat swatch hanging straight down between the pins' first positions.
    const Eigen::Vector3d left = capture.swatch->pins[0].positions_m.front();
    const Eigen::Vector3d right = capture.swatch->pins[1].positions_m.front();
    std::vector<Eigen::Vector3d> flat;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const double u = static_cast<double>(c) / (cols - 1), v = static_cast<double>(r) / (rows - 1);
            flat.push_back(left + u * (right - left) - (1.0 - v) * capture.swatch->height_m * Eigen::Vector3d::UnitZ());
        }
    const video::FrameError e_flat = evaluate(flat, "flat", &flat_edge);

    figure("frame1.png", frame.gray);
    figure("angle_real.png", angle_map_image(real.angles));
    figure("mask_real.png", mask_image(real.angles.gradient_mask, real.angles.width, real.angles.height));

    EXPECT_GT(e_truth.overlap_px, 20000);
    EXPECT_LT(e_truth.rms_angle_rad, 8.0 * kPi / 180.0);
    EXPECT_LT(e_truth.total, 0.25 * e_flat.total);
    EXPECT_LT(e_truth.fold_rad2, 0.25 * e_flat.fold_rad2);
    EXPECT_LT(truth_edge.silhouette, 0.1 * flat_edge.silhouette);
}

// Not a speed test (timings depend on the machine): prints what one
// simulated frame costs, render + angle map + metric, for the report.
TEST(ClothFootage, PrintsTheCostOfOneSimulatedFrame) {
    const formats::Capture& capture = static_capture();
    ClothFootage footage(capture);
    const ClothFrame frame = footage.frame(1);
    AngleMapper mapper(AngleMapSettings::for_stripe_period(expected_stripe_period_px(capture)));
    video::ReferenceFrame real;
    real.silhouette = frame.silhouette;
    mapper.compute(frame.gray, frame.silhouette, real.angles);
    video::prepare_reference(real);
    const auto truth = formats::read_capture_truth_positions(capture);
    ASSERT_TRUE(truth.has_value());
    const std::vector<Eigen::Vector3d> vertices = vertices_of_frame(*truth, 0);
    const auto triangles = grid_triangles(24, 24);
    StripeRenderer renderer(*capture.camera, *capture.projector);
    StripeImage rendered;
    AngleMap sim;
    const int repeats = std::getenv("FLOWVID_REPEATS") ? std::atoi(std::getenv("FLOWVID_REPEATS")) : 20;
    double render_s = 0, map_s = 0, metric_s = 0;
    timespec c0{}, c1{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c0);
    for (int i = 0; i < repeats; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        renderer.render(vertices, triangles, rendered);
        const auto t1 = std::chrono::steady_clock::now();
        mapper.compute(rendered.image, rendered.silhouette, sim);
        const auto t2 = std::chrono::steady_clock::now();
        const video::FrameError e = video::angle_map_frame_error(real, sim, rendered.silhouette);
        const auto t3 = std::chrono::steady_clock::now();
        EXPECT_GT(e.overlap_px, 0);
        render_s += std::chrono::duration<double>(t1 - t0).count();
        map_s += std::chrono::duration<double>(t2 - t1).count();
        metric_s += std::chrono::duration<double>(t3 - t2).count();
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &c1);
    const double cpu_s = static_cast<double>(c1.tv_sec - c0.tv_sec) + 1e-9 * static_cast<double>(c1.tv_nsec - c0.tv_nsec);
    std::printf("[measured] per 480x360 frame (wall): render %.2f ms, angle map %.2f ms, metric %.2f ms; "
                "process CPU time %.2f ms in all\n",
                1e3 * render_s / repeats, 1e3 * map_s / repeats, 1e3 * metric_s / repeats, 1e3 * cpu_s / repeats);
}
