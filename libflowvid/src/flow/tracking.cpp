#include "flowvid/flow/tracking.hpp"
#include "flowvid/threads.hpp"

#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/sampling.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <future>
#include <limits>
#include <stdexcept>
#include <thread>

namespace flowvid::flow {

namespace {

// The frame resampled along a line: row r is arc length s0 + r, column j the
// lateral offset j - (P - 1) / 2 along the smoothed normal; RGB display
// values. Sample positions are fixed per line, so they are precomputed.
struct Ribbon {
    int rows = 0;
    int cols = 0;
    double s0 = 0.0;
    std::vector<int> ix, iy;  // top-left tap of the bilinear sample
    std::vector<float> fx, fy;
    std::vector<float> values;        // rows x cols x 3
    std::vector<double> prefix_sum;   // over rows: sum of values
    std::vector<double> prefix_sq;    // sum of squares
    std::vector<std::uint8_t> valid;  // rows x cols: the sample lies inside the frame
    std::vector<int> prefix_invalid;  // over rows: count of samples outside the frame

    void setup(const LineGeometry& g, int patch, double extra_px, int width, int height) {
        cols = patch;
        const double half = (patch - 1) / 2.0;
        s0 = -std::ceil(half + 2.0);
        rows = static_cast<int>(std::ceil(g.length_px() + extra_px + half + 2.0 - s0)) + 1;
        const std::size_t n = static_cast<std::size_t>(rows) * cols;
        ix.resize(n);
        iy.resize(n);
        valid.assign(n, 1);
        prefix_invalid.assign(static_cast<std::size_t>(rows) + 1, 0);
        fx.resize(n);
        fy.resize(n);
        for (int r = 0; r < rows; ++r) {
            const double s = s0 + r;
            const Eigen::Vector2d p = g.point(s);
            const Eigen::Vector2d nrm = g.normal(s);
            for (int j = 0; j < cols; ++j) {
                const Eigen::Vector2d q = p + (j - half) * nrm;
                const bool inside = q.x() >= -0.5 && q.y() >= -0.5 && q.x() <= width - 0.5 && q.y() <= height - 0.5;
                const double x = std::clamp(q.x(), 0.0, static_cast<double>(width - 1));
                const double y = std::clamp(q.y(), 0.0, static_cast<double>(height - 1));
                int x0 = std::min(static_cast<int>(x), std::max(0, width - 2));
                int y0 = std::min(static_cast<int>(y), std::max(0, height - 2));
                const std::size_t k = static_cast<std::size_t>(r) * cols + j;
                ix[k] = x0;
                iy[k] = y0;
                fx[k] = static_cast<float>(x - x0);
                fy[k] = static_cast<float>(y - y0);
                valid[k] = inside ? 1 : 0;
                prefix_invalid[static_cast<std::size_t>(r) + 1] += inside ? 0 : 1;
            }
            prefix_invalid[static_cast<std::size_t>(r) + 1] += prefix_invalid[static_cast<std::size_t>(r)];
        }
        values.assign(n * 3, 0.0f);
        prefix_sum.assign(static_cast<std::size_t>(rows) + 1, 0.0);
        prefix_sq.assign(static_cast<std::size_t>(rows) + 1, 0.0);
    }

