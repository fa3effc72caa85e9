#pragma once
// Angle maps of projected stripes (thesis 2.4.3, figure 2.9): the dominant
// local orientation of the stripe pattern at every pixel, measured with the
// steerable quadrature pair G2/H2 of Freeman & Adelson ("The design and use
// of steerable filters", 1991, appendix I), and the gradient mask M_k of
// eq. 2.19 that keeps the pixels where the orientation changes (folds).
//
// Method: the image is filtered with the 7 separable basis filters (3 for G2,
// 4 for H2); the oriented energy E(theta) = (G2_theta)^2 + (H2_theta)^2 is,
// to its lowest Fourier terms, C1 + C2 cos 2 theta + C3 sin 2 theta. The
// coefficients C1..C3 are blurred with a Gaussian (the thesis blurs the
// coefficients, not the angles) and the dominant orientation is
// arg(C2, C3) / 2. The steering coefficients and C1..C3 are derived in
// angle_map.cpp from the filter definitions.
//
// Conventions: image coordinates (x right, y down). The angle map holds the
// direction *along* the stripes in (-pi/2, pi/2]: 0 for horizontal stripes,
// positive when the stripe direction turns from +x towards +y (clockwise as
// seen on screen). Orientations are defined mod pi: compare them with
// orientation_difference().

#include "flowvid/metrics/silhouette.hpp"
#include "flowvid/render/rasterizer.hpp"
#include "flowvid/video/image.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace flowvid::video {

struct AngleMapSettings {
    // Pixels per unit of the filter formulas (G2a = 0.9213 (2x^2 - 1) exp(-(x^2 + y^2)), ...).
    // G2 peaks at a period of pi units: for_stripe_period() matches it to the stripes.
    double filter_scale_px = 3.8;
    // Half-width of the kernels in filter units (exp(-2.7^2) = 7e-4).
    double kernel_radius_units = 2.7;
    // Gaussian blur of the energy coefficients C1, C2, C3, pixels.
    double blur_sigma_px = 4.0;
    // tau of eq. 2.19: |grad theta| >= tau marks a fold pixel, radians per pixel.
    double gradient_threshold_rad_per_px = 0.03;
    // Pixels closer than this to the silhouette boundary are not valid: the
    // filters straddle the boundary there and see the outline, not the stripes.
    int edge_margin_px = 3;
    // Pixels whose coherence (strength / C1) is below this are not valid
    // (no stripes seen there, e.g. shadow). Clean stripes give about 1.3.
    double min_coherence = 0.2;

    // Settings for stripes of about `period_px` image pixels.
    static AngleMapSettings for_stripe_period(double period_px);
};

// Per pixel of the whole image, row-major; values outside `region` are zero
// and not valid.
struct AngleMap {
    int width = 0;
    int height = 0;
    render::PixelRect region;                 // where the values were computed
    std::vector<float> angle_rad;             // stripe direction, (-pi/2, pi/2]
    std::vector<float> strength;              // sqrt(C2^2 + C3^2), oriented energy (image units^2)
    std::vector<float> coherence;             // strength / C1: ~1.3 for one clean orientation, 0 when isotropic
    std::vector<float> gradient_rad_per_px;   // |grad theta| (eq. 2.19), 0 where not valid
    std::vector<std::uint8_t> valid;          // silhouette minus margin, coherent
    std::vector<std::uint8_t> gradient_mask;  // M_k: valid and |grad theta| >= tau

    std::size_t index(int x, int y) const {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    }
    long long valid_count() const;
    long long mask_count() const;
};

// Difference a - b of two orientations (mod pi), wrapped into [-pi/2, pi/2).
double orientation_difference(double a_rad, double b_rad);
float orientation_difference(float a_rad, float b_rad);

// Computes angle maps. Holds the kernels and scratch buffers: reuse one per
// thread (not thread-safe); results do not depend on which object computes them.
class AngleMapper {
public:
    explicit AngleMapper(AngleMapSettings settings = {});
    ~AngleMapper();
    AngleMapper(AngleMapper&&) noexcept;
    AngleMapper& operator=(AngleMapper&&) noexcept;
    AngleMapper(const AngleMapper&) = delete;
    AngleMapper& operator=(const AngleMapper&) = delete;

    const AngleMapSettings& settings() const;
    int kernel_radius_px() const;

    // Angle map of `image` inside `silhouette` (same size; pixels outside it
    // are replaced by the mean inside before filtering, so the outline
    // contrast does not dominate the orientation near the edge). `out` is
    // reused. Throws std::invalid_argument when the sizes differ.
    void compute(const ImageF& image, const metrics::Silhouette& silhouette, AngleMap& out);
    AngleMap compute(const ImageF& image, const metrics::Silhouette& silhouette);
    // The whole image, no silhouette.
    AngleMap compute(const ImageF& image);

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// The angle map as an image for figures: angle mapped to [0, 1] over
// (-pi/2, pi/2], `invalid_value` where not valid.
ImageF angle_map_image(const AngleMap& map, float invalid_value = 0.0f);

}  // namespace flowvid::video
