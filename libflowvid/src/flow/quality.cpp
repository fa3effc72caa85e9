#include "flowvid/flow/quality.hpp"
#include "flowvid/random.hpp"

#include "flowvid/flow/geometry.hpp"

#include "series_statistics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace flowvid::flow {

using detail::mean_of;
using detail::percentile;

std::vector<std::uint8_t> line_band_mask(const std::vector<std::vector<Eigen::Vector2d>>& lines, int width, int height,
                                         double half_width_px) {
    const std::vector<double> distance = distance_to_polylines(lines, width, height, half_width_px);
    std::vector<std::uint8_t> mask(distance.size(), 0);
    for (std::size_t i = 0; i < distance.size(); ++i) mask[i] = distance[i] <= half_width_px ? 1 : 0;
    return mask;
}

SequenceStats sequence_stats(const std::vector<std::vector<float>>& frames, int width, int height,
                             const std::vector<std::uint8_t>& mask) {
    SequenceStats stats;
    std::size_t inside = 0;
    for (std::uint8_t m : mask) inside += m;
    if (inside == 0) return stats;
    for (std::size_t t = 0; t < frames.size(); ++t) {
        const std::vector<float>& g = frames[t];
        double hf = 0.0;
        std::size_t n = 0;
        for (int y = 1; y + 1 < height; ++y)
            for (int x = 1; x + 1 < width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * width + x;
                if (!mask[i]) continue;
                double box = 0.0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) box += g[i + static_cast<std::size_t>(dy * width + dx)];
                const double d = g[i] - box / 9.0;
                hf += d * d;
                ++n;
            }
        stats.hf_energy.push_back(n ? hf / static_cast<double>(n) : 0.0);
        if (t + 1 < frames.size()) {
            const std::vector<float>& h = frames[t + 1];
            double sum = 0.0;
            for (std::size_t i = 0; i < g.size(); ++i)
                if (mask[i]) sum += std::fabs(static_cast<double>(h[i]) - g[i]);
            stats.transitions.push_back(sum / static_cast<double>(inside));
        }
    }
    return stats;
}

namespace {

double coefficient_of_variation(const std::vector<double>& values) {
    if (values.size() < 2) return 0.0;
    const double mean = std::accumulate(values.begin(), values.end(), 0.0) / values.size();
    double var = 0.0;
    for (double v : values) var += (v - mean) * (v - mean);
    var /= static_cast<double>(values.size() - 1);
    return mean > 0.0 ? std::sqrt(var) / mean : 0.0;
}


// Mean RMS distance from query patches of `queries_from` to their nearest
// patch in `search_in`, at offsets within the radius, skipping frames closer
// than `exclude` when both sequences are the same.
double nearest_patch_distance(const std::vector<std::vector<float>>& queries_from,
                              const std::vector<std::vector<float>>& search_in, bool same, int width, int height,
                              const std::vector<std::uint8_t>& mask, const QualitySettings& s, std::uint64_t seed) {
    const int p = s.patch_px;
    std::vector<std::pair<int, int>> centres;  // top-left corners whose patch lies inside the mask
    for (int y = s.search_radius_px; y + p + s.search_radius_px <= height; y += 2)
        for (int x = s.search_radius_px; x + p + s.search_radius_px <= width; x += 2) {
            const std::size_t c = static_cast<std::size_t>(y + p / 2) * width + (x + p / 2);
            if (mask[c] && mask[static_cast<std::size_t>(y) * width + x] &&
                mask[static_cast<std::size_t>(y + p - 1) * width + (x + p - 1)])
                centres.emplace_back(x, y);
        }
    if (centres.empty() || queries_from.empty() || search_in.empty()) return 0.0;
    Random rng(seed);
    double total = 0.0;
    int counted = 0;
    for (int q = 0; q < s.queries; ++q) {
        const auto [qx, qy] = centres[rng.below(centres.size())];
        const int qt = static_cast<int>(rng.below(queries_from.size()));
        const std::vector<float>& src = queries_from[static_cast<std::size_t>(qt)];
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t f = 0; f < search_in.size(); ++f) {
            if (same && std::abs(static_cast<int>(f) - qt) < s.exclude_frames) continue;
            const std::vector<float>& dst = search_in[f];
            for (int dy = -s.search_radius_px; dy <= s.search_radius_px; dy += s.search_stride_px)
                for (int dx = -s.search_radius_px; dx <= s.search_radius_px; dx += s.search_stride_px) {
                    double ssd = 0.0;
                    for (int y = 0; y < p && ssd < best; ++y) {
                        const float* a = src.data() + static_cast<std::size_t>(qy + y) * width + qx;
                        const float* b = dst.data() + static_cast<std::size_t>(qy + y + dy) * width + qx + dx;
                        for (int x = 0; x < p; ++x) {
                            const double d = a[x] - b[x];
                            ssd += d * d;
                        }
                    }
                    best = std::min(best, ssd);
                }
        }
        if (std::isfinite(best)) {
            total += std::sqrt(best / (p * p));
            ++counted;
        }
    }
    return counted ? total / counted : 0.0;
}

