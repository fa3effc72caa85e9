#pragma once
// Inverse simulation of a tossed rigid body from silhouettes (thesis 2.3):
// finds the initial position, orientation, linear and angular velocity and
// the direction of gravity in camera space, without a hand-given guess.
//
// Pipeline (docs/rigid.md has the details and measured figures):
//  1. Trajectory: the silhouette centroids trace the projected parabola of
//     the COM. With gravity's magnitude known (9.81 m/s^2 assumed) its image
//     curvature fixes the depth, the silhouette areas (against the mesh's
//     mean projected area) add a weak depth prior: a small least-squares fit
//     gives COM position, velocity and gravity (tilt, roll).
//  2. Orientation candidates: in the first two frames, every orientation of a
//     uniform SO(3) grid is rendered at the estimated position (re-centred
//     and re-scaled onto the observed silhouette) and scored by XOR; the
//     best distinct ones (non-maximum suppression up to the body's symmetry)
//     are polished by a 6-DOF pose fit on the edge distance.
//  3. Starts: every pair (candidate in frame 1, candidate in frame 2, body
//     symmetry) gives an orientation and an angular velocity; the pairs are
//     scored on the first frames and the best distinct ones kept.
//  4. Refinement: each start is optimized on a growing window of frames
//     (6, 12, 24, all; gravity frozen on the first), weaker starts dropped
//     between windows. Starts run on parallel threads; the result does not
//     depend on the thread count.

#include "flowvid/progress.hpp"
#include "flowvid/rigid/dynamics.hpp"
#include "flowvid/rigid/optimize.hpp"
#include "flowvid/rigid/silhouette_residuals.hpp"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::rigid {

enum class OptimizerKind { levenberg_marquardt, hybrid_gradient };
const char* optimizer_name(OptimizerKind kind);

// A rough guess, any subset; what is missing is estimated. Values hold at
// `time_s` relative to the first fitted frame; a guess at another time must
// be complete (position, orientation, both velocities) so it can be moved.
struct InitialGuess {
    double time_s = 0.0;
    std::optional<Eigen::Vector3d> origin_m;  // body-frame origin (files: "position_cam")
    std::optional<Eigen::Quaterniond> orientation;
    std::optional<Eigen::Vector3d> com_velocity_m_per_s;
    std::optional<Eigen::Vector3d> angular_velocity_rad_per_s;
    std::optional<Eigen::Vector3d> gravity_m_per_s2;  // only the direction is used
    bool complete() const { return origin_m && orientation && com_velocity_m_per_s && angular_velocity_rad_per_s; }
};

struct FitSettings {
    OptimizerKind optimizer = OptimizerKind::levenberg_marquardt;
    HybridMetric hybrid_metric = HybridMetric::edge_distance;
    int threads = 0;  // 0 = std::thread::hardware_concurrency()
    SimulationSettings simulation;
    std::optional<InitialGuess> guess;
    int orientation_samples = 2000;   // SO(3) grid per searched frame (about 12 degrees apart)
    int candidates_per_frame = 12;
    int starts = 8;                   // starts refined by the optimizer
    // A fit left above this edge error per frame (px^2; a good one is ~0.06)
    // searches again with this many candidates per frame and twice the starts,
    // keeping the better: on a small, fast-tumbling silhouette one frame's 12
    // best orientations can miss the true one.
    double wide_search_above_px2 = 0.5;
    int wide_candidates_per_frame = 120;
    int max_iterations = 40;          // per window (LM); hybrid: 5x this
    double gravity_magnitude_m_per_s2 = kStandardGravity_m_per_s2;
    double corner_radius_px = 1.5;    // see SilhouetteModel::set_corner_radius
    // Stages "trajectory", "candidates", "starts", "refine", fractions of the
    // whole fit; false cancels (the result then has status cancelled).
    Progress progress;
    std::function<void(const std::string&)> log;  // the library never prints
};

// How well one frame is matched.
struct FrameFit {
    int frame = 0;
    double edge_rms_px = 0.0;  // sqrt(E_k)
    long long xor_px = 0;      // eq. 2.5
    double iou = 0.0;
};

struct TrajectoryEstimate {
    Eigen::Vector3d com_m = Eigen::Vector3d::Zero();  // at time 0
    Eigen::Vector3d com_velocity_m_per_s = Eigen::Vector3d::Zero();
    GravityAngles gravity;
    double rms_centroid_px = 0.0;  // centroid track vs projected parabola
    int frames_used = 0;
};

struct FitResult {
    FlightParameters parameters;  // at time 0 = reference_frame
    int reference_frame = 0;      // the first fitted frame
    double fps = 0.0;
    double final_cost_px2 = 0.0;  // E = sum over fitted frames of E_k
    std::vector<FrameFit> frames;
    OptimizerReport report;       // of the winning start's last window
    OptimizerKind optimizer = OptimizerKind::levenberg_marquardt;
    TrajectoryEstimate trajectory;  // step 1
    int candidate_orientations = 0;
    int starts_scored = 0;
    int starts_refined = 0;
    bool widened = false;  // the wider search (FitSettings::wide_search_above_px2) gave this fit
    std::vector<double> start_costs_px2;  // final E of the starts that reached the last window, best first
    double seconds = 0.0;

    // The state at any frame (integrating forwards or backwards).
    RigidState state_at_frame(const RigidBody& body, int frame, const SimulationSettings& simulation = {}) const;
};

// Frames must be sorted by frame number, with time_s relative to the first.
FitResult fit_rigid(const RigidBody& body, const formats::CameraModel& camera, double fps,
                    const std::vector<FrameObservation>& frames, const FitSettings& settings);

// Step 1 on its own. With quadratic drag (FlightEffects::quadratic_drag_per_m)
// the COM follows dv/dt = g - k |v| v instead of a parabola, as in simulate().
TrajectoryEstimate estimate_trajectory(const SilhouetteModel& model, const std::vector<FrameObservation>& frames,
                                       double gravity_magnitude_m_per_s2 = kStandardGravity_m_per_s2,
                                       double quadratic_drag_per_m = 0.0);

// Deterministic, nearly uniform rotations (super-Fibonacci spirals, Alexa 2022).
std::vector<Eigen::Quaterniond> uniform_rotations(int count);

// Masks of frames first..last of a capture (time relative to `reference_frame`),
// thresholded at 0.5. Without masks, segments each frame against the
// background image (largest region differing by more than 10 %). Throws
// IoError naming the file that cannot be read, ValidationError when the
// capture has neither masks nor a background.
std::vector<FrameObservation> load_observations(const formats::Capture& capture, int first, int last,
                                                int reference_frame, int threads = 0);

// Predicted silhouettes (whole image) of the fitted motion at the given frames.
std::vector<metrics::Silhouette> predict_silhouettes(const RigidBody& body, const formats::CameraModel& camera,
                                                     const FitResult& fit, const std::vector<int>& frames,
                                                     const SimulationSettings& simulation = {});

}  // namespace flowvid::rigid
