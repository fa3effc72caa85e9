// The HTML report pieces (cli/report_html, cli/commands/diagnose_report):
// plots put data where their axes say, gaps in data break lines, heat-map
// colours follow the values, text is escaped, and a diagnosis renders with
// and without its optional parts. Also writes report_sample.html into the
// build folder for a person (or a headless browser) to look at.

#include "report_html.hpp"
#include "commands/diagnose_report.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <sstream>
#include <regex>
#include <string>
#include <vector>

using namespace flowvid::cli;
using nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Point {
    double x, y;
};

// The points of every <polyline data-series="name">, one vector per polyline.
std::vector<std::vector<Point>> polylines(const std::string& svg, const std::string& name) {
    std::vector<std::vector<Point>> lines;
    const std::string open = "<polyline data-series=\"" + html::escape(name) + "\"";
    for (std::size_t at = svg.find(open); at != std::string::npos; at = svg.find(open, at + 1)) {
        const std::size_t begin = svg.find("points=\"", at) + 8;
        const std::string points = svg.substr(begin, svg.find('"', begin) - begin);
        std::vector<Point> line;
        std::istringstream stream(points);
        std::string pair;
        while (stream >> pair) {
            const std::size_t comma = pair.find(',');
            line.push_back({std::stod(pair.substr(0, comma)), std::stod(pair.substr(comma + 1))});
        }
        lines.push_back(line);
    }
    return lines;
}

std::size_t count(const std::string& text, const std::string& what) {
    std::size_t n = 0;
    for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
    return n;
}

// Relative luminance of "#rrggbb" (sRGB, Rec. 709 weights).
double luminance(const std::string& colour) {
    const auto linear = [&](int offset) {
        const double c = std::stoi(colour.substr(offset, 2), nullptr, 16) / 255.0;
        return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    };
    return 0.2126 * linear(1) + 0.7152 * linear(3) + 0.0722 * linear(5);
}

std::vector<std::string> cell_fills(const std::string& svg) {
    std::vector<std::string> fills;
    const std::regex cell("<rect class=\"cell\"[^>]*fill=\"(#[0-9a-f]{6})\"");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), cell); it != std::sregex_iterator(); ++it) fills.push_back((*it)[1]);
    return fills;
}

// The section of `text` from `begin` to the next `end`.
std::string section(const std::string& text, const std::string& begin, const std::string& end) {
    const std::size_t from = text.find(begin);
    if (from == std::string::npos) return {};
    return text.substr(from, text.find(end, from) - from);
}

