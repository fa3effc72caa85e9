#include "report_html.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>

namespace flowvid::cli::html {
namespace {

const char* const kDash = "\xE2\x80\x94";  // em dash, for missing values

// SVG coordinates: two decimals is a hundredth of a pixel.
std::string px(double value) {
    char text[32];
    std::snprintf(text, sizeof text, "%.2f", value);
    return text;
}

bool usable(double value, bool log_axis) { return std::isfinite(value) && (!log_axis || value > 0.0); }

// Width of `text` at `font_px`: an estimate (no font metrics offline), a
// little generous so that legends and labels do not collide.
double text_width_px(const std::string& text, double font_px) {
    std::size_t characters = 0;
    for (unsigned char c : text)
        if ((c & 0xC0) != 0x80) ++characters;  // count UTF-8 code points, not bytes
    return 0.62 * font_px * static_cast<double>(characters);
}

std::string text_element(double x, double y, const std::string& text, const std::string& attributes = {}) {
    return "<text x=\"" + px(x) + "\" y=\"" + px(y) + "\"" + (attributes.empty() ? "" : " " + attributes) + ">" + escape(text) +
           "</text>";
}

std::string line_element(double x1, double y1, double x2, double y2, const std::string& stroke) {
    return "<line x1=\"" + px(x1) + "\" y1=\"" + px(y1) + "\" x2=\"" + px(x2) + "\" y2=\"" + px(y2) + "\" stroke=\"" + stroke +
           "\"/>";
}

std::string svg_open(const std::string& css_class, double width, double height, const std::string& title) {
    return "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"" + css_class + "\" width=\"" + px(width) + "\" height=\"" +
           px(height) + "\" viewBox=\"0 0 " + px(width) + ' ' + px(height) +
           "\" font-family=\"sans-serif\" font-size=\"11\" role=\"img\"><title>" + escape(title) + "</title>" +
           text_element(8, 17, title, "font-size=\"13\" font-weight=\"bold\"");
}

// Decade ticks 10^k covering [low, high] (both > 0), at most about eight.
std::vector<double> decade_ticks(double low, double high) {
    int first = static_cast<int>(std::floor(std::log10(low) + 1e-9));
    int last = static_cast<int>(std::ceil(std::log10(high) - 1e-9));
    if (last <= first) {
        --first;
        ++last;
    }
    const int stride = std::max(1, (last - first + 7) / 8);
    last = first + stride * ((last - first + stride - 1) / stride);
    std::vector<double> ticks;
    for (int k = first; k <= last; k += stride) ticks.push_back(std::pow(10.0, k));
    return ticks;
}

std::string decade_label(double value) {
    const int k = static_cast<int>(std::lround(std::log10(value)));
    if (k >= -3 && k <= 5) return format_number(value, 1);
    return "1e" + std::to_string(k);
}

// Ticks for an axis: the data's range widened to round values, or a fixed
// range with the round values inside it.
struct AxisTicks {
    double low = 0.0, high = 1.0;
    std::vector<double> ticks;
};

AxisTicks axis_ticks(double data_low, double data_high, std::optional<double> fixed_low, std::optional<double> fixed_high,
                     bool log_axis, int target_count) {
    AxisTicks axis;
    if (log_axis) {
        if (!(data_low > 0.0) || !std::isfinite(data_low)) data_low = 0.1, data_high = 1.0;
        const std::vector<double> decades = decade_ticks(fixed_low.value_or(data_low), fixed_high.value_or(data_high));
        axis.low = fixed_low.value_or(decades.front());
        axis.high = fixed_high.value_or(decades.back());
        for (double t : decades)
            if (t >= axis.low * (1 - 1e-9) && t <= axis.high * (1 + 1e-9)) axis.ticks.push_back(t);
        return axis;
    }
    const std::vector<double> ticks = nice_ticks(fixed_low.value_or(data_low), fixed_high.value_or(data_high), target_count);
    axis.low = fixed_low.value_or(ticks.front());
    axis.high = fixed_high.value_or(ticks.back());
    if (!(axis.high > axis.low)) axis.high = axis.low + 1.0;
    const double slack = 1e-9 * (axis.high - axis.low);
    for (double t : ticks)
        if (t >= axis.low - slack && t <= axis.high + slack) axis.ticks.push_back(t);
    return axis;
}

// The legend: one entry per named series, then the bands; wrapped into rows.
struct LegendEntry {
    std::string text;
    std::string colour;
    bool dashed = false;
    bool band = false;
    double x = 0.0;
    int row = 0;
};

std::vector<LegendEntry> legend_layout(const LinePlot& plot, double left, double available_px) {
    std::vector<LegendEntry> entries;
    for (const Series& s : plot.series)
        if (!s.name.empty()) entries.push_back({s.name, s.colour, s.dashed, false});
    if (!plot.bands.empty() && !plot.band_label.empty()) entries.push_back({plot.band_label, "#000", false, true});
    double x = left;
    int row = 0;
    for (LegendEntry& e : entries) {
        const double width = 26.0 + text_width_px(e.text, 11) + 16.0;
        if (x > left && x + width > left + available_px) {
            x = left;
            ++row;
        }
        e.x = x;
        e.row = row;
        x += width;
    }
    return entries;
}

int legend_rows(const std::vector<LegendEntry>& entries) { return entries.empty() ? 0 : entries.back().row + 1; }

constexpr double kLegendTop = 30.0, kLegendRow = 16.0;

}  // namespace

std::string escape(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (char c : text) {
        switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        case '\'': out += "&#39;"; break;
        default: out += c;
        }
    }
    return out;
}

