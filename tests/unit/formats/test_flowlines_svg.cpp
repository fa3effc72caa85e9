// Flow lines drawn in SVG: the two real captures, transforms and viewBox
// against hand-computed pixels, path syntax, Bézier flattening against the
// analytic curves, refused constructs and malformed XML named by file and
// element, and the export an artist keeps drawing in.

#include "flowvid/formats/flowlines.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>

namespace flowvid::formats {
namespace {

using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::shared_path;
using flowvid::testing::test_data;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;
using Points = std::vector<Eigen::Vector2d>;

std::string data(const std::string& name) { return test_data("formats/flowlines/" + name); }

const FlowLine& line_by_id(const std::vector<FlowLine>& lines, const std::string& id) {
    for (const FlowLine& line : lines)
        if (line.id == id) return line;
    ADD_FAILURE() << "no line " << id;
    static const FlowLine none;
    return none;
}

void expect_points(const Points& actual, const Points& expected, double tolerance, const std::string& what) {
    ASSERT_EQ(actual.size(), expected.size()) << what;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        EXPECT_NEAR(actual[i].x(), expected[i].x(), tolerance) << what << " point " << i;
        EXPECT_NEAR(actual[i].y(), expected[i].y(), tolerance) << what << " point " << i;
    }
}

std::string joined(const std::vector<Problem>& problems, Problem::Severity severity) {
    std::string text;
    for (const Problem& p : problems)
        if (p.severity == severity) text += p.to_string() + "\n";
    return text;
}

bool has_line_with(const std::string& messages, const std::vector<std::string>& words) {
    std::size_t start = 0;
    while (start < messages.size()) {
        std::size_t end = messages.find('\n', start);
        if (end == std::string::npos) end = messages.size();
        const std::string line = messages.substr(start, end - start);
        bool all = true;
        for (const std::string& word : words) all = all && line.find(word) != std::string::npos;
        if (all) return true;
        start = end + 1;
    }
    return false;
}

// Problems of an SVG given as text, reported under `name`.
std::vector<Problem> svg_problems(const std::string& text, const std::string& name = "inline.svg",
                                  std::optional<FlowLineSet>* result = nullptr) {
    Diagnostics diagnostics("unused");
    std::optional<FlowLineSet> set = parse_flowlines_svg(text, name, diagnostics);
    if (result) *result = set;
    return diagnostics.problems();
}

TEST(FlowLinesSvg, WaterfallCaptureImports) {
    std::vector<Problem> warnings;
    const FlowLineSet set =
        import_flowlines_svg(shared_path("captures/video-waterfall-cascade/flowlines.svg"), &warnings);
    EXPECT_TRUE(warnings.empty()) << joined(warnings, Problem::Severity::warning);
    EXPECT_EQ(set.width, 640);
    EXPECT_EQ(set.height, 360);
    EXPECT_EQ(set.description.rfind("waterfall cascade:", 0), 0u) << set.description;
    ASSERT_EQ(set.inputs.size(), 7u);
    ASSERT_EQ(set.outputs.size(), 10u);
    for (std::size_t i = 0; i < 7; ++i) EXPECT_EQ(set.inputs[i].id, "in-" + std::to_string(i + 1));
    for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(set.outputs[i].id, "out-" + std::to_string(i + 1));
    EXPECT_EQ(set.inputs[0].points.front(), Eigen::Vector2d(200, 0));
    EXPECT_EQ(set.inputs[0].points.back(), Eigen::Vector2d(260, 230));
    EXPECT_EQ(set.inputs[6].points.front(), Eigen::Vector2d(600, 40));
    EXPECT_EQ(set.inputs[6].points.back(), Eigen::Vector2d(500, 150));
    EXPECT_EQ(set.inputs[5].points.size(), 6u);
    EXPECT_EQ(set.outputs[9].points.front(), Eigen::Vector2d(160, 0));
    EXPECT_EQ(set.outputs[9].points.back(), Eigen::Vector2d(235, 355));
    const char* from[10] = {"in-1", "in-2", "in-3", "in-4", "in-5", "in-6", "in-7", "in-3", "in-4", "in-5"};
    for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(set.outputs[i].from, from[i]) << set.outputs[i].id;
    for (const FlowLine& line : set.outputs) EXPECT_FALSE(line.is_time_varying());
}

TEST(FlowLinesSvg, FirePotCaptureImports) {
    const FlowLineSet set = import_flowlines_svg(shared_path("captures/video-fire-pot/flowlines.svg"));
    EXPECT_EQ(set.width, 640);
    EXPECT_EQ(set.height, 360);
    ASSERT_EQ(set.inputs.size(), 6u);
    ASSERT_EQ(set.outputs.size(), 6u);
    EXPECT_EQ(set.inputs[0].points.front(), Eigen::Vector2d(150, 359));
    EXPECT_EQ(set.inputs[0].points.back(), Eigen::Vector2d(140, 250));
    EXPECT_EQ(set.inputs[5].points.back(), Eigen::Vector2d(600, 100));
    EXPECT_EQ(set.outputs[0].points.front(), Eigen::Vector2d(150, 359));
    EXPECT_EQ(set.outputs[0].points.back(), Eigen::Vector2d(117.7, 250));
    EXPECT_EQ(set.outputs[5].points.back(), Eigen::Vector2d(531.4, 100));
    for (std::size_t i = 0; i < 6; ++i) {
        EXPECT_EQ(set.outputs[i].id, "out-" + std::to_string(i + 1));
        EXPECT_EQ(set.outputs[i].from, "in-" + std::to_string(i + 1));
    }
    // The imported set passes the JSON writer's validation and round-trips.
    const std::string path = scratch_dir("flowlines_firepot") + "/fire.flowlines.json";
    write_flowline_set(path, set);
    EXPECT_EQ(read_flowline_set(path), set);
}

TEST(FlowLinesSvg, TransformsAndViewBoxMatchHandComputedPixels) {
    const FlowLineSet set = import_flowlines_svg(data("transforms.svg"));
    EXPECT_EQ(set.width, 200);
    EXPECT_EQ(set.height, 100);
    EXPECT_EQ(set.description, "transforms & viewBox \xE2\x80\x94 test");
    // viewBox 400x200 on 200x100 pixels: everything is halved last.
    // a: scale(2 3) then translate(10 20): (1,2) -> (2,6) -> (12,26) -> (6,13)
    expect_points(line_by_id(set.inputs, "a").points, {{6, 13}, {8, 16}}, 1e-12, "a");
    // b: rotate(90) about (10,10): (10,0) -> (20,10) -> (30,30) -> (15,15)
    expect_points(line_by_id(set.inputs, "b").points, {{15, 15}, {10, 20}}, 1e-12, "b");
    // c: skewX(45) then translate(5 -5): (10,10) -> (20,10) -> (25,5) -> (35,25) -> (17.5,12.5)
    expect_points(line_by_id(set.inputs, "c").points, {{7.5, 7.5}, {17.5, 12.5}}, 1e-9, "c");
    // d: skewY(45): (10,0) -> (10,10) -> (20,30) -> (10,15)
    expect_points(line_by_id(set.inputs, "d").points, {{5, 10}, {10, 15}}, 1e-9, "d");
    // e: scale(-1 1) then translate(100): (50,50) -> (-50,50) -> (50,50) -> (25,25)
    const FlowLine& e = line_by_id(set.outputs, "e");
    expect_points(e.points, {{50, 0}, {25, 25}}, 1e-12, "e");
    EXPECT_EQ(e.from, "a");
}

TEST(FlowLinesSvg, RelativeCommandsImplicitRepeatsAndNumberSyntax) {
    const FlowLineSet set = import_flowlines_svg(data("relative.svg"));
    EXPECT_EQ(set.width, 100);
    EXPECT_EQ(set.height, 100);
    expect_points(line_by_id(set.inputs, "rel").points, {{10, 10}, {20, 10}, {25, 10}, {25, 15}, {20, 10}}, 0, "rel");
    expect_points(line_by_id(set.inputs, "implicit").points, {{0, 0}, {10, 10}, {20, 0}}, 0, "implicit");
    expect_points(line_by_id(set.inputs, "implicit-rel").points, {{5, 5}, {15, 5}, {15, 15}}, 0, "implicit-rel");
    expect_points(line_by_id(set.inputs, "numbers").points, {{0.5, 0.5}, {10, 20}, {-1, -2}}, 0, "numbers");
    expect_points(line_by_id(set.inputs, "hv").points, {{1, 1}, {11, 1}, {11, 21}, {10, 21}, {10, 20}}, 0, "hv");
    EXPECT_EQ(line_by_id(set.outputs, "o").from, "rel");  // inside a nested group of "output"
}

// ---- Bézier flattening -----------------------------------------------------------

using Curve = std::function<Eigen::Vector2d(double)>;

Curve cubic(Eigen::Vector2d p0, Eigen::Vector2d p1, Eigen::Vector2d p2, Eigen::Vector2d p3) {
    return [=](double t) {
        const double s = 1.0 - t;
        return Eigen::Vector2d(s * s * s * p0 + 3 * s * s * t * p1 + 3 * s * t * t * p2 + t * t * t * p3);
    };
}

Curve quadratic(Eigen::Vector2d p0, Eigen::Vector2d q, Eigen::Vector2d p1) {
    return [=](double t) {
        const double s = 1.0 - t;
        return Eigen::Vector2d(s * s * p0 + 2 * s * t * q + t * t * p1);
    };
}

double distance_to_polyline(const Eigen::Vector2d& p, const Points& polyline) {
    double best = INFINITY;
    for (std::size_t i = 1; i < polyline.size(); ++i) {
        const Eigen::Vector2d a = polyline[i - 1], ab = polyline[i] - a;
        const double t = ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
        best = std::min(best, (p - (a + t * ab)).norm());
    }
    return best;
}

// Distance from p to the curve: dense sampling, then a ternary refinement.
double distance_to_curve(const Eigen::Vector2d& p, const Curve& curve) {
    const int samples = 4000;
    int best_i = 0;
    double best = INFINITY;
    for (int i = 0; i <= samples; ++i) {
        const double d = (curve(double(i) / samples) - p).norm();
        if (d < best) best = d, best_i = i;
    }
    double lo = std::max(0.0, (best_i - 1.0) / samples), hi = std::min(1.0, (best_i + 1.0) / samples);
    for (int k = 0; k < 100; ++k) {
        const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
        if ((curve(m1) - p).norm() < (curve(m2) - p).norm()) hi = m2;
        else lo = m1;
    }
    return std::min(best, (curve(0.5 * (lo + hi)) - p).norm());
}

// The polyline is a flattening of the joined curves: ends exact, every vertex
// on a curve, every curve point within the tolerance of the polyline.
void expect_flattening(const Points& polyline, const std::vector<Curve>& curves, const Eigen::Vector2d& first,
                       const Eigen::Vector2d& last, const std::string& what) {
    ASSERT_GE(polyline.size(), 3u) << what;
    EXPECT_EQ(polyline.front(), first) << what;
    EXPECT_EQ(polyline.back(), last) << what;
    EXPECT_LT(polyline.size(), 200u) << what << ": not adaptive";
    for (const Eigen::Vector2d& vertex : polyline) {
        double d = INFINITY;
        for (const Curve& curve : curves) d = std::min(d, distance_to_curve(vertex, curve));
        EXPECT_LT(d, 1e-6) << what << ": vertex (" << vertex.transpose() << ") is off the curve";
    }
    double worst = 0.0;
    for (const Curve& curve : curves)
        for (int i = 0; i <= 2000; ++i) worst = std::max(worst, distance_to_polyline(curve(i / 2000.0), polyline));
    EXPECT_LE(worst, kFlowLinesSvgTolerancePx + 1e-9) << what;
    EXPECT_GT(worst, 0.01) << what << ": suspiciously exact (over-refined?)";
}

TEST(FlowLinesSvg, BezierFlatteningStaysWithinTolerance) {
    const FlowLineSet set = import_flowlines_svg(data("curves.svg"));
    expect_flattening(line_by_id(set.inputs, "cubic").points, {cubic({10, 100}, {10, 10}, {190, 10}, {190, 100})},
                      {10, 100}, {190, 100}, "cubic");
    expect_flattening(line_by_id(set.inputs, "quad").points, {quadratic({10, 150}, {100, 50}, {190, 150})}, {10, 150},
                      {190, 150}, "quad");
    // S reflects the previous second control point: (2*70-50, 2*190-170) = (90, 210).
    expect_flattening(line_by_id(set.inputs, "smooth").points,
                      {cubic({10, 190}, {30, 170}, {50, 170}, {70, 190}), cubic({70, 190}, {90, 210}, {110, 210}, {130, 190})},
                      {10, 190}, {130, 190}, "smooth");
    // T reflects the previous quadratic control point: (2*20-10, 2*0-20) = (30, -20).
    expect_flattening(line_by_id(set.inputs, "tquad").points,
                      {quadratic({0, 0}, {10, 20}, {20, 0}), quadratic({20, 0}, {30, -20}, {40, 0})}, {0, 0}, {40, 0},
                      "tquad");
    expect_flattening(line_by_id(set.inputs, "relcurve").points, {cubic({10, 10}, {10, 0}, {30, 0}, {30, 10})},
                      {10, 10}, {30, 10}, "relcurve");
    // Drawn at a tenth of the size and scaled up by its transform: the
    // tolerance holds in pixels, not in the path's own units.
    expect_flattening(line_by_id(set.outputs, "big").points, {cubic({10, 10}, {10, 150}, {190, 150}, {190, 10})},
                      {10, 10}, {190, 10}, "big");
    // The S curve's join is kept exactly.
    const Points& smooth = line_by_id(set.inputs, "smooth").points;
    EXPECT_NE(std::find(smooth.begin(), smooth.end(), Eigen::Vector2d(70, 190)), smooth.end());
}

TEST(FlowLinesSvg, InkscapeLayersAndForeignMarkup) {
    std::vector<Problem> warnings;
    const FlowLineSet set = import_flowlines_svg(data("inkscape.svg"), &warnings);
    EXPECT_EQ(set.width, 320);
    EXPECT_EQ(set.height, 240);
    ASSERT_EQ(set.inputs.size(), 2u);  // the path in <defs> is not a line
    ASSERT_EQ(set.outputs.size(), 1u);
    const FlowLine& curve = line_by_id(set.inputs, "path111");
    EXPECT_EQ(curve.points.front(), Eigen::Vector2d(10, 10));  // layer transform translate(0,-10)
    EXPECT_EQ(curve.points.back(), Eigen::Vector2d(40, 40));
    expect_points(line_by_id(set.inputs, "path222").points, {{100, 100}, {200, 100}}, 0, "path222");
    EXPECT_EQ(set.outputs[0].from, "path111");
    const std::string text = joined(warnings, Problem::Severity::warning);
    const std::string file = data("inkscape.svg");
    EXPECT_TRUE(has_line_with(text, {file, "<text id=\"text1\"> (line 46)", "ignored"})) << text;
    EXPECT_TRUE(has_line_with(text, {file, "<path id=\"stray\"> (line 48)", "outside"})) << text;
}

TEST(FlowLinesSvg, IllustratorDoctypeEntitiesCdataAndComments) {
    const std::string svg = R"(<?xml version="1.0" encoding="iso-8859-1"?>
<!-- Generator: Adobe Illustrator 16.0.0, SVG Export Plug-In -->
<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd" [
  <!ENTITY ns_svg "http://www.w3.org/2000/svg">
  <!ENTITY ns_flows "in-&#49;">
]>
<svg xmlns="&ns_svg;" width='50' height="40">
  <style><![CDATA[ g > path { stroke: red } ]]></style>
  <!-- <g id="output"><path id="commented" d="M 0 0 L 1 1"/></g> -->
  <g id="input"><path id='in-1' d="M 1,2&#10;L 3,4"/></g>
  <g id="output"><polyline id="o&amp;1" data-from="&ns_flows;" points="1,1 &#x33;,3"/></g>
</svg>)";
    std::optional<FlowLineSet> set;
    const std::vector<Problem> problems = svg_problems(svg, "illustrator.svg", &set);
    ASSERT_TRUE(set.has_value()) << joined(problems, Problem::Severity::error);
    EXPECT_TRUE(problems.empty()) << joined(problems, Problem::Severity::warning);
    ASSERT_EQ(set->outputs.size(), 1u);
    EXPECT_EQ(set->outputs[0].id, "o&1");
    EXPECT_EQ(set->outputs[0].from, "in-1");  // character references in entity values are expanded
    expect_points(set->outputs[0].points, {{1, 1}, {3, 3}}, 0, "polyline");
    expect_points(set->inputs[0].points, {{1, 2}, {3, 4}}, 0, "path");
}

