// SVG import and export of flow-line sets: the importer walks the XML
// (svg_xml.hpp) and turns paths into polylines (svg_geometry.hpp); the
// exporter writes what the importer reads. The rules are in
// formats/specs/flowlines.md.

#include "flowvid/formats/flowlines.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include "svg_geometry.hpp"
#include "svg_xml.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <ostream>
#include <set>

namespace flowvid::formats {
namespace {

using namespace svg;

// ---- import ------------------------------------------------------------------------

enum class Role { none, input, output };

struct Frame {
    std::string name;  // local name
    Affine ctm;        // user coordinates of this element -> pixels
    Role role = Role::none;
    bool skip = false;  // not rendered (defs, metadata, foreign namespace, ...)
};

struct ImportedLine {
    FlowLine line;
    std::string element;  // "<path id=\"in-1\"> (line 4)"
    bool broken = false;  // conversion failed (reported); skip geometry checks
    bool generated_id = false;
    std::size_t xml_line = 0;
};

std::string local_name(const std::string& name, bool& foreign) {
    const std::size_t colon = name.find(':');
    foreign = colon != std::string::npos && name.compare(0, colon, "svg") != 0;
    return colon == std::string::npos ? name : name.substr(colon + 1);
}

std::string describe_element(const XmlEvent& event, const std::string& local) {
    const std::string* id = event.attribute("id");
    std::string text = "<" + local;
    if (id) text += " id=\"" + *id + "\"";
    return text + "> (line " + std::to_string(event.line) + ")";
}

bool is_unrendered(const std::string& name) {
    static const std::set<std::string> kNames = {"defs", "symbol", "clipPath", "mask", "marker", "pattern",
                                                 "linearGradient", "radialGradient", "filter", "metadata", "title",
                                                 "desc", "style", "script", "foreignObject"};
    return kNames.count(name) > 0;
}

// Whether the XML declaration names a single-byte Western encoding.
bool is_latin1_declared(const std::string& text) {
    if (text.compare(0, 5, "<?xml") != 0) return false;
    const std::size_t end = text.find("?>");
    const std::size_t at = text.find("encoding", 0);
    if (end == std::string::npos || at == std::string::npos || at > end) return false;
    const std::size_t open = text.find_first_of("\"'", at);
    if (open == std::string::npos || open > end) return false;
    const std::size_t close = text.find(text[open], open + 1);
    if (close == std::string::npos || close > end) return false;
    std::string name = text.substr(open + 1, close - open - 1);
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return name == "iso-8859-1" || name == "latin1" || name == "latin-1" || name == "iso_8859-1" ||
           name == "windows-1252" || name == "cp1252";
}

std::string latin1_to_utf8(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (char c : text) append_utf8(out, static_cast<unsigned char>(c));
    return out;
}

class SvgImporter {
public:
    SvgImporter(const std::string& text, Diagnostics& diagnostics) : m_text(text), m_diag(diagnostics) {}

