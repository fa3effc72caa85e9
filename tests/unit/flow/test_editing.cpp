// Editing (thesis 3.3): the dynamic programme of eq. 3.1 against brute force,
// the known best assignment on a constructed case, dense interpolation,
// texture warping with equal and scaled arc length (fig. 3.17), moving output
// lines, and flow-line files round-tripping through SVG and JSON.

#include "flowvid/flow/editing.hpp"
#include "flowvid/flow/geometry.hpp"
#include "flowvid/flow/sampling.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

using namespace flowvid;
using namespace flowvid::flow;

namespace {

// A bank of vertical input lines; particles enter every frame, live `life`
// frames and run from y0 to y1. `colour(line, particle_arc, texel_row_offset)`
// gives the grey level of a texel.
std::shared_ptr<formats::ParticleBank> vertical_bank(const std::vector<double>& xs, double y0, double y1, int life,
                                                     const std::function<float(int, double, double)>& colour,
                                                     int width = 120, int height = 120, int patch = 8) {
    auto bank = std::make_shared<formats::ParticleBank>();
    bank->patch_size_px = patch;
    bank->clip_width_px = width;
    bank->clip_height_px = height;
    const int count = 12;
    bank->clip_frame_count = count + life;
    for (std::size_t l = 0; l < xs.size(); ++l) {
        const std::string id = "in-" + std::to_string(l);
        bank->lines.push_back({id, static_cast<float>(y1 - y0)});
        for (int p = 0; p < count; ++p) {
            formats::TrackedParticle particle;
            particle.line_id = id;
            particle.start_frame = p;
            for (int a = 0; a < life; ++a) {
                const double s = (y1 - y0) * a / (life - 1);
                particle.arc_length_px.push_back(static_cast<float>(s));
                for (int i = 0; i < patch; ++i)
                    for (int j = 0; j < patch; ++j) {
                        const float g = colour(static_cast<int>(l), s, i - (patch - 1) / 2.0);
                        particle.texture_rgba.insert(particle.texture_rgba.end(), {g, g, g, 1.0f});
                    }
            }
            bank->particles.push_back(std::move(particle));
        }
    }
    return bank;
}

formats::FlowLine line(const std::string& id, const std::vector<Eigen::Vector2d>& points, const std::string& from = {}) {
    formats::FlowLine l;
    l.id = id;
    l.points = points;
    l.from = from;
    return l;
}

std::vector<std::vector<Eigen::Vector2d>> vertical_lines(const std::vector<double>& xs, double y0, double y1) {
    std::vector<std::vector<Eigen::Vector2d>> out;
    for (double x : xs) out.push_back({{x, y0}, {x, y1}});
    return out;
}

// A 120 x 120 drawing whose inputs are the vertical lines in-0, in-1, ... at xs, from y = 10 to 110.
formats::FlowLineSet vertical_drawing(const std::vector<double>& xs) {
    formats::FlowLineSet d;
    d.width = d.height = 120;
    for (std::size_t i = 0; i < xs.size(); ++i) d.inputs.push_back(line("in-" + std::to_string(i), {{xs[i], 10.0}, {xs[i], 110.0}}));
    return d;
}

double brute_force(const std::vector<Eigen::MatrixXd>& e, const std::vector<std::vector<int>>& allowed, int y_count,
                   std::vector<int>& best_choice) {
    const std::size_t x_count = allowed.size();
    std::vector<int> choice(x_count, 0);
    double best = std::numeric_limits<double>::infinity();
    while (true) {
        bool ok = true;
        for (std::size_t x = 0; x < x_count; ++x)
            if (!allowed[x].empty() && std::find(allowed[x].begin(), allowed[x].end(), choice[x]) == allowed[x].end()) ok = false;
        if (ok) {
            double cost = 0.0;
            for (std::size_t x = 1; x < x_count; ++x) cost += e[x - 1](choice[x - 1], choice[x]);
            if (cost < best) {
                best = cost;
                best_choice = choice;
            }
        }
        std::size_t k = 0;
        while (k < x_count && ++choice[k] == y_count) choice[k++] = 0;
        if (k == x_count) break;
    }
    return best;
}

}  // namespace

TEST(FlowEditing, DynamicProgrammeMatchesBruteForce) {
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> cost(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        const int x_count = 6, y_count = 4;
        std::vector<Eigen::MatrixXd> e;
        for (int x = 1; x < x_count; ++x) {
            Eigen::MatrixXd m(y_count, y_count);
            for (int i = 0; i < y_count; ++i)
                for (int j = 0; j < y_count; ++j) m(i, j) = cost(rng);
            e.push_back(m);
        }
        std::vector<std::vector<int>> allowed(x_count);
        allowed.front() = {trial % y_count};
        allowed.back() = {(trial + 1) % y_count};
        std::vector<int> expected;
        const double best = brute_force(e, allowed, y_count, expected);
        const ChainAssignment dp = solve_chain(e, allowed, y_count);
        EXPECT_NEAR(dp.cost, best, 1e-12);
        EXPECT_EQ(dp.choice, expected);
    }
    EXPECT_THROW(solve_chain({Eigen::MatrixXd::Zero(2, 2)}, {{0}, {5}}, 2), std::invalid_argument);
}

TEST(FlowEditing, PicksTheKnownBestAssignmentOnAConstructedCase) {
    // Five input lines of solid grey 0.1, 0.3, 0.5, 0.7, 0.9. The artist draws
    // two output lines 48 px apart carrying the darkest and the brightest; the
    // three interpolated lines between them (12 px apart, 16-px patches, so
    // neighbours overlap) should step through the middle greys in order: any
    // other choice leaves a larger colour jump somewhere (the sum of squared
    // steps is smallest for equal steps).
    const std::vector<double> xs = {20, 35, 50, 65, 80};
    auto bank = vertical_bank(xs, 10.0, 110.0, 10, [](int l, double, double) { return 0.1f + 0.2f * l; }, 120, 120, 16);
    SynthesisSettings settings;
    const ParticleStreams streams(bank, vertical_lines(xs, 10.0, 110.0), settings);
    formats::FlowLineSet drawing = vertical_drawing(xs);
    drawing.outputs.push_back(line("dark", {{36.0, 10.0}, {36.0, 110.0}}, "in-0"));
    drawing.outputs.push_back(line("bright", {{84.0, 10.0}, {84.0, 110.0}}, "in-4"));
    EditSettings edit;
    edit.spacing_px = 12.0;
    edit.correspondence_frames = 4;
    edit.threads = 2;
    const EditPlan plan = plan_edit(drawing, streams, edit);
    ASSERT_EQ(plan.lines.size(), 5u);
    ASSERT_EQ(plan.chains.size(), 1u);
    std::vector<std::string> froms;
    for (int index : plan.chains[0]) froms.push_back(plan.lines[static_cast<std::size_t>(index)].output.from);
    EXPECT_EQ(froms, (std::vector<std::string>{"in-0", "in-1", "in-2", "in-3", "in-4"}));
    EXPECT_TRUE(plan.lines[static_cast<std::size_t>(plan.chains[0].front())].drawn);
    EXPECT_FALSE(plan.lines[static_cast<std::size_t>(plan.chains[0][2])].drawn);

    // The same optimum by brute force over the measured overlap errors.
    std::vector<formats::FlowLine> chain;
    for (int index : plan.chains[0]) chain.push_back(plan.lines[static_cast<std::size_t>(index)].output.line);
    std::vector<int> candidates = {0, 1, 2, 3, 4};
    const auto errors = overlap_errors(streams, chain, candidates, edit);
    // Overlap error of greys a and b is (a - b)^2 (solid colours, linear RGB, 3 channels summed).
    EXPECT_NEAR(errors[0](0, 1), 3 * 0.04, 1e-4);
    EXPECT_NEAR(errors[1](1, 1), 0.0, 1e-6);
    std::vector<int> best;
    const double cost = brute_force(errors, {{0}, {}, {}, {}, {4}}, 5, best);
    EXPECT_EQ(best, (std::vector<int>{0, 1, 2, 3, 4}));
    EXPECT_NEAR(plan.total_cost, cost, 1e-9);
}