// measure_quality with the per-frame statistics of both sequences already made.
QualityReport quality_from_stats(const SequenceStats& clip, const SequenceStats& out,
                                 const std::vector<std::vector<float>>& clip_luma,
                                 const std::vector<std::vector<float>>& output_luma, int width, int height,
                                 const std::vector<std::uint8_t>& mask, const QualitySettings& settings) {
    QualityReport r;
    r.clip_p95 = percentile(clip.transitions, 0.95);
    r.clip_p99 = percentile(clip.transitions, 0.99);
    r.clip_max = clip.transitions.empty() ? 0.0 : *std::max_element(clip.transitions.begin(), clip.transitions.end());
    if (r.clip_p95 > 0.0 && !clip.transitions.empty()) {
        r.clip_max_ratio = r.clip_max / r.clip_p95;
        r.clip_min_ratio = *std::min_element(clip.transitions.begin(), clip.transitions.end()) / r.clip_p95;
    }
    r.transitions = static_cast<int>(out.transitions.size());
    if (!out.transitions.empty() && r.clip_p95 > 0.0) {
        r.max_transition_ratio = *std::max_element(out.transitions.begin(), out.transitions.end()) / r.clip_p95;
        int above = 0;
        for (double d : out.transitions) above += d > r.clip_p99 ? 1 : 0;
        r.share_above_p99 = static_cast<double>(above) / out.transitions.size();
    }
    const double clip_median = percentile(clip.transitions, 0.5), out_median = percentile(out.transitions, 0.5);
    if (clip_median > 0.0) r.clip_seam_spike = r.clip_max / clip_median;
    if (out_median > 0.0 && !out.transitions.empty())
        r.seam_spike = *std::max_element(out.transitions.begin(), out.transitions.end()) / out_median;
    if (clip_median > 0.0) r.motion_ratio = out_median / clip_median;
    r.pulsing = coefficient_of_variation(out.hf_energy);
    r.clip_pulsing = coefficient_of_variation(clip.hf_energy);
    const double clip_hf = mean_of(clip.hf_energy);
    r.hf_power_ratio = clip_hf > 0.0 ? mean_of(out.hf_energy) / clip_hf : 0.0;
    r.patch_distance = nearest_patch_distance(output_luma, clip_luma, false, width, height, mask, settings, settings.seed);
    r.clip_self_distance = nearest_patch_distance(clip_luma, clip_luma, true, width, height, mask, settings, settings.seed + 1);
    return r;
}

}  // namespace

QualityReport measure_quality(const std::vector<std::vector<float>>& clip_luma,
                              const std::vector<std::vector<float>>& output_luma, int width, int height,
                              const std::vector<std::uint8_t>& mask, const QualitySettings& settings) {
    return quality_from_stats(sequence_stats(clip_luma, width, height, mask), sequence_stats(output_luma, width, height, mask),
                              clip_luma, output_luma, width, height, mask, settings);
}

double detail_kept(const Synthesizer& synth, const ClipFrames& footage, const std::vector<std::vector<Eigen::Vector2d>>& lines,
                   int sample_frames, double region_px) {
    const int width = footage.width(), height = footage.height();
    const std::vector<std::uint8_t> region = line_band_mask(lines, width, height, region_px);
    const std::vector<std::vector<float>> clip_luma = footage.luma_frames();
    std::vector<std::vector<float>> output_luma;
    const int period = std::max(1, synth.period_frames());
    for (int k = 0; k < sample_frames; ++k)
        output_luma.push_back(luma(to_display(synth.render(1 + k * period / std::max(1, sample_frames)))));
    const std::vector<double> clip_hf = sequence_stats(clip_luma, width, height, region).hf_energy;
    const std::vector<double> output_hf = sequence_stats(output_luma, width, height, region).hf_energy;
    const double clip_mean = mean_of(clip_hf);
    return clip_mean > 0.0 ? mean_of(output_hf) / clip_mean : 1.0;
}

BackgroundChoice choose_background(const std::shared_ptr<const ParticleStreams>& streams,
                                   const std::shared_ptr<const ClipFrames>& clip, const ClipFrames& footage,
                                   const SynthesisSettings& settings, const std::vector<std::vector<Eigen::Vector2d>>& lines,
                                   double min_detail) {
    BackgroundChoice choice;
    const Synthesizer over_median(streams, {}, make_background(BackgroundMode::median, clip, streams->schedule(), streams->patch_size()),
                                  settings);
    choice.median_detail = detail_kept(over_median, footage, lines);
    if (choice.median_detail < min_detail) choice.mode = BackgroundMode::replay;
    return choice;
}