TEST(FlowLinesSvg, TextEncodings) {
    // A Latin-1 file says so in its XML declaration and is converted.
    const std::string latin1 = "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n"
                               "<svg width=\"9\" height=\"9\"><title>caf\xE9</title><g id=\"input\">"
                               "<path id=\"a\" d=\"M 0 0 L 1 1\"/></g></svg>";
    std::optional<FlowLineSet> set;
    svg_problems(latin1, "latin1.svg", &set);
    ASSERT_TRUE(set);
    EXPECT_EQ(set->description, "caf\xC3\xA9");
    // Undeclared bytes that are not UTF-8 cannot become JSON: refused with the element.
    const std::string broken = "<svg width=\"9\" height=\"9\"><g id=\"input\">\n"
                               "<path id=\"caf\xE9\" d=\"M 0 0 L 1 1\"/></g></svg>";
    const std::string errors = joined(svg_problems(broken, "bytes.svg", &set), Problem::Severity::error);
    EXPECT_FALSE(set);
    EXPECT_TRUE(has_line_with(errors, {"bytes.svg", "(line 2)", "UTF-8"})) << errors;
    EXPECT_TRUE(has_line_with(joined(svg_problems("\xFF\xFE<\0s\0", "wide.svg"), Problem::Severity::error),
                              {"wide.svg", "UTF-16"}));
}