// The part of a line inside the frame, by hand: a diagonal 3-4-5 leaving the
// frame halfway, a line along the border, one beside the frame.
TEST(FlowEditing, LengthInsideTheFrameClipsEachSegmentToTheFrame) {
    using P = std::vector<Eigen::Vector2d>;
    EXPECT_NEAR(length_inside_frame(P{{-30.0, -40.0}, {30.0, 40.0}}, 100, 100), 50.0, 1e-12);
    EXPECT_NEAR(length_inside_frame(P{{10.0, 10.0}, {10.0, 50.0}, {200.0, 50.0}}, 100, 60), 40.0 + 90.0, 1e-12);
    EXPECT_NEAR(length_inside_frame(P{{0.0, -10.0}, {0.0, 70.0}}, 100, 60), 60.0, 1e-12);
    EXPECT_EQ(length_inside_frame(P{{120.0, -4.0}, {150.0, 84.0}}, 96, 80), 0.0);
    EXPECT_EQ(length_inside_frame(P{{10.0, 10.0}}, 96, 80), 0.0);
}

TEST(FlowEditing, InterpolatesDenseLinesBetweenNeighboursOnly) {
    const std::vector<std::vector<Eigen::Vector2d>> drawn = {
        {{10.0, 0.0}, {12.0, 100.0}},   // a
        {{40.0, 0.0}, {44.0, 100.0}},   // b: 30-32 px right of a
        {{200.0, 0.0}, {200.0, 100.0}}, // c: too far
        {{0.0, 50.0}, {100.0, 50.0}},   // d: flows across (90 degrees)
    };
    const auto chains = neighbour_chains(drawn, 60.0);
    ASSERT_EQ(chains.size(), 3u);
    EXPECT_EQ(chains[0], (std::vector<int>{0, 1}));
    const auto between = interpolate_between(drawn, chains, 12.0);
    ASSERT_EQ(between.size(), 2u);  // 32 px / 12 -> 2 lines at 1/3, 2/3
    EXPECT_NEAR(between[0].weight, 1.0 / 3.0, 1e-12);
    const std::string id = interpolated_line_id("out-1", "out-2", between[1].weight);
    EXPECT_EQ(id, "out-1~out-2@0.667");
    std::string a, b;
    double w = 0.0;
    ASSERT_TRUE(parse_interpolated_line_id(id, a, b, w));
    EXPECT_EQ(a, "out-1");
    EXPECT_EQ(b, "out-2");
    EXPECT_DOUBLE_EQ(w, 0.667);
    EXPECT_FALSE(parse_interpolated_line_id("in-1", a, b, w));
    double f0 = 0.0, f1 = 0.0;
    ASSERT_TRUE(parse_segment_id(segment_line_id("in-1~in-2@0.500", 12.0, 40.5), a, f0, f1));
    EXPECT_EQ(a, "in-1~in-2@0.500");
    EXPECT_DOUBLE_EQ(f1, 40.5);

    // Densified input lines resolve back to geometry from the drawing alone.
    formats::FlowLineSet drawing;
    drawing.width = drawing.height = 120;
    drawing.inputs = {line("in-1", drawn[0]), line("in-2", drawn[1])};
    const auto dense = densify_input_lines(drawing, 12.0, 60.0);
    ASSERT_EQ(dense.size(), 4u);
    const auto rebuilt = input_line_points(InputLineIndex(drawing), dense[2].id, "drawing.svg");
    ASSERT_EQ(rebuilt.size(), dense[2].points.size());
    for (std::size_t i = 0; i < rebuilt.size(); ++i) EXPECT_TRUE(rebuilt[i].isApprox(dense[2].points[i]));
    const auto segment = input_line_points(InputLineIndex(drawing), segment_line_id(dense[2].id, 10.0, 50.0), "drawing.svg");
    EXPECT_NEAR(formats::polyline_length(segment), 40.0, 1e-9);
    const std::string message = flowvid::testing::validation_messages([&] { input_line_points(InputLineIndex(drawing), "nope", "drawing.svg"); });
    // The index finds what a scan of the drawing finds: the first of equal ids.
    formats::FlowLineSet twice = drawing;
    twice.inputs.push_back(line("in-1", drawn[1]));
    const InputLineIndex index(twice);
    EXPECT_EQ(index.find("in-1"), formats::find_input_line(twice, "in-1"));
    EXPECT_EQ(index.find("in-2"), &twice.inputs[1]);
    EXPECT_EQ(index.find("in-3"), nullptr);
    EXPECT_NE(message.find("drawing.svg"), std::string::npos) << message;
    EXPECT_NE(message.find("nope"), std::string::npos) << message;
}

namespace {

// Texel grey = arc position of the texel along the input line / 100: the
// texture is a ramp along the flow, so a rendered grey tells which input arc
// length a pixel shows.
std::shared_ptr<formats::ParticleBank> ramp_bank() {
    return vertical_bank({20.0}, 10.0, 50.0, 9, [](int, double s, double row) { return static_cast<float>((s + row) / 100.0); },
                         120, 120, 8);
}

// Over a black background the colour is texture x coverage.
double rendered_arc(const RgbImage& image, const std::vector<float>& coverage, int x, int y) {
    const float c = coverage[static_cast<std::size_t>(y) * image.width + x];
    if (c < 0.2f) return -1.0;
    return image.pixel(x, y)[0] / c * 100.0;
}

}  // namespace