// A diagnosis as the lead's code writes it: two trials of 40 frames at 25 fps,
// held out in blocks of five, three candidates (one passes, one refitted but
// failing, one screened only), a swatch map with unseen cells and a spectrum.
json sample_diagnosis() {
    json frames = json::array();
    for (int trial = 0; trial < 2; ++trial)
        for (int frame = 1; frame <= 40; ++frame) {
            const double t = (frame - 1) / 25.0;
            const double floor = 40.0 + 6.0 * std::sin(3.0 * t + trial);
            const double error = floor + 55.0 + 30.0 * std::sin(2.0 * kPi * 1.2 * t) + 2.0 * frame;
            frames.push_back({{"trial", trial},
                              {"frame", frame},
                              {"time_s", t},
                              {"error", error},
                              {"floor", floor},
                              {"held_out", ((frame - 1) / 5) % 2 == 1},
                              {"driver", 0.35 * std::fabs(std::sin(2.0 * kPi * 1.2 * t))},
                              // One frame without the effect's run: its line breaks there.
                              {"error_with_effect", frame == 20 ? json() : json(floor + 12.0 + 0.2 * frame)}});
        }
    json values = json::array();
    for (int r = 0; r < 12; ++r)
        for (int c = 0; c < 16; ++c)
            values.push_back(r < 2 && c < 3 ? json() : json(0.2 + 3.0 * std::exp(-((c - 11) * (c - 11) + (r - 4) * (r - 4)) / 12.0)));
    json frequency = json::array(), residual = json::array(), floor_power = json::array();
    for (int k = 0; k <= 40; ++k) {  // k = 0: the zero-frequency bin of a mean-removed residual
        const double f = 0.3125 * k;
        frequency.push_back(f);
        residual.push_back(k == 0 ? 1e-33 : 2.0 / (1.0 + f * f) + 40.0 * std::exp(-(f - 1.25) * (f - 1.25) / 0.02));
        floor_power.push_back(k == 0 ? 0.0 : 1.5 / (1.0 + f * f));
    }
    return {{"format", "flowvid.diagnosis"},
            {"version", 1},
            {"kind", "cloth"},
            {"trials", {"cloth-cotton-waving-2", "cloth-cotton-waving-3"}},
            {"model", {{"preset", "cotton.fabric.json"}, {"resolution", "12x12"}, {"bend_N_m", 2.4e-6}}},
            {"gap", {{"detected", true}, {"held_out_error", 131.2}, {"held_out_floor", 42.7}, {"ratio", 3.07}, {"threshold", 1.5}}},
            {"verdict",
             {{"status", "named"},
              {"effects", {"wind"}},
              {"class", ""},
              {"message", "A steady wind of 0.8 m/s across the swatch explains most of the held-out gap."},
              {"gap_closed", 0.62}}},
            {"candidates",
             {{{"name", "pin_lag"},
               {"domain", "cloth"},
               {"screen_score", 3.1},
               {"refitted", true},
               {"parameters", {{"delay_s", 0.012}}},
               {"base_changes", {{{"key", "bend_N_m"}, {"before", 2.4e-6}, {"after", 2.5e-6}}}},
               {"held_out_error", 120.4},
               {"gap_closed", 0.12},
               {"delta_bic", 4.2},
               {"bootstrap_stability", 0.41},
               {"passes", false},
               {"equivalence_class", ""}},
              {{"name", "camera_roll"},
               {"domain", "camera"},
               {"screen_score", 0.4},
               {"refitted", false},
               {"passes", false},
               {"equivalence_class", "camera_roll|gravity_tilt"}},
              {{"name", "wind"},
               {"domain", "cloth"},
               {"screen_score", 7.9},
               {"refitted", true},
               {"parameters", {{"x_m_per_s", 0.8}, {"z_m_per_s", -0.1}}},
               {"base_changes",
                {{{"key", "bend_N_m"}, {"before", 2.4e-6}, {"after", 1.9e-6}}, {{"key", "drag"}, {"before", 0.9}, {"after", 0.6}}}},
               {"held_out_error", 73.0},
               {"gap_closed", 0.62},
               {"delta_bic", -38.5},
               {"bootstrap_stability", 0.93},
               {"passes", true},
               {"equivalence_class", ""}}}},
            {"frames", frames},
            {"maps", {{{"name", "swatch uv"}, {"units", "E_k"}, {"rows", 12}, {"cols", 16}, {"values", values}}}},
            {"spectrum", {{"frequency_hz", frequency}, {"residual_power", residual}, {"floor_power", floor_power}}},
            {"seconds", 412.5}};
}

TEST(ReportHtml, EscapesTheFiveSpecialCharactersEverywhereTextGoes) {
    const std::string nasty = "a<b>&\"'c";
    const std::string escaped = "a&lt;b&gt;&amp;&quot;&#39;c";
    EXPECT_EQ(html::escape(nasty), escaped);

    const std::string page = html::page(nasty, html::element("h1", nasty));
    html::Table table;
    table.header = {nasty};
    table.rows = {{nasty, "1"}};
    table.caption = nasty;
    html::LinePlot plot;
    plot.title = nasty;
    plot.x_label = nasty;
    plot.series = {{nasty, "#000", {0, 1}, {0, 1}}};
    html::HeatMap map;
    map.title = nasty;
    map.units = nasty;
    map.rows = map.cols = 1;
    map.values = {1.0};
    html::BarChart bars;
    bars.title = nasty;
    bars.bars = {{nasty, 1.0}};
    for (const std::string& out : {page, html::table(table), html::line_plot_svg(plot), html::heat_map_svg(map), html::bar_chart_svg(bars)}) {
        EXPECT_EQ(out.find(nasty), std::string::npos) << out;
        EXPECT_NE(out.find(escaped), std::string::npos) << out;
    }
    // Exactly once in <title>, once in the heading: nothing escaped twice.
    EXPECT_EQ(count(page, escaped), 2u);
    EXPECT_EQ(page.find("&amp;amp;"), std::string::npos);
}

