#include "flowvid/flow/editing.hpp"
#include "flowvid/threads.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <future>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>

namespace flowvid::flow {

ChainAssignment solve_chain(const std::vector<Eigen::MatrixXd>& pair_costs, const std::vector<std::vector<int>>& allowed,
                            int candidate_count) {
    const std::size_t lines = allowed.size();
    if (lines == 0) return {};
    if (pair_costs.size() + 1 != lines) throw std::invalid_argument("solve_chain: one cost matrix per neighbour pair");
    const double inf = std::numeric_limits<double>::infinity();
    const auto permitted = [&](std::size_t x) {
        std::vector<bool> ok(static_cast<std::size_t>(candidate_count), allowed[x].empty());
        for (int y : allowed[x])
            if (y >= 0 && y < candidate_count) ok[static_cast<std::size_t>(y)] = true;
        return ok;
    };
    // C(x, y) = min_y' [C(x-1, y') + E(x-1, y', x, y)]  (eq. 3.1)
    std::vector<std::vector<double>> cost(lines, std::vector<double>(static_cast<std::size_t>(candidate_count), inf));
    std::vector<std::vector<int>> from(lines, std::vector<int>(static_cast<std::size_t>(candidate_count), -1));
    const std::vector<bool> first = permitted(0);
    for (int y = 0; y < candidate_count; ++y)
        if (first[static_cast<std::size_t>(y)]) cost[0][static_cast<std::size_t>(y)] = 0.0;
    for (std::size_t x = 1; x < lines; ++x) {
        const Eigen::MatrixXd& e = pair_costs[x - 1];
        if (e.rows() != candidate_count || e.cols() != candidate_count)
            throw std::invalid_argument("solve_chain: cost matrices must be candidates x candidates");
        const std::vector<bool> ok = permitted(x);
        for (int y = 0; y < candidate_count; ++y) {
            if (!ok[static_cast<std::size_t>(y)]) continue;
            for (int yp = 0; yp < candidate_count; ++yp) {
                const double c = cost[x - 1][static_cast<std::size_t>(yp)] + e(yp, y);
                if (c < cost[x][static_cast<std::size_t>(y)]) {
                    cost[x][static_cast<std::size_t>(y)] = c;
                    from[x][static_cast<std::size_t>(y)] = yp;
                }
            }
        }
    }
    ChainAssignment result;
    int best = -1;
    double best_cost = inf;
    for (int y = 0; y < candidate_count; ++y)
        if (cost[lines - 1][static_cast<std::size_t>(y)] < best_cost) {
            best_cost = cost[lines - 1][static_cast<std::size_t>(y)];
            best = y;
        }
    if (best < 0) throw std::invalid_argument("solve_chain: no assignment satisfies the allowed candidates");
    result.cost = best_cost;
    result.choice.assign(lines, -1);
    for (std::size_t x = lines; x-- > 0;) {
        result.choice[x] = best;
        best = from[x][static_cast<std::size_t>(best)];
    }
    return result;
}

namespace {

// Sample points in the overlap of two neighbouring lines at one frame, and
// their coordinates (arc, lateral offset) on each line.
struct PairSamples {
    std::vector<float> s_a, n_a, s_b, n_b;
    double length_a = 0.0, length_b = 0.0;
};

PairSamples pair_samples(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b, int along,
                         double smoothing_px, double reach_px) {
    PairSamples out;
    const LineGeometry ga(a, smoothing_px), gb(b, smoothing_px);
    out.length_a = ga.length_px();
    out.length_b = gb.length_px();
    for (int i = 0; i < along; ++i) {
        const double f = (i + 0.5) / along;
        const Eigen::Vector2d pa = ga.point(f * out.length_a), pb = gb.point(f * out.length_b);
        for (int j = 0; j < 5; ++j) {
            const Eigen::Vector2d q = pa + (pb - pa) * (j / 4.0);
            const LineGeometry::Projection qa = ga.project(q, reach_px), qb = gb.project(q, reach_px);
            out.s_a.push_back(static_cast<float>(qa.s));
            out.n_a.push_back(static_cast<float>(qa.n));
            out.s_b.push_back(static_cast<float>(qb.s));
            out.n_b.push_back(static_cast<float>(qb.n));
        }
    }
    return out;
}

Eigen::MatrixXd pair_error(const ParticleStreams& streams, const formats::FlowLine& line_a, const formats::FlowLine& line_b,
                           const std::vector<int>& candidates, const EditSettings& settings,
                           const std::vector<ParticleStreams::FrameParticles>& particles_a,
                           const std::vector<ParticleStreams::FrameParticles>& particles_b) {
    const int y_count = static_cast<int>(candidates.size());
    const int patch = streams.patch_size();
    const int frames = std::max(1, settings.correspondence_frames);
    const int along = std::max(2, settings.samples_along);
    const std::size_t per_frame = static_cast<std::size_t>(along) * 5;
    const std::size_t samples = per_frame * static_cast<std::size_t>(frames);
    // Per candidate: weight, weighted colour, weighted squared norm, on each side.
    Eigen::MatrixXd wa = Eigen::MatrixXd::Zero(y_count, static_cast<Eigen::Index>(samples));
    Eigen::MatrixXd wb = wa;
    Eigen::MatrixXd a2 = wa, b2 = wa;
    std::array<Eigen::MatrixXd, 3> ac{wa, wa, wa}, bc{wa, wa, wa};
    const bool fixed = !line_a.is_time_varying() && !line_b.is_time_varying();
    PairSamples geometry;
    ParticleStreams::Samples sa, sb;
    std::vector<ParticleStreams::SamplePoints> points_a(static_cast<std::size_t>(y_count)), points_b(points_a.size());
    for (int t = 0; t < frames; ++t) {
        const int frame = settings.first_frame + t;
        if (!fixed || t == 0) {
            geometry = pair_samples(formats::points_at_frame(line_a, frame), formats::points_at_frame(line_b, frame), along,
                                    patch / 3.0, patch);
            for (int y = 0; y < y_count; ++y) {
                const int input = candidates[static_cast<std::size_t>(y)];
                points_a[static_cast<std::size_t>(y)] = streams.prepare_samples(input, settings.mapping, geometry.length_a, geometry.s_a, geometry.n_a);
                points_b[static_cast<std::size_t>(y)] = streams.prepare_samples(input, settings.mapping, geometry.length_b, geometry.s_b, geometry.n_b);
            }
        }
        for (int y = 0; y < y_count; ++y) {
            streams.sample(points_a[static_cast<std::size_t>(y)], particles_a[static_cast<std::size_t>(t)], sa);
            streams.sample(points_b[static_cast<std::size_t>(y)], particles_b[static_cast<std::size_t>(t)], sb);
            for (std::size_t k = 0; k < per_frame; ++k) {
                const Eigen::Index col = static_cast<Eigen::Index>(static_cast<std::size_t>(t) * per_frame + k);
                const double w1 = std::min(1.0f, sa.weight[k]), w2 = std::min(1.0f, sb.weight[k]);
                wa(y, col) = w1;
                wb(y, col) = w2;
                double n1 = 0.0, n2 = 0.0;
                for (int c = 0; c < 3; ++c) {
                    const double c1 = sa.rgb[3 * k + static_cast<std::size_t>(c)], c2 = sb.rgb[3 * k + static_cast<std::size_t>(c)];
                    ac[static_cast<std::size_t>(c)](y, col) = w1 * c1;
                    bc[static_cast<std::size_t>(c)](y, col) = w2 * c2;
                    n1 += c1 * c1;
                    n2 += c2 * c2;
                }
                a2(y, col) = w1 * n1;
                b2(y, col) = w2 * n2;
            }
        }
    }
    // sum_k wa wb |ca - cb|^2 = (wa|ca|^2) wb^T + wa (wb|cb|^2)^T - 2 sum_c (wa ca_c)(wb cb_c)^T
    Eigen::MatrixXd numerator = a2 * wb.transpose() + wa * b2.transpose();
    for (int c = 0; c < 3; ++c) numerator -= 2.0 * ac[static_cast<std::size_t>(c)] * bc[static_cast<std::size_t>(c)].transpose();
    const Eigen::MatrixXd denominator = wa * wb.transpose();
    Eigen::MatrixXd e(y_count, y_count);
    for (int i = 0; i < y_count; ++i)
        for (int j = 0; j < y_count; ++j)
            e(i, j) = denominator(i, j) > 1e-9 ? std::max(0.0, numerator(i, j)) / denominator(i, j) : 0.0;
    return e;
}

}  // namespace

std::vector<Eigen::MatrixXd> overlap_errors(const ParticleStreams& streams, const std::vector<formats::FlowLine>& chain,
                                            const std::vector<int>& candidate_streams, const EditSettings& settings) {
    std::vector<Eigen::MatrixXd> out(chain.size() > 0 ? chain.size() - 1 : 0);
    const int frames = std::max(1, settings.correspondence_frames);
    const auto particles_at = [&](int offset) {
        std::vector<ParticleStreams::FrameParticles> particles;
        for (int t = 0; t < frames; ++t) particles.push_back(streams.frame_particles(settings.first_frame + t + offset));
        return particles;
    };
    // Lines without an offset (drawn ones) share one set. Each worker takes a
    // run of consecutive pairs, so that a shifted line's set, needed by the
    // pair on either side of it, is made once and handed on.
    const std::vector<ParticleStreams::FrameParticles> unshifted = particles_at(0);
    const auto work = [&](std::size_t first, std::size_t last) {
        std::vector<ParticleStreams::FrameParticles> shifted_a, shifted_b;  // of chain[i], chain[i + 1]
        for (std::size_t i = first; i < last; ++i) {
            const int offset_a = chain[i].time_offset_frames, offset_b = chain[i + 1].time_offset_frames;
            if (i == first && offset_a != 0) shifted_a = particles_at(offset_a);
            shifted_b.clear();
            if (offset_b != 0) shifted_b = particles_at(offset_b);
            out[i] = pair_error(streams, chain[i], chain[i + 1], candidate_streams, settings,
                                offset_a != 0 ? shifted_a : unshifted, offset_b != 0 ? shifted_b : unshifted);
            shifted_a = std::move(shifted_b);
        }
    };
    const std::size_t workers = std::min<std::size_t>(static_cast<std::size_t>(resolve_thread_count(settings.threads)), out.size());
    std::vector<std::future<void>> jobs;
    for (std::size_t w = 0; w < workers; ++w)
        jobs.push_back(std::async(std::launch::async, work, w * out.size() / workers, (w + 1) * out.size() / workers));
    for (auto& job : jobs) job.get();
    return out;
}

EditPlan plan_edit(const formats::FlowLineSet& drawing, const ParticleStreams& streams, const EditSettings& settings,
                   const Progress& progress) {
    if (drawing.outputs.empty()) throw std::invalid_argument("the drawing has no output line to edit with");
    EditPlan plan;
    const int patch = streams.patch_size();
    const double spacing = settings.spacing_px > 0.0 ? settings.spacing_px : patch / 2.0;
    const double max_gap = settings.max_gap_px > 0.0 ? settings.max_gap_px : 6.0 * patch;

    std::vector<std::vector<Eigen::Vector2d>> drawn;
    for (const formats::FlowLine& line : drawing.outputs) drawn.push_back(formats::points_at_frame(line, settings.first_frame));
    const std::vector<std::vector<int>> sparse_chains = neighbour_chains(drawn, max_gap, settings.max_angle_deg);
    const std::vector<InterpolatedLine> between = interpolate_between(drawn, sparse_chains, spacing);

    // Candidates: every input line with particles (a line tracked in
    // segments counts once, with all its segments).
    std::vector<int> candidates;
    for (std::size_t i = 0; i < streams.input_lines().size(); ++i) candidates.push_back(static_cast<int>(i));
    const auto streams_for = [&](const std::string& from) {
        std::vector<int> out;
        const int line = streams.input_line_index(from);
        if (line >= 0) out.push_back(line);
        return out;
    };

    // Offsets spread evenly over the period whatever the number of lines
    // (fractional parts of multiples of the golden ratio), so that no two
    // neighbours are close in time.
    int interpolated_count = 0;
    const auto next_time_offset = [&] {
        if (!settings.offset_interpolated_lines) return 0;
        const double golden = 0.6180339887498949;
        const double fraction = std::fmod(golden * ++interpolated_count, 1.0);
        return static_cast<int>(std::floor(fraction * streams.schedule().period_frames));
    };
    // Input lines ordered across the flow (their segments joined back into
    // whole lines), for the inputs an interpolated line may take and for
    // stretches of the flow an edit leaves as filmed.
    std::map<int, std::pair<std::size_t, std::size_t>> input_place;  // candidate -> (chain, position)
    std::vector<std::vector<int>> input_chains;
    {
        std::vector<std::vector<Eigen::Vector2d>> whole;
        for (const ParticleStreams::InputLine& in : streams.input_lines()) {
            std::vector<Eigen::Vector2d> points;
            for (const ParticleStreams::InputLine::Segment& seg : in.segments)
                for (const Eigen::Vector2d& p : streams.geometry(seg.stream).points())
                    if (points.empty() || (p - points.back()).norm() > 1e-9) points.push_back(p);
            whole.push_back(points);
        }
        input_chains = neighbour_chains(whole, max_gap, settings.max_angle_deg);
        for (std::size_t c = 0; c < input_chains.size(); ++c)
            for (std::size_t k = 0; k < input_chains[c].size(); ++k) input_place[input_chains[c][k]] = {c, k};
    }
    // Candidates (indices into `candidates`, which are input line indices) between two drawn lines' inputs.
    const auto inputs_between = [&](const std::string& from_a, const std::string& from_b) {
        std::vector<int> out;
        if (settings.interpolated_inputs != EditSettings::InterpolatedInputs::between) return out;  // any
        const auto a = input_place.find(streams.input_line_index(from_a));
        const auto b = input_place.find(streams.input_line_index(from_b));
        if (a == input_place.end() || b == input_place.end() || a->second.first != b->second.first) return out;  // any
        const std::vector<int>& chain = input_chains[a->second.first];
        const std::size_t lo = std::min(a->second.second, b->second.second), hi = std::max(a->second.second, b->second.second);
        for (std::size_t k = lo; k <= hi; ++k)
            for (std::size_t c = 0; c < candidates.size(); ++c)
                if (candidates[c] == chain[k]) out.push_back(static_cast<int>(c));
        return out;
    };

    // Two neighbouring drawn lines that lie on their own input lines, with
    // only lines `track` added (densified, not drawn) between those inputs,
    // leave that stretch of the flow as filmed: it is rendered as synthesis
    // renders it (the input lines between, each at its own time, over the
    // clip's own background) rather than interpolated, whose lines would
    // show other moments over a replayed clip.
    std::set<std::string> drawn_inputs;
    for (const formats::FlowLine& line : drawing.inputs) drawn_inputs.insert(line.id);
    const auto on_own_input = [&](const formats::FlowLine& line) {
        const int input = streams.input_line_index(line.from);
        if (line.is_time_varying() || input < 0) return false;
        const std::vector<Eigen::Vector2d>& points = streams.input_lines()[static_cast<std::size_t>(input)].points;
        if (points.size() != line.points.size()) return false;
        for (std::size_t i = 0; i < points.size(); ++i)
            if ((points[i] - line.points[i]).norm() > 1e-6) return false;
        return true;
    };
    // Drawn lines that carry an input an earlier drawn line already carries
    // (a particle system's lines, all from one input) show its particles at
    // their own offset in time: side by side at one time they would show the
    // same texture shifted a few pixels, which blends into a flat blur. A
    // drawn line lying on its input line keeps it as filmed (no offset, so a
    // replayed clip follows it) wherever it comes in the drawing.
    std::set<std::string> carried_by_a_drawn_line;
    for (const formats::FlowLine& line : drawing.outputs)
        if (on_own_input(line)) carried_by_a_drawn_line.insert(line.from);
    // The input lines strictly between two drawn lines' inputs when the
    // stretch is as filmed (see above); nullopt otherwise.
    const auto as_filmed_between = [&](const formats::FlowLine& a, const formats::FlowLine& b) -> std::optional<std::vector<int>> {
        if (!on_own_input(a) || !on_own_input(b)) return std::nullopt;
        const auto pa = input_place.find(streams.input_line_index(a.from));
        const auto pb = input_place.find(streams.input_line_index(b.from));
        if (pa == input_place.end() || pb == input_place.end() || pa->second.first != pb->second.first) return std::nullopt;
        const std::vector<int>& inputs = input_chains[pa->second.first];
        std::vector<int> between_inputs;
        const std::size_t lo = std::min(pa->second.second, pb->second.second), hi = std::max(pa->second.second, pb->second.second);
        if (lo == hi) return std::nullopt;
        for (std::size_t k = lo + 1; k < hi; ++k) {
            const ParticleStreams::InputLine& in = streams.input_lines()[static_cast<std::size_t>(inputs[k])];
            if (drawn_inputs.count(in.id) || in.points.size() < 2) return std::nullopt;
            between_inputs.push_back(inputs[k]);
        }
        if (pa->second.second > pb->second.second) std::reverse(between_inputs.begin(), between_inputs.end());
        return between_inputs;
    };
    for (const std::vector<int>& chain : sparse_chains) {
        // The dense chain: drawn lines with the interpolated ones between them.
        std::vector<DenseLine> dense;
        std::vector<std::vector<int>> interpolated_allowed;  // per dense line (drawn lines: unused)
        for (std::size_t k = 0; k < chain.size(); ++k) {
            const formats::FlowLine& line = drawing.outputs[static_cast<std::size_t>(chain[k])];
            DenseLine d;
            d.output.line = line;
            d.output.from = line.from;
            d.drawn = true;
            if (!on_own_input(line) && !carried_by_a_drawn_line.insert(line.from).second)
                d.output.line.time_offset_frames = next_time_offset();
            dense.push_back(std::move(d));
            interpolated_allowed.emplace_back();
            if (k + 1 == chain.size()) break;
            if (const auto filmed = as_filmed_between(drawing.outputs[static_cast<std::size_t>(chain[k])],
                                                      drawing.outputs[static_cast<std::size_t>(chain[k + 1])])) {
                for (int input : *filmed) {
                    const ParticleStreams::InputLine& in = streams.input_lines()[static_cast<std::size_t>(input)];
                    DenseLine d2;
                    d2.output.line.id = in.id;
                    d2.output.line.points = in.points;
                    d2.output.from = in.id;
                    dense.push_back(std::move(d2));
                    for (std::size_t c = 0; c < candidates.size(); ++c)
                        if (candidates[c] == input) interpolated_allowed.push_back({static_cast<int>(c)});
                }
                continue;
            }
            for (const InterpolatedLine& inter : between) {
                if (inter.a != chain[k] || inter.b != chain[k + 1]) continue;
                const formats::FlowLine& a = drawing.outputs[static_cast<std::size_t>(inter.a)];
                const formats::FlowLine& b = drawing.outputs[static_cast<std::size_t>(inter.b)];
                DenseLine d2;
                d2.output.line.id = interpolated_line_id(a.id, b.id, inter.weight);
                d2.output.line.time_offset_frames = next_time_offset();
                if (a.is_time_varying() || b.is_time_varying()) {
                    std::set<int> frames;
                    for (const auto& key : a.keys) frames.insert(key.frame);
                    for (const auto& key : b.keys) frames.insert(key.frame);
                    // One point count for every key: the most any frame's lengths ask for.
                    int samples = 0;
                    for (int f : frames)
                        samples = std::max(samples, static_cast<int>(interpolated_points(a, b, inter.weight, f).size()));
                    for (int f : frames)
                        d2.output.line.keys.push_back({f, interpolated_points(a, b, inter.weight, f, samples)});
                } else {
                    d2.output.line.points = interpolated_points(a, b, inter.weight, settings.first_frame);
                }
                dense.push_back(std::move(d2));
                interpolated_allowed.push_back(inputs_between(a.from, b.from));
            }
        }
        // Allowed inputs: drawn lines keep theirs.
        std::vector<std::vector<int>> allowed;
        for (std::size_t x = 0; x < dense.size(); ++x) {
            const DenseLine& d = dense[x];
            if (!d.drawn) {
                allowed.push_back(interpolated_allowed[x]);
                continue;
            }
            std::vector<int> ok;
            for (int stream : streams_for(d.output.from))
                for (std::size_t c = 0; c < candidates.size(); ++c)
                    if (candidates[c] == stream) ok.push_back(static_cast<int>(c));
            if (ok.empty())
                plan.warnings.push_back("output line " + d.output.line.id + " carries " + d.output.from +
                                        ", which has no tracked particle; it may take any input");
            allowed.push_back(ok);
        }
        std::vector<formats::FlowLine> geometry;
        for (const DenseLine& d : dense) geometry.push_back(d.output.line);
        ChainAssignment assignment;
        if (dense.size() > 1 && !candidates.empty()) {
            const std::vector<Eigen::MatrixXd> errors = overlap_errors(streams, geometry, candidates, settings);
            assignment = solve_chain(errors, allowed, static_cast<int>(candidates.size()));
        } else if (!candidates.empty()) {
            assignment.choice = {allowed[0].empty() ? 0 : allowed[0][0]};
        }
        std::vector<int> indices;
        for (std::size_t x = 0; x < dense.size(); ++x) {
            DenseLine& d = dense[x];
            if (!assignment.choice.empty() && (!d.drawn || !allowed[x].empty()))
                d.output.from = streams.input_lines()[static_cast<std::size_t>(candidates[static_cast<std::size_t>(assignment.choice[x])])].id;
            indices.push_back(static_cast<int>(plan.lines.size()));
            plan.lines.push_back(std::move(d));
        }
        plan.total_cost += assignment.cost;
        plan.chains.push_back(indices);
        // Stage "correspondence": chains solved of all; false stops with the chains so far.
        if (progress && !progress({"correspondence",
                                   static_cast<double>(plan.chains.size()) / std::max<std::size_t>(1, sparse_chains.size()), {}}))
            break;
    }
    return plan;
}

std::vector<OutputLine> output_lines(const EditPlan& plan) {
    std::vector<OutputLine> out;
    for (const DenseLine& d : plan.lines) out.push_back(d.output);
    return out;
}

formats::FlowLineSet plan_to_flowlines(const formats::FlowLineSet& drawing, const EditPlan& plan) {
    formats::FlowLineSet set;
    set.width = drawing.width;
    set.height = drawing.height;
    set.description = drawing.description.empty() ? "dense edit" : drawing.description + " (dense edit)";
    set.inputs = drawing.inputs;
    std::set<std::string> input_ids;
    for (const auto& line : set.inputs) input_ids.insert(line.id);
    for (const DenseLine& d : plan.lines) {
        formats::FlowLine line = d.output.line;
        line.from = d.output.from;
        // Lines carrying a segment or an interpolated input name the drawn
        // input it comes from in the file (`from` must name an input line).
        if (!input_ids.count(line.from)) {
            std::string base = line.from, a, b;
            double f0 = 0.0, f1 = 0.0, w = 0.0;
            if (parse_segment_id(base, a, f0, f1)) base = a;
            if (parse_interpolated_line_id(base, a, b, w)) base = w < 0.5 ? a : b;
            line.from = input_ids.count(base) ? base : set.inputs.front().id;
        }
        set.outputs.push_back(std::move(line));
    }
    return set;
}

}  // namespace flowvid::flow