TEST(FlowEditing, WarpsTextureWithEqualOrScaledArcLength) {
    auto bank = ramp_bank();
    for (ArcMapping mapping : {ArcMapping::equal, ArcMapping::scaled}) {
        SynthesisSettings settings;
        settings.mapping = mapping;
        settings.fade_frames = 0;
        auto streams = std::make_shared<ParticleStreams>(bank, vertical_lines({20.0}, 10.0, 50.0), settings);
        // The output line is twice as long (80 px) and 50 px to the right.
        const Synthesizer synth(streams, {{line("out", {{70.0, 10.0}, {70.0, 90.0}}), "in-0"}}, Background(), settings);
        std::vector<float> coverage;
        const RgbImage image = synth.render(20, &coverage);
        for (int s_out : {8, 16, 24, 32}) {
            const double shown = rendered_arc(image, coverage, 70, 10 + s_out);
            const double expected = mapping == ArcMapping::equal ? s_out : s_out / 2.0;
            EXPECT_NEAR(shown, expected, 1.0) << to_string(mapping) << " at output arc " << s_out;
        }
        if (mapping == ArcMapping::equal) {
            // Past the input line's end (40 px + half a patch) nothing is drawn.
            EXPECT_LT(coverage[static_cast<std::size_t>(10 + 60) * 120 + 70], 0.01f);
        } else {
            EXPECT_NEAR(rendered_arc(image, coverage, 70, 10 + 72), 36.0, 1.5);
        }
    }
}

TEST(FlowEditing, TimeVaryingOutputLinesFollowTheirKeys) {
    auto bank = ramp_bank();
    SynthesisSettings settings;
    auto streams = std::make_shared<ParticleStreams>(bank, vertical_lines({20.0}, 10.0, 50.0), settings);
    formats::FlowLine moving;
    moving.id = "sway";
    moving.keys = {{1, {{60.0, 10.0}, {60.0, 50.0}}}, {11, {{80.0, 10.0}, {80.0, 50.0}}}};
    const Synthesizer synth(streams, {{moving, "in-0"}}, Background(), settings);
    for (int frame : {1, 6, 11, 20}) {
        std::vector<float> coverage;
        synth.render(frame, &coverage);
        // The covered columns on row 30 are centred on the line's x at this frame.
        double sum = 0.0, weight = 0.0;
        for (int x = 0; x < 120; ++x) {
            sum += x * coverage[30 * 120 + static_cast<std::size_t>(x)];
            weight += coverage[30 * 120 + static_cast<std::size_t>(x)];
        }
        const double expected = frame >= 11 ? 80.0 : 60.0 + 2.0 * (frame - 1);
        ASSERT_GT(weight, 0.0);
        EXPECT_NEAR(sum / weight, expected, 0.6) << "frame " << frame;
    }
}

namespace {

// Three vertical input lines at x = 20, 35, 50 (y 10..110) with a bank of
// 10 particles each, and a 120 x 120 drawing holding them as in-0..in-2.
struct ThreeVerticalInputs {
    std::vector<double> xs = {20, 35, 50};
    ParticleStreams streams{vertical_bank(xs, 10.0, 110.0, 10, [](int l, double, double) { return 0.2f + 0.3f * l; }),
                            vertical_lines(xs, 10.0, 110.0), SynthesisSettings{}};
    formats::FlowLineSet drawing = vertical_drawing(xs);
};

}  // namespace

TEST(FlowEditing, DensePlanRoundTripsThroughSvgAndJson) {
    const ThreeVerticalInputs setup;
    const ParticleStreams& streams = setup.streams;
    formats::FlowLineSet drawing = setup.drawing;
    drawing.outputs.push_back(line("left", {{30.0, 10.0}, {26.0, 110.0}}, "in-0"));
    drawing.outputs.push_back(line("right", {{54.0, 10.0}, {60.0, 110.0}}, "in-2"));
    EditSettings edit;
    edit.correspondence_frames = 2;
    const formats::FlowLineSet dense = plan_to_flowlines(drawing, plan_edit(drawing, streams, edit));
    ASSERT_GT(dense.outputs.size(), 2u);
    // Interpolated lines carry their time offsets through both files.
    EXPECT_TRUE(std::any_of(dense.outputs.begin(), dense.outputs.end(),
                            [](const formats::FlowLine& l) { return l.time_offset_frames != 0; }));
    const std::string dir = flowvid::testing::scratch_dir("flow_editing");
    formats::write_flowlines_svg(dir + "/dense.svg", dense);
    const formats::FlowLineSet from_svg = formats::import_flowlines_svg(dir + "/dense.svg");
    EXPECT_EQ(from_svg.outputs, dense.outputs);
    EXPECT_EQ(from_svg.inputs, dense.inputs);
    formats::write_flowline_set(dir + "/dense.flowlines.json", dense);
    EXPECT_EQ(formats::read_flowline_set(dir + "/dense.flowlines.json"), dense);
}

// Moving output lines whose lengths change differently from key to key (a
// Blender particle system's trajectories seen by a panning camera): the lines
// interpolated between them are moving lines too, and every key of one line
// needs the same point count (regression: the count followed each frame's
// lengths, and rendering refused the line).
TEST(FlowEditing, LinesBetweenMovingLinesKeepOnePointCountPerLine) {
    const ThreeVerticalInputs setup;
    const ParticleStreams& streams = setup.streams;
    formats::FlowLineSet drawing = setup.drawing;
    formats::FlowLine left, right;
    left.id = "left";
    left.from = "in-0";
    left.keys = {{1, {{30.0, 10.0}, {30.0, 70.0}}}, {5, {{30.0, 10.0}, {30.0, 110.0}}}};        // grows 60 -> 100 px
    right.id = "right";
    right.from = "in-2";
    right.keys = {{1, {{60.0, 10.0}, {60.0, 40.0}, {60.0, 70.0}}}, {5, {{60.0, 10.0}, {60.0, 30.0}, {60.0, 40.0}}}};  // shrinks
    drawing.outputs = {left, right};
    EditSettings edit;
    edit.correspondence_frames = 2;
    const EditPlan plan = plan_edit(drawing, streams, edit);
    int interpolated = 0;
    for (const DenseLine& d : plan.lines) {
        if (d.drawn) continue;
        ++interpolated;
        ASSERT_EQ(d.output.line.keys.size(), 2u) << d.output.line.id;
        EXPECT_EQ(d.output.line.keys[0].points.size(), d.output.line.keys[1].points.size()) << d.output.line.id;
        // Still the blend at each key: the ends lie between the two lines' ends.
        std::string a, b;
        double w = 0.0;
        ASSERT_TRUE(parse_interpolated_line_id(d.output.line.id, a, b, w));
        for (const auto& key : d.output.line.keys) {
            const auto pl = formats::points_at_frame(left, key.frame), pr = formats::points_at_frame(right, key.frame);
            EXPECT_TRUE(key.points.back().isApprox((1 - w) * pl.back() + w * pr.back(), 1e-9)) << key.frame;
        }
        EXPECT_NO_THROW(formats::points_at_frame(d.output.line, 3.0));
    }
    EXPECT_GT(interpolated, 0);
}