TEST(ReportHtml, NiceTicksAreRoundAndCoverTheRange) {
    const auto expect_ticks = [](const std::vector<double>& ticks, const std::vector<double>& expected) {
        ASSERT_EQ(ticks.size(), expected.size());
        for (std::size_t i = 0; i < ticks.size(); ++i) EXPECT_NEAR(ticks[i], expected[i], 1e-12) << i;
    };
    expect_ticks(html::nice_ticks(0.0, 0.87, 5), {0.0, 0.2, 0.4, 0.6, 0.8, 1.0});
    expect_ticks(html::nice_ticks(3.2, 47.0, 5), {0, 10, 20, 30, 40, 50});
    expect_ticks(html::nice_ticks(-7.0, 12.0, 4), {-10, -5, 0, 5, 10, 15});
    const std::vector<double> small = html::nice_ticks(-0.0031, 0.0042, 4);  // step 0.002
    ASSERT_FALSE(small.empty());
    EXPECT_NEAR(small.front(), -0.004, 1e-15);
    EXPECT_NEAR(small.back(), 0.006, 1e-15);
    EXPECT_EQ(html::tick_label(small[2], 0.002), "0.000");
    EXPECT_EQ(html::tick_label(0.6000000000000001, 0.2), "0.6");
    // A degenerate range still gives an axis.
    EXPECT_GE(html::nice_ticks(5.0, 5.0, 5).size(), 2u);
    EXPECT_EQ(html::format_number(0.012345), "0.0123");
    EXPECT_EQ(html::format_number(9.996), "10.0");
    EXPECT_EQ(html::format_number(1234.5), "1230");
    EXPECT_EQ(html::format_number(1e-5), "1.00e-05");
    EXPECT_EQ(html::format_number(std::nan("")), "\xE2\x80\x94");
    EXPECT_EQ(html::format_percent(0.734), "73%");
}

TEST(ReportHtml, LinePlotPutsEveryPointWhereItsAxesSay) {
    html::LinePlot plot;
    plot.title = "mapping";
    plot.right_y_label = "speed (m/s)";
    plot.series = {{"left", "#c00", {0, 1, 2, 3, 4}, {0.1, 0.5, 0.9, 0.3, 0.7}},
                   {"driver", "#888", {0, 1, 2, 3, 4}, {0.0, 2.0, 7.1, 6.0, 3.0}, true}};
    const html::PlotFrame f = html::plot_frame(plot);
    // The data's ranges widened to round ticks: x 0..4, y 0..1 (from zero), right 0..8.
    EXPECT_DOUBLE_EQ(f.x_min, 0.0);
    EXPECT_DOUBLE_EQ(f.x_max, 4.0);
    EXPECT_DOUBLE_EQ(f.y_min, 0.0);
    EXPECT_DOUBLE_EQ(f.y_max, 1.0);
    EXPECT_DOUBLE_EQ(f.right_min, 0.0);
    EXPECT_DOUBLE_EQ(f.right_max, 8.0);
    EXPECT_TRUE(f.has_right_axis);
    EXPECT_GT(f.width_px, 400.0);
    EXPECT_GT(f.height_px, 120.0);
    EXPECT_LE(f.left_px + f.width_px, plot.width_px);
    EXPECT_LE(f.top_px + f.height_px, plot.height_px);

    const std::string svg = html::line_plot_svg(plot);
    const auto check = [&](const std::string& name, double low, double high) {
        const auto lines = polylines(svg, name);
        ASSERT_EQ(lines.size(), 1u) << name;
        const html::Series& s = name == "left" ? plot.series[0] : plot.series[1];
        ASSERT_EQ(lines[0].size(), s.x.size());
        for (std::size_t i = 0; i < s.x.size(); ++i) {
            EXPECT_NEAR(lines[0][i].x, f.left_px + f.width_px * (s.x[i] - f.x_min) / (f.x_max - f.x_min), 0.006) << name << i;
            EXPECT_NEAR(lines[0][i].y, f.top_px + f.height_px * (1.0 - (s.y[i] - low) / (high - low)), 0.006) << name << i;
        }
    };
    check("left", 0.0, 1.0);
    check("driver", 0.0, 8.0);
    // Every round tick is labelled.
    for (const char* label : {">0.0<", ">0.5<", ">1.0<", ">4<", ">8<"}) EXPECT_NE(svg.find(label), std::string::npos) << label;

    // Fixed ranges are used as given, and a log axis maps decades evenly.
    plot.x_min = -1.0, plot.x_max = 9.0, plot.y_min = 0.0, plot.y_max = 2.0;
    const html::PlotFrame fixed = html::plot_frame(plot);
    EXPECT_EQ(fixed.x_min, -1.0);
    EXPECT_EQ(fixed.x_max, 9.0);
    EXPECT_EQ(fixed.y_max, 2.0);
    html::LinePlot log_plot;
    log_plot.log_y = true;
    log_plot.series = {{"power", "#00c", {1, 2, 3}, {0.02, 3.0, 70.0}}};
    const html::PlotFrame lf = html::plot_frame(log_plot);
    EXPECT_EQ(lf.x_min, 1.0);  // x spans the data exactly, round or not
    EXPECT_EQ(lf.x_max, 3.0);
    EXPECT_DOUBLE_EQ(lf.y_min, 0.01);
    EXPECT_DOUBLE_EQ(lf.y_max, 100.0);
    const auto line = polylines(html::line_plot_svg(log_plot), "power");
    ASSERT_EQ(line.size(), 1u);
    for (std::size_t i = 0; i < 3; ++i)
        EXPECT_NEAR(line[0][i].y, lf.top_px + lf.height_px * (1.0 - (std::log10(log_plot.series[0].y[i]) + 2.0) / 4.0), 0.006);
}