TEST(FlowLinesSvg, UnsupportedConstructsAreNamedWithElementAndLine) {
    const std::string file = data("unsupported.svg");
    const std::string messages = validation_messages([&] { import_flowlines_svg(file); });
    EXPECT_TRUE(has_line_with(messages, {file, "<path id=\"arc\"> (line 3), attribute d", "arcs"})) << messages;
    EXPECT_TRUE(has_line_with(messages, {file, "<circle id=\"ring\"> (line 4)", "cannot be a flow line"})) << messages;
    EXPECT_TRUE(has_line_with(messages, {file, "<path id=\"two-strokes\"> (line 5)", "2 subpaths", "Break Apart"}))
        << messages;
    EXPECT_TRUE(has_line_with(messages, {file, "<use id=\"clone\"> (line 6)", "Unlink Clone"})) << messages;
    EXPECT_TRUE(has_line_with(messages, {file, "<path id=\"no-from\"> (line 10), attribute data-from",
                                         "does not name its input"}))
        << messages;
    EXPECT_TRUE(has_line_with(messages, {file, "<path id=\"bad-from\"> (line 11), attribute data-from", "\"nope\""}))
        << messages;
    EXPECT_FALSE(has_line_with(messages, {"<path id=\"ok\">"})) << messages;
}