RgbImage naive_loop_frame(const ClipFrames& clip, int frame) {
    const int n = clip.count();
    if (n == 0) throw std::invalid_argument("empty clip");
    return clip.linear((((frame - 1) % n) + n) % n);
}

VelocityField velocity_field(const ParticleStreams& streams, int width, int height, double sigma_px) {
    VelocityField field;
    field.width = width;
    field.height = height;
    const std::size_t pixels = static_cast<std::size_t>(width) * height;
    std::vector<double> vx(pixels, 0.0), vy(pixels, 0.0), w(pixels, 0.0);
    const formats::ParticleBank& bank = streams.bank();
    const int radius = static_cast<int>(std::ceil(3.0 * sigma_px));
    constexpr double bin_px = 4.0;
    for (std::size_t k = 0; k < streams.schedule().lines.size(); ++k) {
        const LineGeometry& g = streams.geometry(static_cast<int>(k));
        const std::string& id = streams.schedule().lines[k].line_id;
        const std::size_t bins = static_cast<std::size_t>(g.length_px() / bin_px) + 1;
        std::vector<double> sum(bins, 0.0), count(bins, 0.0);
        for (const formats::TrackedParticle& p : bank.particles) {
            if (p.line_id != id) continue;
            for (std::size_t i = 1; i < p.arc_length_px.size(); ++i) {
                const std::size_t b = std::min(bins - 1, static_cast<std::size_t>(std::max(0.0f, p.arc_length_px[i - 1]) / bin_px));
                sum[b] += p.arc_length_px[i] - p.arc_length_px[i - 1];
                count[b] += 1.0;
            }
        }
        double last = 0.0;
        for (std::size_t b = 0; b < bins; ++b) {
            const double speed = count[b] > 0.0 ? sum[b] / count[b] : last;
            last = speed;
            const double s = (b + 0.5) * bin_px;
            const Eigen::Vector2d p = g.point(s), t = g.tangent(s);
            const int cx = static_cast<int>(std::lround(p.x())), cy = static_cast<int>(std::lround(p.y()));
            for (int y = std::max(0, cy - radius); y <= std::min(height - 1, cy + radius); ++y)
                for (int x = std::max(0, cx - radius); x <= std::min(width - 1, cx + radius); ++x) {
                    const double d2 = (Eigen::Vector2d(x, y) - p).squaredNorm();
                    const double k = std::exp(-d2 / (2.0 * sigma_px * sigma_px));
                    const std::size_t i = static_cast<std::size_t>(y) * width + x;
                    vx[i] += k * speed * t.x();
                    vy[i] += k * speed * t.y();
                    w[i] += k;
                }
        }
    }
    // Full coverage where the weight of one line's samples reaches half its
    // on-line value (a Gaussian sampled every bin_px sums to sqrt(2 pi) sigma / bin_px).
    const double full = 0.5 * std::sqrt(2.0 * M_PI) * sigma_px / bin_px;
    field.velocity.resize(pixels);
    field.coverage.resize(pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
        field.velocity[i] = w[i] > 1e-9 ? Eigen::Vector2f(static_cast<float>(vx[i] / w[i]), static_cast<float>(vy[i] / w[i]))
                                        : Eigen::Vector2f::Zero();
        field.coverage[i] = static_cast<float>(std::min(1.0, w[i] / full));
    }
    return field;
}

FlowMapBaseline::FlowMapBaseline(VelocityField field, RgbImage texture, RgbImage background, int cycle_frames)
    : m_field(std::move(field)), m_texture(std::move(texture)), m_background(std::move(background)),
      m_cycle(std::max(2, cycle_frames)) {}

RgbImage FlowMapBaseline::render(int frame) const {
    const int w = m_field.width, h = m_field.height;
    RgbImage out = m_background.width == w && m_background.height == h ? m_background : RgbImage(w, h);
    const double phase = static_cast<double>(frame - 1) / m_cycle;
    double f0 = phase - std::floor(phase);
    double f1 = f0 + 0.5;
    f1 -= std::floor(f1);
    // Each layer's weight falls to zero when its advection offset resets.
    const float w0 = static_cast<float>(1.0 - std::fabs(2.0 * f0 - 1.0));
    const float w1 = 1.0f - w0;
    const float o0 = static_cast<float>(f0 * m_cycle), o1 = static_cast<float>(f1 * m_cycle);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            const float c = m_field.coverage[i];
            if (c <= 0.0f) continue;
            const Eigen::Vector2f v = m_field.velocity[i];
            float a[3], b[3];
            sample_bilinear(m_texture, x - v.x() * o0, y - v.y() * o0, a);
            sample_bilinear(m_texture, x - v.x() * o1, y - v.y() * o1, b);
            float* o = out.pixel(x, y);
            for (int k = 0; k < 3; ++k) o[k] = o[k] * (1.0f - c) + (w0 * a[k] + w1 * b[k]) * c;
        }
    return out;
}