namespace {

// One vertical input line at x = 20 whose particles (one entering per frame,
// 10 frames from y = 10 to 110) are each one flat grey: (p + 1) / 14 for the
// p-th, so that a pixel tells which particle it shows.
std::shared_ptr<const ParticleStreams> one_grey_per_particle_streams() {
    auto bank = std::make_shared<formats::ParticleBank>();
    const int patch = 8, life = 10;
    bank->patch_size_px = patch;
    bank->clip_width_px = bank->clip_height_px = 120;
    bank->clip_frame_count = 12 + life;
    bank->lines.push_back({"in-0", 100.0f});
    for (int p = 0; p < 12; ++p) {
        formats::TrackedParticle particle;
        particle.line_id = "in-0";
        particle.start_frame = p;
        const float grey = (p + 1) / 14.0f;
        for (int a = 0; a < life; ++a) {
            particle.arc_length_px.push_back(100.0f * a / (life - 1));
            for (int k = 0; k < patch * patch; ++k) particle.texture_rgba.insert(particle.texture_rgba.end(), {grey, grey, grey, 1.0f});
        }
        bank->particles.push_back(std::move(particle));
    }
    SynthesisSettings settings;
    settings.fade_frames = 0;
    return std::make_shared<ParticleStreams>(bank, vertical_lines({20.0}, 10.0, 110.0), settings);
}

}  // namespace

// The sequence is infinite and the same whatever range is rendered, so a line
// shown at an offset in time is exactly the unshifted line some frames later.
TEST(FlowEditing, ALineAtATimeOffsetShowsTheSequenceThatManyFramesLater) {
    const auto streams = one_grey_per_particle_streams();
    formats::FlowLine shifted = line("out", {{70.0, 10.0}, {66.0, 110.0}});
    shifted.time_offset_frames = 5;
    formats::FlowLine unshifted = shifted;
    unshifted.time_offset_frames = 0;
    const Synthesizer a(streams, {{shifted, "in-0"}}, Background(), SynthesisSettings{});
    const Synthesizer b(streams, {{unshifted, "in-0"}}, Background(), SynthesisSettings{});
    for (int frame : {1, 17, 40}) {
        const RgbImage late = b.render(frame + 5), now = a.render(frame);
        EXPECT_EQ(now.rgb, late.rgb) << "frame " << frame;
        EXPECT_NE(a.render(frame).rgb, b.render(frame).rgb) << "frame " << frame;
    }
}

// Interpolated lines that carry the same input must not show the same
// particles side by side (regression: every such line replayed the input at
// the same time, so the texture repeated every half patch across the flow:
// streaks on the fire's wind edit, flat areas on the waterfall's new channel).
TEST(FlowEditing, NeighbouringInterpolatedLinesShowDifferentParticles) {
    const auto streams = one_grey_per_particle_streams();
    formats::FlowLineSet drawing = vertical_drawing({20.0});
    drawing.outputs.push_back(line("left", {{60.0, 10.0}, {60.0, 110.0}}, "in-0"));
    drawing.outputs.push_back(line("right", {{100.0, 10.0}, {100.0, 110.0}}, "in-0"));
    // Mean grey difference between neighbouring dense lines' centre columns,
    // where both are fully covered, over a few frames.
    auto neighbour_difference = [&](bool offsets, EditPlan& plan) {
        EditSettings edit;
        edit.correspondence_frames = 2;
        edit.offset_interpolated_lines = offsets;
        plan = plan_edit(drawing, *streams, edit);
        SynthesisSettings settings;
        settings.fade_frames = 0;
        const Synthesizer synth(streams, output_lines(plan), Background(), settings);
        double sum = 0.0;
        int count = 0;
        for (int frame : {20, 23, 31}) {
            std::vector<float> coverage;
            const RgbImage image = synth.render(frame, &coverage);
            for (int x = 60; x + 4 <= 100; x += 4)
                for (int y = 30; y <= 90; ++y) {
                    const std::size_t a = static_cast<std::size_t>(y) * 120 + x, b = a + 4;
                    if (coverage[a] < 0.99f || coverage[b] < 0.99f) continue;
                    sum += std::fabs(image.rgb[3 * a] - image.rgb[3 * b]);
                    ++count;
                }
        }
        EXPECT_GT(count, 500);
        return count > 0 ? sum / count : 0.0;
    };
    EditPlan same_time, own_time;
    const double replicated = neighbour_difference(false, same_time);
    const double varied = neighbour_difference(true, own_time);
    EXPECT_LT(replicated, 1e-4);  // the same particle, shifted across by the spacing
    EXPECT_GT(varied, 0.05);      // greys 1/14 apart: different particles
    // The first drawn line keeps the input's time; the second, carrying the
    // same input, and the interpolated neighbours differ in time.
    ASSERT_EQ(own_time.lines.size(), 11u);
    const int period = streams->schedule().period_frames;
    int drawn_lines = 0;
    for (std::size_t i = 0; i < own_time.lines.size(); ++i) {
        const DenseLine& d = own_time.lines[i];
        if (d.drawn && drawn_lines++ == 0) {
            EXPECT_EQ(d.output.line.time_offset_frames, 0);
        } else if (d.drawn) {
            EXPECT_GT(d.output.line.time_offset_frames, 0);
        }
        EXPECT_GE(d.output.line.time_offset_frames, 0);
        EXPECT_LT(d.output.line.time_offset_frames, period);
        if (i > 0) {
            EXPECT_NE(d.output.line.time_offset_frames, own_time.lines[i - 1].output.line.time_offset_frames) << i;
        }
    }
}