TEST(FlowLinesSvg, TruncatedFileIsRefusedWithItsPosition) {
    const std::string full = read_text(shared_path("captures/video-waterfall-cascade/flowlines.svg"));
    const std::string dir = scratch_dir("flowlines_truncated");
    // Inside an attribute value, inside a tag, between elements, before </svg>.
    for (const std::string& cut : {std::string("d=\"M 250,0 L 262"), std::string("<path id=\"out-3\" data"),
                                   std::string("  <g id=\"output\""), std::string("</svg>")}) {
        const std::size_t at = full.find(cut) + cut.size() / 2;
        const std::string path = dir + "/cut_" + std::to_string(at) + ".svg";
        write_text(path, full.substr(0, at));
        const std::string messages = validation_messages([&] { import_flowlines_svg(path); });
        EXPECT_TRUE(has_line_with(messages, {path, "line ", "malformed XML", "truncated"})) << messages;
    }
}

TEST(FlowLinesSvg, MalformedXmlNamesLineAndColumn) {
    struct Case {
        const char* svg;
        const char* field;
        const char* words;
    };
    const Case cases[] = {
        {"<svg width=\"10\" height=\"10\">\n<g id=\"input\">\n</svg>", "line 3, column 1", "does not match <g>"},
        {"<svg width=10 height=\"10\"/>", "line 1, column 12", "not quoted"},
        {"<svg width=\"10\" height=\"10\">\n  <title>a&nbsp;b</title>\n</svg>", "line 2, column 11", "&nbsp;"},
        {"<svg width=\"10\" height=\"10\" width=\"20\"/>", "line 1, column 29", "twice"},
        {"<svg width=\"10\" height=\"10\"/>\n<svg/>", "line 2, column 1", "second element"},
        {"<!-- unterminated <svg/>", "line 1, column 1", "comment"},
    };
    for (const Case& c : cases) {
        const std::string text = joined(svg_problems(c.svg, "bad.svg"), Problem::Severity::error);
        EXPECT_TRUE(has_line_with(text, {"bad.svg", std::string(c.field) + ":", c.words})) << c.svg << "\n" << text;
    }
    const std::string html = joined(svg_problems("<html><body/></html>", "page.svg"), Problem::Severity::error);
    EXPECT_TRUE(has_line_with(html, {"page.svg", "<html> (line 1)", "not an SVG"})) << html;
}