    std::optional<FlowLineSet> run() {
        if (m_text.compare(0, 2, "\xFE\xFF") == 0 || m_text.compare(0, 2, "\xFF\xFE") == 0) {
            m_diag.error("line 1", "the file is UTF-16 encoded", "save the drawing as UTF-8 (the SVG default)");
            return std::nullopt;
        }
        // Latin-1 files (old Illustrator exports) are read as what they say they are.
        const std::string converted = is_latin1_declared(m_text) ? latin1_to_utf8(m_text) : std::string();
        XmlTokenizer xml(converted.empty() ? m_text : converted, m_diag);
        while (true) {
            XmlEvent event = xml.next();
            if (event.kind == XmlEvent::Kind::failed) return std::nullopt;
            if (event.kind == XmlEvent::Kind::done) break;
            if (event.kind == XmlEvent::Kind::text) {
                if (m_in_title) m_title += event.text;
                continue;
            }
            if (event.kind == XmlEvent::Kind::end) {
                if (m_in_title && m_stack.size() == 2) {
                    m_in_title = false;
                    m_title_done = true;
                }
                m_stack.pop_back();
                continue;
            }
            start_element(event);
        }
        if (!m_svg_found) return std::nullopt;
        return finish();
    }

private:
    void start_element(const XmlEvent& event) {
        bool foreign = false;
        const std::string local = local_name(event.name, foreign);
        if (m_stack.empty()) {
            Frame root;
            root.name = local;
            if (local != "svg" || foreign) {
                m_diag.error("<" + event.name + "> (line " + std::to_string(event.line) + ")",
                             "the document is not an SVG drawing (root element <" + event.name + ">)",
                             "give an SVG file whose root element is <svg>");
                root.skip = true;
            } else {
                m_svg_found = true;
                m_svg_element = describe_element(event, local);
                root.ctm = read_svg_size(event);
                if (event.attribute("transform"))
                    m_diag.error(m_svg_element + ", attribute transform", "a transform on the <svg> element is not supported",
                                 "move the transform to a <g> element around the drawing");
            }
            m_stack.push_back(root);
            return;
        }
        const Frame& parent = m_stack.back();
        Frame frame;
        frame.name = local;
        frame.ctm = parent.ctm;
        frame.role = parent.role;
        frame.skip = parent.skip || foreign || is_unrendered(local);
        if (local == "title" && !foreign && m_stack.size() == 1 && !m_title_done) m_in_title = true;
        if (!frame.skip) {
            const std::string element = describe_element(event, local);
            if (const std::string* transform = event.attribute("transform")) {
                std::string error;
                if (std::optional<Affine> affine = parse_transform(*transform, error))
                    frame.ctm = parent.ctm.after(*affine);
                else
                    m_diag.error(element + ", attribute transform", error,
                                 "write a list of matrix(), translate(), scale(), rotate(), skewX(), skewY()");
            }
            if (local == "g") frame.role = group_role(event, element, parent.role);
            handle_element(event, local, element, frame);
            if (local == "svg") frame.skip = true;  // nested <svg>: refused in handle_element
        }
        m_stack.push_back(frame);
    }

    Role group_role(const XmlEvent& event, const std::string& element, Role parent_role) {
        // The group's id; Inkscape layers carry their name in inkscape:label.
        Role role = Role::none;
        for (const char* key : {"id", "inkscape:label"}) {
            const std::string* value = event.attribute(key);
            if (!value) continue;
            if (*value == "input") role = Role::input;
            if (*value == "output") role = Role::output;
            if (role != Role::none) break;
        }
        if (role == Role::none) return parent_role;
        if (role == Role::input) m_input_group = m_input_group.empty() ? element : m_input_group;
        if (role == Role::output) m_output_group = m_output_group.empty() ? element : m_output_group;
        if (parent_role != Role::none && parent_role != role)
            m_diag.error(element,
                         std::string("the ") + (role == Role::input ? "input" : "output") + " group is inside the " +
                             (parent_role == Role::input ? "input" : "output") + " group",
                         "keep <g id=\"input\"> and <g id=\"output\"> side by side, not nested");
        return role;
    }