TEST(ReportHtml, NanBreaksALineAndALonePointIsADot) {
    const double nan = std::nan("");
    html::LinePlot plot;
    plot.series = {{"e", "#000", {1, 2, 3, 4, 5, 6, 7, 8}, {1, 2, nan, 3, 4, 5, nan, 6}}};
    const std::string svg = html::line_plot_svg(plot);
    const auto lines = polylines(svg, "e");
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_EQ(lines[0].size(), 2u);
    EXPECT_EQ(lines[1].size(), 3u);
    EXPECT_LT(lines[0].back().x, lines[1].front().x);
    EXPECT_EQ(count(svg, "<circle data-series=\"e\""), 1u);  // frame 8 alone
    // A single frame (a static capture) is a dot with one tick under it.
    html::LinePlot single;
    single.series = {{"e", "#000", {1.0}, {934.6}}};
    EXPECT_EQ(html::plot_frame(single).x_ticks, std::vector<double>{1.0});
    EXPECT_EQ(count(html::line_plot_svg(single), "<circle data-series=\"e\""), 1u);
    // A gap in x breaks it too, and a series of only NaN draws nothing.
    plot.series = {{"f", "#000", {1, nan, 3, 4}, {1, 2, 3, 4}}, {"g", "#000", {1, 2}, {nan, nan}}};
    const std::string svg2 = html::line_plot_svg(plot);
    EXPECT_EQ(polylines(svg2, "f").size(), 1u);
    EXPECT_EQ(count(svg2, "data-series=\"f\""), 2u);  // a dot at x = 1 and the line 3..4
    EXPECT_EQ(count(svg2, "data-series=\"g\""), 0u);
}

TEST(ReportHtml, HeatMapColoursRiseWithTheValueAndNanCellsAreGrey) {
    html::HeatMap map;
    map.rows = 2;
    map.cols = 4;
    map.values = {0.0, 0.2, std::nan(""), 0.5, 0.9, 1.3, 0.7, 0.35};
    const std::string svg = html::heat_map_svg(map);
    const std::vector<std::string> fills = cell_fills(svg);
    ASSERT_EQ(fills.size(), 8u);
    EXPECT_EQ(fills[2], html::kMissingColour);
    std::vector<std::pair<double, double>> value_luminance;
    for (std::size_t i = 0; i < fills.size(); ++i)
        if (std::isfinite(map.values[i])) value_luminance.emplace_back(map.values[i], luminance(fills[i]));
    std::sort(value_luminance.begin(), value_luminance.end());
    for (std::size_t i = 1; i < value_luminance.size(); ++i)
        EXPECT_GT(value_luminance[i].second, value_luminance[i - 1].second) << "value " << value_luminance[i].first;
    // The scale spans round values (0..1.5 here) and says where grey comes from.
    EXPECT_NE(svg.find(">1.5<"), std::string::npos);
    EXPECT_NE(svg.find(">no data<"), std::string::npos);
    // The whole scale is monotonic in lightness, not only these cells.
    for (int k = 1; k <= 100; ++k) EXPECT_GT(luminance(html::scale_colour(k / 100.0)), luminance(html::scale_colour((k - 1) / 100.0))) << k;
    // Too few values: the rest are grey rather than read past the end.
    map.values.resize(5);
    const std::vector<std::string> short_fills = cell_fills(html::heat_map_svg(map));
    ASSERT_EQ(short_fills.size(), 8u);
    EXPECT_EQ(short_fills[7], html::kMissingColour);
}

