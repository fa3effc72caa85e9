#include "flowvid/video/angle_map.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>

namespace flowvid::video {

namespace {

constexpr double kPi = std::numbers::pi;

// The 1-D factors of the separable G2/H2 basis (Freeman & Adelson, tables 3
// and 4 of their paper give the 2-D formulas; every basis filter is a product
// f(x) g(y) of these, with the Gaussian split between the two factors):
//   G2a = 0.9213 (2x^2 - 1) e  = 0.9213 g2(x) g0(y)
//   G2b = 1.843 x y e          = 1.843  g1(x) g1(y)
//   G2c = 0.9213 (2y^2 - 1) e  = 0.9213 g0(x) g2(y)
//   H2a = 0.9780 (x^3 - 2.254 x) e          = 0.978 h3(x) g0(y)
//   H2b = 0.9780 (x^2 - 0.7515) y e         = 0.978 h2(x) g1(y)
//   H2c = 0.9780 (y^2 - 0.7515) x e         = 0.978 g1(x) h2(y)
//   H2d = 0.9780 (y^3 - 2.254 y) e          = 0.978 g0(x) h3(y)
// with e = exp(-(x^2 + y^2)).
enum Factor { g0, g1, g2, h2, h3, kFactorCount };

double factor_value(Factor f, double t) {
    const double e = std::exp(-t * t);
    switch (f) {
        case g0: return e;
        case g1: return t * e;
        case g2: return (2.0 * t * t - 1.0) * e;
        case h2: return (t * t - 0.7515) * e;
        case h3: return (t * t * t - 2.254 * t) * e;
        default: return 0.0;
    }
}

struct Basis {
    Factor along_x;
    Factor along_y;
    double gain;
};
constexpr std::array<Basis, 7> kBasis = {{
    {g2, g0, 0.9213}, {g1, g1, 1.843}, {g0, g2, 0.9213},                         // G2a, G2b, G2c
    {h3, g0, 0.978},  {h2, g1, 0.978}, {g1, h2, 0.978},  {g0, h3, 0.978},       // H2a .. H2d
}};

// Steering, derived from the formulas above with x' = x cos t + y sin t
// (the filter's axis at angle t, image coordinates):
//   G2_t = c^2 G2a + 2cs G2b + s^2 G2c
//   H2_t = c^3 H2a + 3c^2 s H2b + 3cs^2 H2c + s^3 H2d
// (expand 0.9213 (2x'^2 - 1) and 0.978 (x'^3 - 2.254 x'); 3 * 0.7515 = 2.254).
// The oriented energy E(t) = G2_t^2 + H2_t^2 to its lowest Fourier terms in
// 2t, C1 + C2 cos 2t + C3 sin 2t (Freeman & Adelson, appendix I), derived
// from the steering above with c^2 = (1 + cos 2t)/2, 2cs = sin 2t,
// c^3 = (3 cos t + cos 3t)/4, c^2 s = (sin t + sin 3t)/4,
// c s^2 = (cos t - cos 3t)/4, s^3 = (3 sin t - sin 3t)/4:
//   G2_t = A + B cos 2t + C sin 2t,   A = (Ga + Gc)/2, B = (Ga - Gc)/2, C = Gb
//   H2_t = P cos t + Q sin t + R cos 3t + S sin 3t,
//          P = 3(Ha + Hc)/4, Q = 3(Hb + Hd)/4, R = (Ha - 3Hc)/4, S = (3Hb - Hd)/4
// Squaring and keeping the terms in 1, cos 2t and sin 2t:
//   C1 = A^2 + (B^2 + C^2)/2 + (P^2 + Q^2 + R^2 + S^2)/2
//   C2 = 2AB + (P^2 - Q^2)/2 + PR + QS
//   C3 = 2AC + PQ + PS - QR
// (the tests recover stripe orientations to 0.002 degrees over the half
// circle, which any slip here would spoil).
inline void energy_coefficients(float ga, float gb, float gc, float ha, float hb, float hc, float hd, float& c1,
                                float& c2, float& c3) {
    const float A = 0.5f * (ga + gc), B = 0.5f * (ga - gc), C = gb;
    const float P = 0.75f * (ha + hc), Q = 0.75f * (hb + hd), R = 0.25f * (ha - 3.0f * hc), S = 0.25f * (3.0f * hb - hd);
    c1 = A * A + 0.5f * (B * B + C * C) + 0.5f * (P * P + Q * Q + R * R + S * S);
    c2 = 2.0f * A * B + 0.5f * (P * P - Q * Q) + P * R + Q * S;
    c3 = 2.0f * A * C + P * Q + P * S - Q * R;
}

// sepFilter2D with a unit kernel on the other axis: OpenCV's vectorised
// separable path (filter2D with a 1-D kernel takes the slower generic one).
const cv::Mat& unit_kernel() {
    static const cv::Mat unit = cv::Mat::ones(1, 1, CV_32F);
    return unit;
}

void filter_rows(const cv::Mat& src, const cv::Mat& kernel_row, cv::Mat& dst) {
    cv::sepFilter2D(src, dst, CV_32F, kernel_row, unit_kernel(), cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
}

void filter_columns(const cv::Mat& src, const cv::Mat& kernel_column, cv::Mat& dst) {
    cv::sepFilter2D(src, dst, CV_32F, unit_kernel(), kernel_column, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
}

// Bounding box of the object pixels, reading 8 bytes at a time (most of a
// frame is background).
render::PixelRect bounding_box(const metrics::Silhouette& s) {
    int x0 = s.width, y0 = s.height, x1 = 0, y1 = 0;
    for (int y = 0; y < s.height; ++y) {
        const std::uint8_t* row = s.pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(s.width);
        int first = -1, last = -1;
        int x = 0;
        for (; x + 8 <= s.width; x += 8) {
            std::uint64_t word;
            std::memcpy(&word, row + x, 8);
            if (word == 0) continue;
            for (int k = 0; k < 8; ++k)
                if (row[x + k]) {
                    if (first < 0) first = x + k;
                    last = x + k;
                }
        }
        for (; x < s.width; ++x)
            if (row[x]) {
                if (first < 0) first = x;
                last = x;
            }
        if (first < 0) continue;
        x0 = std::min(x0, first);
        x1 = std::max(x1, last + 1);
        y0 = std::min(y0, y);
        y1 = std::max(y1, y + 1);
    }
    if (x1 <= x0) return {};
    return {x0, y0, x1, y1};
}

// Sizes `map` for a width x height image and zeroes it. When it already has
// that size, only its previous region can hold values: clearing just that is
// much cheaper than clearing six whole-image arrays every frame.
void reset(AngleMap& map, int width, int height) {
    const std::size_t total = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    const bool same = map.width == width && map.height == height && map.angle_rad.size() == total &&
                      map.strength.size() == total && map.coherence.size() == total &&
                      map.gradient_rad_per_px.size() == total && map.valid.size() == total &&
                      map.gradient_mask.size() == total;
    if (!same) {
        map.width = width;
        map.height = height;
        map.angle_rad.assign(total, 0.0f);
        map.strength.assign(total, 0.0f);
        map.coherence.assign(total, 0.0f);
        map.gradient_rad_per_px.assign(total, 0.0f);
        map.valid.assign(total, 0);
        map.gradient_mask.assign(total, 0);
    } else {
        const render::PixelRect r = map.region.intersected(render::PixelRect::image(width, height));
        for (int y = r.y0; y < r.y1; ++y) {
            const std::size_t begin = map.index(r.x0, y), end = map.index(r.x1, y);
            std::fill(map.angle_rad.begin() + static_cast<std::ptrdiff_t>(begin), map.angle_rad.begin() + static_cast<std::ptrdiff_t>(end), 0.0f);
            std::fill(map.strength.begin() + static_cast<std::ptrdiff_t>(begin), map.strength.begin() + static_cast<std::ptrdiff_t>(end), 0.0f);
            std::fill(map.coherence.begin() + static_cast<std::ptrdiff_t>(begin), map.coherence.begin() + static_cast<std::ptrdiff_t>(end), 0.0f);
            std::fill(map.gradient_rad_per_px.begin() + static_cast<std::ptrdiff_t>(begin), map.gradient_rad_per_px.begin() + static_cast<std::ptrdiff_t>(end), 0.0f);
            std::fill(map.valid.begin() + static_cast<std::ptrdiff_t>(begin), map.valid.begin() + static_cast<std::ptrdiff_t>(end), std::uint8_t{0});
            std::fill(map.gradient_mask.begin() + static_cast<std::ptrdiff_t>(begin), map.gradient_mask.begin() + static_cast<std::ptrdiff_t>(end), std::uint8_t{0});
        }
    }
    map.region = {};
}

}  // namespace

AngleMapSettings AngleMapSettings::for_stripe_period(double period_px) {
    AngleMapSettings s;
    // G2 (second derivative of exp(-x^2)) responds most at 2 rad per unit, a
    // period of pi units.
    s.filter_scale_px = std::max(period_px, 2.5) / kPi;
    s.blur_sigma_px = std::max(0.35 * period_px, 1.0);
    s.edge_margin_px = std::max(1, static_cast<int>(std::lround(0.25 * period_px)));
    return s;
}

long long AngleMap::valid_count() const {
    long long n = 0;
    for (std::uint8_t v : valid) n += v != 0;
    return n;
}

long long AngleMap::mask_count() const {
    long long n = 0;
    for (std::uint8_t v : gradient_mask) n += v != 0;
    return n;
}

double orientation_difference(double a_rad, double b_rad) {
    double d = std::fmod(a_rad - b_rad, kPi);
    if (d >= 0.5 * kPi) d -= kPi;
    if (d < -0.5 * kPi) d += kPi;
    return d;
}

float orientation_difference(float a_rad, float b_rad) {
    constexpr float pi = static_cast<float>(kPi);
    float d = a_rad - b_rad;  // both in (-pi/2, pi/2] in angle maps: one wrap suffices
    while (d >= 0.5f * pi) d -= pi;
    while (d < -0.5f * pi) d += pi;
    return d;
}

struct AngleMapper::Impl {
    AngleMapSettings settings;
    int radius = 0;
    std::array<cv::Mat, kFactorCount> rows;     // 1 x (2r+1)
    std::array<cv::Mat, kFactorCount> columns;  // (2r+1) x 1
    // Scratch.
    cv::Mat input;
    std::array<cv::Mat, kFactorCount> row_pass;
    std::array<cv::Mat, 7> response;
    std::array<cv::Mat, 3> coefficient;
    cv::Mat inside, eroded;
};

AngleMapper::AngleMapper(AngleMapSettings settings) : m_impl(std::make_unique<Impl>()) {
    if (!(settings.filter_scale_px > 0.0) || !(settings.kernel_radius_units > 0.0) || settings.blur_sigma_px < 0.0 ||
        settings.edge_margin_px < 0)
        throw std::invalid_argument("AngleMapSettings: filter_scale_px and kernel_radius_units must be positive, "
                                    "blur_sigma_px and edge_margin_px not negative");
    m_impl->settings = settings;
    const int r = std::max(1, static_cast<int>(std::ceil(settings.kernel_radius_units * settings.filter_scale_px)));
    m_impl->radius = r;
    for (int f = 0; f < kFactorCount; ++f) {
        cv::Mat row(1, 2 * r + 1, CV_32F);
        for (int k = -r; k <= r; ++k)
            row.at<float>(0, k + r) = static_cast<float>(factor_value(static_cast<Factor>(f), k / settings.filter_scale_px));
        m_impl->rows[static_cast<std::size_t>(f)] = row;
        m_impl->columns[static_cast<std::size_t>(f)] = row.t();
    }
}

AngleMapper::~AngleMapper() = default;
AngleMapper::AngleMapper(AngleMapper&&) noexcept = default;
AngleMapper& AngleMapper::operator=(AngleMapper&&) noexcept = default;

const AngleMapSettings& AngleMapper::settings() const { return m_impl->settings; }
int AngleMapper::kernel_radius_px() const { return m_impl->radius; }

AngleMap AngleMapper::compute(const ImageF& image, const metrics::Silhouette& silhouette) {
    AngleMap map;
    compute(image, silhouette, map);
    return map;
}

AngleMap AngleMapper::compute(const ImageF& image) {
    metrics::Silhouette all(image.width, image.height);
    std::fill(all.pixels.begin(), all.pixels.end(), std::uint8_t{1});
    return compute(image, all);
}

void AngleMapper::compute(const ImageF& image, const metrics::Silhouette& silhouette, AngleMap& out) {
    if (image.width != silhouette.width || image.height != silhouette.height)
        throw std::invalid_argument("angle map: image " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                                    " and silhouette " + std::to_string(silhouette.width) + "x" +
                                    std::to_string(silhouette.height) + " differ in size");
    Impl& m = *m_impl;
    const AngleMapSettings& s = m.settings;
    const int width = image.width, height = image.height;
    reset(out, width, height);
    const render::PixelRect object = bounding_box(silhouette);
    out.region = object;
    if (object.empty()) return;
    // Filter a padded rectangle so that every object pixel sees its full
    // kernel (replicated at the image border). Beyond one kernel radius from
    // the object the input is the constant fill, where the zero-mean filters
    // respond with ~0: the blur's replicated border sees the same ~0 there,
    // so the blur needs no further padding.
    const render::PixelRect padded =
        object.expanded(m.radius + 2).intersected(render::PixelRect::image(width, height));
    const int pw = padded.width(), ph = padded.height();

    // Outside the silhouette: the mean inside, so the outline adds little energy.
    double sum = 0.0;
    long long count = 0;
    for (int y = object.y0; y < object.y1; ++y)
        for (int x = object.x0; x < object.x1; ++x)
            if (silhouette.at(x, y)) {
                sum += image.at(x, y);
                ++count;
            }
    const float fill = static_cast<float>(sum / static_cast<double>(std::max(count, 1LL)));
    m.input.create(ph, pw, CV_32F);
    for (int y = 0; y < ph; ++y) {
        float* row = m.input.ptr<float>(y);
        const std::size_t offset = image.index(padded.x0, y + padded.y0);
        const float* src = image.pixels.data() + offset;
        const std::uint8_t* in = silhouette.pixels.data() + offset;
        for (int x = 0; x < pw; ++x) row[x] = in[x] ? src[x] : fill;
    }

    // 5 row passes, then 7 column passes.
    for (int f = 0; f < kFactorCount; ++f)
        filter_rows(m.input, m.rows[static_cast<std::size_t>(f)], m.row_pass[static_cast<std::size_t>(f)]);
    for (std::size_t b = 0; b < kBasis.size(); ++b) {
        filter_columns(m.row_pass[kBasis[b].along_x], m.columns[kBasis[b].along_y], m.response[b]);
        m.response[b] *= kBasis[b].gain;
    }

    // Energy coefficients per pixel.
    for (cv::Mat& c : m.coefficient) c.create(ph, pw, CV_32F);
    for (int y = 0; y < ph; ++y) {
        const float* __restrict ra = m.response[0].ptr<float>(y);
        const float* __restrict rb = m.response[1].ptr<float>(y);
        const float* __restrict rc = m.response[2].ptr<float>(y);
        const float* __restrict rd = m.response[3].ptr<float>(y);
        const float* __restrict re = m.response[4].ptr<float>(y);
        const float* __restrict rf = m.response[5].ptr<float>(y);
        const float* __restrict rg = m.response[6].ptr<float>(y);
        float* __restrict out1 = m.coefficient[0].ptr<float>(y);
        float* __restrict out2 = m.coefficient[1].ptr<float>(y);
        float* __restrict out3 = m.coefficient[2].ptr<float>(y);
        for (int x = 0; x < pw; ++x)
            energy_coefficients(ra[x], rb[x], rc[x], rd[x], re[x], rf[x], rg[x], out1[x], out2[x], out3[x]);
    }
    // +-3 sigma (OpenCV's default for float images is +-4 sigma: 30 % more work for 0.3 % of the weight).
    const int blur_size = 2 * static_cast<int>(std::ceil(3.0 * s.blur_sigma_px)) + 1;
    if (s.blur_sigma_px > 0.0)
        for (cv::Mat& c : m.coefficient)
            cv::GaussianBlur(c, c, cv::Size(blur_size, blur_size), s.blur_sigma_px, s.blur_sigma_px, cv::BORDER_REPLICATE);

    // Valid pixels: the silhouette eroded by the margin (a disc).
    m.inside.create(ph, pw, CV_8U);
    for (int y = 0; y < ph; ++y) {
        std::uint8_t* row = m.inside.ptr<std::uint8_t>(y);
        for (int x = 0; x < pw; ++x) row[x] = silhouette.at(x + padded.x0, y + padded.y0) ? 255 : 0;
    }
    if (s.edge_margin_px > 0) {
        const int k = 2 * s.edge_margin_px + 1;
        // Beyond the image the object continues (the camera cut it, not its outline).
        cv::erode(m.inside, m.eroded, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)), cv::Point(-1, -1), 1,
                  cv::BORDER_REPLICATE);
    } else {
        m.inside.copyTo(m.eroded);
    }

