#pragma once
// The cloth metric of the thesis (2.4.3, eq. 2.19-2.24): per frame k
//
//   E_k = sum over overlapping pixels of M_k (theta_real - theta_sim)^2     (eq. 2.20)
//         + alpha * silhouette term                                         (eq. 2.21, 2.23)
//   E   = sum_k w_k E_k                                                     (eq. 2.24, with weights)
//
// theta are angle maps (video/angle_map.hpp), their difference wrapped mod pi
// into [-pi/2, pi/2) (radians); M_k is the gradient mask of the real frame
// (eq. 2.19; optionally of either frame); "overlapping" means valid in both
// angle maps. The silhouette term is the XOR pixel count |A_real - A_sim|
// (eq. 2.21, the thesis's) or the symmetric silhouette-edge distance of the
// rigid-body chapter (eq. 2.6, squared pixels, distance transform), which
// keeps a gradient when the silhouettes do not overlap at all. Weights w_k
// let late frames, where cloth is chaotic (captures README: "How predictable
// the cloth is"), count less.

#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/video/angle_map.hpp"

#include <vector>

namespace flowvid::video {

enum class SilhouetteTerm {
    pixel_xor,      // eq. 2.21: mismatched pixels
    edge_distance,  // eq. 2.6, both directions: sum of squared edge distances, px^2
};

enum class GradientMaskSource {
    real,                // thesis: M_k of the video frame
    real_or_simulated,   // folds of either frame (a fold the simulation has and the video lacks also counts)
};

struct AngleMapMetricSettings {
    double alpha = 0.1;  // weight of the silhouette term (thesis: 0.1)
    SilhouetteTerm silhouette_term = SilhouetteTerm::pixel_xor;
    GradientMaskSource mask_source = GradientMaskSource::real;
    // Weight of overlapping pixels outside the gradient mask (thesis: 0, the
    // metric ignores planar regions).
    double planar_weight = 0.0;
};

// The real side of one frame, prepared once per fit.
struct ReferenceFrame {
    int number = 0;                 // capture frame number (1-based)
    AngleMap angles;
    metrics::Silhouette silhouette;
    double weight = 1.0;            // w_k
    // Distance to the real silhouette edge (edge_distance term); filled by prepare_reference().
    metrics::DistanceField edge_distance;
};

// Fills `reference.edge_distance` (once, when the edge-distance term is used).
void prepare_reference(ReferenceFrame& reference);

struct FrameError {
    double fold_rad2 = 0.0;        // eq. 2.20
    double silhouette = 0.0;       // eq. 2.21 (pixels) or eq. 2.6 (px^2)
    double total = 0.0;            // fold + alpha * silhouette (unweighted E_k)
    long long overlap_px = 0;      // valid in both angle maps
    long long masked_px = 0;       // overlap pixels with M_k = 1
    double rms_angle_rad = 0.0;    // RMS of theta_real - theta_sim over the masked overlap (diagnostic)
};

// E_k of one frame. `simulated_angles` / `simulated_silhouette` come from the
// stripe renderer + the same angle-map settings. Sizes must agree
// (std::invalid_argument otherwise). For the edge-distance term, call
// prepare_reference() on `real` once; without it the real side's distance
// field is recomputed on every call (correct, slower).
FrameError angle_map_frame_error(const ReferenceFrame& real, const AngleMap& simulated_angles,
                                 const metrics::Silhouette& simulated_silhouette, const AngleMapMetricSettings& settings = {});

struct SequenceError {
    double total = 0.0;               // sum_k w_k E_k
    std::vector<FrameError> frames;   // unweighted, in order
};
// Adds up frames: `frames[k]` with weight `weights[k]` (sizes must agree).
SequenceError combine_frames(const std::vector<FrameError>& frames, const std::vector<double>& weights);

// Frame weights: 1 for the first `full_weight_frames` frames, then halving
// every `half_life_frames` (<= 0: all 1).
std::vector<double> decaying_frame_weights(int count, int full_weight_frames, double half_life_frames);

}  // namespace flowvid::video