// Drawn lines lying on their own input lines leave the flow between them as
// filmed: that stretch renders exactly as plain synthesis renders it (the
// densified input line between, no interpolated lines at other times), and
// those drawn lines keep the input's time even when a line drawn before them
// carries the same input elsewhere (regression: the waterfall's edit offset
// its own unmoved lines, and interpolated over them, so they no longer
// matched the replayed clip behind them).
TEST(FlowEditing, StretchesLeftAsFilmedRenderAsSynthesisDoes) {
    const std::vector<double> xs = {20, 35, 50};
    auto bank = vertical_bank(xs, 10.0, 110.0, 10, [](int l, double s, double row) {
        return static_cast<float>(0.1 + 0.25 * l + 0.004 * s + 0.01 * row);
    });
    // The middle line is the one `track` added between the drawn in-0 and in-2.
    const std::string densified = interpolated_line_id("in-0", "in-2", 0.5);
    bank->lines[1].id = densified;
    for (auto& particle : bank->particles)
        if (particle.line_id == "in-1") particle.line_id = densified;
    formats::FlowLineSet drawing;
    drawing.width = drawing.height = 120;
    drawing.inputs = {line("in-0", {{20.0, 10.0}, {20.0, 110.0}}), line("in-2", {{50.0, 10.0}, {50.0, 110.0}})};
    // Listed first: a new line carrying in-0, 40 px right of in-2.
    drawing.outputs = {line("new", {{90.0, 10.0}, {90.0, 110.0}}, "in-0"), line("kept-0", drawing.inputs[0].points, "in-0"),
                       line("kept-2", drawing.inputs[1].points, "in-2")};
    SynthesisSettings settings;
    settings.fade_frames = 0;
    const auto streams = std::make_shared<ParticleStreams>(
        bank, ParticleStreams::input_points_from_drawing(*bank, drawing, "drawing.svg"), settings, &drawing);

    EditSettings edit;
    edit.correspondence_frames = 4;
    const EditPlan plan = plan_edit(drawing, *streams, edit);
    std::map<std::string, const DenseLine*> by_id;
    for (const DenseLine& d : plan.lines) by_id[d.output.line.id] = &d;
    ASSERT_TRUE(by_id.count("kept-0") && by_id.count("kept-2") && by_id.count("new"));
    EXPECT_EQ(by_id["kept-0"]->output.line.time_offset_frames, 0);
    EXPECT_EQ(by_id["kept-2"]->output.line.time_offset_frames, 0);
    EXPECT_GT(by_id["new"]->output.line.time_offset_frames, 0);
    // Between kept-0 and kept-2: the densified input line itself, at its time.
    ASSERT_TRUE(by_id.count(densified));
    EXPECT_EQ(by_id[densified]->output.from, densified);
    EXPECT_EQ(by_id[densified]->output.line.time_offset_frames, 0);
    int between_kept = 0, between_kept_and_new = 0;
    for (const DenseLine& d : plan.lines) {
        if (d.drawn) continue;
        const double x = d.output.line.points.front().x();
        (x < 50.0 ? between_kept : between_kept_and_new) += 1;
    }
    EXPECT_EQ(between_kept, 1);
    EXPECT_GT(between_kept_and_new, 5);  // 40 px at half-patch spacing: interpolated as before

    // Left of kept-2's patches (x < 46) the edit is the plain synthesis, pixel for pixel.
    const Synthesizer edited(streams, output_lines(plan), Background(), settings);
    const Synthesizer plain(streams, {}, Background(), settings);
    for (int frame : {3, 17, 40}) {
        const RgbImage a = edited.render(frame), b = plain.render(frame);
        for (int y = 0; y < 120; ++y)
            for (int x = 0; x < 46; ++x)
                for (int k = 0; k < 3; ++k)
                    ASSERT_EQ(a.pixel(x, y)[k], b.pixel(x, y)[k]) << "frame " << frame << " at " << x << ", " << y;
    }
}

// An input line far to the side whose grey lies between the drawn lines'
// greys lowers eq. 3.1 if any input may be taken; the default keeps the
// interpolated lines to the inputs between the drawn lines' own.
TEST(FlowEditing, InterpolatedLinesTakeInputsBetweenTheirDrawnLinesInputs) {
    const std::vector<double> xs = {20, 35, 50, 65, 80, 100};
    const float greys[] = {0.1f, 0.3f, 0.5f, 0.7f, 0.9f, 0.2f};
    auto bank = vertical_bank(xs, 10.0, 110.0, 10, [&](int l, double, double) { return greys[l]; }, 120, 120, 16);
    const ParticleStreams streams(bank, vertical_lines(xs, 10.0, 110.0), SynthesisSettings{});
    formats::FlowLineSet drawing = vertical_drawing(xs);
    drawing.outputs.push_back(line("dark", {{36.0, 10.0}, {36.0, 110.0}}, "in-0"));
    drawing.outputs.push_back(line("lighter", {{84.0, 10.0}, {84.0, 110.0}}, "in-1"));
    EditSettings edit;
    edit.spacing_px = 12.0;
    edit.correspondence_frames = 4;
    std::map<std::string, std::set<std::string>> taken;
    for (auto inputs : {EditSettings::InterpolatedInputs::between, EditSettings::InterpolatedInputs::any}) {
        edit.interpolated_inputs = inputs;
        const EditPlan plan = plan_edit(drawing, streams, edit);
        ASSERT_EQ(plan.lines.size(), 5u);
        for (const DenseLine& d : plan.lines)
            if (!d.drawn) taken[inputs == EditSettings::InterpolatedInputs::any ? "any" : "between"].insert(d.output.from);
    }
    ASSERT_FALSE(taken["between"].empty());
    for (const std::string& from : taken["between"]) EXPECT_TRUE(from == "in-0" || from == "in-1") << from;
    EXPECT_TRUE(taken["any"].count("in-5")) << "the far grey 0.2 halves the steps";
}

namespace {

// A plate whose red channel is x / 120 and green y / 120: a carried pixel's
// colour tells which input-frame position it was read from.
RgbImage position_plate() {
    RgbImage plate(120, 120);
    for (int y = 0; y < 120; ++y)
        for (int x = 0; x < 120; ++x) {
            float* p = plate.pixel(x, y);
            p[0] = x / 120.0f;
            p[1] = y / 120.0f;
            p[2] = 0.5f;
        }
    return plate;
}

}  // namespace

