#include "flowvid/flow/synthesis.hpp"

#include "flowvid/flow/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace flowvid::flow {

namespace {

// Detail-preserving blending rescales detail by at most this (two groups
// mixed evenly: sqrt(2)), around a local mean over this radius.
constexpr float kMaxDetailGain = 1.4142f;
constexpr int kDetailRadiusPx = 2;

double smoothstep01(double x) {
    const double t = std::clamp(x, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// Texture over the background at coverage c: covering it (whole patches), or
// screened over it (the moving layer's residuals, TextureLayer::moving).
inline void composite(float* out, const float tex[3], float c, bool screen) {
    for (int k = 0; k < 3; ++k)
        out[k] = screen ? std::max(0.0f, out[k] + tex[k] * c * (1.0f - std::min(out[k], kMovingLayerMaxStill)))
                        : out[k] * (1.0f - c) + std::max(0.0f, tex[k]) * c;
}

// SynthesisSettings::overlap_sharpness at one pixel where groups of patches
// showing different input frames overlap: the pixel's colour (rgbw,
// premultiplied sum; its total weight is kept) becomes the groups' colours
// weighted by W_g^exponent, and the group weights become those powers (the
// detail gain then follows them). group_rgb: the sums of weight x colour of
// the second group and of the rest (kGroupColourFloats; the first group's is
// the total's remainder, so a pixel of one group costs no colour sums).
constexpr std::size_t kGroupColourFloats = 6;
void sharpen_groups(float* rgbw, float& w0, float& w1, float& w2, const float* group_rgb, float exponent) {
    if (!(w1 > 0.0f) || rgbw[3] <= 1e-6f) return;
    float* weights[3] = {&w0, &w1, &w2};
    float sums[9];
    for (int k = 0; k < 3; ++k) {
        sums[3 + k] = group_rgb[k];
        sums[6 + k] = group_rgb[3 + k];
        sums[k] = rgbw[k] - sums[3 + k] - sums[6 + k];
    }
    float num[3] = {0.0f, 0.0f, 0.0f}, den = 0.0f;
    for (int g = 0; g < 3; ++g) {
        const float w = *weights[g];
        if (w <= 1e-9f) {
            *weights[g] = 0.0f;
            continue;
        }
        // The default exponent 4 by multiplication: powf was a tenth of a frame's time.
        const float powered = exponent == 4.0f ? (w * w) * (w * w) : std::pow(w, exponent);
        for (int k = 0; k < 3; ++k) num[k] += powered * (sums[3 * g + k] / w);
        den += powered;
        *weights[g] = powered;
    }
    if (den <= 0.0f) return;
    for (int k = 0; k < 3; ++k) rgbw[k] = num[k] / den * rgbw[3];
}

// Bicubic (Catmull-Rom) sample of a premultiplied RGBA patch at patch
// coordinates (u, v) (pixel j's centre at j), zero outside the patch.
void sample_patch_bicubic(const float* texture, int patch, float u, float v, float out[4]) {
    const float fu = std::floor(u), fv = std::floor(v);
    const int iu = static_cast<int>(fu), iv = static_cast<int>(fv);
    const auto wu = catmull_rom_weights(u - fu);
    const auto wv = catmull_rom_weights(v - fv);
    if (iu >= 1 && iv >= 1 && iu + 2 < patch && iv + 2 < patch) {
        // All 16 taps inside: the four channels of a pixel as one 4-lane
        // vector (the same additions in the same order as below, so the same
        // result; most samples of a warped patch land here).
        using Rgba = float __attribute__((vector_size(16)));
        const auto load = [](const float* t) {
            Rgba x;
            std::memcpy(&x, t, sizeof x);
            return x;
        };
        Rgba sum = {0.0f, 0.0f, 0.0f, 0.0f};
        const float* t = texture + (static_cast<std::size_t>(iv - 1) * patch + (iu - 1)) * 4;
        for (int b = 0; b < 4; ++b, t += static_cast<std::size_t>(patch) * 4) {
            Rgba row = {0.0f, 0.0f, 0.0f, 0.0f};
            for (int a = 0; a < 4; ++a) row += wu[static_cast<std::size_t>(a)] * load(t + 4 * a);
            sum += wv[static_cast<std::size_t>(b)] * row;
        }
        std::memcpy(out, &sum, sizeof sum);
        return;
    }
    out[0] = out[1] = out[2] = out[3] = 0.0f;
    for (int b = 0; b < 4; ++b) {
        const int y = iv - 1 + b;
        if (y < 0 || y >= patch) continue;
        float row[4] = {0.0f, 0.0f, 0.0f, 0.0f};
        for (int a = 0; a < 4; ++a) {
            const int x = iu - 1 + a;
            if (x < 0 || x >= patch) continue;
            const float* t = texture + (static_cast<std::size_t>(y) * patch + x) * 4;
            const float w = wu[static_cast<std::size_t>(a)];
            row[0] += w * t[0];
            row[1] += w * t[1];
            row[2] += w * t[2];
            row[3] += w * t[3];
        }
        const float w = wv[static_cast<std::size_t>(b)];
        out[0] += w * row[0];
        out[1] += w * row[1];
        out[2] += w * row[2];
        out[3] += w * row[3];
    }
}

// Accumulation buffer: premultiplied colour times feather weight, and the
// weight. With detail preservation also the weight of each group of patches
// showing one input frame, per pixel (two groups by id, the rest lumped
// together: more than two input frames rarely meet at a pixel).
struct Accumulator {
    int width = 0;
    int height = 0;
    bool groups = false;
    std::vector<float> rgbw;          // 4 per pixel
    std::vector<int> group_id;        // 2 per pixel, -1 = none yet
    std::vector<float> group_weight;  // 3 per pixel: the two groups, the rest
    bool colours = false;
    std::vector<float> group_rgb;     // with colours, per pixel: the second group's and the rest's sum of weight x colour

    void reset(int w, int h, bool with_groups, bool with_colours) {
        width = w;
        height = h;
        groups = with_groups;
        colours = with_groups && with_colours;
        const std::size_t pixels = static_cast<std::size_t>(w) * h;
        rgbw.assign(pixels * 4, 0.0f);
        if (groups) {
            group_id.assign(pixels * 2, -1);
            group_weight.assign(pixels * 3, 0.0f);
        }
        if (colours) group_rgb.assign(pixels * kGroupColourFloats, 0.0f);
    }
    void add_group(std::size_t pixel, float wa, int group, const float* wrgb) {
        int* g = group_id.data() + pixel * 2;
        float* gw = group_weight.data() + pixel * 3;
        int slot = 2;
        if (g[0] == group) slot = 0;
        else if (g[0] < 0) {
            g[0] = group;
            gw[0] = 0.0f;
            slot = 0;
        } else if (g[1] == group) slot = 1;
        else if (g[1] < 0) {
            g[1] = group;
            gw[1] = 0.0f;
            slot = 1;
        }
        gw[slot] += wa;
        if (colours && slot > 0)  // the first group's colour is the total's remainder
            for (int k = 0; k < 3; ++k)
                group_rgb[pixel * kGroupColourFloats + static_cast<std::size_t>(slot - 1) * 3 + k] += wrgb[k];
    }
};

// Horizontal sums of 4-channel `values` over 2r+1 pixels, zero outside, for
// the rows [y0, y1]: the first pass of a box mean, the second done only at the
// pixels that need it.
void row_box_sums(const std::vector<float>& values, int width, int y0, int y1, int r, std::vector<float>& out) {
    out.resize(values.size());
    for (int y = y0; y <= y1; ++y) {
        const float* src = values.data() + static_cast<std::size_t>(y) * width * 4;
        float* dst = out.data() + static_cast<std::size_t>(y) * width * 4;
        float sum[4] = {0.0f, 0.0f, 0.0f, 0.0f};
        for (int x = 0; x < std::min(r, width); ++x)
            for (int c = 0; c < 4; ++c) sum[c] += src[x * 4 + c];
        for (int x = 0; x < width; ++x) {
            for (int c = 0; c < 4; ++c) {
                if (x + r < width) sum[c] += src[(x + r) * 4 + c];
                if (x - r - 1 >= 0) sum[c] -= src[(x - r - 1) * 4 + c];
                dst[x * 4 + c] = sum[c];
            }
        }
    }
}

// Splats a feathered patch back on the whole pixels it was cut from
// (patch_origin of its centre): an exact copy, weighted.
void splat_patch(Accumulator& acc, const ParticleStreams::Visible& v, int patch, const std::vector<float>& feather) {
    const int ox = patch_origin(v.centre.x(), patch), oy = patch_origin(v.centre.y(), patch);
    const int j_lo = std::max(0, -ox), j_hi = std::min(patch, acc.width - ox);
    for (int i = 0; i < patch; ++i) {
        const int y = oy + i;
        if (y < 0 || y >= acc.height) continue;
        const float fy = feather[static_cast<std::size_t>(i)] * v.weight;
        const std::size_t row = static_cast<std::size_t>(y) * acc.width + ox;
        float* dst = acc.rgbw.data() + row * 4;
        const float* src = v.texture + static_cast<std::size_t>(i) * patch * 4;
        for (int j = j_lo; j < j_hi; ++j) {
            const float w = fy * feather[static_cast<std::size_t>(j)];
            const float* t = src + static_cast<std::size_t>(j) * 4;
            float* d = dst + static_cast<std::size_t>(j) * 4;
            d[0] += w * t[0];
            d[1] += w * t[1];
            d[2] += w * t[2];
            d[3] += w * t[3];
        }
        if (acc.groups)
            for (int j = j_lo; j < j_hi; ++j) {
                const float w = fy * feather[static_cast<std::size_t>(j)];
                const float* t = src + static_cast<std::size_t>(j) * 4;
                const float wrgb[3] = {w * t[0], w * t[1], w * t[2]};
                acc.add_group(row + static_cast<std::size_t>(j), w * t[3], v.input_frame, wrgb);
            }
    }
}

// Output pixels near an output line, mapped into the input frame.
struct WarpEntry {
    int pixel = 0;
    int row = 0;                 // pixel / width, kept: rendering reads it per sample
    float qx = 0.0f, qy = 0.0f;  // input-frame position
    float fade = 1.0f;
    // Weight of the background carried from around the input line: a patch's
    // feather across the line (zero half a patch to the side), falling to
    // zero over half a patch beyond either end.
    float carry = 0.0f;
};
struct WarpTable {
    double s_min = 0.0;                  // arc of bucket 0 (input line)
    std::vector<int> bucket_start;       // entries of bucket b: [bucket_start[b], bucket_start[b+1])
    std::vector<WarpEntry> entries;      // by bucket, then by pixel
    std::vector<int> bucket_row_lo;      // image rows a bucket's entries span (lo > hi: none)
    std::vector<int> bucket_row_hi;
    double reach_in = 0.0;               // input-space reach of a patch around its centre
};

WarpTable build_warp(const LineGeometry& out_line, const LineGeometry& in_line, ArcMapping mapping, int patch, int width,
                     int height) {
    WarpTable table;
    const double half = (patch - 1) / 2.0;
    const double length_out = out_line.length_px(), length_in = in_line.length_px();
    const double scale = arc_mapping_scale(mapping, length_in, length_out);
    table.reach_in = (half + 1.0) * std::sqrt(2.0) + 1.0;
    const double reach_out = table.reach_in * std::max(1.0, 1.0 / scale);

    const auto& pts = out_line.points();
    Eigen::Vector2d lo = pts.front(), hi = pts.front();
    for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const int bx0 = std::max(0, static_cast<int>(std::floor(lo.x() - 2.0 * reach_out)));
    const int by0 = std::max(0, static_cast<int>(std::floor(lo.y() - 2.0 * reach_out)));
    const int bx1 = std::min(width - 1, static_cast<int>(std::ceil(hi.x() + 2.0 * reach_out)));
    const int by1 = std::min(height - 1, static_cast<int>(std::ceil(hi.y() + 2.0 * reach_out)));
    if (bx1 < bx0 || by1 < by0) return table;
    const int bw = bx1 - bx0 + 1, bh = by1 - by0 + 1;
    std::vector<float> best(static_cast<std::size_t>(bw) * bh, std::numeric_limits<float>::infinity());
    std::vector<float> best_s(best.size()), best_n(best.size());
    const auto& arc = out_line.arc_lengths();
    const std::size_t segments = pts.size() - 1;
    for (std::size_t i = 0; i < segments; ++i) {
        const Eigen::Vector2d a = pts[i];
        const Eigen::Vector2d d = pts[i + 1] - a;
        const double len = d.norm();
        if (len <= 0.0) continue;
        const Eigen::Vector2d u = d / len, normal(-u.y(), u.x());
        const double t_lo = i == 0 ? -reach_out : 0.0;
        const double t_hi = i + 1 == segments ? len + reach_out : len;
        const Eigen::Vector2d e0 = a + t_lo * u, e1 = a + t_hi * u;
        const int x0 = std::max(bx0, static_cast<int>(std::floor(std::min(e0.x(), e1.x()) - reach_out)));
        const int x1 = std::min(bx1, static_cast<int>(std::ceil(std::max(e0.x(), e1.x()) + reach_out)));
        const int y0 = std::max(by0, static_cast<int>(std::floor(std::min(e0.y(), e1.y()) - reach_out)));
        const int y1 = std::min(by1, static_cast<int>(std::ceil(std::max(e0.y(), e1.y()) + reach_out)));
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const Eigen::Vector2d q(x, y);
                const double t = std::clamp((q - a).dot(u), t_lo, t_hi);
                const Eigen::Vector2d r = q - (a + t * u);
                const float dist = static_cast<float>(r.norm());
                const std::size_t k = static_cast<std::size_t>(y - by0) * bw + (x - bx0);
                if (dist < best[k]) {
                    best[k] = dist;
                    best_s[k] = static_cast<float>(arc[i] + t);
                    best_n[k] = static_cast<float>(r.dot(normal) >= 0.0 ? dist : -dist);
                }
            }
    }
    std::vector<std::pair<float, WarpEntry>> entries;
    for (int y = by0; y <= by1; ++y)
        for (int x = bx0; x <= bx1; ++x) {
            const std::size_t k = static_cast<std::size_t>(y - by0) * bw + (x - bx0);
            if (!(best[k] <= reach_out)) continue;
            const double s_out = best_s[k];
            const double s_in = s_out * scale;
            if (s_in < -table.reach_in || s_in > length_in + table.reach_in) continue;
            const Eigen::Vector2d q_in = in_line.point(s_in) + static_cast<double>(best_n[k]) * in_line.normal(s_in);
            WarpEntry entry;
            entry.pixel = y * width + x;
            entry.row = y;
            entry.qx = static_cast<float>(q_in.x());
            entry.qy = static_cast<float>(q_in.y());
            // Particles carried past the end of a shorter output line fade out
            // instead of being cut.
            entry.fade = s_out > length_out ? static_cast<float>(std::clamp(1.0 - (s_out - length_out) / reach_out, 0.0, 1.0)) : 1.0f;
            if (entry.fade <= 0.0f) continue;
            const double beyond = std::max(-s_out, s_out - length_out);  // > 0 past an end
            const double along = std::clamp(1.0 - std::max(0.0, beyond) / (0.5 * patch), 0.0, 1.0);
            // Carried background reaches three quarters of a patch across
            // (cos^2): a new channel's outer edge fades like mist, where half
            // a patch ended in a hard edge.
            const double band_px = 0.75 * patch;
            const double across = std::cos(0.5 * M_PI * static_cast<double>(best_n[k]) / band_px);
            entry.carry = std::abs(best_n[k]) < band_px ? static_cast<float>(along * across * across) : 0.0f;
            entries.emplace_back(static_cast<float>(s_in), entry);
        }
    table.s_min = -table.reach_in - 1.0;
    const int buckets = static_cast<int>(std::ceil(length_in + 2.0 * table.reach_in + 2.0)) + 1;
    std::vector<int> count(static_cast<std::size_t>(buckets) + 1, 0);
    const auto bucket_of = [&](float s) {
        return std::clamp(static_cast<int>(std::floor(s - table.s_min)), 0, buckets - 1);
    };
    for (const auto& e : entries) ++count[static_cast<std::size_t>(bucket_of(e.first)) + 1];
    table.bucket_start.assign(static_cast<std::size_t>(buckets) + 1, 0);
    for (int b = 0; b < buckets; ++b) table.bucket_start[static_cast<std::size_t>(b) + 1] = table.bucket_start[static_cast<std::size_t>(b)] + count[static_cast<std::size_t>(b) + 1];
    table.entries.resize(entries.size());
    std::vector<int> fill(table.bucket_start.begin(), table.bucket_start.end() - 1);
    table.bucket_row_lo.assign(static_cast<std::size_t>(buckets), std::numeric_limits<int>::max());
    table.bucket_row_hi.assign(static_cast<std::size_t>(buckets), std::numeric_limits<int>::min());
    for (const auto& e : entries) {
        const auto b = static_cast<std::size_t>(bucket_of(e.first));
        table.entries[static_cast<std::size_t>(fill[b]++)] = e.second;
        const int row = e.second.row;
        table.bucket_row_lo[b] = std::min(table.bucket_row_lo[b], row);
        table.bucket_row_hi[b] = std::max(table.bucket_row_hi[b], row);
    }
    return table;
}

// Carried background comes only from where the flow is: entries whose input
// arc lies outside every range of `arcs_px` (stretches of the input line no
// particle crossed, such as a rock ledge it runs over) lose their carry,
// fading over `fade_px` beyond each range. Empty `arcs_px`: unchanged.
void keep_carry_on_flowing_arcs(WarpTable& table, const std::vector<std::pair<double, double>>& arcs_px, double fade_px) {
    if (arcs_px.empty()) return;
    for (std::size_t b = 0; b + 1 < table.bucket_start.size(); ++b) {
        const double s = table.s_min + static_cast<double>(b) + 0.5;  // the bucket's input arc
        double weight = 0.0;
        for (const auto& [from, to] : arcs_px) {
            const double outside = std::max({0.0, from - s, s - to});
            weight = std::max(weight, std::clamp(1.0 - outside / fade_px, 0.0, 1.0));
        }
        for (int i = table.bucket_start[b]; i < table.bucket_start[b + 1]; ++i)
            table.entries[static_cast<std::size_t>(i)].carry *= static_cast<float>(weight);
    }
}

void splat_warped(Accumulator& acc, const WarpTable& table, const ParticleStreams::Visible& particle, int patch) {
    if (table.bucket_start.size() < 2) return;
    const int buckets = static_cast<int>(table.bucket_start.size()) - 1;
    const int b0 = std::clamp(static_cast<int>(std::floor(particle.arc_px - table.reach_in - table.s_min)), 0, buckets - 1);
    const int b1 = std::clamp(static_cast<int>(std::floor(particle.arc_px + table.reach_in - table.s_min)), 0, buckets - 1);
    const float cx = static_cast<float>(patch_origin(particle.centre.x(), patch));
    const float cy = static_cast<float>(patch_origin(particle.centre.y(), patch));
    for (int i = table.bucket_start[static_cast<std::size_t>(b0)]; i < table.bucket_start[static_cast<std::size_t>(b1) + 1]; ++i) {
        const WarpEntry& e = table.entries[static_cast<std::size_t>(i)];
        const float u = e.qx - cx, v = e.qy - cy;
        if (u <= -0.5f || v <= -0.5f || u >= patch - 0.5f || v >= patch - 0.5f) continue;
        const float w = feather_weight(u, patch) * feather_weight(v, patch) * e.fade * particle.weight;
        if (w <= 0.0f) continue;
        float c[4];
        sample_patch_bicubic(particle.texture, patch, u, v, c);
        float* d = acc.rgbw.data() + static_cast<std::size_t>(e.pixel) * 4;
        const float alpha = std::clamp(c[3], 0.0f, 1.0f);
        d[0] += w * c[0];
        d[1] += w * c[1];
        d[2] += w * c[2];
        d[3] += w * alpha;
        if (acc.groups) {
            const float wrgb[3] = {w * c[0], w * c[1], w * c[2]};
            acc.add_group(static_cast<std::size_t>(e.pixel), w * alpha, particle.input_frame, wrgb);
        }
    }
}

// `image` smoothed by a box of (2 radius + 1)^2 pixels, twice (a tent),
// shrinking the box at the borders.
RgbImage smoothed(const RgbImage& image, int radius) {
    RgbImage a = image, b(image.width, image.height);
    const auto pass = [radius](const RgbImage& in, RgbImage& out, bool along_x) {
        const int n = along_x ? in.width : in.height, lines = along_x ? in.height : in.width;
        for (int l = 0; l < lines; ++l) {
            const auto at = [&](const RgbImage& im, int i) -> std::size_t {
                return (along_x ? static_cast<std::size_t>(l) * im.width + i : static_cast<std::size_t>(i) * im.width + l) * 3;
            };
            double sum[3] = {0.0, 0.0, 0.0};
            int count = 0;
            for (int i = 0; i < std::min(n, radius); ++i, ++count)
                for (int k = 0; k < 3; ++k) sum[k] += in.rgb[at(in, i) + k];
            for (int i = 0; i < n; ++i) {
                if (i + radius < n) {
                    for (int k = 0; k < 3; ++k) sum[k] += in.rgb[at(in, i + radius) + k];
                    ++count;
                }
                if (i - radius - 1 >= 0) {
                    for (int k = 0; k < 3; ++k) sum[k] -= in.rgb[at(in, i - radius - 1) + k];
                    --count;
                }
                for (int k = 0; k < 3; ++k) out.rgb[at(out, i) + k] = static_cast<float>(sum[k] / count);
            }
        }
    };
    for (int repeat = 0; repeat < 2; ++repeat) {
        pass(a, b, true);
        pass(b, a, false);
    }
    return a;
}

// Composites over `out` the background found around each warped line's
// input line: `source` (the frame's background) sampled at the warp's input
// positions, weighted by WarpEntry::carry and shown fully where the weights
// reach `full` (smoothstep, as particles), times `allowed` per pixel. `sums`
// is scratch (4 per pixel).
void carry_background(const std::vector<const WarpTable*>& tables, const RgbImage& source, float full,
                      const std::vector<float>& allowed, std::vector<float>& sums, RgbImage& out) {
    if (tables.empty()) return;
    const std::size_t pixels = static_cast<std::size_t>(out.width) * out.height;
    sums.assign(pixels * 4, 0.0f);
    for (const WarpTable* table : tables)
        for (const WarpEntry& e : table->entries) {
            if (e.carry <= 0.0f) continue;
            float c[3];
            sample_bilinear(source, e.qx, e.qy, c);
            float* d = sums.data() + static_cast<std::size_t>(e.pixel) * 4;
            d[0] += e.carry * c[0];
            d[1] += e.carry * c[1];
            d[2] += e.carry * c[2];
            d[3] += e.carry;
        }
    for (std::size_t i = 0; i < pixels; ++i) {
        const float* d = sums.data() + 4 * i;
        if (d[3] <= 1e-6f) continue;
        const float c = static_cast<float>(smoothstep01(d[3] / full)) * allowed[i];
        float* o = out.rgb.data() + 3 * i;
        for (int k = 0; k < 3; ++k) o[k] = o[k] * (1.0f - c) + d[k] / d[3] * c;
    }
}

// A particle around which a replayed background shows the frame it shows.
struct ShownFrame {
    Eigen::Vector2d centre;
    float weight = 0.0f;
    bool continuing = false;  // the frame after the window (else the window's)
};

// Per pixel, the share of the continuing frame in a replayed background:
// that of the particles around the pixel (their fade weights, a tent over
// each patch), spread half a patch beyond the patches by two box blurs on a
// grid of quarter-patch cells and interpolated bilinearly; where no particle
// reaches (a patch and a half from every centre), `fallback` (the wrap's
// dissolve), approached smoothly as their weight falls off.
std::vector<float> continuing_share_map(const std::vector<ShownFrame>& particles, int w, int h, int patch, float fallback) {
    const int cell = std::max(2, patch / 4);
    const int gw = w / cell + 2, gh = h / cell + 2;
    std::vector<float> cont(static_cast<std::size_t>(gw) * gh, 0.0f), all(cont.size(), 0.0f);
    const double half = 0.5 * patch;
    for (const ShownFrame& p : particles) {
        const int x0 = std::max(0, static_cast<int>(std::ceil((p.centre.x() - half) / cell)));
        const int x1 = std::min(gw - 1, static_cast<int>(std::floor((p.centre.x() + half) / cell)));
        const int y0 = std::max(0, static_cast<int>(std::ceil((p.centre.y() - half) / cell)));
        const int y1 = std::min(gh - 1, static_cast<int>(std::floor((p.centre.y() + half) / cell)));
        for (int gy = y0; gy <= y1; ++gy)
            for (int gx = x0; gx <= x1; ++gx) {
                const double tent = (1.0 - std::fabs(gx * cell - p.centre.x()) / half) * (1.0 - std::fabs(gy * cell - p.centre.y()) / half);
                if (tent <= 0.0) continue;
                const std::size_t i = static_cast<std::size_t>(gy) * gw + gx;
                all[i] += static_cast<float>(tent * p.weight);
                if (p.continuing) cont[i] += static_cast<float>(tent * p.weight);
            }
    }
    const int radius = std::max(1, static_cast<int>(std::lround(half / cell)));
    std::vector<float> line;
    const auto box = [&](std::vector<float>& g, bool rows) {
        const int n = rows ? gw : gh, lines = rows ? gh : gw;
        line.resize(static_cast<std::size_t>(n));
        for (int l = 0; l < lines; ++l) {
            const auto at = [&](int k) -> float& {
                return rows ? g[static_cast<std::size_t>(l) * gw + k] : g[static_cast<std::size_t>(k) * gw + l];
            };
            for (int k = 0; k < n; ++k) line[static_cast<std::size_t>(k)] = at(k);
            for (int k = 0; k < n; ++k) {
                float sum = 0.0f;
                for (int j = std::max(0, k - radius); j <= std::min(n - 1, k + radius); ++j) sum += line[static_cast<std::size_t>(j)];
                at(k) = sum / static_cast<float>(2 * radius + 1);
            }
        }
    };
    for (std::vector<float>* g : {&cont, &all})
        for (int pass = 0; pass < 2; ++pass) {
            box(*g, true);
            box(*g, false);
        }
    // A hundredth of an isolated particle's peak after the blurs (a tent of
    // about two cells each way, spread over 2 radius + 1 twice).
    const float eps = 0.01f * std::pow(2.0f / static_cast<float>(2 * radius + 1), 2.0f);
    std::vector<float> share_grid(cont.size());
    for (std::size_t i = 0; i < cont.size(); ++i) share_grid[i] = (cont[i] + eps * fallback) / (all[i] + eps);
    std::vector<float> share(static_cast<std::size_t>(w) * h);
    for (int y = 0; y < h; ++y) {
        const int gy = y / cell;
        const float fy = static_cast<float>(y - gy * cell) / cell;
        for (int x = 0; x < w; ++x) {
            const int gx = x / cell;
            const float fx = static_cast<float>(x - gx * cell) / cell;
            const std::size_t i = static_cast<std::size_t>(gy) * gw + gx;
            const float top = share_grid[i] + fx * (share_grid[i + 1] - share_grid[i]);
            const float bottom = share_grid[i + gw] + fx * (share_grid[i + gw + 1] - share_grid[i + gw]);
            share[static_cast<std::size_t>(y) * w + x] = top + fy * (bottom - top);
        }
    }
    return share;
}

bool same_points(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if ((a[i] - b[i]).norm() > 1e-9) return false;
    return true;
}

}  // namespace

const char* to_string(ArcMapping mapping) { return mapping == ArcMapping::equal ? "equal" : "scaled"; }

ArcMapping arc_mapping_from_string(const std::string& text) {
    if (text == "equal") return ArcMapping::equal;
    if (text == "scaled") return ArcMapping::scaled;
    throw std::invalid_argument("unknown arc-length mapping '" + text + "' (equal or scaled)");
}

const char* to_string(TextureLayer layer) { return layer == TextureLayer::whole ? "whole" : "moving"; }

TextureLayer texture_layer_from_string(const std::string& text) {
    if (text == "whole") return TextureLayer::whole;
    if (text == "moving") return TextureLayer::moving;
    throw std::invalid_argument("unknown texture layer '" + text + "' (whole or moving)");
}

Background make_background(BackgroundMode mode, std::shared_ptr<const ClipFrames> clip, const Schedule& schedule,
                           int patch_size_px) {
    if (mode == BackgroundMode::none || !clip) return Background();
    if (mode == BackgroundMode::median) return Background::plate(median_plate(*clip));
    if (mode == BackgroundMode::loop) return Background::looped(std::move(clip));
    if (mode == BackgroundMode::relit) {
        // Light measured at the scale of a patch: what a lone patch's round
        // end shows against the plate.
        RgbImage plate = median_plate(*clip);
        return Background::relit(std::move(clip), std::move(plate), schedule.first_start_frame, schedule.period_frames,
                                 std::max(1, schedule.start_every), 0.5 * std::max(2, patch_size_px));
    }
    // The particles already on a line when it wraps go on showing the frames
    // after the window until they leave; following them would keep two
    // frames mixed for most of a period. The background changes over the
    // entry spacing instead, as the new particles fade in.
    return Background::replayed(std::move(clip), schedule.first_start_frame, schedule.period_frames,
                                std::max(1, schedule.start_every));
}

double arc_mapping_scale(ArcMapping mapping, double length_in, double length_out) {
    return mapping == ArcMapping::scaled && length_out > 0.0 ? length_in / length_out : 1.0;
}

// ---- synthesizer --------------------------------------------------------------------------------------

struct Synthesizer::Plan {
    struct Line {
        int stream = -1;
        bool identity = false;
        bool keyed = false;
        int time_offset_frames = 0;  // shows the particles of frame + this
        formats::FlowLine line;  // keyed lines: geometry per frame
        WarpTable warp;          // fixed, non-identity lines
        // Whether a replayed or relit background follows its particles (fill_background).
        bool followed_by(const Background& background) const {
            const BackgroundMode mode = background.mode();
            return (mode == BackgroundMode::replay || mode == BackgroundMode::relit) && identity && time_offset_frames == 0;
        }
    };
    std::vector<Line> lines;
    // SynthesisSettings::carry_background: each warped output line as a
    // whole, mapped onto its whole input line (segments and the gaps between
    // them alike).
    struct CarryLine {
        formats::FlowLine line;  // keyed lines: geometry per frame
        std::shared_ptr<const LineGeometry> input;
        // Arc ranges of the input line its particles were tracked on, px
        // (empty: all of it); the stretches between (rock nothing crossed)
        // are not carried.
        std::vector<std::pair<double, double>> flowing_arcs_px;
        WarpTable warp;          // fixed lines
    };
    std::vector<CarryLine> carry_lines;
    // Per pixel, how much of the carried background may show
    // (carry_allowed_map): none on the flow's own region, whose background
    // already is the flow's.
    std::vector<float> carry_allowed;
    RgbImage carried_plate;  // fixed carry lines over a median plate: the composite, made once
    RgbImage carry_source;   // the median plate smoothed: what is carried (empty: per frame)
    int width = 0;
    int height = 0;
};

struct Synthesizer::CarryBuffers {
    std::vector<WarpTable> keyed_warps;
    std::vector<const WarpTable*> tables;
    RgbImage source;  // the frame's background, sampled while `out` changes
    std::vector<float> sums;
};

namespace {

// SynthesisSettings::carry_background: per pixel, how much carried background
// may show: 0 within half a patch of the flow's own region (its input lines
// and lines interpolated between neighbouring ones, as edits interpolate
// output lines), rising to 1 a patch away.
std::vector<float> carry_allowed_map(const ParticleStreams& streams, int w, int h, int patch) {
    std::vector<std::vector<Eigen::Vector2d>> flow_lines;
    for (const ParticleStreams::InputLine& in : streams.input_lines())
        if (in.points.size() >= 2) flow_lines.push_back(in.points);
        else
            for (const auto& seg : in.segments) flow_lines.push_back(streams.geometry(seg.stream).points());
    std::vector<std::vector<Eigen::Vector2d>> region = flow_lines;
    const auto chains = neighbour_chains(flow_lines, 6.0 * patch);
    for (const InterpolatedLine& between : interpolate_between(flow_lines, chains, 0.5 * patch))
        region.push_back(blend_polylines(flow_lines[static_cast<std::size_t>(between.a)],
                                         flow_lines[static_cast<std::size_t>(between.b)], between.weight, 32));
    const std::vector<double> distance = distance_to_polylines(region, w, h, patch);
    std::vector<float> allowed(distance.size());
    for (std::size_t i = 0; i < distance.size(); ++i)
        allowed[i] = static_cast<float>(smoothstep01(2.0 * std::min(distance[i], static_cast<double>(patch)) / patch - 1.0));
    return allowed;
}

}  // namespace

Synthesizer::Synthesizer(std::shared_ptr<const ParticleStreams> streams, std::vector<OutputLine> outputs,
                         Background background, const SynthesisSettings& settings)
    : m_streams(std::move(streams)), m_plan(std::make_unique<Plan>()), m_background(std::move(background)),
      m_settings(settings) {
    if (!m_streams) throw std::invalid_argument("no particle streams");
    if (settings.texture_layer == TextureLayer::moving &&
        (m_background.mode() == BackgroundMode::loop || m_background.mode() == BackgroundMode::replay ||
         m_background.mode() == BackgroundMode::relit))
        throw std::invalid_argument(std::string("the moving texture layer needs a still background (median or none), not ") +
                                    to_string(m_background.mode()) + ": the clip already shows the flames it would add");
    const formats::ParticleBank& bank = m_streams->bank();
    m_plan->width = bank.clip_width_px;
    m_plan->height = bank.clip_height_px;
    m_warnings = m_streams->schedule().warnings;
    m_carry_background = settings.carry_background && m_background.mode() != BackgroundMode::none;
    const int patch = bank.patch_size_px;
    if (outputs.empty()) {
        for (std::size_t i = 0; i < m_streams->schedule().lines.size(); ++i) {
            Plan::Line line;
            line.stream = static_cast<int>(i);
            line.identity = true;
            m_plan->lines.push_back(std::move(line));
        }
        return;
    }
    const auto add = [&](formats::FlowLine geometry, int stream) {
        Plan::Line line;
        line.stream = stream;
        const LineGeometry& in = m_streams->geometry(stream);
        line.keyed = geometry.is_time_varying();
        line.time_offset_frames = geometry.time_offset_frames;
        if (!line.keyed) {
            // An output line drawn exactly over its input line is the input
            // line: render it exactly, without warping.
            line.identity = same_points(geometry.points, in.points());
            if (!line.identity)
                line.warp = build_warp(LineGeometry(geometry.points, patch / 3.0), in, settings.mapping, patch,
                                       m_plan->width, m_plan->height);
        }
        line.line = std::move(geometry);
        m_plan->lines.push_back(std::move(line));
    };
    const auto add_carry = [&](const formats::FlowLine& output_line, std::vector<Eigen::Vector2d> input_points,
                               std::vector<std::pair<double, double>> flowing_arcs_px) {
        if (!m_carry_background || input_points.size() < 2) return;
        if (!output_line.is_time_varying() && same_points(output_line.points, input_points)) return;
        Plan::CarryLine carry;
        carry.line = output_line;
        carry.input = std::make_shared<const LineGeometry>(std::move(input_points), patch / 3.0);
        carry.flowing_arcs_px = std::move(flowing_arcs_px);
        if (!output_line.is_time_varying()) {
            carry.warp = build_warp(LineGeometry(output_line.points, patch / 3.0), *carry.input, settings.mapping, patch,
                                    m_plan->width, m_plan->height);
            keep_carry_on_flowing_arcs(carry.warp, carry.flowing_arcs_px, 0.5 * patch);
        }
        m_plan->carry_lines.push_back(std::move(carry));
    };
    std::vector<std::string> off_frame, too_short;
    for (OutputLine& output : outputs) {
        // A line drawn off the frame, or shorter than a pixel (in every key), shows nothing: say so.
        double longest_px = 0.0, longest_inside_px = 0.0;
        const auto measure = [&](const std::vector<Eigen::Vector2d>& points) {
            longest_px = std::max(longest_px, formats::polyline_length(points));
            longest_inside_px = std::max(longest_inside_px, length_inside_frame(points, m_plan->width, m_plan->height));
        };
        if (!output.line.is_time_varying()) measure(output.line.points);
        for (const formats::FlowLineKey& key : output.line.keys) measure(key.points);
        if (longest_inside_px < 1.0) (longest_px < 1.0 ? too_short : off_frame).push_back(output.line.id);
        const int stream = m_streams->stream_index(output.from);
        if (stream >= 0) {
            add_carry(output.line, m_streams->geometry(stream).points(), {});
            add(std::move(output.line), stream);
            continue;
        }
        const int group = m_streams->input_line_index(output.from);
        if (group < 0) {
            m_warnings.push_back("output line " + output.line.id + " carries " + output.from +
                                 ", which has no tracked particle; it is left out");
            continue;
        }
        // A line tracked in segments: each segment goes to the matching part
        // of the output line (equal arc length, or scaled to the output's length).
        const ParticleStreams::InputLine& in = m_streams->input_lines()[static_cast<std::size_t>(group)];
        std::vector<std::pair<double, double>> tracked_arcs;
        for (const ParticleStreams::InputLine::Segment& seg : in.segments) tracked_arcs.emplace_back(seg.from_px, seg.to_px);
        add_carry(output.line, in.points, tracked_arcs);
        const auto part_of = [&](const std::vector<Eigen::Vector2d>& points, const ParticleStreams::InputLine::Segment& seg,
                                 bool& empty) {
            const double length = formats::polyline_length(points);
            const double k = settings.mapping == ArcMapping::scaled && in.length_px > 0.0 ? length / in.length_px : 1.0;
            const double from = std::min(seg.from_px * k, length), to = std::min(seg.to_px * k, length);
            empty = to - from < 1.0;
            return sub_polyline(points, from, std::max(to, std::min(length, from + 1.0)));
        };
        for (const ParticleStreams::InputLine::Segment& seg : in.segments) {
            formats::FlowLine part;
            part.id = output.line.id + "/" + m_streams->schedule().lines[static_cast<std::size_t>(seg.stream)].line_id;
            part.time_offset_frames = output.line.time_offset_frames;
            bool empty = false;
            if (!output.line.is_time_varying()) {
                part.points = part_of(output.line.points, seg, empty);
            } else {
                bool all_empty = true;
                for (const formats::FlowLineKey& key : output.line.keys) {
                    bool key_empty = false;
                    const std::vector<Eigen::Vector2d> sub = part_of(key.points, seg, key_empty);
                    all_empty = all_empty && key_empty;
                    part.keys.push_back({key.frame, blend_polylines(sub, sub, 0.0, 32)});
                }
                empty = all_empty;
            }
            if (!empty) add(std::move(part), seg.stream);
        }
    }
    const auto show_nothing = [&](const std::vector<std::string>& ids, const std::string& why) {
        if (ids.empty()) return;
        m_warnings.push_back(std::to_string(ids.size()) + (ids.size() == 1 ? " output line " : " output lines ") + why +
                             " and show" + (ids.size() == 1 ? "s" : "") + " nothing (" + some_line_ids(ids) + ")");
    };
    show_nothing(off_frame, (off_frame.size() == 1 ? "lies" : "lie") + std::string(" outside the ") +
                                std::to_string(m_plan->width) + " x " + std::to_string(m_plan->height) + " frame");
    show_nothing(too_short, too_short.size() == 1 ? "is shorter than a pixel" : "are shorter than a pixel");
    if (!m_plan->carry_lines.empty())
        m_plan->carry_allowed = carry_allowed_map(*m_streams, m_plan->width, m_plan->height, patch);
    // Fixed lines over a still plate carry the same background every frame:
    // composite it once.
    const bool all_fixed = std::none_of(m_plan->carry_lines.begin(), m_plan->carry_lines.end(),
                                        [](const Plan::CarryLine& l) { return l.line.is_time_varying(); });
    if (!m_plan->carry_lines.empty() && m_background.mode() == BackgroundMode::median) {
        RgbImage plate;
        m_background.fill(1, m_plan->width, m_plan->height, plate);
        m_plan->carry_source = smoothed(plate, std::max(1, patch / 2));
        if (all_fixed) {
            CarryBuffers buffers;
            carry_background_into(1, plate, buffers);  // before carried_plate is set: composites
            m_plan->carried_plate = std::move(plate);
        }
    }
}

Synthesizer::~Synthesizer() = default;

void Synthesizer::carry_background_into(int frame, RgbImage& out, CarryBuffers& b) const {
    if (m_plan->carry_lines.empty()) return;
    if (!m_plan->carried_plate.empty()) {
        out = m_plan->carried_plate;
        return;
    }
    const int w = m_plan->width, h = m_plan->height, patch = m_streams->patch_size();
    std::size_t keyed = 0;
    for (const Plan::CarryLine& line : m_plan->carry_lines) keyed += line.line.is_time_varying() ? 1 : 0;
    b.keyed_warps.resize(keyed);  // never reallocated below: `tables` points into it
    b.tables.clear();
    keyed = 0;
    for (const Plan::CarryLine& line : m_plan->carry_lines) {
        if (!line.line.is_time_varying()) {
            b.tables.push_back(&line.warp);
            continue;
        }
        b.keyed_warps[keyed] = build_warp(LineGeometry(formats::points_at_frame(line.line, frame), patch / 3.0),
                                          *line.input, m_settings.mapping, patch, w, h);
        keep_carry_on_flowing_arcs(b.keyed_warps[keyed], line.flowing_arcs_px, 0.5 * patch);
        b.tables.push_back(&b.keyed_warps[keyed++]);
    }
    if (m_plan->carry_source.empty()) b.source = smoothed(out, std::max(1, patch / 2));
    carry_background(b.tables, m_plan->carry_source.empty() ? b.source : m_plan->carry_source,
                     static_cast<float>(std::max(1e-6, m_settings.coverage_weight)), m_plan->carry_allowed, b.sums, out);
}


int Synthesizer::width() const { return m_plan->width; }
int Synthesizer::height() const { return m_plan->height; }

RgbImage Synthesizer::render(int frame) const { return render(frame, nullptr); }

// A replayed (or relit) background follows the ladder: after the wrap, the particles
// still on a line from before it show the frames after the window, ahead of
// the first new particle, and the background around them shows those too, so
// texture and background agree where patches end on both sides of the
// ladder step. Lines rendered as they were tracked only: on warped or
// time-shifted lines (edits) the background keeps the wrap's dissolve.
void Synthesizer::fill_background(int frame, const std::vector<ParticleStreams::Visible>& on_followed_lines,
                                  RgbImage& out) const {
    const int w = m_plan->width, h = m_plan->height;
    const Background::ReplayFrames frames = m_background.replay_frames(frame);
    if (frames.continuing < 0) {
        m_background.fill(frame, w, h, out);
        return;
    }
    std::vector<ShownFrame> shown;
    bool any_continuing = false;
    for (const auto& v : on_followed_lines) {
        if (v.input_frame != frames.now && v.input_frame != frames.continuing) continue;  // a borrowed start's
        shown.push_back({v.centre, v.weight, v.input_frame == frames.continuing});
        any_continuing = any_continuing || v.input_frame == frames.continuing;
    }
    if (!any_continuing) {
        m_background.fill(frame, w, h, out);
        return;
    }
    m_background.fill_replay(frame, w, h,
                             continuing_share_map(shown, w, h, m_streams->patch_size(), frames.dissolve_share), out);
}

// The straightforward whole-frame version of render_into, kept as the
// reference the banded renderer must reproduce (SynthesisSettings::reference_rendering).
RgbImage Synthesizer::render_reference(int frame, std::vector<float>* coverage) const {
    const int w = m_plan->width, h = m_plan->height;
    const int patch = m_streams->patch_size();
    const bool detail = m_settings.preserve_detail, sharpen = m_settings.overlap_sharpness != 1.0;
    Accumulator acc;
    acc.reset(w, h, detail || sharpen, sharpen);
    std::vector<ParticleStreams::Visible> visible;
    std::vector<float> feather(static_cast<std::size_t>(patch));
    for (int i = 0; i < patch; ++i) feather[static_cast<std::size_t>(i)] = feather_weight(static_cast<float>(i), patch);
    std::vector<ParticleStreams::Visible> followed;  // what a replayed background follows
    for (const Plan::Line& line : m_plan->lines) {
        m_streams->visible(line.stream, frame + line.time_offset_frames, visible);
        if (line.followed_by(m_background)) followed.insert(followed.end(), visible.begin(), visible.end());
        if (line.identity) {
            for (const auto& v : visible) splat_patch(acc, v, patch, feather);
            continue;
        }
        if (line.keyed) {
            const WarpTable warp = build_warp(LineGeometry(formats::points_at_frame(line.line, frame), patch / 3.0),
                                              m_streams->geometry(line.stream), m_settings.mapping, patch, w, h);
            for (const auto& v : visible) splat_warped(acc, warp, v, patch);
        } else {
            for (const auto& v : visible) splat_warped(acc, line.warp, v, patch);
        }
    }
    RgbImage out;
    fill_background(frame, followed, out);
    CarryBuffers carry;
    carry_background_into(frame, out, carry);
    if (coverage) coverage->assign(static_cast<std::size_t>(w) * h, 0.0f);
    const float full = static_cast<float>(std::max(1e-6, m_settings.coverage_weight));
    const bool screen = m_settings.texture_layer == TextureLayer::moving;
    const std::size_t pixels = static_cast<std::size_t>(w) * h;
    if (sharpen)
        for (std::size_t i = 0; i < pixels; ++i) {
            float* gw = acc.group_weight.data() + 3 * i;
            sharpen_groups(acc.rgbw.data() + 4 * i, gw[0], gw[1], gw[2], acc.group_rgb.data() + kGroupColourFloats * i,
                           static_cast<float>(m_settings.overlap_sharpness));
        }
    // Detail preservation: where groups of different input frames mix, the
    // detail around the local mean (a normalised box mean of the blend, fine
    // scale: larger structures of nearby frames are alike and blend as they
    // are) is rescaled by sum(W) / sqrt(sum(W_g^2)), 1 for a single group.
    std::vector<float> gain;
    std::vector<float> rows;
    if (detail) {
        int y0 = h, y1 = -1;
        gain.assign(pixels, 1.0f);
        for (std::size_t i = 0; i < pixels; ++i) {
            const float* gw = acc.group_weight.data() + 3 * i;
            if (!(gw[1] > 0.0f)) continue;
            const float squares = gw[0] * gw[0] + gw[1] * gw[1] + gw[2] * gw[2];
            const float total = gw[0] + gw[1] + gw[2];
            if (squares > 0.0f) gain[i] = std::clamp(total / std::sqrt(squares), 1.0f, kMaxDetailGain);
            if (gain[i] > 1.0f) {
                const int y = static_cast<int>(i / static_cast<std::size_t>(w));
                y0 = std::min(y0, y);
                y1 = std::max(y1, y);
            }
        }
        if (y1 >= 0) row_box_sums(acc.rgbw, w, std::max(0, y0 - kDetailRadiusPx), std::min(h - 1, y1 + kDetailRadiusPx),
                                  kDetailRadiusPx, rows);
        else gain.clear();
    }
    for (std::size_t i = 0; i < pixels; ++i) {
        const float* a = acc.rgbw.data() + 4 * i;
        if (a[3] <= 1e-6f) continue;
        const float c = static_cast<float>(smoothstep01(a[3] / full));
        const float inv = 1.0f / a[3];
        float tex[3] = {a[0] * inv, a[1] * inv, a[2] * inv};
        if (!gain.empty() && gain[i] > 1.0f) {
            const int y = static_cast<int>(i / static_cast<std::size_t>(w)), x = static_cast<int>(i % static_cast<std::size_t>(w));
            float l[4] = {0.0f, 0.0f, 0.0f, 0.0f};
            for (int yy = std::max(0, y - kDetailRadiusPx); yy <= std::min(h - 1, y + kDetailRadiusPx); ++yy) {
                const float* r = rows.data() + (static_cast<std::size_t>(yy) * w + x) * 4;
                for (int k = 0; k < 4; ++k) l[k] += r[k];
            }
            if (l[3] > 1e-6f)
                for (int k = 0; k < 3; ++k) {
                    const float mean = l[k] / l[3];
                    tex[k] = mean + (tex[k] - mean) * gain[i];
                }
        }
        composite(out.rgb.data() + 3 * i, tex, c, screen);
        if (coverage) (*coverage)[i] = c;
    }
    return out;
}

// ---- banded rendering ----------------------------------------------------------------------------
// The whole-frame pass above touches several frame-sized buffers per frame
// (~35 MB at 1280 x 720 with detail preservation); here the frame goes by
// bands of kBandRows rows through a ring holding the band and the
// kDetailRadiusPx rows either side the local mean reads. Step k adds every
// patch crossing rows [lo_k, hi_k) (the rows not yet accumulated that band k
// needs), in the whole-frame order, so each pixel sees the same additions in
// the same order; then band k is finished.

namespace {

constexpr int kBandRows = 16;

struct RenderBuffers {
    // One patch to add: identity lines put the patch on whole pixels at
    // (ox, oy); warped lines go through a warp table.
    struct Splat {
        const float* texture = nullptr;
        float weight = 1.0f;
        int input_frame = 0;
        int ox = 0, oy = 0;               // identity: patch origin
        const WarpTable* warp = nullptr;  // warped: the table, its buckets and the patch origin
        int b0 = 0, b1 = -1;
        float cx = 0.0f, cy = 0.0f;
        int row_lo = 0, row_hi = 0;       // image rows touched, [lo, hi)
    };