std::string format_number(double value, int significant) {
    if (!std::isfinite(value)) return kDash;
    if (value == 0.0) return "0";
    significant = std::clamp(significant, 1, 17);
    // Round to the significant digits first, so 9.996 -> 10.0 gets its decimals
    // from the rounded magnitude.
    char text[64];
    std::snprintf(text, sizeof text, "%.*e", significant - 1, value);
    const double rounded = std::strtod(text, nullptr);
    const double magnitude = std::fabs(rounded);
    if (magnitude >= 1e-3 && magnitude < 1e6) {
        const int exponent = static_cast<int>(std::floor(std::log10(magnitude) + 1e-12));
        const int decimals = std::max(0, significant - 1 - exponent);
        std::snprintf(text, sizeof text, "%.*f", decimals, rounded);
    }
    return text;
}

std::string format_compact(double value, int significant) {
    if (!std::isfinite(value)) return kDash;
    char text[64];
    std::snprintf(text, sizeof text, "%.*g", std::clamp(significant, 1, 17), value);
    return text;
}

std::string format_percent(double fraction) {
    if (!std::isfinite(fraction)) return kDash;
    char text[32];
    std::snprintf(text, sizeof text, "%.0f%%", 100.0 * fraction);
    return std::string(text) == "-0%" ? "0%" : text;
}

std::string page(const std::string& title, const std::string& body_html) {
    std::string out =
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>" +
        escape(title) +
        "</title>\n<style>\n"
        "body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:2em auto;max-width:1140px;"
        "padding:0 1.2em;color:#222;line-height:1.45}\n"
        "h1{font-size:1.55em;margin-bottom:.2em}h2{font-size:1.2em;border-bottom:1px solid #ddd;padding-bottom:.2em;"
        "margin-top:1.8em}h3{font-size:1.02em;margin:1.2em 0 .3em}\n"
        "table{border-collapse:collapse;margin:.6em 0;font-variant-numeric:tabular-nums}"
        "th,td{padding:3px 10px;text-align:right;border-bottom:1px solid #e6e6e6}"
        "th{background:#f4f4f4;font-weight:600}td:first-child,th:first-child{text-align:left}"
        "caption{text-align:left;font-weight:600;padding:4px 0}tr.pass td{background:#eaf6ea}\n"
        ".verdict{border:2px solid #888;border-radius:6px;padding:.8em 1.2em;margin:1.2em 0}"
        ".verdict.good{border-color:#2e7d32;background:#f1f8f1}.verdict.warn{border-color:#b7791f;background:#fdf7ea}"
        ".verdict.bad{border-color:#c0392b;background:#fcf0ef}.verdict p{margin:.3em 0}"
        ".headline{font-size:1.25em;font-weight:700}\n"
        ".note{color:#555;font-size:.92em}.muted{color:#777}figure{margin:.8em 0}svg{max-width:100%;height:auto}\n"
        "</style></head><body>\n" +
        body_html + "\n</body></html>\n";
    return out;
}

std::string element(const std::string& tag, const std::string& text, const std::string& css_class) {
    return "<" + tag + (css_class.empty() ? "" : " class=\"" + escape(css_class) + "\"") + ">" + escape(text) + "</" + tag + ">";
}