    void handle_element(const XmlEvent& event, const std::string& local, const std::string& element,
                        const Frame& frame) {
        static const std::set<std::string> kLineElements = {"path", "polyline", "polygon", "line"};
        static const std::set<std::string> kContainers = {"g", "a", "switch"};
        if (kContainers.count(local)) return;
        if (local == "svg") {
            m_diag.error(element, "nested <svg> elements are not supported",
                         "move its content into the top-level <svg> (in Inkscape: ungroup it)");
            return;
        }
        if (kLineElements.count(local)) {
            if (frame.role == Role::none) {
                m_diag.warning(element, "this " + local + " is outside the groups \"input\" and \"output\": ignored",
                               "move it into <g id=\"input\"> or <g id=\"output\"> if it is a flow line");
                return;
            }
            import_line(event, local, element, frame);
            return;
        }
        if (frame.role == Role::none) return;  // backgrounds, annotations: not ours
        if (local == "circle" || local == "ellipse" || local == "rect" || local == "use") {
            const std::string fix = local == "use" ? "unlink the clone (in Inkscape: Edit > Clone > Unlink Clone) and "
                                                     "convert it to a path"
                                                   : "draw flow lines as open paths or polylines (in Inkscape: "
                                                     "Path > Object to Path, then cut the shape open)";
            m_diag.error(element, "<" + local + "> cannot be a flow line", fix);
            return;
        }
        m_diag.warning(element, "<" + local + "> in a flow-line group is ignored",
                       "move it out of the group \"" + std::string(frame.role == Role::input ? "input" : "output") +
                           "\" (only path, polyline and line elements are flow lines)");
    }

    void import_line(const XmlEvent& event, const std::string& local, const std::string& element, const Frame& frame) {
        ImportedLine imported;
        imported.element = element;
        imported.xml_line = event.line;
        if (const std::string* id = event.attribute("id")) imported.line.id = *id;
        const std::string* from = event.attribute("data-from");
        if (frame.role == Role::output) {
            if (from) imported.line.from = trim(*from);
        } else if (from) {
            m_diag.warning(element + ", attribute data-from", "data-from on an input line is ignored",
                           "only output lines name the input line whose texture they carry: remove it");
        }
        auto refuse = [&](const std::string& field, const std::string& message, const std::string& fix) {
            m_diag.error(element + (field.empty() ? "" : ", attribute " + field), message, fix);
            imported.broken = true;
        };
        if (const std::string* offset = event.attribute("data-time-offset-frames")) {
            const std::string text = trim(*offset);
            std::size_t end = 0;
            const std::optional<double> value = read_number(text, end);
            if (frame.role != Role::output) {
                m_diag.warning(element + ", attribute data-time-offset-frames", "a time offset on an input line is ignored",
                               "only output lines are shown at an offset in time: remove it");
            } else if (!value || end != text.size() || *value != std::floor(*value) || std::abs(*value) > 1e9) {
                refuse("data-time-offset-frames", "\"" + text + "\" is not a whole number of frames",
                       "write an integer, e.g. data-time-offset-frames=\"12\", or remove the attribute");
            } else {
                imported.line.time_offset_frames = static_cast<int>(*value);
            }
        }
        bool closed = false;
        if (local == "path") {
            const std::string* d = event.attribute("d");
            if (!d || trim(*d).empty()) {
                refuse("d", "the path has no path data", "draw the line, or delete the empty path");
            } else {
                PathResult path = convert_path(*d, frame.ctm, kFlowLinesSvgTolerancePx, m_budget);
                if (!path.error.empty()) refuse("d", path.error, path.error_fix);
                imported.line.points = std::move(path.points);
                closed = path.closed;
            }
        } else if (local == "polyline" || local == "polygon") {
            const std::string* points = event.attribute("points");
            std::optional<std::vector<double>> values = points ? read_number_list(*points) : std::nullopt;
            if (!points) {
                refuse("points", "missing", "give the line's points as points=\"x1,y1 x2,y2 ...\"");
            } else if (!values) {
                refuse("points", "not a list of numbers", "write points=\"x1,y1 x2,y2 ...\"");
            } else if (values->size() % 2 != 0) {
                refuse("points", "an odd count of numbers (" + std::to_string(values->size()) + ")",
                       "give an x and a y for every point");
            } else if (values->size() / 2 > m_budget) {
                refuse("points", "too many points", "simplify the line");
            } else {
                for (std::size_t i = 0; i + 1 < values->size(); i += 2)
                    imported.line.points.push_back(frame.ctm.apply({(*values)[i], (*values)[i + 1]}));
                if (local == "polygon" && !imported.line.points.empty()) {
                    imported.line.points.push_back(imported.line.points.front());
                    closed = true;
                }
                m_budget -= imported.line.points.size();
            }
        } else {  // <line x1 y1 x2 y2>
            double coordinates[4] = {0, 0, 0, 0};
            const char* keys[4] = {"x1", "y1", "x2", "y2"};
            for (int k = 0; k < 4; ++k) {
                const std::string* value = event.attribute(keys[k]);
                if (!value) continue;  // SVG's default is 0
                std::string error;
                std::optional<Length> length = parse_length(*value, error);
                if (!length || length->percent || (!length->unit.empty() && length->unit != "px"))
                    refuse(keys[k], length ? "only plain numbers (user units) are supported" : error,
                           "write a number without a unit");
                else
                    coordinates[k] = length->px;
            }
            if (!imported.broken)
                imported.line.points = {frame.ctm.apply({coordinates[0], coordinates[1]}),
                                        frame.ctm.apply({coordinates[2], coordinates[3]})};
        }
        if (closed)
            m_diag.warning(element, "the " + local + " is closed; read as an open line that ends at its start point",
                           "a flow line runs from where the flow starts to where it ends: open the shape");
        remove_repeats(imported.line.points);
        (frame.role == Role::input ? m_inputs : m_outputs).push_back(std::move(imported));
    }