TEST(ReportHtml, BarChartDrawsBarsToScaleInTheGivenOrder) {
    html::BarChart chart;
    chart.bars = {{"wind", 8.0}, {"pin_lag", 2.0}, {"roll", std::nan("")}};
    const std::string svg = html::bar_chart_svg(chart);
    const std::regex bar("<rect class=\"bar\" x=\"([0-9.]+)\" y=\"([0-9.]+)\" width=\"([0-9.]+)\"");
    std::vector<std::array<double, 3>> bars;
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), bar); it != std::sregex_iterator(); ++it)
        bars.push_back({std::stod((*it)[1]), std::stod((*it)[2]), std::stod((*it)[3])});
    ASSERT_EQ(bars.size(), 2u);  // none for the missing value
    EXPECT_NEAR(bars[0][2] / bars[1][2], 4.0, 1e-3);
    EXPECT_LT(bars[0][1], bars[1][1]);
    EXPECT_LT(svg.find(">wind<"), svg.find(">pin_lag<"));
}

TEST(DiagnosisReport, ShowsTheVerdictAPlotPerTrialAndARowPerCandidate) {
    const json d = sample_diagnosis();
    const std::string page = diagnosis_report_html(d);
    // Verdict box first, with the named effect, its message and the gap closed.
    const std::string verdict = section(page, "<div class=\"verdict warn\"", "</div>");
    ASSERT_FALSE(verdict.empty());
    EXPECT_LT(page.find("id=\"verdict\""), page.find("<svg"));
    EXPECT_NE(verdict.find("named effect: wind (a draught past the swatch) [wind]"), std::string::npos) << verdict;
    EXPECT_NE(verdict.find("A steady wind of 0.8 m/s across the swatch explains most of the held-out gap."), std::string::npos);
    // The message states the share closed; the box does not say it again,
    // except for a file whose verdict has no message.
    EXPECT_EQ(verdict.find("62%"), std::string::npos);
    json quiet = d;
    quiet["verdict"]["message"] = "";
    EXPECT_NE(section(diagnosis_report_html(quiet), "<div class=\"verdict warn\"", "</div>").find("62%"), std::string::npos);
    EXPECT_NE(verdict.find("131"), std::string::npos);
    EXPECT_EQ(verdict.find("Equivalence class"), std::string::npos);  // wind belongs to none

    // One residual plot per trial, with the effect, the driver and the held-out blocks.
    EXPECT_EQ(count(page, "<title>Residual over time: "), 2u);
    EXPECT_NE(page.find("<title>Residual over time: cloth-cotton-waving-3</title>"), std::string::npos);
    const std::string first = section(page, "<title>Residual over time: cloth-cotton-waving-2", "</svg>");
    EXPECT_EQ(count(first, "class=\"band\""), 4u);  // frames 6-10, 16-20, 26-30, 36-40
    EXPECT_EQ(polylines(first, "error").size(), 1u);
    EXPECT_EQ(polylines(first, "error with wind").size(), 2u);  // frame 20 has no value
    EXPECT_EQ(polylines(first, "pin speed (m/s)").size(), 1u);
    EXPECT_NE(first.find(">metric E_k<"), std::string::npos);

    EXPECT_EQ(count(page, "class=\"heat-map\""), 1u);
    EXPECT_EQ(cell_fills(page).size(), 12u * 16u);
    // The spectrum spans decades (0.01 .. 40) on a log axis; the zero-frequency
    // bin (round-off) is left out instead of stretching it to 1e-33.
    const std::string spectrum = section(page, "<title>Power spectrum of the residual and of the floor</title>", "</svg>");
    ASSERT_FALSE(spectrum.empty());
    EXPECT_NE(spectrum.find(">power (log scale)<"), std::string::npos);
    EXPECT_NE(spectrum.find(">100<"), std::string::npos);
    EXPECT_EQ(spectrum.find("1e-33"), std::string::npos);
    EXPECT_EQ(spectrum.find(">1e-"), std::string::npos);
    ASSERT_EQ(polylines(spectrum, "residual").size(), 1u);
    EXPECT_EQ(polylines(spectrum, "residual")[0].size(), 40u);

    // The ablation: one row per candidate, ranked by screening score; the passing one marked.
    const std::string ablation = section(page, "<table class=\"ablation\">", "</table>");
    EXPECT_EQ(count(ablation, "<tr"), 1u + 3u);
    EXPECT_LT(ablation.find("<td>wind</td>"), ablation.find("<td>pin_lag</td>"));
    EXPECT_LT(ablation.find("<td>pin_lag</td>"), ablation.find("<td>camera_roll</td>"));
    EXPECT_NE(ablation.find("<tr class=\"pass\"><td>wind</td>"), std::string::npos);
    EXPECT_NE(ablation.find("<td>-38.5</td>"), std::string::npos);
    EXPECT_NE(ablation.find("<td>camera_roll|gravity_tilt</td>"), std::string::npos);
    // Parameters of refitted effects only, and how the base moved (0.9 -> 0.6 is -33%).
    const std::string parameters = section(page, "<table class=\"effect-parameters\">", "</table>");
    EXPECT_EQ(count(parameters, "<tr"), 1u + 3u);
    EXPECT_NE(parameters.find("<td>wind</td><td>x_m_per_s</td><td>0.8</td>"), std::string::npos);
    const std::string base = section(page, "<table class=\"base-changes\">", "</table>");
    EXPECT_NE(base.find("<td>wind</td><td>drag</td><td>0.9</td><td>0.6</td><td>-33%</td>"), std::string::npos);
    EXPECT_EQ(count(base, "<tr"), 1u + 3u);

    EXPECT_NE(page.find("<td>resolution</td><td>12x12</td>"), std::string::npos);
    EXPECT_NE(page.find("version 1."), std::string::npos);

    // Self-contained: nothing fetched from elsewhere.
    for (const char* outside : {"<script", "<link", "src=", "@import", "url("}) EXPECT_EQ(page.find(outside), std::string::npos) << outside;

    // The sample for people and browsers to look at.
    std::ofstream(std::string(FLOWVID_BINARY_DIR) + "/report_sample.html") << page;
}