std::string table(const Table& t) {
    std::ostringstream out;
    out << "<table" << (t.css_class.empty() ? "" : " class=\"" + escape(t.css_class) + "\"") << '>';
    if (!t.caption.empty()) out << "<caption>" << escape(t.caption) << "</caption>";
    if (!t.header.empty()) {
        out << "<tr>";
        for (const std::string& h : t.header) out << "<th>" << escape(h) << "</th>";
        out << "</tr>";
    }
    for (std::size_t r = 0; r < t.rows.size(); ++r) {
        const bool has_class = r < t.row_classes.size() && !t.row_classes[r].empty();
        out << "<tr" << (has_class ? " class=\"" + escape(t.row_classes[r]) + "\"" : std::string()) << '>';
        for (const std::string& cell : t.rows[r]) out << "<td>" << escape(cell) << "</td>";
        out << "</tr>";
    }
    out << "</table>\n";
    return out.str();
}

// ---------------------------------------------------------------- axes

std::vector<double> nice_ticks(double low, double high, int target_count) {
    if (!std::isfinite(low) || !std::isfinite(high)) low = 0.0, high = 1.0;
    if (high < low) std::swap(low, high);
    if (high == low) {
        const double pad = low == 0.0 ? 1.0 : 0.5 * std::fabs(low);
        low -= low == 0.0 ? 0.0 : pad;
        high += pad;
    }
    const double raw = (high - low) / std::max(1, target_count);
    const double power = std::pow(10.0, std::floor(std::log10(raw)));
    const double fraction = raw / power;
    const double step = (fraction <= 1.0 ? 1.0 : fraction <= 2.0 ? 2.0 : fraction <= 5.0 ? 5.0 : 10.0) * power;
    const long long first = static_cast<long long>(std::floor(low / step + 1e-9));
    const long long last = static_cast<long long>(std::ceil(high / step - 1e-9));
    std::vector<double> ticks;
    for (long long k = first; k <= last && ticks.size() < 1000; ++k) ticks.push_back(static_cast<double>(k) * step);
    if (ticks.size() < 2) ticks.push_back(ticks.empty() ? high : ticks.back() + step);
    return ticks;
}

std::string tick_label(double value, double step) {
    step = std::fabs(step);
    if (std::fabs(value) < 1e-9 * step) value = 0.0;  // no "-0.0" from floating round-off
    if (!(step > 0.0) || step >= 1e6 || step < 1e-4) return format_number(value, 3);
    const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
    char text[48];
    std::snprintf(text, sizeof text, "%.*f", decimals, value);
    return text;
}

// ---------------------------------------------------------------- line plots

PlotFrame plot_frame(const LinePlot& plot) {
    PlotFrame frame;
    frame.log_y = plot.log_y;
    double x_low = std::numeric_limits<double>::infinity(), x_high = -x_low;
    double y_low = x_low, y_high = -x_low, r_low = x_low, r_high = -x_low;
    for (const Series& s : plot.series) {
        const std::size_t n = std::min(s.x.size(), s.y.size());
        const bool log_axis = plot.log_y && !s.right_axis;
        if (s.right_axis) frame.has_right_axis = true;
        for (std::size_t i = 0; i < n; ++i) {
            if (!std::isfinite(s.x[i]) || !usable(s.y[i], log_axis)) continue;
            x_low = std::min(x_low, s.x[i]);
            x_high = std::max(x_high, s.x[i]);
            double& low = s.right_axis ? r_low : y_low;
            double& high = s.right_axis ? r_high : y_high;
            low = std::min(low, s.y[i]);
            high = std::max(high, s.y[i]);
        }
    }
    if (!(x_low <= x_high)) x_low = 0.0, x_high = 1.0;
    const auto from_zero = [&](double& low, double& high) {
        if (!(low <= high)) low = 0.0, high = 1.0;
        if (plot.y_from_zero && low >= 0.0) low = 0.0;
        if (plot.y_from_zero && high <= 0.0) high = 0.0;
    };
    if (!plot.log_y) from_zero(y_low, y_high);
    else if (!(y_low <= y_high)) y_low = 0.1, y_high = 1.0;
    from_zero(r_low, r_high);

    const std::vector<LegendEntry> legend = legend_layout(plot, 8.0, plot.width_px - 16.0);
    frame.left_px = 66.0;
    frame.top_px = kLegendTop + kLegendRow * legend_rows(legend) + 8.0;
    frame.width_px = std::max(40.0, plot.width_px - frame.left_px - (frame.has_right_axis ? 66.0 : 20.0));
    frame.height_px = std::max(40.0, plot.height_px - frame.top_px - 46.0);

    // x spans the data exactly (a time axis widened to round values wastes
    // width); y axes are widened to round ticks so their ends are labelled.
    const bool one_x = x_low == x_high;  // a single frame: one tick at it, not fractions around it
    const double only_x = x_low;
    if (one_x) x_low -= 0.5, x_high += 0.5;
    AxisTicks x = axis_ticks(x_low, x_high, plot.x_min.value_or(x_low), plot.x_max.value_or(x_high), false,
                             std::max(2, static_cast<int>(frame.width_px / 90)));
    if (one_x && !plot.x_min && !plot.x_max) x.ticks = {only_x};
    const int y_count = std::max(2, static_cast<int>(frame.height_px / 45));
    const AxisTicks y = axis_ticks(y_low, y_high, plot.y_min, plot.y_max, plot.log_y, y_count);
    const AxisTicks r = axis_ticks(r_low, r_high, std::nullopt, std::nullopt, false, y_count);
    frame.x_min = x.low, frame.x_max = x.high, frame.x_ticks = x.ticks;
    frame.y_min = y.low, frame.y_max = y.high, frame.y_ticks = y.ticks;
    if (frame.has_right_axis) frame.right_min = r.low, frame.right_max = r.high, frame.right_ticks = r.ticks;
    return frame;
}