    const float half_pi = static_cast<float>(0.5 * kPi);
    const float min_coherence = static_cast<float>(s.min_coherence);
    for (int y = object.y0; y < object.y1; ++y) {
        const int py = y - padded.y0;
        const float* c1 = m.coefficient[0].ptr<float>(py);
        const float* c2 = m.coefficient[1].ptr<float>(py);
        const float* c3 = m.coefficient[2].ptr<float>(py);
        const std::uint8_t* ok = m.eroded.ptr<std::uint8_t>(py);
        for (int x = object.x0; x < object.x1; ++x) {
            const int px = x - padded.x0;
            if (!ok[px]) continue;
            const std::size_t i = out.index(x, y);
            const float strength = std::sqrt(c2[px] * c2[px] + c3[px] * c3[px]);
            const float coherence = c1[px] > 0.0f ? strength / c1[px] : 0.0f;
            // The filter axis (across the stripes) is arg(C2, C3) / 2; the
            // stripes run at right angles to it.
            float angle = 0.5f * std::atan2(c3[px], c2[px]) + half_pi;
            if (angle > half_pi) angle -= 2.0f * half_pi;
            out.angle_rad[i] = angle;
            out.strength[i] = strength;
            out.coherence[i] = coherence;
            out.valid[i] = coherence >= min_coherence && strength > 0.0f ? 1 : 0;
        }
    }