    // Image size from width/height (or the viewBox), and the map from the
    // root's user coordinates (viewBox) to pixels.
    Affine read_svg_size(const XmlEvent& event) {
        const std::string where = m_svg_element;
        std::optional<std::array<double, 4>> view_box;
        if (const std::string* text = event.attribute("viewBox")) {
            std::optional<std::vector<double>> values = read_number_list(*text);
            if (!values || values->size() != 4) {
                m_diag.error(where + ", attribute viewBox", "\"" + *text + "\" is not four numbers",
                             "write viewBox=\"0 0 WIDTH HEIGHT\" in pixels");
                m_size_reported = true;
            } else if (!((*values)[2] > 0.0 && (*values)[3] > 0.0) ||
                       !std::all_of(values->begin(), values->end(), [](double v) { return std::isfinite(v); })) {
                m_diag.error(where + ", attribute viewBox", "the viewBox width and height must be positive",
                             "write viewBox=\"0 0 WIDTH HEIGHT\" in pixels");
                m_size_reported = true;
            } else {
                view_box = std::array<double, 4>{(*values)[0], (*values)[1], (*values)[2], (*values)[3]};
            }
        }
        std::optional<double> size[2];
        const char* keys[2] = {"width", "height"};
        for (int k = 0; k < 2; ++k) {
            const std::string* text = event.attribute(keys[k]);
            if (!text) continue;
            std::string error;
            std::optional<Length> length = parse_length(*text, error);
            if (!length) {
                m_diag.error(where + ", attribute " + keys[k], error, "give the frame size in pixels, e.g. 640");
                m_size_reported = true;
                continue;
            }
            if (length->percent) continue;  // relative to a viewport we do not have: use the viewBox
            if (!length->unit.empty() && length->unit != "px")
                m_diag.warning(where + ", attribute " + keys[k],
                               "size in \"" + length->unit + "\" converted to pixels at 96 per inch",
                               "set the document size in pixels, equal to the video frames");
            size[k] = length->px;
        }
        if (size[0].has_value() != size[1].has_value() && !view_box && !m_size_reported) {
            m_diag.error(where, "only one of width and height is given", "give both, in pixels");
            m_size_reported = true;
        }
        double width = size[0] ? *size[0] : (view_box ? (*view_box)[2] : 0.0);
        double height = size[1] ? *size[1] : (view_box ? (*view_box)[3] : 0.0);
        if (size[0] && !size[1] && view_box) height = width * (*view_box)[3] / (*view_box)[2];
        if (size[1] && !size[0] && view_box) width = height * (*view_box)[2] / (*view_box)[3];
        if (!size[0] && !size[1] && !view_box && !m_size_reported) {
            m_diag.error(where, "the drawing has no size (no width, height or viewBox)",
                         "set width and height to the video frame size in pixels");
            m_size_reported = true;
        }
        for (int k = 0; k < 2 && !m_size_reported; ++k) {
            const double value = k == 0 ? width : height;
            if (!(value >= 1.0 && value <= 1e6) || std::fabs(value - std::round(value)) > 1e-6) {
                m_diag.error(where + ", attribute " + keys[k],
                             std::string("the image ") + keys[k] + " " + std::to_string(value) +
                                 " is not a whole number of pixels",
                             "set the document size to the video frame size in pixels");
                m_size_reported = true;
            }
        }
        if (!m_size_reported) {
            m_set.width = static_cast<int>(std::lround(width));
            m_set.height = static_cast<int>(std::lround(height));
        }
        if (!view_box || m_size_reported) return Affine{};

        // viewBox -> viewport (SVG 1.1, 7.8 and 7.7: preserveAspectRatio).
        const auto [vx, vy, vw, vh] = *view_box;
        double sx = width / vw, sy = height / vh;
        std::string align = "xMidYMid", meet_or_slice = "meet";
        if (const std::string* text = event.attribute("preserveAspectRatio")) {
            std::vector<std::string> words;
            std::size_t pos = 0;
            const std::string s = trim(*text);
            while (pos < s.size()) {
                const std::size_t end = std::min(s.find(' ', pos), s.size());
                if (end > pos) words.push_back(s.substr(pos, end - pos));
                pos = end + 1;
            }
            if (!words.empty() && words.front() == "defer") words.erase(words.begin());
            static const std::set<std::string> kAlign = {"none",     "xMinYMin", "xMidYMin", "xMaxYMin", "xMinYMid",
                                                         "xMidYMid", "xMaxYMid", "xMinYMax", "xMidYMax", "xMaxYMax"};
            if (words.empty() || words.size() > 2 || !kAlign.count(words[0]) ||
                (words.size() == 2 && words[1] != "meet" && words[1] != "slice")) {
                m_diag.error(where + ", attribute preserveAspectRatio", "\"" + *text + "\" is not understood",
                             "remove it, or write e.g. \"xMidYMid meet\" or \"none\"");
            } else {
                align = words[0];
                if (words.size() == 2) meet_or_slice = words[1];
            }
        }
        if (align != "none" && sx != sy) {
            sx = sy = meet_or_slice == "meet" ? std::min(sx, sy) : std::max(sx, sy);
            m_diag.warning(where + ", attribute viewBox",
                           "the viewBox's aspect ratio differs from the image size's; mapped with preserveAspectRatio " +
                               align + " " + meet_or_slice,
                           "make the viewBox and width/height the same shape (ideally viewBox=\"0 0 W H\")");
        }
        double tx = -vx * sx, ty = -vy * sy;
        if (align != "none") {
            const std::string x_align = align.substr(0, 4), y_align = align.substr(4, 4);
            if (x_align == "xMid") tx += (width - vw * sx) / 2.0;
            if (x_align == "xMax") tx += width - vw * sx;
            if (y_align == "YMid") ty += (height - vh * sy) / 2.0;
            if (y_align == "YMax") ty += height - vh * sy;
        }
        if (sx == 1.0 && sy == 1.0 && tx == 0.0 && ty == 0.0) return Affine{};
        return Affine::matrix(sx, 0, 0, sy, tx, ty);
    }