std::string line_plot_svg(const LinePlot& plot) {
    const PlotFrame f = plot_frame(plot);
    const double bottom = f.top_px + f.height_px, right = f.left_px + f.width_px;
    const auto map_x = [&](double x) { return f.left_px + f.width_px * (x - f.x_min) / (f.x_max - f.x_min); };
    const auto map_y = [&](double y) {
        if (f.log_y) return bottom - f.height_px * (std::log10(y) - std::log10(f.y_min)) / (std::log10(f.y_max) - std::log10(f.y_min));
        return bottom - f.height_px * (y - f.y_min) / (f.y_max - f.y_min);
    };
    const auto map_right = [&](double y) { return bottom - f.height_px * (y - f.right_min) / (f.right_max - f.right_min); };

    std::ostringstream svg;
    svg << svg_open("line-plot", plot.width_px, plot.height_px, plot.title);

    // Legend: a short stroke (or a shaded box for bands) and the name.
    for (const LegendEntry& e : legend_layout(plot, 8.0, plot.width_px - 16.0)) {
        const double y = kLegendTop + kLegendRow * e.row;
        if (e.band)
            svg << "<rect x=\"" << px(e.x) << "\" y=\"" << px(y - 8) << "\" width=\"20\" height=\"10\" fill=\"#000\" fill-opacity=\"0.09\"/>";
        else
            svg << "<line x1=\"" << px(e.x) << "\" y1=\"" << px(y - 4) << "\" x2=\"" << px(e.x + 20) << "\" y2=\"" << px(y - 4)
                << "\" stroke=\"" << escape(e.colour) << "\" stroke-width=\"2.5\"" << (e.dashed ? " stroke-dasharray=\"5 3\"" : "")
                << "/>";
        svg << text_element(e.x + 26, y, e.text);
    }

    // Bands behind everything, clipped to the plot area.
    for (const Band& b : plot.bands) {
        const double x0 = std::clamp(map_x(std::min(b.x_begin, b.x_end)), f.left_px, right);
        const double x1 = std::clamp(map_x(std::max(b.x_begin, b.x_end)), f.left_px, right);
        if (x1 > x0)
            svg << "<rect class=\"band\" x=\"" << px(x0) << "\" y=\"" << px(f.top_px) << "\" width=\"" << px(x1 - x0) << "\" height=\""
                << px(f.height_px) << "\" fill=\"#000\" fill-opacity=\"0.07\"/>";
    }

    // Grid and ticks.
    const double x_step = f.x_ticks.size() > 1 ? f.x_ticks[1] - f.x_ticks[0] : 1.0;
    for (double t : f.x_ticks) {
        const double x = map_x(t);
        svg << line_element(x, bottom, x, bottom + 4, "#888")
            << text_element(x, bottom + 16, tick_label(t, x_step), "text-anchor=\"middle\"");
    }
    const double y_step = f.y_ticks.size() > 1 ? f.y_ticks[1] - f.y_ticks[0] : 1.0;
    for (double t : f.y_ticks) {
        const double y = map_y(t);
        svg << line_element(f.left_px, y, right, y, "#ececec") << line_element(f.left_px - 4, y, f.left_px, y, "#888")
            << text_element(f.left_px - 7, y + 4, f.log_y ? decade_label(t) : tick_label(t, y_step), "text-anchor=\"end\"");
    }
    if (f.has_right_axis) {
        const double r_step = f.right_ticks.size() > 1 ? f.right_ticks[1] - f.right_ticks[0] : 1.0;
        for (double t : f.right_ticks) {
            const double y = map_right(t);
            svg << line_element(right, y, right + 4, y, "#888") << text_element(right + 7, y + 4, tick_label(t, r_step), "fill=\"#555\"");
        }
        svg << line_element(right, f.top_px, right, bottom, "#888");
        svg << "<text transform=\"translate(" << px(plot.width_px - 8) << ',' << px(f.top_px + f.height_px / 2)
            << ") rotate(90)\" text-anchor=\"middle\" fill=\"#555\">" << escape(plot.right_y_label) << "</text>";
    }
    svg << line_element(f.left_px, f.top_px, f.left_px, bottom, "#888") << line_element(f.left_px, bottom, right, bottom, "#888");
    svg << text_element(f.left_px + f.width_px / 2, plot.height_px - 8, plot.x_label, "text-anchor=\"middle\"");
    svg << "<text transform=\"translate(14," << px(f.top_px + f.height_px / 2) << ") rotate(-90)\" text-anchor=\"middle\">"
        << escape(plot.y_label) << "</text>";

    // Series: one polyline per unbroken run, so a gap in the data shows as a
    // gap. Right-axis series (drivers) first and thinner: context behind the data.
    std::vector<const Series*> order;
    for (const Series& s : plot.series)
        if (s.right_axis) order.push_back(&s);
    for (const Series& s : plot.series)
        if (!s.right_axis) order.push_back(&s);
    for (const Series* series : order) {
        const Series& s = *series;
        const std::size_t n = std::min(s.x.size(), s.y.size());
        const bool log_axis = plot.log_y && !s.right_axis;
        const std::string style = " stroke=\"" + escape(s.colour) + "\"" + (s.dashed ? " stroke-dasharray=\"5 3\"" : "");
        std::size_t i = 0;
        while (i < n) {
            if (!std::isfinite(s.x[i]) || !usable(s.y[i], log_axis)) {
                ++i;
                continue;
            }
            std::size_t end = i;
            while (end < n && std::isfinite(s.x[end]) && usable(s.y[end], log_axis)) ++end;
            const auto point = [&](std::size_t k) {
                return px(map_x(s.x[k])) + ',' + px(s.right_axis ? map_right(s.y[k]) : map_y(s.y[k]));
            };
            if (end - i == 1) {
                const std::string p = point(i);
                const std::size_t comma = p.find(',');
                svg << "<circle data-series=\"" << escape(s.name) << "\" cx=\"" << p.substr(0, comma) << "\" cy=\"" << p.substr(comma + 1)
                    << "\" r=\"3\" fill=\"" << escape(s.colour) << "\"/>";
            } else {
                svg << "<polyline data-series=\"" << escape(s.name) << "\" fill=\"none\" stroke-width=\"" << (s.right_axis ? "1.2" : "1.8")
                    << "\" stroke-linejoin=\"round\""
                    << style << " points=\"";
                for (std::size_t k = i; k < end; ++k) svg << (k > i ? " " : "") << point(k);
                svg << "\"/>";
            }
            i = end;
        }
    }
    svg << "</svg>";
    return svg.str();
}

