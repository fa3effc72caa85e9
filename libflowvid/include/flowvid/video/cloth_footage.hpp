#pragma once
// The video side of cloth fitting: frames of a cloth capture as gray images,
// the swatch's silhouette (from the capture's masks, or segmented against the
// background plate), and the stripe period the calibration predicts (to tune
// the angle-map filters). Reads only what a fit may read: capture.json,
// frames, masks, background; never truth/.

#include "flowvid/formats/capture.hpp"
#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/video/image.hpp"

#include <memory>
#include <optional>

namespace flowvid::video {

struct SegmentationSettings {
    enum class Source {
        automatic,   // the capture's masks when it has them, else the background plate
        masks,       // the capture's masks (ValidationError when it has none)
        background,  // difference against background.png (ValidationError when it has none)
    };
    Source source = Source::automatic;
    // A pixel is object when max over R, G, B of |frame - background| (sRGB
    // values in [0, 1]) exceeds this; <= 0 picks it per frame with Otsu's
    // method on the difference image (floored at 6 noise sigmas: 6/255).
    double difference_threshold = 0.0;
    int open_radius_px = 1;   // removes isolated noise pixels
    int close_radius_px = 2;  // closes dark stripe troughs that fall under the threshold
    bool keep_largest_component = true;
    bool fill_holes = true;
};

// The swatch silhouette of `frame` against `background` (same size, any
// channel count). Throws std::invalid_argument when the sizes differ.
metrics::Silhouette segment_against_background(const formats::Image& frame, const formats::Image& background,
                                               const SegmentationSettings& settings = {});

struct ClothFrame {
    int number = 0;                  // 1-based frame number of the capture
    ImageF gray;                     // linear luminance
    metrics::Silhouette silhouette;  // the swatch
};

// Frame access for a cloth capture. Not thread-safe (one per thread).
class ClothFootage {
public:
    // Throws ValidationError (naming capture.json and the field) when the
    // capture is not a cloth capture, lacks camera or projector, or the
    // segmentation source it asks for is missing.
    explicit ClothFootage(const formats::Capture& capture, SegmentationSettings segmentation = {});
    ~ClothFootage();
    ClothFootage(ClothFootage&&) noexcept;
    ClothFootage& operator=(ClothFootage&&) noexcept;

    const formats::Capture& capture() const;
    const formats::CameraModel& camera() const;
    const formats::Projector& projector() const;
    int first() const;
    int count() const;
    int last() const;
    // Whether silhouettes come from masks (else from the background plate).
    bool uses_masks() const;

    // Frame `number` (first..last): gray image and silhouette. Throws
    // std::out_of_range outside the capture, IoError / ValidationError from
    // reading the files.
    ClothFrame frame(int number);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// Image-space period (pixels) of the projected stripes on a swatch hanging
// vertically below the pins, from the calibration and the first pin
// positions only (no truth): the period the angle-map filters should be
// tuned to. Throws ValidationError when the capture is not a cloth capture.
double expected_stripe_period_px(const formats::Capture& capture);

// The same estimate as a vector: the image gradient of the projector
// coordinate v_p (projector pixels per image pixel) on that hanging swatch.
// The stripes run across it; its length is period_px / the image period.
Eigen::Vector2d expected_stripe_gradient(const formats::Capture& capture);

}  // namespace flowvid::video