TEST(FlowLinesSvg, PathSyntaxErrorsNameTheElement) {
    auto problems_of = [](const std::string& d, const std::string& transform = "") {
        const std::string svg = "<svg width=\"100\" height=\"100\">\n<g id=\"input\">\n<path id=\"p\" d=\"" + d + "\"" +
                                (transform.empty() ? "" : " transform=\"" + transform + "\"") + "/>\n</g></svg>";
        return joined(svg_problems(svg, "syntax.svg"), Problem::Severity::error);
    };
    EXPECT_TRUE(has_line_with(problems_of("L 1,1 2,2"), {"syntax.svg", "<path id=\"p\"> (line 3), attribute d", "start with M"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 L 2"), {"syntax.svg", "<path id=\"p\">", "expected a number"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 X 2,2"), {"syntax.svg", "<path id=\"p\">", "unknown path command 'X'"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 L 5,5 Z 3"), {"syntax.svg", "<path id=\"p\">", "after Z"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1"), {"syntax.svg", "<path id=\"p\"> (line 3)", "at least 2 points"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 L 1,1"), {"syntax.svg", "<path id=\"p\">", "at least 2 points"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 L 2,2", "translate(1,2,3)"),
                              {"syntax.svg", "<path id=\"p\"> (line 3), attribute transform", "translate() takes 1 or 2"}));
    EXPECT_TRUE(has_line_with(problems_of("M 1,1 L 2,2", "spin(3)"), {"attribute transform", "unknown transform"}));
    EXPECT_TRUE(problems_of("M 1,1 L 2,2", " translate(1 2)\n rotate(-30, 4 ,5) ").empty());
}

TEST(FlowLinesSvg, ImageSizeRules) {
    auto import = [](const std::string& svg_attributes, const std::string& d, std::vector<Problem>& problems) {
        const std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" " + svg_attributes +
                                "><g id=\"input\"><path id=\"p\" d=\"" + d + "\"/></g></svg>";
        std::optional<FlowLineSet> set;
        problems = svg_problems(svg, "size.svg", &set);
        return set;
    };
    std::vector<Problem> problems;
    std::optional<FlowLineSet> set = import("viewBox=\"0 0 320 240\"", "M 0,0 L 320,240", problems);
    ASSERT_TRUE(set);
    EXPECT_EQ(set->width, 320);
    EXPECT_EQ(set->height, 240);

    set = import("width=\"2in\" height=\"1in\" viewBox=\"0 0 192 96\"", "M 0,0 L 192,96", problems);
    ASSERT_TRUE(set);
    EXPECT_EQ(set->width, 192);
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::warning), {"size.svg", "attribute width", "96 per inch"}));
    expect_points(set->inputs[0].points, {{0, 0}, {192, 96}}, 1e-12, "inches");

    // A viewBox of another shape is fitted (xMidYMid meet) ...
    set = import("width=\"200\" height=\"100\" viewBox=\"0 0 100 100\"", "M 0,0 L 100,100", problems);
    ASSERT_TRUE(set);
    expect_points(set->inputs[0].points, {{50, 0}, {150, 100}}, 1e-12, "meet");
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::warning), {"size.svg", "attribute viewBox", "aspect ratio"}));
    // ... or stretched with preserveAspectRatio="none".
    set = import("width=\"200\" height=\"100\" viewBox=\"10 0 100 100\" preserveAspectRatio=\"none\"", "M 10,0 L 110,100",
                 problems);
    ASSERT_TRUE(set);
    expect_points(set->inputs[0].points, {{0, 0}, {200, 100}}, 1e-12, "none");

    set = import("width=\"640.5\" height=\"360\"", "M 0,0 L 1,1", problems);
    EXPECT_FALSE(set);
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::error), {"size.svg", "<svg> (line 1), attribute width", "whole number"}));
    set = import("", "M 0,0 L 1,1", problems);
    EXPECT_FALSE(set);
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::error), {"size.svg", "<svg> (line 1)", "no size"}));
    set = import("width=\"10em\" height=\"10\"", "M 0,0 L 1,1", problems);
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::error), {"size.svg", "attribute width", "\"em\""}));
}