// ---------------------------------------------------------------- heat maps

const char* const kMissingColour = "#bdbdbd";

std::string scale_colour(double t) {
    // Nine evenly spaced samples of the viridis scale (van der Walt and Smith
    // for matplotlib), interpolated linearly: lightness rises monotonically.
    static constexpr std::array<std::array<int, 3>, 9> kStops{{{0x44, 0x01, 0x54},
                                                               {0x47, 0x2d, 0x7b},
                                                               {0x3b, 0x52, 0x8b},
                                                               {0x2c, 0x72, 0x8e},
                                                               {0x21, 0x90, 0x8c},
                                                               {0x27, 0xad, 0x81},
                                                               {0x5d, 0xc8, 0x63},
                                                               {0xaa, 0xdc, 0x32},
                                                               {0xfd, 0xe7, 0x25}}};
    if (!std::isfinite(t)) return kMissingColour;
    const double position = std::clamp(t, 0.0, 1.0) * (kStops.size() - 1);
    const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(position), kStops.size() - 2);
    const double fraction = position - static_cast<double>(i);
    char text[8];
    int channel[3];
    for (int c = 0; c < 3; ++c)
        channel[c] = static_cast<int>(std::lround(kStops[i][c] + fraction * (kStops[i + 1][c] - kStops[i][c])));
    std::snprintf(text, sizeof text, "#%02x%02x%02x", channel[0], channel[1], channel[2]);
    return text;
}