TEST(DiagnosisReport, NamesTheEquivalenceClassAndAnUnexplainedGap) {
    json d = sample_diagnosis();
    d["verdict"] = {{"status", "named"},
                    {"effects", {"camera_roll"}},
                    {"class", "camera_roll|gravity_tilt"},
                    {"message", "The image is rolled or gravity is tilted: that closes 48 % of the held-out gap."},
                    {"next_step", "check the camera calibration"},
                    {"gap_closed", 0.48}};
    const std::string verdict = section(diagnosis_report_html(d), "<div class=\"verdict", "</div>");
    EXPECT_NE(verdict.find("Equivalence class camera_roll|gravity_tilt"), std::string::npos);
    EXPECT_NE(verdict.find("cannot tell camera_roll and gravity_tilt apart"), std::string::npos);
    EXPECT_EQ(count(verdict, "48"), 1u) << "the share is stated once: " << verdict;
    EXPECT_NE(verdict.find("Next step: check the camera calibration."), std::string::npos);

    d["verdict"] = {{"status", "unexplained"}, {"effects", json::array()}, {"class", ""}, {"message", "No effect passes."}, {"gap_closed", nullptr}};
    const std::string page = diagnosis_report_html(d);
    const std::string unexplained = section(page, "<div class=\"verdict bad\"", "</div>");
    EXPECT_NE(unexplained.find("unexplained"), std::string::npos);
    EXPECT_NE(unexplained.find("No effect passes."), std::string::npos);
    EXPECT_EQ(unexplained.find("gap closed"), std::string::npos);
    // A model term named before an unexplained rest is the headline's finding.
    d["verdict"]["model_terms"] = {"compression_softness"};
    const std::string with_term = section(diagnosis_report_html(d), "<div class=\"verdict bad\"", "</div>");
    EXPECT_NE(with_term.find("the fabric model lacks soft compression (buckling) [compression_softness]; the rest unexplained"),
              std::string::npos)
        << with_term;
}