TEST(FlowEditing, ANewLineCarriesTheBackgroundAroundItsInputLineWhereParticlesLeaveGaps) {
    // in-0 is drawn from y = 10 to 110 at x = 20, and tracked on its first
    // 70 px (the segment in-0[0.0:70.0]; the rest, like a rock ledge nothing
    // crossed, is left out), where its particles cover the first 40 px; the
    // output line lies 50 px to the right, from y = 10 to 90.
    auto bank = ramp_bank();
    bank->lines[0].id = "in-0[0.0:70.0]";
    bank->lines[0].length_px = 70.0f;
    for (auto& p : bank->particles) p.line_id = "in-0[0.0:70.0]";
    formats::FlowLineSet drawing;
    drawing.width = drawing.height = 120;
    drawing.inputs.push_back(line("in-0", {{20.0, 10.0}, {20.0, 110.0}}));
    const RgbImage plate = position_plate();

    const auto render = [&](bool carry, bool reference, std::vector<float>* coverage, double output_x = 70.0) {
        SynthesisSettings settings;
        settings.carry_background = carry;
        settings.reference_rendering = reference;
        auto streams = std::make_shared<ParticleStreams>(bank, vertical_lines({20.0}, 10.0, 80.0), settings, &drawing);
        const Synthesizer synth(streams, {{line("out", {{output_x, 10.0}, {output_x, 90.0}}), "in-0"}},
                                Background::plate(plate), settings);
        return synth.render(20, coverage);
    };
    std::vector<float> coverage_on, coverage_off;
    const RgbImage on = render(true, false, &coverage_on);
    const RgbImage off = render(false, false, &coverage_off);

    // Beyond the particles' reach (output arc 55..70) no particle covers the
    // line: without carrying, the output's own plate shows (red = 70/120);
    // carried, the plate around the input line at the same arc length and
    // lateral offset (red = (20 + n)/120, green unchanged; the smoothing
    // keeps this plate's linear ramps).
    for (int y : {65, 72, 80})
        for (int n : {-1, 0, 1}) {
            ASSERT_LT(coverage_on[static_cast<std::size_t>(y) * 120 + 70 + n], 0.01f) << y;
            EXPECT_NEAR(off.pixel(70 + n, y)[0], (70.0 + n) / 120.0, 1e-5);
            EXPECT_NEAR(on.pixel(70 + n, y)[0], (20.0 + n) / 120.0, 2e-3) << "y " << y << " n " << n;
            EXPECT_NEAR(on.pixel(70 + n, y)[1], y / 120.0, 2e-3) << "y " << y << " n " << n;
        }
    // Carried background fades out a patch and a half (12 px) to the side:
    // a little shows 10 px off, none 13 px off or past the line's end.
    EXPECT_GT(std::fabs(on.pixel(80, 72)[0] - off.pixel(80, 72)[0]), 1e-3);
    EXPECT_NEAR(on.pixel(83, 72)[0], off.pixel(83, 72)[0], 1e-6);
    EXPECT_NEAR(on.pixel(84, 72)[0], 84.0 / 120.0, 1e-5);
    // Nor from the stretch of the input line no particle crossed (arc beyond
    // 70 + half a patch): its rock would stand in the new flow.
    for (int y : {86, 89}) EXPECT_NEAR(on.pixel(70, y)[0], 70.0 / 120.0, 1e-5) << y;
    EXPECT_NEAR(on.pixel(70, 100)[0], 70.0 / 120.0, 1e-5);
    // Where particles cover the line fully they show, whatever lies below.
    int covered = 0;
    for (int y = 20; y < 50; ++y) {
        const std::size_t i = static_cast<std::size_t>(y) * 120 + 70;
        if (coverage_on[i] < 0.999f) continue;
        ++covered;
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(on.pixel(70, y)[k], off.pixel(70, y)[k], 1e-6) << y;
    }
    EXPECT_GT(covered, 5);

    // The whole-frame reference renderer gives the same frame.
    const RgbImage reference = render(true, true, nullptr);
    float largest = 0.0f;
    for (std::size_t i = 0; i < on.rgb.size(); ++i) largest = std::max(largest, std::fabs(on.rgb[i] - reference.rgb[i]));
    EXPECT_LT(largest, 1e-5f);

    // A keyed line (composited every frame) standing where the fixed one is
    // (whose carried background is composited once) gives the same frame.
    {
        SynthesisSettings settings;
        settings.carry_background = true;
        auto streams = std::make_shared<ParticleStreams>(bank, vertical_lines({20.0}, 10.0, 80.0), settings, &drawing);
        formats::FlowLine keyed;
        keyed.id = "out";
        keyed.keys = {{1, {{70.0, 10.0}, {70.0, 90.0}}}, {40, {{70.0, 10.0}, {70.0, 90.0}}}};
        const Synthesizer synth(streams, {{keyed, "in-0"}}, Background::plate(plate), settings);
        const RgbImage moving = synth.render(20);
        float worst = 0.0f;
        for (std::size_t i = 0; i < on.rgb.size(); ++i) worst = std::max(worst, std::fabs(on.rgb[i] - moving.rgb[i]));
        EXPECT_LT(worst, 1e-6f);
    }

    // Nothing is carried onto the flow's own region (within half a patch of
    // the input line), whose background already is the flow's; a patch away
    // it is.
    const RgbImage near_on = render(true, false, nullptr, 25.0), near_off = render(false, false, nullptr, 25.0);
    for (int y = 10; y <= 90; ++y)
        for (int x = 16; x <= 24; ++x)
            for (int k = 0; k < 3; ++k) ASSERT_EQ(near_on.pixel(x, y)[k], near_off.pixel(x, y)[k]) << x << ", " << y;
    EXPECT_GT(std::fabs(near_on.pixel(27, 75)[0] - near_off.pixel(27, 75)[0]), 1e-3);
}

