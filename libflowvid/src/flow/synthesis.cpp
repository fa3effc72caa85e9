#include "flowvid/flow/synthesis.hpp"

#include "layer_edges.hpp"
#include "synthesis_kernels.hpp"
#include "synthesis_plan.hpp"
#include "warp_table.hpp"

#include "flowvid/flow/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

namespace flowvid::flow {

using namespace detail;

namespace {

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
                                    m_plan->width, m_plan->height, carry_band_px(patch));
            keep_carry_on_flowing_arcs(carry.warp, carry.flowing_arcs_px, 0.5 * patch);
        }
        m_plan->carry_lines.push_back(std::move(carry));
    };
    RgbImage flow_look;  // what the background shows around the input lines
    std::vector<float> flow_look_luma;
    if (m_carry_background) {
        m_background.fill(1, m_plan->width, m_plan->height, flow_look);
        flow_look_luma = luma(to_display(flow_look));
    }
    std::unordered_map<int, std::vector<std::pair<double, double>>> carried_arcs;  // per input line, found once
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
        if (m_carry_background) {
            const auto [arcs, fresh] = carried_arcs.try_emplace(group);
            if (fresh) {
                std::vector<std::pair<double, double>> tracked_arcs;
                for (const ParticleStreams::InputLine::Segment& seg : in.segments) tracked_arcs.emplace_back(seg.from_px, seg.to_px);
                arcs->second = arcs_to_carry(in.points, tracked_arcs, flow_look_luma, m_plan->width, m_plan->height, patch);
            }
            add_carry(output.line, in.points, arcs->second);
        }
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
        RgbImage plate = std::move(flow_look);  // carry lines exist only when carrying: filled above
        m_plan->carry_source = smoothed(plate, carry_smoothing_radius_px(patch));
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
                                          *line.input, m_settings.mapping, patch, w, h, carry_band_px(patch));
        keep_carry_on_flowing_arcs(b.keyed_warps[keyed], line.flowing_arcs_px, 0.5 * patch);
        b.tables.push_back(&b.keyed_warps[keyed++]);
    }
    if (m_plan->carry_source.empty()) b.source = smoothed(out, carry_smoothing_radius_px(patch));
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
    // With an edge fade the layer is finished first, then faded and composited.
    const bool fade = m_settings.edge_fade_px > 0.0;
    std::vector<float> layer, layer_coverage;
    if (fade) {
        layer.resize(3 * pixels);  // read only where layer_coverage is set below
        layer_coverage.assign(pixels, 0.0f);
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
        if (fade) {
            std::copy(tex, tex + 3, layer.begin() + static_cast<std::ptrdiff_t>(3 * i));
            layer_coverage[i] = c;
            continue;
        }
        composite(out.rgb.data() + 3 * i, tex, c, screen);
        if (coverage) (*coverage)[i] = c;
    }
    if (fade) composite_faded_layer(layer, layer_coverage, m_settings.edge_fade_px, screen, out, coverage);
    return out;
}

}  // namespace flowvid::flow