    std::optional<FlowLineSet> finish() {
        std::string description;
        for (char c : m_title) {  // collapse whitespace as a renderer shows it
            const char ch = is_svg_space(c) ? ' ' : c;
            if (ch == ' ' && (description.empty() || description.back() == ' ')) continue;
            description += ch;
        }
        while (!description.empty() && description.back() == ' ') description.pop_back();
        m_set.description = description;

        // Lines without an id get one so outputs can be checked and written;
        // inputs need a real id for data-from to name them.
        std::set<std::string> used;
        for (const auto* list : {&m_inputs, &m_outputs})
            for (const ImportedLine& imported : *list) used.insert(imported.line.id);
        for (auto* list : {&m_inputs, &m_outputs}) {
            const bool output = list == &m_outputs;
            for (std::size_t i = 0; i < list->size(); ++i) {
                ImportedLine& imported = (*list)[i];
                if (!imported.line.id.empty()) continue;
                std::string id = std::string(output ? "output-" : "input-") + std::to_string(i + 1);
                for (int suffix = 2; used.count(id); ++suffix)
                    id = std::string(output ? "output-" : "input-") + std::to_string(i + 1) + "-" + std::to_string(suffix);
                used.insert(id);
                imported.line.id = id;
                imported.generated_id = true;
                m_diag.warning(imported.element, "the line has no id; named \"" + id + "\"",
                               output ? "give the path an id (in Inkscape: Object > Object Properties)"
                                      : "give the path an id so output lines can name it in data-from");
            }
        }
        std::vector<bool> inputs_broken, outputs_broken;
        for (const ImportedLine& imported : m_inputs) {
            m_set.inputs.push_back(imported.line);
            inputs_broken.push_back(imported.broken);
        }
        for (const ImportedLine& imported : m_outputs) {
            m_set.outputs.push_back(imported.line);
            outputs_broken.push_back(imported.broken);
        }
        auto name = [this](bool output, std::size_t index, const std::string& leaf) -> std::string {
            if (index == detail::kAllLines && leaf == "description") return "<title>";
            if (index == detail::kAllLines) {
                const std::string& group = output ? m_output_group : m_input_group;
                return group.empty() ? std::string(output ? "<g id=\"output\">" : "<g id=\"input\">") + " (missing)"
                                     : group;
            }
            const std::string& element = (output ? m_outputs : m_inputs)[index].element;
            if (leaf == "from") return element + ", attribute data-from";
            if (leaf == "time_offset_frames") return element + ", attribute data-time-offset-frames";
            if (leaf.rfind("points/", 0) == 0) return element + ", point " + leaf.substr(7);
            if (leaf.empty() || leaf == "points" || leaf == "id") return element;
            return element + ", " + leaf;
        };
        Diagnostics checks(m_diag.file());
        detail::check_flowline_set(m_set, checks, name, m_svg_element, &inputs_broken, &outputs_broken);
        for (const Problem& problem : checks.problems())
            if (!(m_size_reported && problem.field == m_svg_element)) m_diag.merge({problem});
        if (m_diag.has_errors()) return std::nullopt;
        return m_set;
    }