TEST(FlowLinesSvg, MissingGroupsAndIdsAreReported) {
    std::optional<FlowLineSet> set;
    std::vector<Problem> problems =
        svg_problems("<svg width=\"10\" height=\"10\"><g id=\"output\"><path id=\"o\" data-from=\"x\" d=\"M 0 0 L 1 1\"/></g></svg>",
                     "groups.svg", &set);
    const std::string errors = joined(problems, Problem::Severity::error);
    EXPECT_TRUE(has_line_with(errors, {"groups.svg", "<g id=\"input\"> (missing)", "no input flow lines"})) << errors;
    EXPECT_TRUE(has_line_with(errors, {"groups.svg", "<path id=\"o\"> (line 1), attribute data-from", "\"x\""})) << errors;

    problems = svg_problems("<svg width=\"10\" height=\"10\"><g id=\"input\"><path d=\"M 0 0 L 1 1\"/>"
                            "<path id=\"input-1\" d=\"M 0 0 L 2 2\"/></g></svg>",
                            "ids.svg", &set);
    ASSERT_TRUE(set) << joined(problems, Problem::Severity::error);
    EXPECT_EQ(set->inputs[0].id, "input-1-2");  // generated, avoiding the explicit id
    EXPECT_TRUE(has_line_with(joined(problems, Problem::Severity::warning), {"ids.svg", "<path> (line 1)", "no id"}));
}