    void fill(const RgbImage& image) {
        const int w = image.width, h = image.height;
        const std::size_t n = ix.size();
        for (std::size_t k = 0; k < n; ++k) {
            const int x0 = ix[k], y0 = iy[k];
            const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
            const float* a = image.pixel(x0, y0);
            const float* b = image.pixel(x1, y0);
            const float* c = image.pixel(x0, y1);
            const float* d = image.pixel(x1, y1);
            const float u = fx[k], v = fy[k];
            for (int ch = 0; ch < 3; ++ch) {
                const float top = a[ch] + u * (b[ch] - a[ch]);
                const float bottom = c[ch] + u * (d[ch] - c[ch]);
                values[3 * k + static_cast<std::size_t>(ch)] = top + v * (bottom - top);
            }
        }
        const std::size_t row_values = static_cast<std::size_t>(cols) * 3;
        for (int r = 0; r < rows; ++r) {
            double sum = 0.0, sq = 0.0;
            const float* row = values.data() + static_cast<std::size_t>(r) * row_values;
            for (std::size_t i = 0; i < row_values; ++i) {
                sum += row[i];
                sq += static_cast<double>(row[i]) * row[i];
            }
            prefix_sum[static_cast<std::size_t>(r) + 1] = prefix_sum[static_cast<std::size_t>(r)] + sum;
            prefix_sq[static_cast<std::size_t>(r) + 1] = prefix_sq[static_cast<std::size_t>(r)] + sq;
        }
    }
};

struct ActiveParticle {
    int start = 0;
    double s = 0.0;
    std::vector<float> arc;
    std::vector<float> texture;
    double last_step = 0.0;
    bool has_step = false;
    int steps = 0;
    int uncertain = 0;
    int extrapolated = 0;
    double correlation_sum = 0.0;
    double step_sum = 0.0;
};

struct LineState {
    const formats::FlowLine* line = nullptr;
    LineGeometry geometry;
    Ribbon current, next;
    std::vector<ActiveParticle> active;
    std::vector<ActiveParticle> completed;
    int started = 0;
    // Stationary speed profile: sums of certain steps per 2-px bin of arc.
    std::vector<double> bin_sum;
    std::vector<int> bin_count;
};

constexpr double kProfileBinPx = 2.0;

// Axis-aligned RGBA patch around `centre`: the block of whole pixels nearest
// to it (patch_origin), linear light, alpha 0 outside the frame.
void extract_patch(const RgbImage& linear, const Eigen::Vector2d& centre, int patch, float* out) {
    const int ox = patch_origin(centre.x(), patch), oy = patch_origin(centre.y(), patch);
    const int w = linear.width, h = linear.height;
    for (int i = 0; i < patch; ++i) {
        const int y = oy + i;
        for (int j = 0; j < patch; ++j) {
            const int x = ox + j;
            float* o = out + (static_cast<std::size_t>(i) * patch + j) * 4;
            if (x < 0 || y < 0 || x >= w || y >= h) {
                o[0] = o[1] = o[2] = o[3] = 0.0f;
                continue;
            }
            const float* p = linear.pixel(x, y);
            o[0] = p[0];
            o[1] = p[1];
            o[2] = p[2];
            o[3] = 1.0f;
        }
    }
}

struct StepResult {
    double step = 0.0;
    double correlation = 0.0;
    bool certain = false;
};

// NCC over the samples inside the frame in both blocks (near image borders).
double masked_ncc(const Ribbon& a, int ra, const Ribbon& b, int rb) {
    const int patch = a.cols;
    const std::size_t pixels = static_cast<std::size_t>(patch) * patch;
    const float* ta = a.values.data() + static_cast<std::size_t>(ra) * patch * 3;
    const float* tb = b.values.data() + static_cast<std::size_t>(rb) * patch * 3;
    const std::uint8_t* va = a.valid.data() + static_cast<std::size_t>(ra) * patch;
    const std::uint8_t* vb = b.valid.data() + static_cast<std::size_t>(rb) * patch;
    double sa = 0.0, sb = 0.0, saa = 0.0, sbb = 0.0, sab = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < pixels; ++i) {
        if (!va[i] || !vb[i]) continue;
        for (int c = 0; c < 3; ++c) {
            const double x = ta[3 * i + static_cast<std::size_t>(c)], y = tb[3 * i + static_cast<std::size_t>(c)];
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
        n += 3;
    }
    if (n < pixels) return 0.0;  // less than a third of the block is visible in both frames
    const double dn = static_cast<double>(n);
    const double cov = sab - sa * sb / dn;
    const double va_ = saa - sa * sa / dn, vb_ = sbb - sb * sb / dn;
    const double denom = std::sqrt(std::max(va_, 0.0) * std::max(vb_, 0.0));
    return denom > 1e-9 ? cov / denom : 0.0;
}

// Gauss-Newton refinement of a match at row `row` + `offset` of ribbon b.
// The candidate is modelled as the template shifted by delta and stretched
// along the line by (1 + kappa) about its centre: falling water stretches
// between frames, and a shift-only fit would lean towards the part of the
// block with finer texture. Rows are resampled with Catmull-Rom weights; the
// gain is normalised. Returns the refined shift (within +-1 px of the start).
double refine_subpixel(const std::vector<float>& templ, const Ribbon& b, int row, double offset) {
    const int patch = b.cols;
    const std::size_t block = static_cast<std::size_t>(patch) * patch * 3;
    const std::size_t row_values = static_cast<std::size_t>(patch) * 3;
    const double half = (patch - 1) / 2.0;
    double t2 = 0.0;
    for (std::size_t i = 0; i < block; ++i) t2 += static_cast<double>(templ[i]) * templ[i];
    if (t2 <= 1e-12) return offset;
    std::vector<double> c(block), g(block);
    double delta = offset, kappa = 0.0;
    for (int iteration = 0; iteration < 5; ++iteration) {
        const double first = row + delta - kappa * half, last = row + delta + patch - 1 + kappa * half;
        if (std::floor(first) - 1 < 0 || std::floor(last) + 3 > b.rows) break;
        const int lo = static_cast<int>(std::floor(first)) - 1, hi = static_cast<int>(std::floor(last)) + 3;
        if (b.prefix_invalid[static_cast<std::size_t>(hi)] != b.prefix_invalid[static_cast<std::size_t>(lo)]) break;
        double mc = 0.0, mg = 0.0, mgy = 0.0;
        for (int i = 0; i < patch; ++i) {
            const double position = row + delta + i + kappa * (i - half);
            const int base = static_cast<int>(std::floor(position));
            const double t = position - base, tt = t * t;
            const double w[4] = {0.5 * (-tt * t + 2.0 * tt - t), 0.5 * (3.0 * tt * t - 5.0 * tt + 2.0),
                                 0.5 * (-3.0 * tt * t + 4.0 * tt + t), 0.5 * (tt * t - tt)};
            const double dw[4] = {0.5 * (-3.0 * tt + 4.0 * t - 1.0), 0.5 * (9.0 * tt - 10.0 * t),
                                  0.5 * (-9.0 * tt + 8.0 * t + 1.0), 0.5 * (3.0 * tt - 2.0 * t)};
            for (std::size_t k = 0; k < row_values; ++k) {
                double cv = 0.0, gv = 0.0;
                for (int q = 0; q < 4; ++q) {
                    const float v = b.values[static_cast<std::size_t>(base - 1 + q) * row_values + k];
                    cv += w[q] * v;
                    gv += dw[q] * v;
                }
                const std::size_t idx = static_cast<std::size_t>(i) * row_values + k;
                c[idx] = cv;
                g[idx] = gv;
                mc += cv;
                mg += gv;
                mgy += gv * (i - half);
            }
        }
        mc /= static_cast<double>(block);
        mg /= static_cast<double>(block);
        mgy /= static_cast<double>(block);
        double c2 = 0.0;
        for (std::size_t i = 0; i < block; ++i) c2 += (c[i] - mc) * (c[i] - mc);
        if (c2 <= 1e-12) break;
        const double gain = std::sqrt(t2 / c2);
        // Normal equations for (delta, kappa).
        double a11 = 0.0, a12 = 0.0, a22 = 0.0, r1 = 0.0, r2 = 0.0;
        for (int i = 0; i < patch; ++i)
            for (std::size_t k = 0; k < row_values; ++k) {
                const std::size_t idx = static_cast<std::size_t>(i) * row_values + k;
                const double j1 = gain * (g[idx] - mg);
                const double j2 = gain * (g[idx] * (i - half) - mgy);
                const double e = templ[idx] - gain * (c[idx] - mc);
                a11 += j1 * j1;
                a12 += j1 * j2;
                a22 += j2 * j2;
                r1 += j1 * e;
                r2 += j2 * e;
            }
        const double det = a11 * a22 - a12 * a12;
        if (!(det > 1e-12 * a11 * a22) || a11 <= 0.0) break;
        const double step_delta = std::clamp((a22 * r1 - a12 * r2) / det, -0.5, 0.5);
        const double step_kappa = std::clamp((a11 * r2 - a12 * r1) / det, -0.05, 0.05);
        delta = std::clamp(delta + step_delta, offset - 1.0, offset + 1.0);
        kappa = std::clamp(kappa + step_kappa, -0.3, 0.3);
        if (std::fabs(step_delta) < 1e-3 && std::fabs(step_kappa) < 1e-4) break;
    }
    return delta;
}

// One step of block matching along the line, from ribbon `a` (this frame) to
// ribbon `b` (next frame), for a particle at arc s.
StepResult match_step(const Ribbon& a, const Ribbon& b, double s, double window_lo, double window_hi,
                      std::vector<float>& templ) {
    const int patch = a.cols;
    const double half = (patch - 1) / 2.0;
    const int r0 = std::clamp(static_cast<int>(std::lround(s - a.s0 - half)), 0, a.rows - patch);
    const std::size_t block = static_cast<std::size_t>(patch) * patch * 3;
    const float* t = a.values.data() + static_cast<std::size_t>(r0) * patch * 3;
    double mean = 0.0;
    for (std::size_t i = 0; i < block; ++i) mean += t[i];
    mean /= static_cast<double>(block);
    templ.resize(block);
    double tnorm = 0.0;
    for (std::size_t i = 0; i < block; ++i) {
        templ[i] = static_cast<float>(t[i] - mean);
        tnorm += static_cast<double>(templ[i]) * templ[i];
    }
    tnorm = std::sqrt(tnorm);

    int dlo = static_cast<int>(std::floor(window_lo));
    int dhi = static_cast<int>(std::ceil(window_hi));
    dlo = std::max(dlo, -r0);
    dhi = std::min(dhi, b.rows - patch - r0);
    StepResult result;
    if (dhi < dlo) return result;
    const bool template_clipped = a.prefix_invalid[static_cast<std::size_t>(r0 + patch)] != a.prefix_invalid[static_cast<std::size_t>(r0)];
    std::vector<double> scores(static_cast<std::size_t>(dhi - dlo + 1));
    int best = dlo;
    double best_score = -2.0;
    for (int d = dlo; d <= dhi; ++d) {
        const int r = r0 + d;
        if (template_clipped || b.prefix_invalid[static_cast<std::size_t>(r + patch)] != b.prefix_invalid[static_cast<std::size_t>(r)]) {
            const double score = masked_ncc(a, r0, b, r);
            scores[static_cast<std::size_t>(d - dlo)] = score;
            if (score > best_score) {
                best_score = score;
                best = d;
            }
            continue;
        }
        const float* c = b.values.data() + static_cast<std::size_t>(r) * patch * 3;
        double dot = 0.0;
        for (std::size_t i = 0; i < block; ++i) dot += static_cast<double>(templ[i]) * c[i];
        const double sum = b.prefix_sum[static_cast<std::size_t>(r + patch)] - b.prefix_sum[static_cast<std::size_t>(r)];
        const double sq = b.prefix_sq[static_cast<std::size_t>(r + patch)] - b.prefix_sq[static_cast<std::size_t>(r)];
        const double var = std::max(sq - sum * sum / static_cast<double>(block), 0.0);
        const double denom = tnorm * std::sqrt(var);
        const double score = denom > 1e-9 ? dot / denom : 0.0;
        scores[static_cast<std::size_t>(d - dlo)] = score;
        if (score > best_score) {
            best_score = score;
            best = d;
        }
    }
    double sub = 0.0;
    bool interior = best > dlo && best < dhi;
    if (interior) {
        const double l = scores[static_cast<std::size_t>(best - 1 - dlo)];
        const double c = scores[static_cast<std::size_t>(best - dlo)];
        const double r = scores[static_cast<std::size_t>(best + 1 - dlo)];
        const double curvature = l - 2.0 * c + r;
        if (curvature < 0.0) sub = std::clamp(0.5 * (l - r) / curvature, -0.5, 0.5);
        // The parabola through correlation scores is biased towards whole
        // pixels ("pixel locking"); a few Gauss-Newton steps on the
        // gain-normalised difference, with the candidate resampled by
        // Catmull-Rom between ribbon rows, remove that bias.
        if (!template_clipped) sub = refine_subpixel(templ, b, r0 + best, sub);
    }
    result.step = best + sub;
    result.correlation = best_score;
    result.certain = interior && tnorm > 1e-6;
    return result;
}

// Per-pixel median of up to `samples` evenly spaced frames (display values).
RgbImage static_plate(FrameSequence& frames, int samples) {
    const int count = frames.count();
    const int n = std::max(1, std::min(count, samples));
    std::vector<RgbImage> picked;
    for (int i = 0; i < n; ++i)
        picked.push_back(frames.frame(n == 1 ? 0 : static_cast<int>(std::lround(static_cast<double>(i) * (count - 1) / (n - 1)))));
    RgbImage plate(frames.width(), frames.height());
    std::vector<float> values(static_cast<std::size_t>(n));
    for (std::size_t k = 0; k < plate.rgb.size(); ++k) {
        for (int i = 0; i < n; ++i) values[static_cast<std::size_t>(i)] = picked[static_cast<std::size_t>(i)].rgb[k];
        std::nth_element(values.begin(), values.begin() + n / 2, values.end());
        plate.rgb[k] = values[static_cast<std::size_t>(n / 2)];
    }
    return plate;
}

}  // namespace

namespace {

struct PassOptions {
    bool probe = false;             // measure speeds only: particles spawned along the line, no textures
    std::vector<int> probe_frames;  // frames probes enter at
    double probe_spacing_px = 16.0;
    int start_every = 1;            // tracking pass: a particle enters every this many frames
    int progress_offset = 0;        // frames already reported (the probe pass)
    int progress_total = 0;
};

// One pass over the clip, advancing every line's particles frame by frame.
// Returns false when cancelled.
bool run_pass(FrameSequence& frames, std::vector<LineState>& states, const RgbImage& plate,
              const TrackingSettings& settings, const PassOptions& pass, const Progress& progress) {
    const int frame_count = frames.count();
    const int patch = settings.patch_size_px;
    const bool stationary = settings.dynamics == formats::ParticleDynamics::stationary;
    const std::size_t patch_values = static_cast<std::size_t>(patch) * patch * 4;
    const int thread_count = std::max(1, std::min<int>(static_cast<int>(states.size()), resolve_thread_count(settings.threads)));
    const auto profile_at = [](const LineState& st, double s, double& value) {
        const std::size_t bin = static_cast<std::size_t>(std::clamp(s / kProfileBinPx, 0.0, static_cast<double>(st.bin_count.size() - 1)));
        if (st.bin_count[bin] < 2) return false;
        value = st.bin_sum[bin] / st.bin_count[bin];
        return true;
    };
    // Matching image: the frame minus the clip's static plate, so that the
    // still outline of a waterfall or the rocks around it do not pull matches
    // towards zero motion; only what moves is compared.
    const auto matching = [&plate](const RgbImage& display) {
        if (plate.empty()) return display;
        RgbImage out = display;
        for (std::size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] -= plate.rgb[i];
        return out;
    };
    if (frame_count < 1) return true;
    RgbImage display = frames.frame(0);
    RgbImage display_next, match_next;
    {
        const RgbImage match = matching(display);
        for (LineState& st : states) st.current.fill(match);
    }

    for (int f = 0; f < frame_count; ++f) {
        const bool last = f + 1 >= frame_count;
        RgbImage linear;
        if (!pass.probe) linear = to_linear(display);
        if (!last) {
            display_next = frames.frame(f + 1);
            match_next = matching(display_next);
        }
        const bool probe_spawn = pass.probe && std::find(pass.probe_frames.begin(), pass.probe_frames.end(), f) != pass.probe_frames.end();

        const auto process = [&](std::size_t line_index) {
            LineState& st = states[line_index];
            std::vector<float> templ;
            const double length = st.geometry.length_px();
            if (!last) st.next.fill(match_next);
            if (!last && !pass.probe && f % pass.start_every == 0) {
                ActiveParticle p;
                p.start = f;
                st.active.push_back(std::move(p));
                ++st.started;
            }
            if (!last && probe_spawn)
                for (double s = 0.0; s < length - 4.0; s += pass.probe_spacing_px) {
                    ActiveParticle p;
                    p.start = f;
                    p.s = s;
                    st.active.push_back(std::move(p));
                }
            std::vector<ActiveParticle> still;
            still.reserve(st.active.size());
            for (ActiveParticle& p : st.active) {
                if (!pass.probe) {
                    p.arc.push_back(static_cast<float>(std::clamp(p.s, 0.0, length)));
                    const std::size_t offset = p.texture.size();
                    p.texture.resize(offset + patch_values);
                    extract_patch(linear, st.geometry.point(p.s), patch, p.texture.data() + offset);
                }
                if (last) continue;  // still on the line when the clip ends: incomplete, dropped

                // Predict the step, then search the window around it.
                double predicted = 0.0, radius = settings.search_radius_px;
                bool have_prediction = false;
                double profile_step = 0.0;
                const bool have_profile = profile_at(st, p.s, profile_step);
                if (stationary && have_profile) {
                    predicted = profile_step;
                    have_prediction = true;
                } else if (p.has_step) {
                    predicted = p.last_step;
                    have_prediction = true;
                } else if (have_profile) {
                    predicted = profile_step;
                    radius *= 2.0;
                    have_prediction = true;
                }
                double lo = -2.0, hi = settings.max_speed_px;
                if (have_prediction) {
                    lo = std::max(-2.0, predicted - radius);
                    hi = std::min(settings.max_speed_px, std::max(predicted + radius, lo + 2.0));
                }
                // A particle whose patch is mostly outside the frame cannot be
                // matched: it moves by the prediction until it leaves the line.
                const int r0 = std::clamp(static_cast<int>(std::lround(p.s - st.current.s0 - (patch - 1) / 2.0)), 0,
                                          st.current.rows - patch);
                const int hidden = st.current.prefix_invalid[static_cast<std::size_t>(r0 + patch)] -
                                   st.current.prefix_invalid[static_cast<std::size_t>(r0)];
                const bool mostly_hidden = 2 * hidden > patch * patch;
                double step;
                bool certain = false;
                if (mostly_hidden && have_prediction) {
                    step = predicted;
                    ++p.extrapolated;
                } else {
                    StepResult m = match_step(st.current, st.next, p.s, lo, hi, templ);
                    // A non-stationary particle's last step predicts its next one
                    // only while its speed changes slowly; a flame's gust can
                    // outrun the window around it. Before extrapolating, search
                    // the whole window once (stationary flows keep the window their
                    // line's profile gives: a step outside it is more likely a
                    // false match in weak texture than a change of speed).
                    if (!stationary && have_prediction && !(m.certain && m.correlation >= settings.min_correlation)) {
                        const StepResult wide = match_step(st.current, st.next, p.s, -2.0, settings.max_speed_px, templ);
                        if (wide.certain && wide.correlation >= settings.min_correlation) m = wide;
                    }
                    certain = m.certain && m.correlation >= settings.min_correlation;
                    step = m.step;
                    if (!certain && have_prediction) step = predicted;
                    if (certain) p.correlation_sum += m.correlation;
                    else ++p.uncertain;
                }
                step = std::max(step, -2.0);
                ++p.steps;
                p.step_sum += step;
                if (certain) {
                    const std::size_t bin = static_cast<std::size_t>(std::clamp(p.s / kProfileBinPx, 0.0, static_cast<double>(st.bin_count.size() - 1)));
                    st.bin_sum[bin] += step;
                    ++st.bin_count[bin];
                }
                p.last_step = step;
                p.has_step = true;
                p.s = std::max(0.0, p.s + step);
                if (p.s > length) {
                    if (!pass.probe) st.completed.push_back(std::move(p));
                } else {
                    still.push_back(std::move(p));
                }
            }
            st.active = std::move(still);
        };

        if (thread_count == 1) {
            for (std::size_t i = 0; i < states.size(); ++i) process(i);
        } else {
            std::vector<std::future<void>> jobs;
            for (int t = 0; t < thread_count; ++t)
                jobs.push_back(std::async(std::launch::async, [&, t] {
                    for (std::size_t i = static_cast<std::size_t>(t); i < states.size(); i += static_cast<std::size_t>(thread_count))
                        process(i);
                }));
            for (auto& job : jobs) job.get();
        }
        for (LineState& st : states) std::swap(st.current, st.next);
        display = std::move(display_next);
        const int done = pass.progress_offset + f + 1;
        if (progress && !progress({"track", static_cast<double>(done) / std::max(1, pass.progress_total),
                                   "frame " + std::to_string(done) + "/" + std::to_string(pass.progress_total)}))
            return false;
    }
    return true;
}

std::vector<LineState> make_states(const std::vector<formats::FlowLine>& lines, const TrackingSettings& settings, int width,
                                   int height) {
    std::vector<LineState> states(lines.size());
    const int patch = settings.patch_size_px;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        LineState& st = states[i];
        st.line = &lines[i];
        st.geometry = LineGeometry(lines[i].points, patch / 3.0);
        st.current.setup(st.geometry, patch, settings.max_speed_px + settings.search_radius_px, width, height);
        st.next = st.current;
        const std::size_t bins = static_cast<std::size_t>(st.geometry.length_px() / kProfileBinPx) + 2;
        st.bin_sum.assign(bins, 0.0);
        st.bin_count.assign(bins, 0);
    }
    return states;
}

// Travel time from the start of a line to every 2-px bin, from the probe
// speeds (gaps filled from the nearest measured bins, speeds floored).
std::vector<double> probe_speeds(const LineState& st, double min_speed) {
    const std::size_t bins = st.bin_count.size();
    std::vector<double> speed(bins, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t b = 0; b < bins; ++b)
        if (st.bin_count[b] > 0) speed[b] = st.bin_sum[b] / st.bin_count[b];
    // Smooth over +-4 bins (16 px) and fill gaps with the nearest known value.
    std::vector<double> smooth(bins, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t b = 0; b < bins; ++b) {
        double sum = 0.0;
        int n = 0;
        for (std::size_t k = b >= 4 ? b - 4 : 0; k <= std::min(bins - 1, b + 4); ++k)
            if (!std::isnan(speed[k])) {
                sum += speed[k];
                ++n;
            }
        if (n > 0) smooth[b] = sum / n;
    }
    for (std::size_t b = 0; b < bins; ++b)
        if (std::isnan(smooth[b])) {
            for (std::size_t d = 1; d < bins; ++d) {
                if (b >= d && !std::isnan(smooth[b - d])) { smooth[b] = smooth[b - d]; break; }
                if (b + d < bins && !std::isnan(smooth[b + d])) { smooth[b] = smooth[b + d]; break; }
            }
            if (std::isnan(smooth[b])) smooth[b] = min_speed;
        }
    return smooth;
}

std::vector<double> travel_times(const std::vector<double>& speeds, double min_speed) {
    std::vector<double> tau(speeds.size() + 1, 0.0);
    for (std::size_t b = 0; b < speeds.size(); ++b) tau[b + 1] = tau[b] + kProfileBinPx / std::max(min_speed, speeds[b]);
    return tau;
}

}  // namespace

