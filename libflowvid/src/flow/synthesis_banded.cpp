// The synthesizer's banded renderer (Synthesizer::render_into) and the
// frame loop around it; the whole-frame reference pass it must reproduce is
// in synthesis.cpp.

#include "flowvid/flow/synthesis.hpp"
#include "flowvid/threads.hpp"

#include "layer_edges.hpp"
#include "synthesis_kernels.hpp"
#include "synthesis_plan.hpp"
#include "warp_table.hpp"

#include "flowvid/flow/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>

namespace flowvid::flow {

using namespace detail;

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
            add_weighted_texel(dst + static_cast<std::size_t>(j) * 4, t, w);
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
    // With an edge fade: the finished layer, faded and composited once every band is done.
    std::vector<float> layer, layer_coverage;
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
    const bool fade = m_settings.edge_fade_px > 0.0;
    if (fade) {
        s.layer.resize(3 * static_cast<std::size_t>(w) * h);  // read only where layer_coverage is set below
        s.layer_coverage.assign(static_cast<std::size_t>(w) * h, 0.0f);
    }
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
                if (fade) {
                    const std::size_t i = static_cast<std::size_t>(y) * w + x;
                    std::copy(tex, tex + 3, s.layer.begin() + static_cast<std::ptrdiff_t>(3 * i));
                    s.layer_coverage[i] = c;
                    continue;
                }
                composite(orow + 3 * x, tex, c, screen);
                if (cov) cov[x] = c;
            }
        }
    }
    if (fade) composite_faded_layer(s.layer, s.layer_coverage, m_settings.edge_fade_px, screen, out, coverage);
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
        std::min(count, resolve_thread_count(threads));
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
