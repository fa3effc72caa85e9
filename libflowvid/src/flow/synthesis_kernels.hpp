#pragma once
// Per-pixel kernels of the synthesizer's two renderers (synthesis.cpp's
// whole-frame reference pass, synthesis_banded.cpp's banded pass): patch
// sampling, accumulation, overlap sharpening, compositing. Inline: they run
// per pixel. Not part of the public interface.

#include "flowvid/flow/sampling.hpp"
#include "flowvid/flow/synthesis.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace flowvid::flow::detail {

// Detail-preserving blending rescales detail by at most this (two groups
// mixed evenly: sqrt(2)), around a local mean over this radius.
constexpr float kMaxDetailGain = 1.4142f;
constexpr int kDetailRadiusPx = 2;

inline double smoothstep01(double x) {
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
inline void sharpen_groups(float* rgbw, float& w0, float& w1, float& w2, const float* group_rgb, float exponent) {
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
inline void sample_patch_bicubic(const float* texture, int patch, float u, float v, float out[4]) {
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
inline void row_box_sums(const std::vector<float>& values, int width, int y0, int y1, int r, std::vector<float>& out) {
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

// d += w t for one premultiplied RGBA texel.
inline void add_weighted_texel(float* d, const float* t, float w) {
    d[0] += w * t[0];
    d[1] += w * t[1];
    d[2] += w * t[2];
    d[3] += w * t[3];
}

// Splats a feathered patch back on the whole pixels it was cut from
// (patch_origin of its centre): an exact copy, weighted.
inline void splat_patch(Accumulator& acc, const ParticleStreams::Visible& v, int patch, const std::vector<float>& feather) {
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
            add_weighted_texel(dst + static_cast<std::size_t>(j) * 4, t, w);
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

}  // namespace flowvid::flow::detail