std::string heat_map_svg(const HeatMap& map) {
    const int rows = std::max(0, map.rows), cols = std::max(0, map.cols);
    const std::size_t cells = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
    double low = std::numeric_limits<double>::infinity(), high = -low;
    bool missing = false;
    for (std::size_t i = 0; i < cells; ++i) {
        const double v = i < map.values.size() ? map.values[i] : std::nan("");
        if (!std::isfinite(v)) {
            missing = true;
            continue;
        }
        low = std::min(low, v);
        high = std::max(high, v);
    }
    if (!(low <= high)) low = 0.0, high = 1.0;
    if (map.from_zero && low >= 0.0) low = 0.0;
    // The scale spans round values, so the colour bar's ends carry labels.
    const std::vector<double> ticks = nice_ticks(low, high, 5);
    const double scale_low = ticks.front(), scale_high = ticks.back();

    // Cells are square; the map is about 420 px on its longer side.
    const double cell = std::clamp(std::floor(420.0 / std::max({rows, cols, 1})), 2.0, 28.0);
    const double left = map.row_label.empty() ? 10.0 : 28.0, top = 30.0;
    const double map_width = cell * cols, map_height = cell * rows;
    const double bar_x = left + map_width + 24.0, bar_height = std::max(map_height, 140.0), bar_width = 14.0;
    const double tick_step = ticks.size() > 1 ? ticks[1] - ticks[0] : 1.0;
    double label_width = 0.0;
    for (double t : ticks) label_width = std::max(label_width, text_width_px(tick_label(t, tick_step), 11));
    const double legend_right = bar_x + bar_width + std::max(8.0 + label_width + 26.0, 5.0 + text_width_px("no data", 11) + 10.0);
    const double width = std::max(legend_right, text_width_px(map.title, 13) + 20.0);
    const double height = top + std::max(map_height, bar_height + (missing ? 26.0 : 0.0)) + (map.col_label.empty() ? 10.0 : 30.0);

    std::ostringstream svg;
    svg << svg_open("heat-map", width, height, map.title);
    const bool tooltips = cells <= 2500;
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const std::size_t i = static_cast<std::size_t>(r) * cols + c;
            const double v = i < map.values.size() ? map.values[i] : std::nan("");
            const std::string fill = std::isfinite(v) ? scale_colour((v - scale_low) / (scale_high - scale_low)) : kMissingColour;
            svg << "<rect class=\"cell\" x=\"" << px(left + c * cell) << "\" y=\"" << px(top + r * cell) << "\" width=\"" << px(cell)
                << "\" height=\"" << px(cell) << "\" fill=\"" << fill << '"';
            if (tooltips)
                svg << "><title>row " << r << ", col " << c << ": " << escape(format_number(v)) << ' ' << escape(map.units)
                    << "</title></rect>";
            else
                svg << "/>";
        }
    svg << "<rect x=\"" << px(left) << "\" y=\"" << px(top) << "\" width=\"" << px(map_width) << "\" height=\"" << px(map_height)
        << "\" fill=\"none\" stroke=\"#888\"/>";
    if (!map.row_label.empty())
        svg << "<text transform=\"translate(16," << px(top + map_height / 2) << ") rotate(-90)\" text-anchor=\"middle\">"
            << escape(map.row_label) << "</text>";
    if (!map.col_label.empty()) svg << text_element(left + map_width / 2, top + map_height + 18, map.col_label, "text-anchor=\"middle\"");

    // Colour bar: low at the bottom, in 64 steps.
    const int steps = 64;
    for (int k = 0; k < steps; ++k) {
        const double y = top + bar_height * (1.0 - static_cast<double>(k + 1) / steps);
        svg << "<rect x=\"" << px(bar_x) << "\" y=\"" << px(y) << "\" width=\"" << px(bar_width) << "\" height=\""
            << px(bar_height / steps + 0.3) << "\" fill=\"" << scale_colour((k + 0.5) / steps) << "\"/>";
    }
    svg << "<rect x=\"" << px(bar_x) << "\" y=\"" << px(top) << "\" width=\"" << px(bar_width) << "\" height=\"" << px(bar_height)
        << "\" fill=\"none\" stroke=\"#888\"/>";
    for (double t : ticks) {
        const double y = top + bar_height * (1.0 - (t - scale_low) / (scale_high - scale_low));
        svg << line_element(bar_x + bar_width, y, bar_x + bar_width + 4, y, "#888")
            << text_element(bar_x + bar_width + 7, y + 4, tick_label(t, tick_step));
    }
    svg << "<text transform=\"translate(" << px(bar_x + bar_width + 12 + label_width + 10) << ',' << px(top + bar_height / 2)
        << ") rotate(90)\" text-anchor=\"middle\">" << escape(map.units) << "</text>";
    if (missing) {
        const double y = top + bar_height + 10;
        svg << "<rect x=\"" << px(bar_x) << "\" y=\"" << px(y) << "\" width=\"" << px(bar_width) << "\" height=\"10\" fill=\""
            << kMissingColour << "\"/>" << text_element(bar_x + bar_width + 5, y + 9, "no data");
    }
    svg << "</svg>";
    return svg.str();
}