    std::vector<ParticleStreams::Visible> visible;
    std::vector<ParticleStreams::Visible> followed;  // on the lines a replayed background follows
    std::vector<float> feather;
    std::vector<WarpTable> keyed_warps;
    std::vector<Splat> splats;
    std::vector<int> step_start;  // splats of step k: step_splats[step_start[k] .. step_start[k + 1])
    std::vector<int> step_splats;
    int width = 0;
    int ring_rows = 0;
    std::vector<float> rgbw;      // ring: 4 per pixel
    // Ring, with groups: per pixel the ids of the first two groups to arrive
    // (-1 = none yet) and the weights of those two and of the rest.
    std::vector<int> group0, group1;
    std::vector<float> weight0, weight1, weight_rest;
    // Ring, with overlap sharpening: the second group's and the rest's sum of
    // weight x colour (kGroupColourFloats per pixel; the first group's is the
    // total's remainder).
    bool colours = false;
    std::vector<float> group_rgb;
    std::vector<float> row_sums;  // ring, with the detail gain: horizontal box sums of rgbw
    // Per ring row: whether a pixel of it has a second group (only there do
    // overlap sharpening and the detail gain act), and whether its row sums
    // are made (they are made when a mixed row within the detail radius is
    // finished: most rows show one input frame and need neither).
    std::vector<unsigned char> mixed_row, summed_row;

