#include "warp_table.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace flowvid::flow::detail {

WarpTable build_warp(const LineGeometry& out_line, const LineGeometry& in_line, ArcMapping mapping, int patch, int width,
                     int height, double reach_across_px) {
    WarpTable table;
    const double half = (patch - 1) / 2.0;
    const double length_out = out_line.length_px(), length_in = in_line.length_px();
    const double scale = arc_mapping_scale(mapping, length_in, length_out);
    table.reach_in = (half + 1.0) * std::sqrt(2.0) + 1.0;
    const double reach_out = std::max(table.reach_in * std::max(1.0, 1.0 / scale), reach_across_px);

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
            const double band_px = carry_band_px(patch);  // cos^2 across
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

namespace {

// The mean of `luma` (`width` x `height`) over the square of `radius`
// pixels around `centre` (clipped to the frame).
double mean_around(const std::vector<float>& luma, int width, int height, const Eigen::Vector2d& centre, int radius) {
    const int cx = static_cast<int>(std::lround(centre.x())), cy = static_cast<int>(std::lround(centre.y()));
    double sum = 0.0;
    int count = 0;
    for (int y = std::max(0, cy - radius); y <= std::min(height - 1, cy + radius); ++y)
        for (int x = std::max(0, cx - radius); x <= std::min(width - 1, cx + radius); ++x) {
            sum += luma[static_cast<std::size_t>(y) * width + x];
            ++count;
        }
    return count > 0 ? sum / count : 0.0;
}

}  // namespace

std::vector<std::pair<double, double>> arcs_to_carry(const std::vector<Eigen::Vector2d>& points,
                                                     const std::vector<std::pair<double, double>>& tracked_px,
                                                     const std::vector<float>& background_luma, int width, int height,
                                                     int patch) {
    if (tracked_px.empty() || points.size() < 2 || background_luma.empty()) return tracked_px;
    const LineGeometry line(points, patch / 3.0);
    const double length = line.length_px();
    constexpr double kStepPx = 2.0;
    const int samples = static_cast<int>(std::floor(length / kStepPx)) + 1;
    std::vector<double> luma_at(static_cast<std::size_t>(samples));
    std::vector<char> tracked(static_cast<std::size_t>(samples), 0);
    std::vector<double> tracked_luma;
    int first = samples, last = -1;
    for (int i = 0; i < samples; ++i) {
        const double s = i * kStepPx;
        luma_at[static_cast<std::size_t>(i)] = mean_around(background_luma, width, height, line.point(s), std::max(1, patch / 2));
        for (const auto& [from, to] : tracked_px)
            if (s >= from && s <= to) tracked[static_cast<std::size_t>(i)] = 1;
        if (!tracked[static_cast<std::size_t>(i)]) continue;
        tracked_luma.push_back(luma_at[static_cast<std::size_t>(i)]);
        first = std::min(first, i);
        last = i;
    }
    if (tracked_luma.empty()) return tracked_px;
    std::sort(tracked_luma.begin(), tracked_luma.end());
    const auto quantile = [&](double q) {
        return tracked_luma[static_cast<std::size_t>(std::lround(q * static_cast<double>(tracked_luma.size() - 1)))];
    };
    const double low = quantile(0.1) - 0.1, high = quantile(0.9) + 0.1;
    const auto looks_like_flow = [&](int i) {
        const double y = luma_at[static_cast<std::size_t>(i)];
        return y >= low && y <= high;
    };
    // Unlike enough to show as a smear in the smoothed flow (a ledge): twice
    // as far outside the tracked range.
    const auto far_unlike_flow = [&](int i) {
        const double y = luma_at[static_cast<std::size_t>(i)];
        return y < low - 0.1 || y > high + 0.1;
    };
    // Grow each tracked arc into the untracked stretches between first and
    // last while the background looks like the flow (from both sides: a
    // gap's middle may be a ledge, its ends still water).
    std::vector<char> flow = tracked;
    for (int i = first + 1; i <= last; ++i)
        if (!flow[static_cast<std::size_t>(i)] && flow[static_cast<std::size_t>(i - 1)] && looks_like_flow(i))
            flow[static_cast<std::size_t>(i)] = 1;
    for (int i = last - 1; i >= first; --i)
        if (!flow[static_cast<std::size_t>(i)] && flow[static_cast<std::size_t>(i + 1)] && looks_like_flow(i))
            flow[static_cast<std::size_t>(i)] = 1;
    std::vector<std::pair<double, double>> arcs = tracked_px;
    for (int i = first; i <= last; ++i)
        if (flow[static_cast<std::size_t>(i)] && !tracked[static_cast<std::size_t>(i)])
            arcs.emplace_back((i - 1) * kStepPx, (i + 1) * kStepPx);  // to the neighbouring samples
    std::sort(arcs.begin(), arcs.end());
    std::vector<std::pair<double, double>> merged;
    for (const auto& arc : arcs) {
        if (!merged.empty() && arc.first <= merged.back().second + 1e-6)
            merged.back().second = std::max(merged.back().second, arc.second);
        else merged.push_back(arc);
    }
    // An end whose smoothing window reaches background far unlike the flow
    // within the line is pulled in by the window's reach.
    const double reach = 2.0 * carry_smoothing_radius_px(patch);
    const int reach_samples = static_cast<int>(std::ceil(reach / kStepPx));
    const auto sees_other = [&](double s, int direction) {
        const int i0 = static_cast<int>(std::lround(s / kStepPx));
        for (int k = 1; k <= reach_samples; ++k) {
            const int i = i0 + direction * k;
            if (i < 0 || i >= samples) break;  // past the line's own end: nothing it crosses
            if (far_unlike_flow(i)) return true;
        }
        return false;
    };
    for (auto& [from, to] : merged) {
        const double middle = 0.5 * (from + to);
        const bool pull_from = sees_other(from, -1), pull_to = sees_other(to, +1);
        if (pull_from) from = std::min(middle, from + reach);
        if (pull_to) to = std::max(middle, to - reach);
    }
    return merged;
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

void smooth_in_place(std::vector<float>& values, int width, int height, int channels, int radius) {
    std::vector<float> across(values.size());
    const auto pass = [radius, channels, width, height](const std::vector<float>& in, std::vector<float>& out, bool along_x) {
        const int n = along_x ? width : height, lines = along_x ? height : width;
        std::vector<double> sum(static_cast<std::size_t>(channels));
        for (int l = 0; l < lines; ++l) {
            const auto at = [&](int i) -> std::size_t {
                return (along_x ? static_cast<std::size_t>(l) * width + i : static_cast<std::size_t>(i) * width + l) * channels;
            };
            std::fill(sum.begin(), sum.end(), 0.0);
            int count = 0;
            for (int i = 0; i < std::min(n, radius); ++i, ++count)
                for (int k = 0; k < channels; ++k) sum[k] += in[at(i) + k];
            for (int i = 0; i < n; ++i) {
                if (i + radius < n) {
                    for (int k = 0; k < channels; ++k) sum[k] += in[at(i + radius) + k];
                    ++count;
                }
                if (i - radius - 1 >= 0) {
                    for (int k = 0; k < channels; ++k) sum[k] -= in[at(i - radius - 1) + k];
                    --count;
                }
                for (int k = 0; k < channels; ++k) out[at(i) + k] = static_cast<float>(sum[k] / count);
            }
        }
    };
    for (int repeat = 0; repeat < 2; ++repeat) {
        pass(values, across, true);
        pass(across, values, false);
    }
}

RgbImage smoothed(const RgbImage& image, int radius) {
    RgbImage out = image;
    smooth_in_place(out.rgb, out.width, out.height, 3, radius);
    return out;
}

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

}  // namespace flowvid::flow::detail