TEST(FlowEditing, ANewLineCarriesTheFlowAcrossAnUntrackedStretchThatLooksLikeIt) {
    // in-0 runs down x = 20 from y = 10 to 110 and was tracked on two
    // stretches, arcs 0-20 and 60-100; nothing was followed between them.
    // Left of x = 45 the background is the flow's (bright, 0.8), right of it
    // rock (0.3). The new line lies 50 px to the right. Between the tracked
    // stretches the flow is either as bright (water too even to follow: the
    // new line shows it, carried) or holds a dark ledge at arcs 30-50 (0.02:
    // left out, the output's own rock shows).
    const auto stretch = [](double from, double to) {
        auto part = vertical_bank({20.0}, 10.0 + from, 10.0 + to, 9, [](int, double, double) { return 0.8f; });
        const std::string id = "in-0[" + std::to_string(static_cast<int>(from)) + ".0:" + std::to_string(static_cast<int>(to)) + ".0]";
        part->lines[0].id = id;
        for (auto& particle : part->particles) particle.line_id = id;
        return part;
    };
    auto bank = stretch(0.0, 20.0);
    const auto lower = stretch(60.0, 100.0);
    bank->lines.push_back(lower->lines[0]);
    bank->particles.insert(bank->particles.end(), lower->particles.begin(), lower->particles.end());
    formats::FlowLineSet drawing;
    drawing.width = drawing.height = 120;
    drawing.inputs.push_back(line("in-0", {{20.0, 10.0}, {20.0, 110.0}}));
    const std::vector<std::vector<Eigen::Vector2d>> tracked = {{{20.0, 10.0}, {20.0, 30.0}}, {{20.0, 70.0}, {20.0, 110.0}}};

    const auto render = [&](float between, std::vector<float>* coverage) {
        RgbImage plate(120, 120);
        for (int y = 0; y < 120; ++y)
            for (int x = 0; x < 120; ++x) {
                const float value = x >= 45 ? 0.3f : (y >= 40 && y <= 60 ? between : 0.8f);
                float* p = plate.pixel(x, y);
                p[0] = p[1] = p[2] = value;
            }
        SynthesisSettings settings;
        settings.carry_background = true;
        auto streams = std::make_shared<ParticleStreams>(bank, tracked, settings, &drawing);
        const Synthesizer synth(streams, {{line("out", {{70.0, 10.0}, {70.0, 110.0}}), "in-0"}}, Background::plate(plate),
                                settings);
        return synth.render(20, coverage);
    };
    std::vector<float> coverage;
    const RgbImage even = render(0.8f, &coverage), ledge = render(0.02f, nullptr);
    // Beyond the particles' reach (arcs 25-45 and the ledge's middle).
    for (int y : {37, 45, 50, 55}) {
        ASSERT_LT(coverage[static_cast<std::size_t>(y) * 120 + 70], 0.01f) << "no particle reaches y " << y;
        EXPECT_NEAR(even.pixel(70, y)[0], 0.8f, 1e-4) << y;
        // y = 37 is bright water 3 px above the ledge, but the carried
        // background is smoothed over a patch along the line: there it would
        // bring the ledge's dark in as a grey smear, so it stops a patch
        // short of the ledge.
        EXPECT_NEAR(ledge.pixel(70, y)[0], 0.3f, 1e-6) << y;
    }
    // Well inside the tracked stretches both carry the flow's background.
    for (int y : {15, 95}) {
        EXPECT_NEAR(even.pixel(70, y)[0], 0.8f, 1e-4) << y;
        EXPECT_NEAR(ledge.pixel(70, y)[0], 0.8f, 1e-4) << y;
    }
}

TEST(FlowEditing, OverlapSharpnessShowsOneInputFrameWhereTwoOverlapInsteadOfADoubleExposure) {
    // Two lines 3 px apart carry one input at offsets 0 and 5 frames: between
    // them every pixel mixes two particles of different input frames, each
    // one flat grey (p + 1) / 14.
    const auto streams = one_grey_per_particle_streams();
    formats::FlowLine a = line("a", {{60.0, 10.0}, {60.0, 110.0}}), b = line("b", {{63.0, 10.0}, {63.0, 110.0}});
    b.time_offset_frames = 5;
    const auto pure_share = [&](double sharpness) {
        SynthesisSettings settings;
        settings.preserve_detail = false;  // the mix alone
        settings.overlap_sharpness = sharpness;
        const Synthesizer synth(streams, {{a, "in-0"}, {b, "in-0"}}, Background(), settings);
        int covered = 0, pure = 0;
        for (int frame : {3, 8, 14, 21}) {
            std::vector<float> coverage;
            const RgbImage image = synth.render(frame, &coverage);
            for (int y = 20; y < 100; ++y)
                for (int x = 60; x <= 63; ++x) {
                    if (coverage[static_cast<std::size_t>(y) * 120 + x] < 0.999f) continue;
                    ++covered;
                    const float grey = image.pixel(x, y)[0];
                    float nearest = 1.0f;
                    for (int p = 0; p < 12; ++p) nearest = std::min(nearest, std::fabs(grey - (p + 1) / 14.0f));
                    pure += nearest < 0.005f ? 1 : 0;
                }
        }
        EXPECT_GT(covered, 200);
        return static_cast<double>(pure) / covered;
    };
    const double mixed = pure_share(1.0), sharp = pure_share(4.0), sharpest = pure_share(64.0);
    std::printf("share of pixels showing one particle's grey: sharpness 1 %.3f, 4 %.3f, 64 %.3f\n", mixed, sharp, sharpest);
    // Measured: 0, 0.56, 0.75 (the rest: pixels where more than two input
    // frames meet, lumped into one group, and bicubic resampling at patch borders).
    EXPECT_LT(mixed, 0.05);
    EXPECT_GT(sharp, 0.4);
    EXPECT_GT(sharpest, sharp + 0.1);
}

namespace {

// A still scene with a vertical edge (dark 0.1 left of x = 50, bright 0.5
// from it, a faint ramp in y) and a flame: a narrow band of light around
// x = 47 whose pattern rises 3 px a frame. One input line runs up the flame
// at x = 47 (y 100 -> 40); particles enter every frame and are cut from the
// scene as tracking would (whole pixels around the centre): an 8 px patch
// holds the edge. Linear values.
struct FlameInFrontOfAnEdge {
    static float still(int x, int y) { return (x < 50 ? 0.1f : 0.5f) + 0.0005f * static_cast<float>(y); }
    static float light(double x, double y, int frame) {
        const double across = (x - 47.0) / 1.2;
        return static_cast<float>(0.3 * std::exp(-0.5 * across * across) *
                                  (0.5 + 0.5 * std::cos(2.0 * M_PI * (y + 3.0 * frame) / 10.0)));
    }
    static float pixel(int x, int y, int frame) { return still(x, y) + light(x, y, frame); }

    std::shared_ptr<formats::ParticleBank> bank = std::make_shared<formats::ParticleBank>();
    RgbImage plate{120, 120};
    std::vector<std::vector<Eigen::Vector2d>> points{{{47.0, 100.0}, {47.0, 40.0}}};

    FlameInFrontOfAnEdge() {
        const int patch = 8, count = 40, life = 21;
        bank->patch_size_px = patch;
        bank->clip_width_px = bank->clip_height_px = 120;
        bank->clip_frame_count = count + life;
        bank->lines.push_back({"in-0", 60.0f});
        for (int p = 0; p < count; ++p) {
            formats::TrackedParticle particle;
            particle.line_id = "in-0";
            particle.start_frame = p;
            for (int a = 0; a < life; ++a) {
                const double y = 100.0 - 3.0 * a;
                particle.arc_length_px.push_back(static_cast<float>(3.0 * a));
                const int ox = patch_origin(47.0, patch), oy = patch_origin(y, patch);
                for (int i = 0; i < patch; ++i)
                    for (int j = 0; j < patch; ++j) {
                        const float v = pixel(ox + j, oy + i, p + a);
                        particle.texture_rgba.insert(particle.texture_rgba.end(), {v, v, v, 1.0f});
                    }
            }
            bank->particles.push_back(std::move(particle));
        }
        for (int y = 0; y < 120; ++y)
            for (int x = 0; x < 120; ++x)
                for (int k = 0; k < 3; ++k) plate.pixel(x, y)[k] = still(x, y);
    }