// ---- export ---------------------------------------------------------------------------

FlowLineSet awkward_set() {
    FlowLineSet set;
    set.width = 640;
    set.height = 360;
    set.description = "edit <with> \"markup\" & ünïcödé";
    set.inputs = {{"in-1", {{0.1, 1.0 / 3.0}, {-0.0, 2.0 / 3.0}, {123.456789012345678, 359.99999999999994}}, {}, ""},
                  {"in&2", {{std::nextafter(100.0, 200.0), 1e-300}, {600.5, 7e-7}, {639.0, 359.0}}, {}, ""}};
    FlowLine moving{"out-2", {}, {}, "in&2"};
    moving.keys = {{3, {{1.0, 2.0}, {3.0, 4.0}}}, {9, {{1.5, 2.0 / 7.0}, {-3.0, 4e-5}}}};
    set.outputs = {{"out-1", {{10.0, 20.0}, {30.25, 40.125}, {-5e-3, 1e2 / 3.0}}, {}, "in-1"}, moving};
    return set;
}

bool same_bits(const Points& a, const Points& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (std::memcmp(a[i].data(), b[i].data(), 2 * sizeof(double)) != 0) return false;
    return true;
}

TEST(FlowLinesSvg, ExportImportRoundTripKeepsCoordinatesBitExact) {
    const FlowLineSet set = awkward_set();
    const std::string svg = flowline_set_to_svg(set);
    std::optional<FlowLineSet> back;
    const std::vector<Problem> problems = svg_problems(svg, "export.svg", &back);
    ASSERT_TRUE(back) << joined(problems, Problem::Severity::error);
    EXPECT_TRUE(problems.empty()) << joined(problems, Problem::Severity::warning);
    EXPECT_EQ(back->width, 640);
    EXPECT_EQ(back->height, 360);
    EXPECT_EQ(back->description, set.description);
    ASSERT_EQ(back->inputs.size(), 2u);
    ASSERT_EQ(back->outputs.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(back->inputs[i].id, set.inputs[i].id);
        EXPECT_TRUE(same_bits(back->inputs[i].points, set.inputs[i].points)) << set.inputs[i].id;
        EXPECT_EQ(back->outputs[i].id, set.outputs[i].id);
        EXPECT_EQ(back->outputs[i].from, set.outputs[i].from);
    }
    EXPECT_TRUE(same_bits(back->outputs[0].points, set.outputs[0].points));
    // A time-varying line goes out as its first key, and says so.
    EXPECT_FALSE(back->outputs[1].is_time_varying());
    EXPECT_TRUE(same_bits(back->outputs[1].points, set.outputs[1].keys[0].points));
    EXPECT_NE(svg.find("<desc>time-varying line with 2 keys (frames 3 to 9)"), std::string::npos);
    EXPECT_NE(svg.find("<path id=\"in-1\" d=\"M 0.1,0.3333333333333333 L -0,0.6666666666666666 L"), std::string::npos)
        << svg;
}