TrackingResult track_particles(FrameSequence& frames, const std::vector<formats::FlowLine>& lines,
                               const TrackingSettings& settings, const Progress& progress) {
    if (settings.patch_size_px < 4 || settings.patch_size_px > formats::kMaxBankPatchSizePx)
        throw std::invalid_argument("patch size must be 4.." + std::to_string(formats::kMaxBankPatchSizePx) + " px");
    if (!(settings.max_speed_px > 0.0) || !(settings.search_radius_px > 0.0))
        throw std::invalid_argument("max speed and search radius must be positive");
    if (settings.start_every < 0) throw std::invalid_argument("start_every must be 0 (automatic) or more");
    if (lines.empty()) throw std::invalid_argument("no flow line to track along");
    for (const formats::FlowLine& line : lines)
        if (line.is_time_varying())
            throw std::invalid_argument("input line " + line.id + " moves over time; input lines must be fixed");
    const int frame_count = frames.count();
    const int width = frames.width(), height = frames.height();
    const int patch = settings.patch_size_px;
    if (frame_count < 2)
        throw std::invalid_argument("tracking follows particles from frame to frame: the clip needs at least 2 frames, "
                                    "it has " + std::to_string(frame_count));
    if (patch > std::min(width, height))
        throw std::invalid_argument("a " + std::to_string(patch) + " px patch does not fit the clip's " +
                                    std::to_string(width) + " x " + std::to_string(height) +
                                    " frame: use a patch of at most " + std::to_string(std::min(width, height)) + " px");
    for (const formats::FlowLine& line : lines)
        if (length_inside_frame(line.points, width, height) < 1.0)
            throw std::invalid_argument("input line " + line.id + " lies outside the clip's " + std::to_string(width) +
                                        " x " + std::to_string(height) +
                                        " frame: draw it over the flow (in pixels of the clip)");

    TrackingResult result;
    RgbImage plate;
    if (settings.remove_static_background && frame_count >= 3) plate = static_plate(frames, 31);

    // Pass 1: probes along every line measure its speed profile, which
    // decides where long lines are cut into segments a particle crosses
    // within max_path_frames, and how often particles enter.
    const int max_path = settings.max_path_frames > 0 ? settings.max_path_frames : std::max(2, frame_count / 5);
    const bool probe = frame_count >= 2;  // also seeds every line's speed prediction
    const int total_progress = (probe ? 2 : 1) * frame_count;
    std::vector<formats::FlowLine> tracked = lines;
    std::vector<std::vector<double>> probed_profiles;  // per drawn line, per 2-px bin
    std::vector<std::size_t> tracked_base;             // drawn line of each tracked line
    std::vector<double> tracked_offset;                // arc of its start on the drawn line
    int start_every = std::max(1, settings.start_every);
    if (probe && frame_count >= 2) {
        std::vector<LineState> probes = make_states(lines, settings, width, height);
        PassOptions pass;
        pass.probe = true;
        pass.probe_frames = {0, frame_count / 3};
        pass.progress_total = total_progress;
        if (!run_pass(frames, probes, plate, settings, pass, progress)) {
            result.report.status = TrackingReport::Status::cancelled;
            return result;
        }
        tracked.clear();
        std::vector<double> speeds;
        for (const LineState& st : probes) {
            const std::vector<double> profile = probe_speeds(st, settings.min_speed_px);
            probed_profiles.push_back(profile);
            const std::vector<double> tau = travel_times(profile, settings.min_speed_px);
            const double length = st.geometry.length_px();
            const double end_bin = std::min(length / kProfileBinPx, static_cast<double>(tau.size() - 1));
            const std::size_t eb = std::min(static_cast<std::size_t>(end_bin), tau.size() - 2);
            const double total = tau[eb] + (end_bin - static_cast<double>(eb)) * (tau[eb + 1] - tau[eb]);
            LineProbe line_probe;
            line_probe.id = st.line->id;
            line_probe.travel_frames = total;
            line_probe.mean_speed_px_per_frame = total > 0.0 ? length / total : 0.0;
            speeds.push_back(line_probe.mean_speed_px_per_frame);
            // Cut greedily: a segment ends where a particle entering it needs
            // max_path frames to get there (segments at least a patch long).
            // Segments no particle can cross within the clip (static parts:
            // rocks a drawn line crosses) are not tracked.
            const auto time_at = [&](double s) {
                const double bin = std::clamp(s / kProfileBinPx, 0.0, static_cast<double>(tau.size() - 1));
                const std::size_t k = std::min(static_cast<std::size_t>(bin), tau.size() - 2);
                return tau[k] + (bin - static_cast<double>(k)) * (tau[k + 1] - tau[k]);
            };
            std::vector<double> cuts{0.0};
            if (settings.max_path_frames >= 0 && total > max_path) {
                double start = 0.0;
                for (double s = patch / 2.0; s < length - patch / 2.0; s += 1.0)
                    if (s - start >= patch / 2.0 && time_at(s) - time_at(start) >= max_path) {
                        start = std::round(s * 10.0) / 10.0;
                        cuts.push_back(start);
                    }
            }
            cuts.push_back(length);
            line_probe.segments = static_cast<int>(cuts.size()) - 1;
            for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
                const double a = std::round(cuts[k] * 10.0) / 10.0;
                const double b = k + 2 == cuts.size() ? length : std::round(cuts[k + 1] * 10.0) / 10.0;
                if (time_at(b) - time_at(a) > frame_count - 2) {
                    line_probe.untracked.push_back(segment_line_id(st.line->id, a, b));
                    continue;
                }
                tracked_base.push_back(probed_profiles.size() - 1);
                tracked_offset.push_back(a);
                if (cuts.size() == 2) {
                    tracked.push_back(*st.line);
                    continue;
                }
                formats::FlowLine segment;
                segment.id = segment_line_id(st.line->id, a, b);
                segment.points = sub_polyline(st.line->points, a, b);
                tracked.push_back(std::move(segment));
            }
            result.report.probes.push_back(line_probe);
        }
        if (settings.start_every == 0) {
            // Particles enter about a third of a patch apart at the typical speed.
            std::vector<double> sorted = speeds;
            std::sort(sorted.begin(), sorted.end());
            const double typical = sorted.empty() ? 1.0 : std::max(settings.min_speed_px, sorted[sorted.size() / 2]);
            start_every = std::clamp(static_cast<int>(std::lround(patch / (3.0 * typical))), 1, std::max(1, frame_count / 8));
        }
    }
    result.report.start_every = start_every;
    result.report.max_path_frames = max_path;

    std::vector<LineState> states = make_states(tracked, settings, width, height);
    // Seed each line's speed profile with the probes' (as two samples per
    // bin), so that even the first particle has a prediction, also where its
    // patch is mostly outside the frame (lines entering from off-screen).
    for (std::size_t i = 0; i < states.size() && i < tracked_base.size(); ++i) {
        const std::vector<double>& profile = probed_profiles[tracked_base[i]];
        const std::size_t offset = static_cast<std::size_t>(std::lround(tracked_offset[i] / kProfileBinPx));
        for (std::size_t b = 0; b < states[i].bin_sum.size(); ++b) {
            const std::size_t k = std::min(profile.size() - 1, b + offset);
            states[i].bin_sum[b] = 2.0 * profile[k];
            states[i].bin_count[b] = 2;
        }
    }
    PassOptions pass;
    pass.start_every = start_every;
    pass.progress_offset = probe ? frame_count : 0;
    pass.progress_total = total_progress;
    if (!run_pass(frames, states, plate, settings, pass, progress)) result.report.status = TrackingReport::Status::cancelled;
    result.report.frames_read = frame_count;
    result.tracked_lines = tracked;

    formats::ParticleBank& bank = result.bank;
    bank.patch_size_px = patch;
    bank.fps = frames.fps() > 0.0 ? frames.fps() : 25.0;
    bank.clip_width_px = width;
    bank.clip_height_px = height;
    bank.clip_frame_count = std::max(1, frame_count);
    bank.source_clip = frames.source();
    bank.dynamics = settings.dynamics;
    for (LineState& st : states) {
        const float length = static_cast<float>(st.geometry.length_px());
        bank.lines.push_back({st.line->id, length});
        std::sort(st.completed.begin(), st.completed.end(),
                  [](const ActiveParticle& a, const ActiveParticle& b) { return a.start < b.start; });
        if (settings.max_particles_per_line > 0 && st.completed.size() > static_cast<std::size_t>(settings.max_particles_per_line))
            st.completed.resize(static_cast<std::size_t>(settings.max_particles_per_line));
        LineTrackingStats stats;
        stats.id = st.line->id;
        stats.length_px = st.geometry.length_px();
        stats.started = st.started;
        stats.completed = static_cast<int>(st.completed.size());
        double correlation = 0.0, speed = 0.0, life = 0.0;
        for (ActiveParticle& p : st.completed) {
            stats.steps += p.steps;
            stats.uncertain_steps += p.uncertain;
            stats.extrapolated_steps += p.extrapolated;
            correlation += p.correlation_sum;
            speed += p.step_sum;
            life += static_cast<double>(p.arc.size());
            formats::TrackedParticle particle;
            particle.line_id = st.line->id;
            particle.start_frame = p.start;
            particle.arc_length_px = std::move(p.arc);
            for (float& s : particle.arc_length_px) s = std::clamp(s, 0.0f, length);
            particle.texture_rgba = std::move(p.texture);
            bank.particles.push_back(std::move(particle));
        }
        const int certain = stats.steps - stats.uncertain_steps - stats.extrapolated_steps;
        stats.mean_correlation = certain > 0 ? correlation / certain : 0.0;
        stats.mean_speed_px_per_frame = stats.steps > 0 ? speed / stats.steps : 0.0;
        stats.mean_life_frames = stats.completed > 0 ? life / stats.completed : 0.0;
        result.report.lines.push_back(stats);
    }
    return result;
}

std::vector<double> speed_profile(const formats::ParticleBank& bank, const std::string& line_id, double bin_px) {
    double length = 0.0;
    for (const formats::BankFlowLine& line : bank.lines)
        if (line.id == line_id) length = line.length_px;
    const std::size_t bins = static_cast<std::size_t>(length / bin_px) + 1;
    std::vector<double> sum(bins, 0.0), count(bins, 0.0);
    for (const formats::TrackedParticle& p : bank.particles) {
        if (p.line_id != line_id) continue;
        for (std::size_t i = 1; i < p.arc_length_px.size(); ++i) {
            const double mid = 0.5 * (p.arc_length_px[i] + p.arc_length_px[i - 1]);
            const std::size_t bin = std::min(bins - 1, static_cast<std::size_t>(std::max(0.0, mid) / bin_px));
            sum[bin] += p.arc_length_px[i] - p.arc_length_px[i - 1];
            count[bin] += 1.0;
        }
    }
    std::vector<double> profile(bins, std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < bins; ++i)
        if (count[i] > 0.0) profile[i] = sum[i] / count[i];
    return profile;
}

}  // namespace flowvid::flow