    RgbImage render(TextureLayer layer, double output_x, bool reference, std::vector<float>* coverage = nullptr) const {
        SynthesisSettings settings;
        settings.first_start_frame = 0;  // K = 40: no wrap on the line at frame 30
        settings.texture_layer = layer;
        settings.reference_rendering = reference;
        auto layer_bank = std::make_shared<formats::ParticleBank>(*bank);
        if (layer == TextureLayer::moving) keep_moving_part(*layer_bank, points, plate);
        auto streams = std::make_shared<ParticleStreams>(layer_bank, points, settings);
        const Synthesizer synth(streams, {{line("out", {{output_x, 100.0}, {output_x, 40.0}}), "in-0"}},
                                Background::plate(plate), settings);
        return synth.render(30, coverage);
    }
};

}  // namespace

// TextureLayer::moving: an edit moves the flame, not the scene's edge behind
// it. Moved 30 px right (onto the bright side), whole patches carry the dark
// side of the edge along; the moving layer leaves the destination's plate
// where the source had no flame light, and screens the light over it
// (plate + coverage * light / (1 - source plate) * (1 - plate)). Unedited, it renders
// as whole patches do (the clip is nowhere darker than its plate here).
TEST(FlowEditing, TheMovingLayerMovesTheFlameNotTheEdgeBehindIt) {
    const FlameInFrontOfAnEdge scene;
    std::vector<float> coverage;
    const RgbImage whole = scene.render(TextureLayer::whole, 77.0, false);
    const RgbImage moving = scene.render(TextureLayer::moving, 77.0, false, &coverage);
    const int input_frame = 29;  // s0 + (30 - 1) mod 40
    int checked = 0;
    float worst_plate = 0.0f, worst_light = 0.0f, smallest_edge = 1.0f;
    for (int y = 50; y <= 90; ++y) {
        if (coverage[static_cast<std::size_t>(y) * 120 + 77] < 0.999f) continue;
        ++checked;
        for (int x = 73; x <= 81; ++x) {
            const float plate = FlameInFrontOfAnEdge::still(x, y);
            const float light = FlameInFrontOfAnEdge::light(x - 30, y, input_frame);
            const float source_plate = FlameInFrontOfAnEdge::still(x - 30, y);
            const float covered = coverage[static_cast<std::size_t>(y) * 120 + static_cast<std::size_t>(x)];
            const float expected = plate + covered * light / (1.0f - source_plate) * (1.0f - plate);
            worst_light = std::max(worst_light, std::fabs(moving.pixel(x, y)[0] - expected));
            if (light < 1e-4f) worst_plate = std::max(worst_plate, std::fabs(moving.pixel(x, y)[0] - plate));
        }
        // Whole patches show the edge's dark side 2 px left of the line (no light there).
        smallest_edge = std::min(smallest_edge, FlameInFrontOfAnEdge::still(75, y) - whole.pixel(75, y)[0]);
    }
    ASSERT_GT(checked, 20);
    std::printf("moved 30 px: moving layer within %.2g of the screened light, %.2g of the plate where no light; whole "
                "patches carry the edge (>= %.3f darker than the plate)\n",
                worst_light, worst_plate, smallest_edge);
    EXPECT_LT(worst_light, 2e-3f);
    EXPECT_LT(worst_plate, 1e-4f);
    EXPECT_GT(smallest_edge, 0.25f);  // 0.4 less the light 2 px from the line

    // Unedited, both layers give the same frame; banded = reference renderer.
    const RgbImage in_place_whole = scene.render(TextureLayer::whole, 47.0, false);
    const RgbImage in_place_moving = scene.render(TextureLayer::moving, 47.0, false);
    const RgbImage reference = scene.render(TextureLayer::moving, 77.0, true);
    float same = 0.0f, renderers = 0.0f;
    for (std::size_t i = 0; i < moving.rgb.size(); ++i) {
        same = std::max(same, std::fabs(in_place_whole.rgb[i] - in_place_moving.rgb[i]));
        renderers = std::max(renderers, std::fabs(moving.rgb[i] - reference.rgb[i]));
    }
    EXPECT_LT(same, 1e-5f);
    EXPECT_LT(renderers, 1e-5f);

    // It needs a still background: over the clip looped the flames would show twice.
    SynthesisSettings settings;
    settings.texture_layer = TextureLayer::moving;
    auto streams = std::make_shared<ParticleStreams>(scene.bank, scene.points, settings);
    auto clip = std::make_shared<ClipFrames>(120, 120, 25.0, "memory");
    clip->append(RgbImage(120, 120));
    EXPECT_THROW(Synthesizer(streams, {}, Background::looped(clip), settings), std::invalid_argument);
}

TEST(FlowGeometry, ThePatchSizeFollowsTheGapBetweenDrawnLines) {
    // Vertical lines `gap` apart, 200 px long: every neighbour pair's mean gap is `gap`.
    const auto parallel = [](int count, double gap) {
        std::vector<std::vector<Eigen::Vector2d>> lines;
        for (int i = 0; i < count; ++i) lines.push_back({{100.0 + gap * i, 0.0}, {100.0 + gap * i, 200.0}});
        return lines;
    };
    const PatchSizeChoice water = patch_size_from_lines(parallel(6, 45.0));
    EXPECT_EQ(water.neighbour_pairs, 5);
    EXPECT_NEAR(water.median_gap_px, 45.0, 1e-9);
    EXPECT_EQ(water.patch_px, 24);  // 22.5 to the nearest multiple of 8
    EXPECT_EQ(patch_size_from_lines(parallel(6, 100.0)).patch_px, 48);  // 50 -> 48
    EXPECT_EQ(patch_size_from_lines(parallel(3, 20.0)).patch_px, 16);   // 10 -> 8, at least 16
    EXPECT_EQ(patch_size_from_lines(parallel(3, 230.0)).patch_px, 96);  // 115 -> 112, at most 96
    // The median is robust to one far line; a line alone, or lines beyond
    // max_gap_px, keep the thesis's 24 px.
    std::vector<std::vector<Eigen::Vector2d>> with_far = parallel(5, 45.0);
    with_far.push_back({{100.0 + 4 * 45.0 + 200.0, 0.0}, {100.0 + 4 * 45.0 + 200.0, 200.0}});
    EXPECT_EQ(patch_size_from_lines(with_far).patch_px, 24);
    const PatchSizeChoice alone = patch_size_from_lines(parallel(1, 0.0));
    EXPECT_EQ(alone.neighbour_pairs, 0);
    EXPECT_EQ(alone.patch_px, 24);
    EXPECT_EQ(patch_size_from_lines(parallel(2, 300.0)).neighbour_pairs, 0);
}
