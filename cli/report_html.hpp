#pragma once
// Self-contained HTML reports (eval.html, report.html, index.html): escaping,
// a page wrapper with inline CSS, tables, and inline SVG charts -- line plots,
// heat maps and bar charts. Nothing refers to an outside resource (no scripts,
// fonts or stylesheets), so a report opens offline and can be mailed as one
// file. Output is deterministic: the same input gives the same bytes.
//
// Text arguments (titles, labels, cells) are plain text and are escaped here;
// arguments named `*_html` are markup and are inserted as they are.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace flowvid::cli::html {

// Replaces & < > " ' by entities: safe in element text and quoted attributes
// of HTML and SVG alike.
std::string escape(std::string_view text);

// A value for people: `significant` digits, no exponent between 1e-3 and 1e6,
// an em dash for NaN or infinity (missing values read as missing, not "nan").
std::string format_number(double value, int significant = 3);
// The shortest form with at most `significant` digits (printf %g): 0.8, 2.4e-06,
// 12; for values read back (parameters) rather than compared down a column.
std::string format_compact(double value, int significant = 4);
// 0.734 -> "73%"; an em dash for NaN.
std::string format_percent(double fraction);

// A complete HTML document: `title` (text) in <title>, then `body_html` (which
// brings its own <h1>). The CSS is inline and also styles the classes reports
// use: .verdict with .good / .warn / .bad, .headline, .note, .muted, tr.pass.
std::string page(const std::string& title, const std::string& body_html);
// <tag class="css_class">escaped text</tag>; the class is left out when empty.
std::string element(const std::string& tag, const std::string& text, const std::string& css_class = {});

// ---------------------------------------------------------------- tables

struct Table {
    std::string css_class;                          // on <table>, e.g. "ablation"
    std::string caption;                            // text; none when empty
    std::vector<std::string> header;                // text
    std::vector<std::vector<std::string>> rows;     // text, one vector per row
    std::vector<std::string> row_classes;           // optional css class per row (same order as rows)
};
// Cells are escaped; the first column is left-aligned, the others right-aligned
// (numbers line up).
std::string table(const Table& table);

// ---------------------------------------------------------------- axes

// Round tick values covering [low, high]: steps of 1, 2 or 5 times a power of
// ten, about `target_count` of them, the first <= low and the last >= high.
// An empty or degenerate range is widened first.
std::vector<double> nice_ticks(double low, double high, int target_count = 5);
// A tick's label: as many decimals as the step needs and no more.
std::string tick_label(double value, double step);

// ---------------------------------------------------------------- line plots

struct Series {
    std::string name;            // legend text
    std::string colour;          // CSS colour, e.g. "#c0392b"
    std::vector<double> x;       // same length as y
    std::vector<double> y;       // NaN (or <= 0 on a log axis) leaves a gap: the line breaks there
    bool right_axis = false;     // plotted against the second y axis (a "driver" such as pin speed)
    bool dashed = false;
};

// A shaded interval of x (e.g. held-out frames), drawn behind the lines.
struct Band {
    double x_begin = 0.0;
    double x_end = 0.0;
};

struct LinePlot {
    std::string title;
    std::string x_label;             // with units: "time (s)"
    std::string y_label;             // left axis, with units
    std::string right_y_label;       // second axis, used when a series has right_axis
    std::vector<Series> series;
    std::vector<Band> bands;
    std::string band_label;          // legend text of the bands ("held-out frames"); none when empty
    double width_px = 720.0;
    double height_px = 280.0;
    bool y_from_zero = true;         // linear axes include 0 when the data are all of one sign
    bool log_y = false;              // left axis logarithmic (decade ticks)
    // Fixed ranges; otherwise x spans the data and y the data widened to round ticks.
    std::optional<double> x_min, x_max, y_min, y_max;
};

// Where a plot's data go: the plot area in pixels (SVG user units from the
// SVG's top left) and the data ranges mapped onto its edges: x spans the
// data (or the fixed range) exactly, the y axes are widened to round ticks
// (decades on a log axis). x maps
// [x_min, x_max] to [left, left + width]; y maps [y_min, y_max] to
// [top + height, top] (log10 of both on a log axis); the right axis maps
// [right_min, right_max] the same way.
struct PlotFrame {
    double left_px = 0.0, top_px = 0.0, width_px = 0.0, height_px = 0.0;
    double x_min = 0.0, x_max = 1.0;
    double y_min = 0.0, y_max = 1.0;
    double right_min = 0.0, right_max = 1.0;
    bool log_y = false;
    bool has_right_axis = false;
    std::vector<double> x_ticks, y_ticks, right_ticks;
};
PlotFrame plot_frame(const LinePlot& plot);

// An <svg class="line-plot"> element. Each unbroken run of a series is one
// <polyline data-series="name">; a run of one point is a <circle>. Right-axis
// series are drawn first (behind the others) and thinner.
std::string line_plot_svg(const LinePlot& plot);

// ---------------------------------------------------------------- heat maps

struct HeatMap {
    std::string title;
    std::string units;               // colour-bar label
    int rows = 0;
    int cols = 0;
    std::vector<double> values;      // `rows x cols`, row-major, row 0 at the top; NaN: nothing there (grey)
    std::string row_label;           // axis texts; none when empty
    std::string col_label;
    bool from_zero = true;           // non-negative maps start their scale at 0
};

// The colour of t in [0, 1] (clamped) on a perceptually ordered scale from
// dark violet through blue and green to yellow: its lightness rises
// monotonically, so it reads in greyscale and for colour-blind readers.
std::string scale_colour(double t);
extern const char* const kMissingColour;  // NaN cells

// An <svg class="heat-map"> element: one <rect class="cell"> per cell and a
// colour bar labelled with round values and the units.
std::string heat_map_svg(const HeatMap& map);

// ---------------------------------------------------------------- bar charts

struct Bar {
    std::string label;
    double value = 0.0;
    std::string colour = "#2e86c1";
};

struct BarChart {
    std::string title;
    std::string value_label;         // axis text with units
    std::vector<Bar> bars;           // drawn top to bottom in this order (rank them first)
    double width_px = 720.0;
};

// An <svg class="bar-chart"> element of horizontal bars, value written at each end.
std::string bar_chart_svg(const BarChart& chart);

}  // namespace flowvid::cli::html
