// flowvid fit rigid: inverse simulation of a tossed rigid body from its silhouettes.

#include "commands/fit.hpp"
#include "frame_options.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/rigid/fit.hpp"
#include "flowvid/rigid/fit_file.hpp"

#include <cmath>
#include <iostream>
#include <memory>

namespace flowvid::cli {
namespace {

struct FitRigidOptions {
    std::string capture;
    std::string out;
    FrameOptions frames;
    std::string guess;
    std::string optimizer = "lm";
    std::string metric = "edge";
    int threads = 0;
    int starts = 8;
    bool json = false;
};

nlohmann::json summary_of(const rigid::RigidFitRecord& record, const rigid::RigidBody& body, const std::string& out) {
    const nlohmann::json document = rigid::rigid_fit_to_json(record, body);
    return {{"fit", out},
            {"frames", std::to_string(record.first_fitted_frame) + ":" + std::to_string(record.last_fitted_frame)},
            {"initial_frame", record.initial_frame},
            {"initial", document["initial"]},
            {"gravity_cam", document["gravity_cam"]},
            {"gravity_angles_deg", document["gravity_angles_deg"]},
            {"error", document["error"]},
            {"seconds", record.seconds}};
}

int run_fit_rigid(const FitRigidOptions& options, const GlobalOptions& global) {
    formats::create_parent_folder(options.out);
    const formats::Capture capture = formats::read_capture_of_kind(options.capture, {"rigid.toss"}, "flowvid fit rigid");
    const std::pair<int, int> frames = resolve_capture_frames(options.frames, capture);
    if (frames.second - frames.first + 1 < 3) {
        throw UsageError("", "", "frames " + std::to_string(frames.first) + ":" + std::to_string(frames.second) +
                                     ": a fit needs at least 3 frames",
                         "give a longer --frames A:B");
    }
    const rigid::RigidBody body = rigid::RigidBody::from_capture(*capture.rigid);

    rigid::FitSettings settings;
    settings.optimizer = options.optimizer == "hybrid" ? rigid::OptimizerKind::hybrid_gradient
                                                       : rigid::OptimizerKind::levenberg_marquardt;
    settings.hybrid_metric = options.metric == "xor" ? rigid::HybridMetric::xor_pixels : rigid::HybridMetric::edge_distance;
    settings.threads = options.threads;
    settings.starts = options.starts;
    if (!options.guess.empty()) {
        const rigid::GuessFile guess = rigid::read_guess_file(options.guess);
        settings.guess = guess.guess;
        const int at = guess.initial_frame.value_or(capture.frames.first);
        settings.guess->time_s = (at - frames.first) / capture.fps;
        if (settings.guess->time_s != 0.0 && !settings.guess->complete())
            throw ValidationError({Problem{Problem::Severity::error, options.guess, "/initial",
                                           "the guess holds at frame " + std::to_string(at) + " but the fit starts at frame " +
                                               std::to_string(frames.first) + ", and it is incomplete, so it cannot be moved there",
                                           "give all of position_cam, orientation_cam_wxyz, com_velocity_cam and "
                                           "angular_velocity_cam, or set \"initial_frame\": " + std::to_string(frames.first)}});
    }
    ProgressBar progress(global, "fit rigid");
    settings.progress = [&](const ProgressReport& p) {
        progress.update(p.fraction, p.stage);
        return true;
    };
    if (!global.quiet) settings.log = [](const std::string& text) { log_message(text); };

    const std::vector<rigid::FrameObservation> observations =
        rigid::load_observations(capture, frames.first, frames.second, frames.first, options.threads);
    const rigid::FitResult fit = rigid::fit_rigid(body, *capture.camera, capture.fps, observations, settings);
    progress.done();
    if (fit.report.status == rigid::OptimizerReport::Status::failed) {
        log_message("error: the fit failed: " + fit.report.reason);
        return kExitFailure;
    }
    if (fit.report.status == rigid::OptimizerReport::Status::cancelled) return kExitInterrupted;

    const rigid::RigidFitRecord record = rigid::make_rigid_fit_record(fit, body, capture, options.capture);
    rigid::write_rigid_fit(options.out, record, body);
    const nlohmann::json summary = summary_of(record, body, options.out);
    if (options.json) std::cout << summary.dump(2) << '\n';
    else std::cout << human_readable(summary);
    return kExitOk;
}

const RegisterFitKind registration{FitKind{
    "rigid", "initial state and gravity of a tossed rigid body (rigid.toss capture)", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<FitRigidOptions>();
        app.footer(
            "Finds the rigid body's position, orientation, linear and angular velocity at the capture's\n"
            "first frame and the direction of gravity, all in camera space, by matching simulated\n"
            "silhouettes to the capture's masks (or to a background segmentation). No guess is needed:\n"
            "the fit searches orientations and spins itself. Gravity's magnitude is taken as 9.81 m/s^2.\n"
            "Writes FILE (format flowvid.rigid_fit, keys as in a capture's truth/truth.json) with the\n"
            "final error and per-frame residuals; prints a summary on stdout (--json for machines).\n"
            "See docs/rigid.md; the file: formats/specs/rigid_fit.md.\n\n"
            "Examples:\n"
            "  flowvid fit rigid --capture ../shared/captures/rigid-toss-major --out fit.json\n"
            "  flowvid fit rigid --capture toss/ --out half.json --frames 1:18\n"
            "  flowvid fit rigid --capture toss/ --out fit.json --guess guess.json --optimizer hybrid\n\n"
            "Exit codes: 0 ok, 1 the fit failed, 2 bad option, 3 invalid capture or guess (every problem\n"
            "is listed with its file and field), 4 unreadable file.");
        app.add_option("--capture", options->capture, "capture folder (kind rigid.toss)")->required();
        app.add_option("--out", options->out, "fit file to write (JSON)")->required();
        add_frame_options(app, options->frames, "frames A to B to fit (inclusive, numbered as in capture.json)", "the first N frames", "all");
        app.add_option("--guess", options->guess,
                       "JSON with a rough initial state: any of initial.position_cam, initial.orientation_cam_wxyz, "
                       "initial.com_velocity_cam, initial.angular_velocity_cam, gravity_cam (e.g. an earlier fit)");
        app.add_option("--optimizer", options->optimizer,
                       "lm: Levenberg-Marquardt on edge-distance residuals; hybrid: the thesis's gradient descent")
            ->check(CLI::IsMember({"lm", "hybrid"}))
            ->capture_default_str();
        app.add_option("--metric", options->metric, "metric of the hybrid optimizer: edge (eq. 2.6) or xor (eq. 2.5)")
            ->check(CLI::IsMember({"edge", "xor"}))
            ->capture_default_str();
        app.add_option("--threads", options->threads, "worker threads (0 = all cores); results do not depend on it")
            ->check(CLI::Range(0, 256))
            ->capture_default_str();
        app.add_option("--starts", options->starts, "starts refined by the optimizer (multi-start)")
            ->check(CLI::Range(1, 64))
            ->capture_default_str();
        app.add_flag("--json", options->json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_fit_rigid(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