    const std::string& m_text;
    Diagnostics& m_diag;
    FlowLineSet m_set;
    std::vector<Frame> m_stack;
    std::vector<ImportedLine> m_inputs, m_outputs;
    std::string m_svg_element = "<svg>";
    std::string m_input_group, m_output_group;
    std::string m_title;
    std::size_t m_budget = kMaxPointsPerDrawing;
    bool m_svg_found = false;
    bool m_size_reported = false;
    bool m_in_title = false;
    bool m_title_done = false;
};

// ---- export ---------------------------------------------------------------------------

std::string xml_escape(const std::string& text) {
    std::string out;
    for (char c : text) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            case '\'': out += "&apos;"; break;
            default: out += c;
        }
    }
    return out;
}

// Shortest text that reads back to the same double (std::to_chars guarantees it).
std::string number_text(double value) {
    char buffer[64];
    auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
    return std::string(buffer, ptr);
}

std::string path_data(const std::vector<Eigen::Vector2d>& points) {
    std::string d;
    for (std::size_t i = 0; i < points.size(); ++i) {
        d += i == 0 ? "M " : " L ";
        d += number_text(points[i].x()) + "," + number_text(points[i].y());
    }
    return d;
}

}  // namespace

std::optional<FlowLineSet> parse_flowlines_svg(const std::string& svg_text, Diagnostics& diagnostics) {
    return SvgImporter(svg_text, diagnostics).run();
}

