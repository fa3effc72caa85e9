#pragma once
// Shape from the projector: a single-shot structured-light scan of the swatch
// in one frame of a cloth capture. The calibrated projector casts sine
// stripes, intensity = 0.5 + 0.5 sin(2 pi v_p / period) of the projector
// coordinate v_p (spec/capture.md). Their phase seen by the calibrated camera
// names v_p modulo one period; v_p and the camera ray through the pixel meet
// in one world point (triangulation).
//
// Method, per frame:
//  1. Phase: the linear image, less its local mean (a normalised Gaussian
//     inside the silhouette), is filtered with a bank of complex Gabor
//     kernels around the stripes' expected image frequency (from the
//     calibration, at the hanging swatch: expected_stripe_gradient). Per
//     pixel the strongest response's argument is the stripes' local phase (a
//     windowed Fourier-transform profilometry); its modulus over the local
//     mean is the stripes' modulation, the quality of that phase.
//  2. Unwrapping: quality-guided region growing (best pixels first); the
//     step between neighbours is the one the local stripe frequency (the
//     strongest filter's) predicts, corrected by the measured phase, and
//     growth never crosses a step that differs from the prediction by more
//     than max_step_rad (folds, occluding edges). Each connected region
//     carries one unknown whole number of periods.
//  3. Absolute periods: a pin is a point of known world position on the
//     swatch; its v_p is known. A region that reaches near a pin's image takes
//     the offset that makes its v_p, extrapolated to the pin's pixel, agree;
//     a region whose pins disagree slipped a period somewhere and is dropped.
//     Frames scanned in order reference a region by the previous frame's
//     scan instead where they overlap (the swatch moves much less than a
//     period's depth, about 6 cm in the captures, between frames).
//     A region without a pin takes the offset that best continues the depth
//     of an already-referenced neighbour across their common border, when one
//     offset clearly does; the rest stay unmeasured (NaN), never guessed.
//  4. Triangulation: the camera ray (distortion removed) meets the projector
//     surface of constant v_p (a plane through the projector's centre without
//     projector distortion; refined along the ray with it).
//
// Reads only what a fit may read: the frame, its silhouette, the calibration
// and the pins' positions.
#include "flowvid/formats/capture.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/video/image.hpp"

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <vector>

namespace flowvid::video {

struct StripeScanSettings {
    // The stripes' image-space gradient of v_p (projector pixels per image
    // pixel) the filter is tuned to; zero: expected_stripe_gradient(capture).
    Eigen::Vector2d stripe_gradient = Eigen::Vector2d::Zero();
    double window_periods = 0.55;     // Gaussian window sigma of each Gabor kernel, in its stripe periods
    // The filter bank: the expected frequency times each scale, turned by
    // each angle (folds compress, stretch and rotate the stripes).
    std::vector<double> bank_scales = {0.7, 1.0, 1.4};
    std::vector<double> bank_turns_deg = {-25.0, 0.0, 25.0};
    double min_modulation = 0.3;      // stripe amplitude over local mean below which no phase is kept
    int edge_margin_px = 4;           // silhouette pixels this close to its outline are not measured
    double max_step_rad = 1.2;        // unwrapping never crosses a neighbour step this far from the local frequency's
    double pin_radius_px = 10.0;      // pixels this close to a pin's image (plus twice the margin) extrapolate v_p to it
    int min_region_px = 40;           // smaller unwrapped regions are dropped (too little to reference)
    double border_tolerance_m = 0.02; // a pinless region joins a neighbour when their border depths agree to this
    // With the previous frame's scan: a region at least this fraction of
    // whose pixels it measured takes its periods from it (not from the pins).
    double min_temporal_overlap = 0.3;
};

// One frame's scan, per pixel of the whole image (row-major).
struct StripeScan {
    int width = 0;
    int height = 0;
    ImageF projector_coordinate;         // absolute v_p, NaN where not measured
    ImageF modulation;                   // stripe amplitude / local mean, 0 outside the silhouette
    std::vector<Eigen::Vector3f> points_m;  // world point per pixel, NaN where not measured
    long long silhouette_px = 0;         // pixels of the silhouette
    long long measured_px = 0;           // pixels with a point
    int regions_referenced = 0;          // unwrapped regions given absolute periods
    int regions_dropped = 0;             // regions left unmeasured (no pin, no clear neighbour, too small, inconsistent)
    int regions_inconsistent = 0;        // of those, regions whose pins disagreed on the periods
    bool measured(int x, int y) const {
        return std::isfinite(projector_coordinate.pixels[projector_coordinate.index(x, y)]);
    }
};

// Scans frames of one capture. Not thread-safe (holds scratch buffers); one
// per thread. Results do not depend on which object computes them.
class StripeScanner {
public:
    // Throws std::invalid_argument when the camera has no size, the pattern
    // has no positive period or an unknown axis, or the stripe gradient is 0.
    StripeScanner(formats::CameraModel camera, formats::Projector projector, StripeScanSettings settings);

    // `gray`: the frame's linear luminance; `silhouette`: the swatch;
    // `pins_m`: world positions of points on the swatch at this frame (its
    // pinned corners); `previous`: the scan of the frame before, when the
    // frames are scanned in order (it references the periods where it
    // overlaps). Throws std::invalid_argument when sizes differ from the
    // camera's.
    StripeScan scan(const ImageF& gray, const metrics::Silhouette& silhouette, const std::vector<Eigen::Vector3d>& pins_m,
                    const StripeScan* previous = nullptr);

    // The world point on the camera ray through `pixel` whose projector
    // coordinate is `v_p`; NaN when the ray does not meet it in front of
    // both (parallel, behind).
    Eigen::Vector3d triangulate(const Eigen::Vector2d& pixel, double v_p) const;
    // v_p of a world point (NaN behind the projector).
    double projector_coordinate(const Eigen::Vector3d& world_m) const;

    const StripeScanSettings& settings() const { return m_settings; }

private:
    formats::CameraModel m_camera;
    formats::Projector m_projector;
    StripeScanSettings m_settings;
    bool m_rows = true;
    Eigen::Vector3d m_camera_centre;
    Eigen::Matrix3d m_world_from_camera;  // rotation
};

// A scanner for `capture`'s calibration with the stripe gradient it predicts
// (settings.stripe_gradient when given). Throws ValidationError when the
// capture has no camera, projector or pins.
StripeScanner scanner_for(const formats::Capture& capture, StripeScanSettings settings = {});

// The pins' world positions at frame `number` (1-based from the capture's first).
std::vector<Eigen::Vector3d> pin_positions_at(const formats::Capture& capture, int number);

}  // namespace flowvid::video