TEST(DiagnosisReport, SaysInWordsWhetherTheFinerMeshClosesOrWidensTheGap) {
    json d = sample_diagnosis();
    d["discretisation_control"] = {{"refinement", "a 28x28 mesh"}, {"gap_closed", 0.05}, {"discounted_effects", json::array()}, {"failure", nullptr}};
    std::string verdict = section(diagnosis_report_html(d), "<div class=\"verdict", "</div>");
    EXPECT_NE(verdict.find("the base model on a 28x28 mesh closes 5% of the held-out gap"), std::string::npos) << verdict;
    // A finer mesh that widens the gap is not "closes -22%".
    d["discretisation_control"]["gap_closed"] = -0.22;
    verdict = section(diagnosis_report_html(d), "<div class=\"verdict", "</div>");
    EXPECT_NE(verdict.find("the base model on a 28x28 mesh widens the held-out gap by 22%"), std::string::npos) << verdict;
    EXPECT_EQ(verdict.find("-22"), std::string::npos) << verdict;
}

TEST(DiagnosisReport, CopesWithoutMapsSpectrumCandidatesOrRefits) {
    json d = sample_diagnosis();
    d.erase("maps");
    d.erase("spectrum");
    d.erase("candidates");
    d["verdict"] = {{"status", "no_gap"}, {"effects", json::array()}, {"class", ""}, {"message", "Within the floor."}, {"gap_closed", nullptr}};
    d["gap"]["detected"] = false;
    for (json& f : d["frames"]) f["error_with_effect"] = nullptr;
    const std::string page = diagnosis_report_html(d);
    EXPECT_NE(page.find("<div class=\"verdict good\""), std::string::npos);
    EXPECT_NE(page.find("No gap"), std::string::npos);
    EXPECT_EQ(page.find("heat-map"), std::string::npos);
    EXPECT_EQ(page.find("spectrum"), std::string::npos);
    EXPECT_NE(page.find("No candidate effects were screened."), std::string::npos);
    EXPECT_EQ(page.find("error with"), std::string::npos);
    EXPECT_EQ(count(page, "<title>Residual over time: "), 2u);

    // Candidates screened but none refitted: no parameter tables.
    d["candidates"] = {{{"name", "wind"}, {"screen_score", 0.1}, {"refitted", false}, {"passes", false}}};
    const std::string screened = diagnosis_report_html(d);
    EXPECT_EQ(count(section(screened, "<table class=\"ablation\">", "</table>"), "<tr"), 2u);
    EXPECT_EQ(screened.find("effect-parameters"), std::string::npos);
    EXPECT_EQ(screened.find("base-changes"), std::string::npos);

    // Nothing at all, or odd types: still a page, with dashes for what is missing.
    const std::string empty = diagnosis_report_html(json::object());
    EXPECT_NE(empty.find("This diagnosis has no per-frame residuals."), std::string::npos);
    EXPECT_NE(empty.find("</html>"), std::string::npos);
    json odd = {{"gap", {{"held_out_error", "high"}, {"held_out_floor", 2.0}}}, {"frames", {{{"trial", 0}, {"frame", "x"}}}}, {"maps", {{{"rows", 2}}}}};
    EXPECT_NO_THROW(diagnosis_report_html(odd));
}

TEST(DiagnosisReport, EscapesNamesAndMessagesFromTheDiagnosis) {
    json d = sample_diagnosis();
    const std::string nasty = "a<b>&\"'c";
    d["trials"][0] = nasty;
    d["verdict"]["message"] = nasty;
    d["candidates"][0]["name"] = nasty;
    d["model"]["preset"] = nasty;
    const std::string page = diagnosis_report_html(d);
    EXPECT_EQ(page.find(nasty), std::string::npos);
    EXPECT_GE(count(page, "a&lt;b&gt;&amp;&quot;&#39;c"), 5u);  // trial context, plot title (x2), message, candidate, model
}

}  // namespace