    // |grad theta| with orientations wrapped mod pi: central differences where
    // both neighbours are valid, one-sided at the edge of the valid region.
    const float tau = static_cast<float>(s.gradient_threshold_rad_per_px);
    auto derivative = [&](std::size_t i, std::size_t minus, std::size_t plus, bool has_minus, bool has_plus) {
        const bool m_ok = has_minus && out.valid[minus];
        const bool p_ok = has_plus && out.valid[plus];
        if (m_ok && p_ok) return 0.5f * orientation_difference(out.angle_rad[plus], out.angle_rad[minus]);
        if (p_ok) return orientation_difference(out.angle_rad[plus], out.angle_rad[i]);
        if (m_ok) return orientation_difference(out.angle_rad[i], out.angle_rad[minus]);
        return 0.0f;
    };
    for (int y = object.y0; y < object.y1; ++y) {
        for (int x = object.x0; x < object.x1; ++x) {
            const std::size_t i = out.index(x, y);
            if (!out.valid[i]) continue;
            const float dx = derivative(i, i - 1, i + 1, x > 0, x + 1 < width);
            const float dy = derivative(i, i - static_cast<std::size_t>(width), i + static_cast<std::size_t>(width), y > 0,
                                        y + 1 < height);
            const float g = std::sqrt(dx * dx + dy * dy);
            out.gradient_rad_per_px[i] = g;
            out.gradient_mask[i] = g >= tau ? 1 : 0;
        }
    }
}

ImageF angle_map_image(const AngleMap& map, float invalid_value) {
    ImageF out(map.width, map.height, invalid_value);
    for (std::size_t i = 0; i < out.pixels.size(); ++i)
        if (map.valid[i]) out.pixels[i] = static_cast<float>((map.angle_rad[i] + 0.5 * kPi) / kPi);
    return out;
}

}  // namespace flowvid::video