    std::size_t ring_pixel(int y, int x) const {
        return static_cast<std::size_t>(y % ring_rows) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    }
};

using Splat = RenderBuffers::Splat;

// Accumulator::add_group on the ring's pixels [pixel, pixel + n), branch-free
// (weights start at 0, so taking a free slot and adding to it are one case).
inline void add_to_groups(RenderBuffers& s, std::size_t pixel, int n, const float* wa, const float* wrgb, int group) {
    int* g0 = s.group0.data() + pixel;
    int* g1 = s.group1.data() + pixel;
    float* w0 = s.weight0.data() + pixel;
    float* w1 = s.weight1.data() + pixel;
    float* w2 = s.weight_rest.data() + pixel;
    bool mixed = false;
    for (int j = 0; j < n; ++j) {
        const bool first = g0[j] == group || g0[j] < 0;
        const bool second = !first && (g1[j] == group || g1[j] < 0);
        g0[j] = first ? group : g0[j];
        g1[j] = second ? group : g1[j];
        w0[j] += first ? wa[j] : 0.0f;
        w1[j] += second ? wa[j] : 0.0f;
        w2[j] += first || second ? 0.0f : wa[j];
        mixed |= !first;
    }
    if (mixed) s.mixed_row[pixel / static_cast<std::size_t>(s.width)] = 1;
    if (!s.colours) return;
    for (int j = 0; j < n; ++j) {
        const int slot = g0[j] == group ? 0 : g1[j] == group ? 1 : 2;
        if (slot == 0) continue;  // the first group's colour is the total's remainder
        float* c = s.group_rgb.data() + (pixel + static_cast<std::size_t>(j)) * kGroupColourFloats +
                   static_cast<std::size_t>(slot - 1) * 3;
        for (int k = 0; k < 3; ++k) c[k] += wrgb[3 * j + k];
    }
}

// Rows [lo, hi) of an identity patch (as splat_patch).
void splat_patch_rows(RenderBuffers& s, bool groups, const Splat& p, int patch, int lo, int hi) {
    const int i_lo = std::max(0, lo - p.oy), i_hi = std::min(patch, hi - p.oy);
    const int j_lo = std::max(0, -p.ox), j_hi = std::min(patch, s.width - p.ox);
    const float* feather = s.feather.data();
    for (int i = i_lo; i < i_hi; ++i) {
        const int y = p.oy + i;
        const float fy = feather[i] * p.weight;
        // Patch column j_lo + j lands on ring pixel row + j.
        const std::size_t row = s.ring_pixel(y, 0) + static_cast<std::size_t>(p.ox + j_lo);
        float* dst = s.rgbw.data() + row * 4;
        const float* src = p.texture + (static_cast<std::size_t>(i) * patch + j_lo) * 4;
        const int n = j_hi - j_lo;
        for (int j = 0; j < n; ++j) {
            const float w = fy * feather[j_lo + j];
            const float* t = src + static_cast<std::size_t>(j) * 4;
            float* d = dst + static_cast<std::size_t>(j) * 4;
            d[0] += w * t[0];
            d[1] += w * t[1];
            d[2] += w * t[2];
            d[3] += w * t[3];
        }
        if (!groups) continue;
        float wa[64], wrgb[64 * 3];  // alpha weight and weighted colour per column, in chunks
        for (int j0 = 0; j0 < n; j0 += 64) {
            const int m = std::min(64, n - j0);
            for (int j = 0; j < m; ++j) wa[j] = fy * feather[j_lo + j0 + j] * src[static_cast<std::size_t>(j0 + j) * 4 + 3];
            if (s.colours)
                for (int j = 0; j < m; ++j) {
                    const float w = fy * feather[j_lo + j0 + j];
                    const float* t = src + static_cast<std::size_t>(j0 + j) * 4;
                    for (int k = 0; k < 3; ++k) wrgb[3 * j + k] = w * t[k];
                }
            add_to_groups(s, row + static_cast<std::size_t>(j0), m, wa, wrgb, p.input_frame);
        }
    }
}

// The entries of a warped patch on rows [lo, hi) (as splat_warped).
void splat_warped_rows(RenderBuffers& s, bool groups, const Splat& p, int patch, int lo, int hi) {
    const WarpTable& table = *p.warp;
    const auto before = [](const WarpEntry& e, int row) { return e.row < row; };
    // Ring row of image row y in [lo, hi) without a division per sample.
    const int lo_ring = lo % s.ring_rows;
    for (int b = p.b0; b <= p.b1; ++b) {
        const auto bi = static_cast<std::size_t>(b);
        if (table.bucket_row_hi[bi] < lo || table.bucket_row_lo[bi] >= hi) continue;
        const WarpEntry* first = table.entries.data() + table.bucket_start[bi];
        const WarpEntry* last = table.entries.data() + table.bucket_start[bi + 1];
        if (table.bucket_row_lo[bi] < lo) first = std::lower_bound(first, last, lo, before);
        if (table.bucket_row_hi[bi] >= hi) last = std::lower_bound(first, last, hi, before);
        for (const WarpEntry* e = first; e != last; ++e) {
            const float u = e->qx - p.cx, v = e->qy - p.cy;
            if (u <= -0.5f || v <= -0.5f || u >= patch - 0.5f || v >= patch - 0.5f) continue;
            const float w = feather_weight(u, patch) * feather_weight(v, patch) * e->fade * p.weight;
            if (w <= 0.0f) continue;
            float c[4];
            sample_patch_bicubic(p.texture, patch, u, v, c);
            const int x = e->pixel - e->row * s.width;
            int ring_row = e->row - lo + lo_ring;
            if (ring_row >= s.ring_rows) ring_row -= s.ring_rows;
            const std::size_t pixel = static_cast<std::size_t>(ring_row) * static_cast<std::size_t>(s.width) + static_cast<std::size_t>(x);
            float* d = s.rgbw.data() + pixel * 4;
            const float alpha = std::clamp(c[3], 0.0f, 1.0f);
            d[0] += w * c[0];
            d[1] += w * c[1];
            d[2] += w * c[2];
            d[3] += w * alpha;
            if (groups) {
                const float wa = w * alpha;
                const float wrgb[3] = {w * c[0], w * c[1], w * c[2]};
                add_to_groups(s, pixel, 1, &wa, wrgb, p.input_frame);
            }
        }
    }
}

// Horizontal box sums of one ring row (as row_box_sums).
void ring_row_sums(RenderBuffers& s, int y, int r) {
    const int width = s.width;
    const float* src = s.rgbw.data() + s.ring_pixel(y, 0) * 4;
    float* dst = s.row_sums.data() + s.ring_pixel(y, 0) * 4;
    float sum[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    for (int x = 0; x < std::min(r, width); ++x)
        for (int c = 0; c < 4; ++c) sum[c] += src[x * 4 + c];
    // The same additions and subtractions, in the same order, without the
    // per-pixel bounds tests: while x + r < width, add; once x > r, subtract.
    const int add_end = std::max(0, width - r), sub_begin = std::min(width, r + 1);
    int x = 0;
    for (; x < std::min(add_end, sub_begin); ++x)
        for (int c = 0; c < 4; ++c) dst[x * 4 + c] = sum[c] += src[(x + r) * 4 + c];
    for (; x < add_end; ++x)
        for (int c = 0; c < 4; ++c) {
            sum[c] += src[(x + r) * 4 + c];
            sum[c] -= src[(x - r - 1) * 4 + c];
            dst[x * 4 + c] = sum[c];
        }
    for (; x < sub_begin; ++x)
        for (int c = 0; c < 4; ++c) dst[x * 4 + c] = sum[c];
    for (; x < width; ++x)
        for (int c = 0; c < 4; ++c) dst[x * 4 + c] = sum[c] -= src[(x - r - 1) * 4 + c];
}

}  // namespace

struct Synthesizer::Scratch : RenderBuffers {
    CarryBuffers carry;
};


void Synthesizer::render_into(int frame, RgbImage& out, std::vector<float>* coverage, Scratch& s) const {
    const int w = m_plan->width, h = m_plan->height;
    const int patch = m_streams->patch_size();
    // Groups of patches by input frame: for the detail gain and for overlap sharpening.
    const bool detail = m_settings.preserve_detail, sharpen = m_settings.overlap_sharpness != 1.0;
    const bool groups = detail || sharpen;
    if (coverage) coverage->assign(static_cast<std::size_t>(w) * h, 0.0f);
    if (w <= 0 || h <= 0) {
        m_background.fill(frame, w, h, out);
        return;
    }

    s.feather.resize(static_cast<std::size_t>(patch));
    for (int i = 0; i < patch; ++i) s.feather[static_cast<std::size_t>(i)] = feather_weight(static_cast<float>(i), patch);

    // The patches of the frame, in whole-frame order.
    s.splats.clear();
    std::size_t keyed = 0;
    for (const Plan::Line& line : m_plan->lines) keyed += line.keyed ? 1 : 0;
    s.keyed_warps.resize(keyed);  // never reallocated below: splats point into it
    keyed = 0;
    s.followed.clear();
    for (const Plan::Line& line : m_plan->lines) {
        m_streams->visible(line.stream, frame + line.time_offset_frames, s.visible);
        if (line.followed_by(m_background)) s.followed.insert(s.followed.end(), s.visible.begin(), s.visible.end());
        const WarpTable* warp = nullptr;
        if (line.keyed) {
            warp = &s.keyed_warps[keyed++];
            s.keyed_warps[keyed - 1] = build_warp(LineGeometry(formats::points_at_frame(line.line, frame), patch / 3.0),
                                                  m_streams->geometry(line.stream), m_settings.mapping, patch, w, h);
        } else if (!line.identity) {
            warp = &line.warp;
        }
        for (const auto& v : s.visible) {
            Splat p;
            p.texture = v.texture;
            p.weight = v.weight;
            p.input_frame = v.input_frame;
            if (!warp) {
                p.ox = patch_origin(v.centre.x(), patch);
                p.oy = patch_origin(v.centre.y(), patch);
                p.row_lo = std::max(0, p.oy);
                p.row_hi = std::min(h, p.oy + patch);
            } else {
                if (warp->bucket_start.size() < 2) continue;
                const int buckets = static_cast<int>(warp->bucket_start.size()) - 1;
                p.warp = warp;
                p.b0 = std::clamp(static_cast<int>(std::floor(v.arc_px - warp->reach_in - warp->s_min)), 0, buckets - 1);
                p.b1 = std::clamp(static_cast<int>(std::floor(v.arc_px + warp->reach_in - warp->s_min)), 0, buckets - 1);
                p.cx = static_cast<float>(patch_origin(v.centre.x(), patch));
                p.cy = static_cast<float>(patch_origin(v.centre.y(), patch));
                p.row_lo = std::numeric_limits<int>::max();
                p.row_hi = std::numeric_limits<int>::min();
                for (int b = p.b0; b <= p.b1; ++b) {
                    p.row_lo = std::min(p.row_lo, warp->bucket_row_lo[static_cast<std::size_t>(b)]);
                    p.row_hi = std::max(p.row_hi, warp->bucket_row_hi[static_cast<std::size_t>(b)] + 1);
                }
            }
            if (p.row_lo < p.row_hi) s.splats.push_back(p);
        }
    }

    fill_background(frame, s.followed, out);
    carry_background_into(frame, out, s.carry);

    // Steps: band k = rows [k B, (k + 1) B) needs rows up to hi_k = (k + 1) B + R;
    // step k accumulates rows [hi_(k-1), hi_k).
    const int radius = detail ? kDetailRadiusPx : 0;
    const int bands = (h + kBandRows - 1) / kBandRows;
    const auto step_hi = [&](int k) { return std::min(h, (k + 1) * kBandRows + radius); };
    const auto step_of = [&](int y) { return std::clamp(y < radius ? 0 : (y - radius) / kBandRows, 0, bands - 1); };
    s.step_start.assign(static_cast<std::size_t>(bands) + 1, 0);
    for (const Splat& p : s.splats)
        for (int k = step_of(p.row_lo); k <= step_of(p.row_hi - 1); ++k) ++s.step_start[static_cast<std::size_t>(k) + 1];
    for (int k = 0; k < bands; ++k) s.step_start[static_cast<std::size_t>(k) + 1] += s.step_start[static_cast<std::size_t>(k)];
    s.step_splats.resize(static_cast<std::size_t>(s.step_start.back()));
    {
        std::vector<int>& fill = s.step_start;  // advanced while filling, then restored
        for (std::size_t i = 0; i < s.splats.size(); ++i)
            for (int k = step_of(s.splats[i].row_lo); k <= step_of(s.splats[i].row_hi - 1); ++k)
                s.step_splats[static_cast<std::size_t>(fill[static_cast<std::size_t>(k)]++)] = static_cast<int>(i);
        for (int k = bands; k > 0; --k) fill[static_cast<std::size_t>(k)] = fill[static_cast<std::size_t>(k) - 1];
        fill[0] = 0;
    }

    // The ring: band k reads rows [k B - R, hi_k), at most B + 2R rows.
    s.width = w;
    s.ring_rows = std::min(h, kBandRows + 2 * radius);
    const std::size_t ring_pixels = static_cast<std::size_t>(s.ring_rows) * w;
    s.rgbw.resize(ring_pixels * 4);
    s.colours = sharpen;
    if (groups) {
        for (auto* v : {&s.group0, &s.group1}) v->resize(ring_pixels);
        for (auto* v : {&s.weight0, &s.weight1, &s.weight_rest}) v->resize(ring_pixels);
    }
    if (sharpen) s.group_rgb.resize(ring_pixels * kGroupColourFloats);
    if (detail) s.row_sums.resize(ring_pixels * 4);
    s.mixed_row.assign(static_cast<std::size_t>(s.ring_rows), 0);
    s.summed_row.assign(static_cast<std::size_t>(s.ring_rows), 0);

    const float full = static_cast<float>(std::max(1e-6, m_settings.coverage_weight));
    const bool screen = m_settings.texture_layer == TextureLayer::moving;
    int lo = 0;
    for (int k = 0; k < bands; ++k) {
        const int hi = step_hi(k);
        for (int y = lo; y < hi; ++y) {
            const std::size_t row = s.ring_pixel(y, 0);
            s.mixed_row[static_cast<std::size_t>(y % s.ring_rows)] = 0;
            s.summed_row[static_cast<std::size_t>(y % s.ring_rows)] = 0;
            std::fill_n(s.rgbw.data() + row * 4, static_cast<std::size_t>(w) * 4, 0.0f);
            if (groups) {
                for (auto* v : {&s.group0, &s.group1}) std::fill_n(v->data() + row, static_cast<std::size_t>(w), -1);
                for (auto* v : {&s.weight0, &s.weight1, &s.weight_rest})
                    std::fill_n(v->data() + row, static_cast<std::size_t>(w), 0.0f);
            }
            if (sharpen)
                std::fill_n(s.group_rgb.data() + row * kGroupColourFloats, static_cast<std::size_t>(w) * kGroupColourFloats, 0.0f);
        }
        for (int i = s.step_start[static_cast<std::size_t>(k)]; i < s.step_start[static_cast<std::size_t>(k) + 1]; ++i) {
            const Splat& p = s.splats[static_cast<std::size_t>(s.step_splats[static_cast<std::size_t>(i)])];
            const int a = std::max(lo, p.row_lo), b = std::min(hi, p.row_hi);
            if (a >= b) continue;
            if (p.warp) splat_warped_rows(s, groups, p, patch, a, b);
            else splat_patch_rows(s, groups, p, patch, a, b);
        }
        if (sharpen)
            for (int y = lo; y < hi; ++y) {
                if (!s.mixed_row[static_cast<std::size_t>(y % s.ring_rows)]) continue;  // one group: nothing to sharpen
                const std::size_t row = s.ring_pixel(y, 0);
                for (int x = 0; x < w; ++x) {
                    const std::size_t i = row + static_cast<std::size_t>(x);
                    sharpen_groups(s.rgbw.data() + i * 4, s.weight0[i], s.weight1[i], s.weight_rest[i],
                                   s.group_rgb.data() + i * kGroupColourFloats, static_cast<float>(m_settings.overlap_sharpness));
                }
            }
        lo = hi;

        // Finish band k (as the whole-frame pass: see render_reference).
        for (int y = k * kBandRows; y < std::min(h, (k + 1) * kBandRows); ++y) {
            const float* arow = s.rgbw.data() + s.ring_pixel(y, 0) * 4;
            const std::size_t ring_row = s.ring_pixel(y, 0);
            const float* w0 = groups ? s.weight0.data() + ring_row : nullptr;
            const float* w1 = groups ? s.weight1.data() + ring_row : nullptr;
            const float* w2 = groups ? s.weight_rest.data() + ring_row : nullptr;
            float* orow = out.rgb.data() + static_cast<std::size_t>(y) * w * 3;
            float* cov = coverage ? coverage->data() + static_cast<std::size_t>(y) * w : nullptr;
            // The row sums the local mean adds, in row order.
            const float* sums[2 * kDetailRadiusPx + 1];
            int sum_rows = 0;
            if (detail && s.mixed_row[static_cast<std::size_t>(y % s.ring_rows)])
                for (int yy = std::max(0, y - kDetailRadiusPx); yy <= std::min(h - 1, y + kDetailRadiusPx); ++yy) {
                    unsigned char& summed = s.summed_row[static_cast<std::size_t>(yy % s.ring_rows)];
                    if (!summed) ring_row_sums(s, yy, kDetailRadiusPx);
                    summed = 1;
                    sums[sum_rows++] = s.row_sums.data() + s.ring_pixel(yy, 0) * 4;
                }
            for (int x = 0; x < w; ++x) {
                const float* a = arow + 4 * x;
                if (a[3] <= 1e-6f) continue;
                const float c = static_cast<float>(smoothstep01(a[3] / full));
                const float inv = 1.0f / a[3];
                float tex[3] = {a[0] * inv, a[1] * inv, a[2] * inv};
                if (detail && w1[x] > 0.0f) {
                    const float gw[3] = {w0[x], w1[x], w2[x]};
                    const float squares = gw[0] * gw[0] + gw[1] * gw[1] + gw[2] * gw[2];
                    const float total = gw[0] + gw[1] + gw[2];
                    const float gain = squares > 0.0f ? std::clamp(total / std::sqrt(squares), 1.0f, kMaxDetailGain) : 1.0f;
                    if (gain > 1.0f) {
                        float l[4] = {0.0f, 0.0f, 0.0f, 0.0f};
                        for (int r = 0; r < sum_rows; ++r)
                            for (int q = 0; q < 4; ++q) l[q] += sums[r][4 * x + q];
                        if (l[3] > 1e-6f)
                            for (int q = 0; q < 3; ++q) {
                                const float mean = l[q] / l[3];
                                tex[q] = mean + (tex[q] - mean) * gain;
                            }
                    }
                }
                composite(orow + 3 * x, tex, c, screen);
                if (cov) cov[x] = c;
            }
        }
    }
}

RgbImage Synthesizer::render(int frame, std::vector<float>* coverage) const {
    if (m_settings.reference_rendering) return render_reference(frame, coverage);
    Scratch scratch;
    RgbImage out;
    render_into(frame, out, coverage, scratch);
    return out;
}

int Synthesizer::render_frames(int first, int last, int threads, const std::function<bool(int, const RgbImage&)>& sink) const {
    if (last < first) return 0;
    const int count = last - first + 1;
    const int workers =
        std::min(count, std::max(1, threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))));
    const auto render_one = [&](int frame, RgbImage& image, Scratch& scratch) {
        if (m_settings.reference_rendering) image = render_reference(frame, nullptr);
        else render_into(frame, image, nullptr, scratch);
    };
    if (workers == 1) {
        Scratch scratch;
        RgbImage image;
        for (int f = first; f <= last; ++f) {
            render_one(f, image, scratch);
            if (!sink(f, image)) return f - first;
        }
        return count;
    }
    // Worker j renders frames first + j, first + j + workers, ... into its two
    // slots in turn (frame index i uses slot i mod 2 workers), each with its
    // own scratch; a slot is reused once its frame has been delivered.
    const int slots = 2 * workers;
    std::vector<RgbImage> images(static_cast<std::size_t>(slots));
    std::vector<char> ready(static_cast<std::size_t>(slots), 0);
    std::mutex mutex;
    std::condition_variable changed;
    int delivered = 0;  // frame indices below this are delivered
    bool stop = false;
    std::exception_ptr failure;
    std::vector<std::thread> pool;
    for (int j = 0; j < workers; ++j)
        pool.emplace_back([&, j] {
            Scratch scratch;
            for (int i = j; i < count; i += workers) {
                const auto slot = static_cast<std::size_t>(i % slots);
                {
                    std::unique_lock<std::mutex> lock(mutex);
                    changed.wait(lock, [&] { return stop || delivered > i - slots; });
                    if (stop) return;
                }
                try {
                    render_one(first + i, images[slot], scratch);
                } catch (...) {
                    const std::lock_guard<std::mutex> lock(mutex);
                    if (!failure) failure = std::current_exception();
                    stop = true;
                    changed.notify_all();
                    return;
                }
                const std::lock_guard<std::mutex> lock(mutex);
                ready[slot] = 1;
                changed.notify_all();
            }
        });
    for (int i = 0; i < count; ++i) {
        const auto slot = static_cast<std::size_t>(i % slots);
        {
            std::unique_lock<std::mutex> lock(mutex);
            changed.wait(lock, [&] { return stop || ready[slot]; });
            if (stop) break;
        }
        bool more = false;
        try {
            more = sink(first + i, images[slot]);
        } catch (...) {
            const std::lock_guard<std::mutex> lock(mutex);
            if (!failure) failure = std::current_exception();
            stop = true;
            changed.notify_all();
            break;
        }
        const std::lock_guard<std::mutex> lock(mutex);
        if (!more) {
            stop = true;
            changed.notify_all();
            break;
        }
        ready[slot] = 0;
        delivered = i + 1;
        changed.notify_all();
    }
    for (std::thread& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
    return delivered;
}

ParticleStreams::Samples Synthesizer::sample_line(const std::vector<Eigen::Vector2d>& output_points, const std::string& from,
                                                  int frame, const std::vector<Eigen::Vector2d>& points) const {
    const LineGeometry g(output_points, m_streams->patch_size() / 3.0);
    std::vector<float> s(points.size()), n(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        const LineGeometry::Projection p = g.project(points[i], m_streams->patch_size());
        s[i] = static_cast<float>(p.s);
        n[i] = static_cast<float>(p.n);
    }
    ParticleStreams::Samples out;
    const int stream = m_streams->stream_index(from);
    if (stream >= 0) m_streams->sample(stream, frame, m_settings.mapping, g.length_px(), s, n, out);
    else m_streams->sample_input_line(m_streams->input_line_index(from), frame, m_settings.mapping, g.length_px(), s, n, out);
    return out;
}

}  // namespace flowvid::flow