Comparison compare_with_baselines(const ClipFrames& clip, const ParticleStreams& streams, const Synthesizer& synth,
                                  const RgbImage& plate, const ComparisonSettings& settings,
                                  const Progress& progress) {
    const int width = clip.width(), height = clip.height(), count = clip.count();
    if (count < 2) throw std::invalid_argument("the clip needs at least two frames to be compared with");
    if (synth.width() != width || synth.height() != height)
        throw std::invalid_argument("the synthesis and the clip differ in size");
    Comparison out;
    out.output_frames = settings.output_frames > 0 ? settings.output_frames : 2 * count;
    const int n = out.output_frames;
    // Steps: clip, ours, loop, flow map (n frames each but the clip).
    const double total = static_cast<double>(count + 3 * n);
    double done = 0.0;
    const auto tick = [&] {
        done += 1.0;
        report_progress(progress, "measure", done / total);
    };
    std::vector<std::vector<float>> clip_luma, ours, loop, flowmap;
    for (int i = 0; i < count; ++i) {
        clip_luma.push_back(clip.luma(i));
        tick();
    }
    bool stopped = false;
    synth.render_frames(1, n, settings.threads, [&](int, const RgbImage& image) {
        ours.push_back(luma(to_display(image)));
        try {
            tick();
        } catch (const std::runtime_error&) {
            stopped = true;
            return false;
        }
        return true;
    });
    if (stopped) throw Cancelled();
    for (int t = 1; t <= n; ++t) {
        loop.push_back(luma(to_display(naive_loop_frame(clip, t))));
        tick();
    }
    const int patch = streams.patch_size();
    const FlowMapBaseline baseline(velocity_field(streams, width, height, patch / 2.0), clip.linear(0), plate,
                                   settings.flow_map_cycle_frames);
    for (int t = 1; t <= n; ++t) {
        flowmap.push_back(luma(to_display(baseline.render(t))));
        tick();
    }
    std::vector<std::vector<Eigen::Vector2d>> lines;
    for (std::size_t k = 0; k < streams.schedule().lines.size(); ++k)
        lines.push_back(streams.geometry(static_cast<int>(k)).points());
    const double half_width = settings.band_half_width_px > 0.0 ? settings.band_half_width_px : patch / 4.0;
    const std::vector<std::uint8_t> mask = line_band_mask(lines, width, height, half_width);
    for (std::uint8_t m : mask) out.mask_pixels += m;
    out.clip_series = sequence_stats(clip_luma, width, height, mask);
    const auto add = [&](const char* method, const std::vector<std::vector<float>>& frames) {
        SequenceStats series = sequence_stats(frames, width, height, mask);
        QualityReport report =
            quality_from_stats(out.clip_series, series, clip_luma, frames, width, height, mask, settings.quality);
        out.methods.push_back({method, std::move(report), std::move(series), {}, {}});
    };
    add("ours", ours);
    add("loop", loop);
    add("flow map", flowmap);
    if (!settings.region_lines.empty()) {
        const std::vector<std::uint8_t> region =
            line_band_mask(settings.region_lines, width, height, settings.region.region_px);
        const auto measure_all = [&](const std::vector<std::vector<float>>& reference, const std::vector<std::uint8_t>& in,
                                     auto member) {
            const RegionMeter meter(reference, width, height, in, settings.region);
            out.methods[0].*member = meter.measure(ours, {in});
            out.methods[1].*member = meter.measure(loop, {in});
            out.methods[2].*member = meter.measure(flowmap, {in});
        };
        if (settings.footage) {
            if (settings.footage->width() != width || settings.footage->height() != height)
                throw std::invalid_argument("the footage and the clip differ in size");
            const std::vector<std::vector<float>> footage_luma = settings.footage->luma_frames();
            const std::vector<std::uint8_t> as_drawn =
                settings.footage_region_lines.empty()
                    ? region
                    : line_band_mask(settings.footage_region_lines, width, height, settings.region.region_px);
            measure_all(footage_luma, as_drawn, &MethodQuality::region);
            measure_all(clip_luma, region, &MethodQuality::region_still_view);
        } else {
            measure_all(clip_luma, region, &MethodQuality::region);
        }
    }
    return out;
}

}  // namespace flowvid::flow