// ---------------------------------------------------------------- bar charts

std::string bar_chart_svg(const BarChart& chart) {
    double low = 0.0, high = 0.0, label_width = 0.0;
    for (const Bar& b : chart.bars) {
        if (std::isfinite(b.value)) low = std::min(low, b.value), high = std::max(high, b.value);
        label_width = std::max(label_width, text_width_px(b.label, 11));
    }
    if (high == low) high = low + 1.0;
    const double left = std::min(260.0, label_width + 20.0), right_margin = 70.0, top = 30.0, row = 22.0, bar = 15.0;
    const double plot_width = std::max(60.0, chart.width_px - left - right_margin);
    const std::vector<double> ticks = nice_ticks(low, high, std::max(2, static_cast<int>(plot_width / 90)));
    const double axis_low = ticks.front(), axis_high = ticks.back();
    const auto map_x = [&](double v) { return left + plot_width * (v - axis_low) / (axis_high - axis_low); };
    const double bottom = top + row * static_cast<double>(chart.bars.size());
    const double height = bottom + 44.0;

    std::ostringstream svg;
    svg << svg_open("bar-chart", chart.width_px, height, chart.title);
    const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : 1.0;
    for (double t : ticks) {
        const double x = map_x(t);
        svg << line_element(x, top, x, bottom, "#ececec") << line_element(x, bottom, x, bottom + 4, "#888")
            << text_element(x, bottom + 16, tick_label(t, step), "text-anchor=\"middle\"");
    }
    for (std::size_t i = 0; i < chart.bars.size(); ++i) {
        const Bar& b = chart.bars[i];
        const double y = top + row * static_cast<double>(i) + (row - bar) / 2;
        svg << text_element(left - 6, y + bar - 3, b.label, "text-anchor=\"end\"");
        if (std::isfinite(b.value)) {
            const double x0 = std::min(map_x(0.0), map_x(b.value)), x1 = std::max(map_x(0.0), map_x(b.value));
            svg << "<rect class=\"bar\" x=\"" << px(x0) << "\" y=\"" << px(y) << "\" width=\"" << px(std::max(x1 - x0, 0.5))
                << "\" height=\"" << px(bar) << "\" fill=\"" << escape(b.colour) << "\"/>";
            svg << text_element(x1 + 4, y + bar - 3, format_number(b.value));
        } else {
            svg << text_element(map_x(0.0) + 4, y + bar - 3, format_number(b.value), "fill=\"#777\"");
        }
    }
    svg << line_element(map_x(0.0), top, map_x(0.0), bottom, "#888") << line_element(left, bottom, left + plot_width, bottom, "#888");
    svg << text_element(left + plot_width / 2, height - 8, chart.value_label, "text-anchor=\"middle\"");
    svg << "</svg>";
    return svg.str();
}

}  // namespace flowvid::cli::html
