// ParticleStreams: the scheduled particles of every input line, where they
// are at an output frame, and their texture sampled in a line's own frame.
#include "flowvid/flow/synthesis.hpp"

#include "flowvid/flow/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

namespace flowvid::flow {

namespace {

// `count` sample points that no particle stream holds yet.
ParticleStreams::SamplePoints unmatched_samples(std::size_t count) {
    ParticleStreams::SamplePoints points;
    points.stream.assign(count, -1);
    points.s.assign(count, 0.0f);
    points.qx.assign(count, 0.0f);
    points.qy.assign(count, 0.0f);
    return points;
}

void sample_patch_bilinear(const float* texture, int patch, float u, float v, float out[4]) {
    const float fu = std::floor(u), fv = std::floor(v);
    const int iu = static_cast<int>(fu), iv = static_cast<int>(fv);
    const float au = u - fu, av = v - fv;
    out[0] = out[1] = out[2] = out[3] = 0.0f;
    for (int b = 0; b < 2; ++b) {
        const int y = iv + b;
        if (y < 0 || y >= patch) continue;
        const float wy = b ? av : 1.0f - av;
        for (int a = 0; a < 2; ++a) {
            const int x = iu + a;
            if (x < 0 || x >= patch) continue;
            const float w = wy * (a ? au : 1.0f - au);
            const float* t = texture + (static_cast<std::size_t>(y) * patch + x) * 4;
            out[0] += w * t[0];
            out[1] += w * t[1];
            out[2] += w * t[2];
            out[3] += w * t[3];
        }
    }
}

}  // namespace

// ---- the moving part ------------------------------------------------------------------------------

RgbImage moving_layer_still_plate(const ClipFrames& clip) { return quantile_plate(clip, kMovingLayerStillQuantile); }

void keep_moving_part(formats::ParticleBank& bank, const std::vector<std::vector<Eigen::Vector2d>>& input_points,
                      const RgbImage& linear_still_plate) {
    if (input_points.size() != bank.lines.size()) throw std::invalid_argument("one polyline per bank line is needed");
    if (linear_still_plate.width != bank.clip_width_px || linear_still_plate.height != bank.clip_height_px)
        throw std::invalid_argument("the still plate is " + std::to_string(linear_still_plate.width) + " x " +
                                    std::to_string(linear_still_plate.height) + " but the bank's clip " +
                                    std::to_string(bank.clip_width_px) + " x " + std::to_string(bank.clip_height_px));
    const int patch = bank.patch_size_px, w = linear_still_plate.width, h = linear_still_plate.height;
    const std::size_t patch_values = static_cast<std::size_t>(patch) * patch * 4;
    std::vector<LineGeometry> geometry;  // as tracking and ParticleStreams build it
    for (const auto& points : input_points) geometry.emplace_back(points, patch / 3.0);
    std::map<std::string, std::size_t> line_of;
    for (std::size_t i = 0; i < bank.lines.size(); ++i) line_of[bank.lines[i].id] = i;
    for (formats::TrackedParticle& p : bank.particles) {
        const auto it = line_of.find(p.line_id);
        if (it == line_of.end()) continue;
        const LineGeometry& g = geometry[it->second];
        for (int age = 0; age < p.life_frames(); ++age) {
            const Eigen::Vector2d centre = g.point(p.arc_length_px[static_cast<std::size_t>(age)]);
            const int ox = patch_origin(centre.x(), patch), oy = patch_origin(centre.y(), patch);
            float* texel = p.texture_rgba.data() + static_cast<std::size_t>(age) * patch_values;
            for (int i = 0; i < patch; ++i)
                for (int j = 0; j < patch; ++j, texel += 4) {
                    const int x = ox + j, y = oy + i;
                    if (x < 0 || y < 0 || x >= w || y >= h) continue;  // alpha 0 there
                    const float* still = linear_still_plate.pixel(x, y);
                    for (int c = 0; c < 3; ++c)
                        texel[c] = std::max(0.0f, texel[c] - texel[3] * still[c]) / (1.0f - std::min(still[c], kMovingLayerMaxStill));
                }
        }
    }
}

// ---- particle streams -----------------------------------------------------------------------------

ParticleStreams::ParticleStreams(std::shared_ptr<const formats::ParticleBank> bank,
                                 std::vector<std::vector<Eigen::Vector2d>> input_points, const SynthesisSettings& settings,
                                 const formats::FlowLineSet* drawing)
    : m_bank(std::move(bank)) {
    if (!m_bank) throw std::invalid_argument("no particle bank");
    if (input_points.size() != m_bank->lines.size())
        throw std::invalid_argument("one polyline per bank line is needed");
    m_schedule = make_schedule(*m_bank, settings);
    m_fade_frames = settings.fade_frames >= 0 ? settings.fade_frames : std::clamp(m_schedule.start_every, 1, 3);
    m_wrap_fade_frames = settings.wrap_fade_frames;
    std::unordered_map<std::string, std::size_t> bank_line_by_id;
    for (std::size_t i = 0; i < m_bank->lines.size(); ++i) bank_line_by_id.emplace(m_bank->lines[i].id, i);
    for (std::size_t k = 0; k < m_schedule.lines.size(); ++k) {
        const std::string& id = m_schedule.lines[k].line_id;
        m_geometry.emplace_back(input_points[bank_line_by_id.at(id)], m_bank->patch_size_px / 3.0);
        m_stream_by_id.emplace(id, static_cast<int>(k));
    }
    // Group segments into the lines they were cut from.
    for (std::size_t k = 0; k < m_schedule.lines.size(); ++k) {
        const std::string& id = m_schedule.lines[k].line_id;
        std::string base;
        double from = 0.0, to = 0.0;
        if (!parse_segment_id(id, base, from, to)) {
            base = id;
            from = 0.0;
            to = m_geometry[k].length_px();
        }
        const auto [found, added] = m_input_by_id.emplace(base, static_cast<int>(m_inputs.size()));
        if (added) m_inputs.push_back(InputLine{base, 0.0, {}, {}});
        InputLine& line = m_inputs[static_cast<std::size_t>(found->second)];
        line.segments.push_back({static_cast<int>(k), from, to});
        line.length_px = std::max(line.length_px, to);
    }
    const std::optional<InputLineIndex> drawn = drawing ? std::optional<InputLineIndex>(*drawing) : std::nullopt;
    for (InputLine& line : m_inputs) {
        std::sort(line.segments.begin(), line.segments.end(),
                  [](const InputLine::Segment& a, const InputLine::Segment& b) { return a.from_px < b.from_px; });
        if (drawn) {
            try {
                line.points = input_line_points(*drawn, line.id, "");
                line.length_px = formats::polyline_length(line.points);
            } catch (const std::exception&) {
                // keep the tracked extent
            }
        }
    }
}

int ParticleStreams::input_line_index(const std::string& id) const {
    const auto found = m_input_by_id.find(id);
    return found == m_input_by_id.end() ? -1 : found->second;
}

std::vector<std::vector<Eigen::Vector2d>> ParticleStreams::input_points_from_drawing(const formats::ParticleBank& bank,
                                                                                     const formats::FlowLineSet& drawing,
                                                                                     const std::string& drawing_file) {
    std::vector<std::vector<Eigen::Vector2d>> out;
    const InputLineIndex inputs(drawing);
    for (const formats::BankFlowLine& line : bank.lines) out.push_back(input_line_points(inputs, line.id, drawing_file));
    return out;
}

int ParticleStreams::stream_index(const std::string& line_id) const {
    const auto found = m_stream_by_id.find(line_id);
    return found == m_stream_by_id.end() ? -1 : found->second;
}

void ParticleStreams::visible(int stream, int frame, std::vector<Visible>& out) const {
    out.clear();
    const int patch = m_bank->patch_size_px;
    const std::size_t patch_values = static_cast<std::size_t>(patch) * patch * 4;
    const LineGeometry& g = m_geometry[static_cast<std::size_t>(stream)];
    for (const ScheduledParticle& sp : scheduled_particles(m_schedule, *m_bank, static_cast<std::size_t>(stream), frame)) {
        const formats::TrackedParticle& p = m_bank->particles[static_cast<std::size_t>(sp.particle)];
        Visible v;
        v.arc_px = p.arc_length_px[static_cast<std::size_t>(sp.age)];
        v.centre = g.point(v.arc_px);
        // Particles fade in after entering and out before leaving, so that
        // a particle whose texture differs from its predecessor's (where the
        // diagonal order wraps, fig. 3.5b) does not pop, and segments hand over
        // smoothly.
        int fade = m_fade_frames;
        if (sp.slot == 0 && m_schedule.particles_per_line > 1)
            fade = std::max(fade, m_wrap_fade_frames >= 0 ? m_wrap_fade_frames
                                                           : std::min(m_schedule.start_every, p.life_frames() / 2));
        const double fade_in = (sp.age + 1.0) / (fade + 1.0);
        const double fade_out = (p.life_frames() - sp.age) / (m_fade_frames + 1.0);
        v.weight = static_cast<float>(std::clamp(std::min(fade_in, fade_out), 0.0, 1.0));
        v.texture = p.texture_rgba.data() + static_cast<std::size_t>(sp.age) * patch_values;
        v.input_frame = p.start_frame + sp.age;
        out.push_back(v);
    }
    std::sort(out.begin(), out.end(), [](const Visible& a, const Visible& b) { return a.arc_px < b.arc_px; });
}

ParticleStreams::SamplePoints ParticleStreams::prepare_samples(int input_line, ArcMapping mapping, double output_length_px,
                                                               const std::vector<float>& s_out,
                                                               const std::vector<float>& n) const {
    const std::size_t count = s_out.size();
    SamplePoints points = unmatched_samples(count);
    if (input_line < 0) return points;
    const InputLine& line = m_inputs[static_cast<std::size_t>(input_line)];
    const double scale = arc_mapping_scale(mapping, line.length_px, output_length_px);
    for (std::size_t i = 0; i < count; ++i) {
        const double s_in = s_out[i] * scale;
        // The segment holding s_in (the first or last one beyond the ends).
        std::size_t k = 0;
        while (k + 1 < line.segments.size() && s_in >= line.segments[k + 1].from_px) ++k;
        if (s_in < line.segments[k].from_px - patch_size() || s_in > line.segments[k].to_px + patch_size()) continue;
        const int stream = line.segments[k].stream;
        const double local = s_in - line.segments[k].from_px;
        const LineGeometry& g = geometry(stream);
        const Eigen::Vector2d q = g.point(local) + static_cast<double>(n[i]) * g.normal(local);
        points.stream[i] = stream;
        points.s[i] = static_cast<float>(local);
        points.qx[i] = static_cast<float>(q.x());
        points.qy[i] = static_cast<float>(q.y());
    }
    return points;
}

void ParticleStreams::sample(const SamplePoints& points, const FrameParticles& particles, Samples& out) const {
    const std::size_t count = points.stream.size();
    out.rgb.assign(count * 3, 0.0f);
    out.weight.assign(count, 0.0f);
    const int patch = patch_size();
    const float half = (patch - 1) / 2.0f;
    const float reach = (half + 1.0f) * std::sqrt(2.0f) + 1.0f;
    for (std::size_t i = 0; i < count; ++i) {
        if (points.stream[i] < 0) continue;
        const std::vector<Visible>& visible = particles.streams[static_cast<std::size_t>(points.stream[i])];
        const std::vector<float>& arcs = particles.arcs[static_cast<std::size_t>(points.stream[i])];
        const float s = points.s[i];
        const auto lo = std::lower_bound(arcs.begin(), arcs.end(), s - reach);
        float acc[4] = {0.0f, 0.0f, 0.0f, 0.0f};
        for (auto it = lo; it != arcs.end() && *it <= s + reach; ++it) {
            const Visible& v = visible[static_cast<std::size_t>(it - arcs.begin())];
            const float u = points.qx[i] - static_cast<float>(patch_origin(v.centre.x(), patch));
            const float w_ = points.qy[i] - static_cast<float>(patch_origin(v.centre.y(), patch));
            if (u <= -0.5f || w_ <= -0.5f || u >= patch - 0.5f || w_ >= patch - 0.5f) continue;
            const float w = feather_weight(u, patch) * feather_weight(w_, patch) * v.weight;
            float c[4];
            sample_patch_bilinear(v.texture, patch, u, w_, c);
            acc[0] += w * c[0];
            acc[1] += w * c[1];
            acc[2] += w * c[2];
            acc[3] += w * c[3];
        }
        if (acc[3] > 1e-6f) {
            out.rgb[3 * i] = acc[0] / acc[3];
            out.rgb[3 * i + 1] = acc[1] / acc[3];
            out.rgb[3 * i + 2] = acc[2] / acc[3];
            out.weight[i] = acc[3];
        }
    }
}

ParticleStreams::FrameParticles ParticleStreams::frame_particles(int frame) const {
    FrameParticles out;
    out.frame = frame;
    out.streams.resize(m_schedule.lines.size());
    out.arcs.resize(m_schedule.lines.size());
    for (std::size_t k = 0; k < m_schedule.lines.size(); ++k) {
        visible(static_cast<int>(k), frame, out.streams[k]);
        for (const Visible& v : out.streams[k]) out.arcs[k].push_back(v.arc_px);
    }
    return out;
}

void ParticleStreams::sample(int stream, int frame, ArcMapping mapping, double output_length_px,
                             const std::vector<float>& s_out, const std::vector<float>& n, Samples& out) const {
    const std::size_t count = s_out.size();
    SamplePoints points = unmatched_samples(count);
    FrameParticles particles;
    if (stream >= 0) {
        const LineGeometry& g = geometry(stream);
        const double scale = arc_mapping_scale(mapping, g.length_px(), output_length_px);
        for (std::size_t i = 0; i < count; ++i) {
            const double s_in = s_out[i] * scale;
            const Eigen::Vector2d q = g.point(s_in) + static_cast<double>(n[i]) * g.normal(s_in);
            points.stream[i] = stream;
            points.s[i] = static_cast<float>(s_in);
            points.qx[i] = static_cast<float>(q.x());
            points.qy[i] = static_cast<float>(q.y());
        }
        particles.streams.resize(m_schedule.lines.size());
        particles.arcs.resize(m_schedule.lines.size());
        visible(stream, frame, particles.streams[static_cast<std::size_t>(stream)]);
        for (const Visible& v : particles.streams[static_cast<std::size_t>(stream)])
            particles.arcs[static_cast<std::size_t>(stream)].push_back(v.arc_px);
    }
    sample(points, particles, out);
}

void ParticleStreams::sample_input_line(int input_line, int frame, ArcMapping mapping, double output_length_px,
                                        const std::vector<float>& s_out, const std::vector<float>& n, Samples& out) const {
    sample(prepare_samples(input_line, mapping, output_length_px, s_out, n), frame_particles(frame), out);
}

}  // namespace flowvid::flow