TEST(FlowLinesSvg, ExportedCapturesReimportIdentically) {
    for (const char* capture : {"video-waterfall-cascade", "video-fire-pot"}) {
        const FlowLineSet set = import_flowlines_svg(shared_path(std::string("captures/") + capture + "/flowlines.svg"));
        const std::string path = scratch_dir(std::string("flowlines_export_") + capture) + "/flowlines.svg";
        write_flowlines_svg(path, set, "frames/000001.png");
        EXPECT_EQ(import_flowlines_svg(path), set) << capture;
        EXPECT_NE(read_text(path).find("xlink:href=\"frames/000001.png\""), std::string::npos);
    }
}

TEST(FlowLinesSvg, FailedWriteKeepsThePreviousFile) {
    const std::string path = scratch_dir("flowlines_svg_atomic") + "/flowlines.svg";
    write_flowlines_svg(path, awkward_set());
    const std::string before = read_text(path);
    FlowLineSet bad = awkward_set();
    bad.outputs[0].from = "missing";
    const std::string messages = validation_messages([&] { write_flowlines_svg(path, bad); });
    EXPECT_TRUE(has_line_with(messages, {path, "/outputs/0/from", "missing"})) << messages;
    EXPECT_EQ(read_text(path), before);
}


TEST(FlowLinesSvg, TimeOffsetsOfOutputLinesAreReadAndBadOnesNamed) {
    const std::string head =
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"100\" height=\"80\">"
        "<g id=\"input\"><path id=\"in-1\" d=\"M 10,0 L 10,70\"/></g><g id=\"output\">";
    std::optional<FlowLineSet> set;
    const std::vector<Problem> good = svg_problems(
        head + "<path id=\"out-1\" data-from=\"in-1\" data-time-offset-frames=\" 12 \" d=\"M 30,0 L 30,70\"/></g></svg>",
        "good.svg", &set);
    EXPECT_EQ(joined(good, Problem::Severity::error), "");
    ASSERT_TRUE(set.has_value());
    EXPECT_EQ(set->outputs.at(0).time_offset_frames, 12);
    const std::string bad = joined(
        svg_problems(head + "<path id=\"out-1\" data-from=\"in-1\" data-time-offset-frames=\"1.5\" d=\"M 30,0 L 30,70\"/></g></svg>",
                     "bad.svg"),
        Problem::Severity::error);
    EXPECT_TRUE(has_line_with(bad, {"bad.svg", "data-time-offset-frames", "whole number"})) << bad;
}

}  // namespace
}  // namespace flowvid::formats
