#include "diagnose_report.hpp"

// Relative, so the CLI tests can compile this file as it is.
#include "report_html.hpp"

#include "flowvid/gap/effects.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

namespace flowvid::cli {
namespace {

using nlohmann::json;

const char* const kErrorColour = "#c0392b";
const char* const kFloorColour = "#2e86c1";
const char* const kEffectColour = "#1e8449";
const char* const kDriverColour = "#8e8e8e";

// Tolerant readers: a missing key or a value of the wrong type reads as absent.
const json* member(const json& object, const char* key) {
    if (!object.is_object()) return nullptr;
    const auto it = object.find(key);
    return it == object.end() || it->is_null() ? nullptr : &*it;
}

double number(const json& object, const char* key) {
    const json* value = member(object, key);
    return value && value->is_number() ? value->get<double>() : std::nan("");
}

std::string text(const json& object, const char* key) {
    const json* value = member(object, key);
    return value && value->is_string() ? value->get<std::string>() : std::string();
}

bool flag(const json& object, const char* key) {
    const json* value = member(object, key);
    return value && value->is_boolean() && value->get<bool>();
}

const json& object_member(const json& object, const char* key) {
    static const json kEmpty = json::object();
    const json* value = member(object, key);
    return value && value->is_object() ? *value : kEmpty;
}

const json& array(const json& object, const char* key) {
    static const json kEmpty = json::array();
    const json* value = member(object, key);
    return value && value->is_array() ? *value : kEmpty;
}

std::vector<double> numbers(const json& values) {
    std::vector<double> out;
    if (!values.is_array()) return out;
    for (const json& v : values) out.push_back(v.is_number() ? v.get<double>() : std::nan(""));
    return out;
}

std::string join(const std::vector<std::string>& parts, const std::string& separator) {
    std::string out;
    for (std::size_t i = 0; i < parts.size(); ++i) out += (i ? separator : "") + parts[i];
    return out;
}

// "a", "a and b", "a, b and c"
std::string join_and(const std::vector<std::string>& parts) {
    if (parts.size() < 2) return join(parts, "");
    return join(std::vector<std::string>(parts.begin(), parts.end() - 1), ", ") + " and " + parts.back();
}

std::vector<std::string> split(const std::string& value, char separator) {
    std::vector<std::string> parts;
    std::stringstream stream(value);
    std::string part;
    while (std::getline(stream, part, separator))
        if (!part.empty()) parts.push_back(part);
    return parts;
}

std::string value_text(const json& value) {
    if (value.is_string()) return value.get<std::string>();
    if (value.is_number_integer()) return value.dump();
    if (value.is_number()) return html::format_compact(value.get<double>());
    if (value.is_boolean()) return value.get<bool>() ? "yes" : "no";
    if (value.is_null()) return "\xE2\x80\x94";
    return value.dump();
}

std::string yes_no(bool value) { return value ? "yes" : "no"; }

struct Units {
    std::string error;   // the per-frame metric
    std::string driver;  // what drives the motion
};

Units units_of(const std::string& kind) {
    if (kind == "cloth") return {"metric E_k", "pin speed (m/s)"};
    if (kind == "rigid") return {"mean squared edge distance (px\xC2\xB2)", "body speed (m/s)"};
    return {"error", "driver"};
}

// ---------------------------------------------------------------- verdict

std::vector<std::string> labelled_names(const std::vector<std::string>& keys) {
    std::vector<std::string> out;
    for (const std::string& key : keys) out.push_back(gap::labelled_name(key));
    return out;
}

std::string verdict_box(const json& d) {
    const json& gap = object_member(d, "gap");
    const json& verdict = object_member(d, "verdict");
    std::string status = text(verdict, "status");
    const bool detected = member(gap, "detected") ? flag(gap, "detected") : status == "named" || status == "unexplained";
    if (status.empty()) status = detected ? "gap" : "no_gap";
    std::vector<std::string> effects;
    for (const json& e : array(verdict, "effects"))
        if (e.is_string()) effects.push_back(e.get<std::string>());

    std::string css = "verdict warn", headline;
    std::vector<std::string> model_terms;
    for (const json& e : array(verdict, "model_terms"))
        if (e.is_string()) model_terms.push_back(e.get<std::string>());
    if (!member(d, "gap") && !member(d, "verdict")) headline = "No verdict: this diagnosis has neither a gap nor a verdict";
    else if (status == "no_gap" && !model_terms.empty())
        headline = "No gap left once the fabric model has " + join(labelled_names(model_terms), " + ");
    else if (status == "no_gap") css = "verdict good", headline = "No gap: the model explains the footage down to its floor";
    else if (status == "named")
        headline = "Gap detected \xE2\x80\x94 named effect: " + (effects.empty() ? std::string("\xE2\x80\x94") : join(labelled_names(effects), " + "));
    else if (status == "unexplained" && !model_terms.empty())
        css = "verdict bad", headline = "Gap detected \xE2\x80\x94 the fabric model lacks " + join(labelled_names(model_terms), " + ") +
                                        "; the rest unexplained";
    else if (status == "unexplained") css = "verdict bad", headline = "Gap detected \xE2\x80\x94 unexplained";
    else headline = detected ? "Gap detected" : "No gap";

    std::ostringstream out;
    out << "<div class=\"" << css << "\" id=\"verdict\">" << html::element("p", headline, "headline");
    const double error = number(gap, "held_out_error"), floor = number(gap, "held_out_floor");
    if (std::isfinite(error) || std::isfinite(floor))
        out << html::element("p", "Held-out error " + html::format_number(error) + " against a floor of " + html::format_number(floor) +
                                      ": ratio " + html::format_number(number(gap, "ratio")) + " (a gap is declared above " +
                                      html::format_number(number(gap, "threshold")) + ").");
    if (const std::string message = text(verdict, "message"); !message.empty()) out << html::element("p", message);
    if (const std::string cls = text(verdict, "class"); !cls.empty()) {
        const std::vector<std::string> members = split(cls, '|');
        out << html::element("p",
                             "Equivalence class " + cls + ": the footage of one camera cannot tell " + join_and(members) +
                                 " apart, so the class is named rather than one of its members.",
                             "note");
    }
    // The message states the shares closed; older files without one get the figure here.
    if (text(verdict, "message").empty() && (status == "named" || member(verdict, "gap_closed")))
        out << html::element("p", "Fraction of the held-out gap closed: " + html::format_percent(number(verdict, "gap_closed")) + ".");
    if (const std::string next = text(verdict, "next_step"); !next.empty())
        out << html::element("p", "Next step: " + next + ".", "next-step");
    if (member(d, "discretisation_control")) {
        const json& control = d["discretisation_control"];
        const std::string failure = text(control, "failure");
        // A finer mesh may also widen the gap (a negative share): say so in words.
        const double control_closed = number(control, "gap_closed");
        const std::string control_effect = control_closed < 0.0
                                               ? " widens the held-out gap by " + html::format_percent(-control_closed) +
                                                     " (so the model's own mesh does not account for it)."
                                               : " closes " + html::format_percent(control_closed) +
                                                     " of the held-out gap (what the model's own mesh accounts for; a named "
                                                     "effect must close clearly more).";
        out << html::element("p",
                             failure.empty()
                                 ? "Discretisation control: the base model on " + text(control, "refinement") + control_effect
                                 : "Discretisation control: the base model on " + text(control, "refinement") +
                                       " could not be measured (" + failure + "); the verdict stands without it.",
                             "note");
    }
    out << "</div>\n";
    return out.str();
}

// ---------------------------------------------------------------- residual over time

struct FrameRow {
    int frame = 0;
    double time_s = 0.0, error = 0.0, floor = 0.0, driver = 0.0, with_effect = 0.0;
    bool held_out = false;
};

// Held-out runs as shaded intervals reaching halfway to the trained neighbours.
std::vector<html::Band> held_out_bands(const std::vector<FrameRow>& rows) {
    std::vector<html::Band> bands;
    const std::size_t n = rows.size();
    const auto half_step = [&](std::size_t i, std::size_t j) { return 0.5 * (rows[j].time_s - rows[i].time_s); };
    for (std::size_t i = 0; i < n;) {
        if (!rows[i].held_out) {
            ++i;
            continue;
        }
        std::size_t j = i;
        while (j + 1 < n && rows[j + 1].held_out) ++j;
        html::Band band;
        band.x_begin = rows[i].time_s - (i > 0 ? half_step(i - 1, i) : n > 1 ? half_step(0, 1) : 0.0);
        band.x_end = rows[j].time_s + (j + 1 < n ? half_step(j, j + 1) : n > 1 ? half_step(n - 2, n - 1) : 0.0);
        bands.push_back(band);
        i = j + 1;
    }
    return bands;
}

std::string residual_plots(const json& d, const std::vector<std::string>& trials, const Units& units,
                           const std::string& effect_name) {
    std::map<int, std::vector<FrameRow>> by_trial;
    for (const json& f : array(d, "frames")) {
        const double trial = number(f, "trial");
        if (!std::isfinite(trial) || std::fabs(trial) > 1e6) continue;
        FrameRow row;
        const double frame = number(f, "frame");
        row.frame = std::isfinite(frame) ? static_cast<int>(std::clamp(frame, -1e9, 1e9)) : 0;
        row.time_s = number(f, "time_s");
        row.error = number(f, "error");
        row.floor = number(f, "floor");
        row.driver = number(f, "driver");
        row.with_effect = number(f, "error_with_effect");
        row.held_out = flag(f, "held_out");
        by_trial[static_cast<int>(trial)].push_back(row);
    }
    if (by_trial.empty()) return html::element("p", "This diagnosis has no per-frame residuals.", "note");

    std::ostringstream out;
    out << html::element("p",
                         "Error: the model's error against the footage, per frame. Floor: what even a perfect model leaves "
                         "there (chaos, image noise). Shaded: held-out frames, which no refit saw. The driver (grey, dashed, "
                         "right axis) shows when the motion is forced hardest.",
                         "note");
    for (auto& [trial, rows] : by_trial) {
        std::sort(rows.begin(), rows.end(), [](const FrameRow& a, const FrameRow& b) { return a.frame < b.frame; });
        html::LinePlot plot;
        const std::string name = trial >= 0 && static_cast<std::size_t>(trial) < trials.size() ? trials[trial] : "trial " + std::to_string(trial);
        plot.title = "Residual over time: " + name;
        plot.x_label = "time (s)";
        plot.y_label = units.error;
        plot.right_y_label = units.driver;
        plot.band_label = "held-out frames";
        plot.bands = held_out_bands(rows);
        html::Series error{"error", kErrorColour, {}, {}}, floor{"floor", kFloorColour, {}, {}};
        html::Series with_effect{"error with " + effect_name, kEffectColour, {}, {}}, driver{units.driver, kDriverColour, {}, {}};
        driver.right_axis = true;
        driver.dashed = true;
        bool any_effect = false, any_driver = false;
        for (const FrameRow& r : rows) {
            for (html::Series* s : {&error, &floor, &with_effect, &driver}) s->x.push_back(r.time_s);
            error.y.push_back(r.error);
            floor.y.push_back(r.floor);
            with_effect.y.push_back(r.with_effect);
            driver.y.push_back(r.driver);
            any_effect = any_effect || std::isfinite(r.with_effect);
            any_driver = any_driver || (std::isfinite(r.driver) && r.driver != 0.0);
        }
        plot.series = {error, floor};
        if (any_effect) plot.series.push_back(with_effect);
        if (any_driver) plot.series.push_back(driver);
        out << "<figure>" << html::line_plot_svg(plot) << "</figure>\n";
    }
    return out.str();
}

// ---------------------------------------------------------------- maps and spectrum

std::string residual_maps(const json& d) {
    std::ostringstream out;
    for (const json& m : array(d, "maps")) {
        html::HeatMap map;
        const std::string name = text(m, "name");
        map.title = "Residual over " + (name.empty() ? std::string("the map") : name);
        map.units = text(m, "units");
        const double rows = number(m, "rows"), cols = number(m, "cols");
        // More cells than a page can draw (a million rects) is a broken map, not a picture.
        const auto size = [](double n) { return std::isfinite(n) && n >= 1.0 && n <= 4096.0 ? static_cast<int>(n) : 0; };
        map.rows = size(rows);
        map.cols = size(cols);
        map.values = numbers(array(m, "values"));
        if (map.rows == 0 || map.cols == 0 || map.rows * map.cols > 1000000) {
            out << html::element("p", "Map \"" + name + "\" is not drawn: it has " + html::format_number(rows) + " x " +
                                          html::format_number(cols) + " cells.", "note");
            continue;
        }
        out << "<figure>" << html::heat_map_svg(map);
        if (map.values.size() != static_cast<std::size_t>(map.rows) * static_cast<std::size_t>(map.cols))
            out << html::element("figcaption",
                                 "This map has " + std::to_string(map.values.size()) + " values for " + std::to_string(map.rows) +
                                     " x " + std::to_string(map.cols) + " cells; the missing ones are grey.",
                                 "note");
        out << "</figure>\n";
    }
    return out.str();
}

std::string spectrum_plot(const json& d) {
    const json* spectrum = member(d, "spectrum");
    if (!spectrum) return {};
    const std::vector<double> frequency = numbers(array(*spectrum, "frequency_hz"));
    if (frequency.empty()) return {};
    html::LinePlot plot;
    plot.title = "Power spectrum of the residual and of the floor";
    plot.x_label = "frequency (Hz)";
    html::Series residual{"residual", kErrorColour, frequency, numbers(array(*spectrum, "residual_power"))};
    html::Series floor{"floor", kFloorColour, frequency, numbers(array(*spectrum, "floor_power"))};
    // Power spans decades: a log axis when it does. Powers a billion times
    // below the peak (the zero-frequency bin of a mean-removed residual) are
    // round-off, left out rather than stretching the axis over 30 decades.
    double high = 0.0;
    for (const std::vector<double>* values : {&residual.y, &floor.y})
        for (double v : *values)
            if (std::isfinite(v)) high = std::max(high, v);
    double low = high;
    for (const std::vector<double>* values : {&residual.y, &floor.y})
        for (double v : *values)
            if (std::isfinite(v) && v > 1e-9 * high) low = std::min(low, v);
    plot.log_y = high > 100.0 * low;
    if (plot.log_y)
        for (std::vector<double>* values : {&residual.y, &floor.y})
            for (double& v : *values)
                if (!(v > 1e-9 * high)) v = std::nan("");
    plot.y_label = plot.log_y ? "power (log scale)" : "power";
    plot.series = {residual, floor};
    return "<figure>" + html::line_plot_svg(plot) + "</figure>\n" +
           html::element("p",
                         "Power of the residual over frequency next to that of the floor: a peak above the floor at a "
                         "frequency of the motion points to an effect that follows the driving.",
                         "note");
}

// ---------------------------------------------------------------- candidates

std::string candidate_sections(const json& d) {
    std::vector<const json*> candidates;
    for (const json& c : array(d, "candidates"))
        if (c.is_object()) candidates.push_back(&c);
    if (candidates.empty()) return html::element("p", "No candidate effects were screened.", "note");
    // Ranked by screening score, highest first; unscored last.
    std::stable_sort(candidates.begin(), candidates.end(), [](const json* a, const json* b) {
        const double x = number(*a, "screen_score"), y = number(*b, "screen_score");
        if (std::isfinite(x) != std::isfinite(y)) return std::isfinite(x);
        return x > y;
    });

    std::ostringstream out;
    html::BarChart chart;
    chart.title = "Screening score of each candidate effect (ranked)";
    chart.value_label = "screening score";
    for (const json* c : candidates)
        chart.bars.push_back({text(*c, "name"), number(*c, "screen_score"),
                              flag(*c, "passes") ? "#27ae60" : flag(*c, "refitted") ? "#2e86c1" : "#a6a6a6"});
    out << "<figure>" << html::bar_chart_svg(chart) << "</figure>\n"
        << html::element("p", "Green: refitted and passes every test; blue: refitted, fails one; grey: screened only.", "note");

    html::Table ablation;
    ablation.css_class = "ablation";
    ablation.header = {"effect", "domain", "screening score", "refitted", "held-out error", "gap closed", "\xCE\x94" "BIC",
                       "bootstrap stability", "passes", "equivalence class"};
    for (const json* c : candidates) {
        const bool refitted = flag(*c, "refitted");
        const auto refit_number = [&](const char* key) { return refitted ? html::format_number(number(*c, key)) : "\xE2\x80\x94"; };
        ablation.rows.push_back({text(*c, "name"), text(*c, "domain"), html::format_number(number(*c, "screen_score")), yes_no(refitted),
                                 refit_number("held_out_error"),
                                 refitted ? html::format_percent(number(*c, "gap_closed")) : "\xE2\x80\x94", refit_number("delta_bic"),
                                 refit_number("bootstrap_stability"), yes_no(flag(*c, "passes")), text(*c, "equivalence_class")});
        ablation.row_classes.push_back(flag(*c, "passes") ? "pass" : "");
    }
    out << html::element("p",
                         "Every candidate, ranked by its screening score. The best screened were refitted jointly with the base "
                         "parameters and judged on the held-out frames: gap closed is the fraction of the held-out gap (error "
                         "above the floor) that the refit removes; \xCE\x94" "BIC below zero favours the effect despite its extra "
                         "parameters; bootstrap stability is the fraction of resamples (the held-out blocks weighed at random) in "
                         "which it stays the best.",
                         "note")
        << html::table(ablation);

    html::Table parameters;
    parameters.css_class = "effect-parameters";
    parameters.header = {"effect", "parameter", "fitted value"};
    html::Table base;
    base.css_class = "base-changes";
    base.header = {"refit with", "base parameter", "before", "after", "change"};
    for (const json* c : candidates) {
        if (!flag(*c, "refitted")) continue;
        const std::string name = text(*c, "name");
        if (const json* values = member(*c, "parameters"); values && values->is_object())
            for (const auto& [key, value] : values->items()) parameters.rows.push_back({name, key, value_text(value)});
        for (const json& change : array(*c, "base_changes")) {
            const double before = number(change, "before"), after = number(change, "after");
            const std::string relative = before != 0.0 && std::isfinite(before)
                                             ? (after >= before ? "+" : "") + html::format_number(100.0 * (after - before) / std::fabs(before), 2) + "%"
                                             : html::format_number(after - before);
            base.rows.push_back({name, text(change, "key"), html::format_compact(before), html::format_compact(after), relative});
        }
    }
    if (!parameters.rows.empty())
        out << html::element("h2", "Fitted effect parameters") << html::element("p", "Units are in the parameter names (SI).", "note")
            << html::table(parameters);
    if (!base.rows.empty())
        out << html::element("h2", "How the base parameters moved") <<
            html::element("p", "Each refit moves the base model's parameters jointly with the effect's; a large move means "
                               "the base fit was absorbing the effect.", "note")
            << html::table(base);
    return out.str();
}

}  // namespace

std::string diagnosis_report_html(const json& d) {
    const std::string kind = text(d, "kind");
    const Units units = units_of(kind);
    std::vector<std::string> trials;
    for (const json& t : array(d, "trials")) trials.push_back(t.is_string() ? t.get<std::string>() : t.dump());
    const json& verdict = object_member(d, "verdict");
    std::vector<std::string> effects;
    for (const json& e : array(verdict, "effects"))
        if (e.is_string()) effects.push_back(e.get<std::string>());

    std::ostringstream body;
    const std::string title = "flowvid diagnose" + (kind.empty() ? std::string() : ": " + kind + " model");
    body << html::element("h1", title);
    std::string context = trials.empty() ? std::string() : (trials.size() == 1 ? "trial " : "trials ") + join(trials, ", ");
    if (const double seconds = number(d, "seconds"); std::isfinite(seconds))
        context += (context.empty() ? "" : " \xC2\xB7 ") + std::string("diagnosed in ") + html::format_number(seconds) + " s";
    if (!context.empty()) body << html::element("p", context, "muted");
    body << verdict_box(d);

    if (const json* model = member(d, "model"); model && model->is_object() && !model->empty()) {
        html::Table table;
        table.css_class = "model";
        table.header = {"model", "value"};
        for (const auto& [key, value] : model->items()) table.rows.push_back({key, value_text(value)});
        body << html::element("h2", "Model") << html::table(table);
    }
    body << html::element("h2", "Residual over time")
         << residual_plots(d, trials, units, effects.empty() ? std::string("the effect") : join(effects, " + "));
    if (const std::string maps = residual_maps(d); !maps.empty())
        body << html::element("h2", "Where the residual lies")
             << html::element("p", "Residual summed over every frame; row 0 at the top. Grey: nothing seen there.", "note") << maps;
    if (const std::string spectrum = spectrum_plot(d); !spectrum.empty()) body << html::element("h2", "Residual spectrum") << spectrum;
    body << html::element("h2", "Candidate effects") << candidate_sections(d);
    body << html::element("p", "Format flowvid.diagnosis, version " + (member(d, "version") ? value_text(d["version"]) : "\xE2\x80\x94") + ".",
                          "muted");
    return html::page(title, body.str());
}

}  // namespace flowvid::cli