std::optional<FlowLineSet> parse_flowlines_svg(const std::string& svg_text, const std::string& file_name,
                                               Diagnostics& diagnostics) {
    if (file_name == diagnostics.file()) return parse_flowlines_svg(svg_text, diagnostics);
    Diagnostics local(file_name);
    std::optional<FlowLineSet> set = SvgImporter(svg_text, local).run();
    diagnostics.merge(local.problems());
    return set;
}

FlowLineSet import_flowlines_svg(const std::string& path, std::vector<Problem>* warnings) {
    const std::string text = read_text_file(path);
    Diagnostics diagnostics(path);
    std::optional<FlowLineSet> set = parse_flowlines_svg(text, diagnostics);
    diagnostics.throw_if_errors();
    if (!set) throw ValidationError({Problem{Problem::Severity::error, path, "", "no flow lines could be read", ""}});
    if (warnings) *warnings = diagnostics.warnings();
    return *set;
}

std::string flowline_set_to_svg(const FlowLineSet& set, const std::string& background_href) {
    const std::string w = std::to_string(set.width), h = std::to_string(set.height);
    std::string svg = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
    svg += "<svg xmlns=\"http://www.w3.org/2000/svg\"";
    if (!background_href.empty()) svg += " xmlns:xlink=\"http://www.w3.org/1999/xlink\"";
    svg += " width=\"" + w + "\" height=\"" + h + "\" viewBox=\"0 0 " + w + " " + h + "\">\n";
    if (!set.description.empty()) svg += "  <title>" + xml_escape(set.description) + "</title>\n";
    svg += "  <desc>flowvid flow lines (flowvid.flowlines " + kFlowLinesFormatVersion.to_string() +
           "). Coordinates are pixels, x right, y down. Lines in the group \"input\" follow the flow in the input "
           "video; each line in \"output\" names its input line in data-from. Draw in the direction of flow.</desc>\n";
    if (!background_href.empty())
        svg += "  <image id=\"background\" xlink:href=\"" + xml_escape(background_href) + "\" x=\"0\" y=\"0\" width=\"" +
               w + "\" height=\"" + h + "\"/>\n";
    auto group = [&](const char* id, const char* colour, const std::vector<FlowLine>& lines, bool output) {
        svg += std::string("  <g id=\"") + id + "\" fill=\"none\" stroke=\"" + colour + "\" stroke-width=\"2\">\n";
        for (const FlowLine& line : lines) {
            svg += "    <path id=\"" + xml_escape(line.id) + "\"";
            if (output) svg += " data-from=\"" + xml_escape(line.from) + "\"";
            if (output && line.time_offset_frames != 0)
                svg += " data-time-offset-frames=\"" + std::to_string(line.time_offset_frames) + "\"";
            const std::vector<Eigen::Vector2d>& points = line.keys.empty() ? line.points : line.keys.front().points;
            svg += " d=\"" + path_data(points) + "\"";
            if (line.keys.empty()) {
                svg += "/>\n";
            } else {
                svg += "><desc>time-varying line with " + std::to_string(line.keys.size()) + " keys (frames " +
                       std::to_string(line.keys.front().frame) + " to " + std::to_string(line.keys.back().frame) +
                       "); this path is the key at frame " + std::to_string(line.keys.front().frame) +
                       " only: the other keys live in the .flowlines.json file</desc></path>\n";
            }
        }
        svg += "  </g>\n";
    };
    group("input", "#2060ff", set.inputs, false);
    group("output", "#ff3030", set.outputs, true);
    return svg + "</svg>\n";
}

void write_flowlines_svg(const std::string& path, const FlowLineSet& set, const std::string& background_href) {
    Diagnostics diagnostics(path);
    validate_flowline_set(set, diagnostics);
    diagnostics.throw_if_errors();
    const std::string text = flowline_set_to_svg(set, background_href);
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace flowvid::formats
