#pragma once
// SVG geometry for the importer (flowlines_svg.cpp): numbers and lengths in
// attributes, transforms, and path data flattened to polylines in pixels.
// The rules are in formats/specs/flowlines.md. Not part of the public
// interface.

#include <Eigen/Core>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace flowvid::formats::svg {

// ---- geometry ---------------------------------------------------------------------

// The affine map p -> [a c; b d] p + [e; f] (SVG's matrix(a b c d e f)).
// `identity` skips the arithmetic so untransformed coordinates stay bit-exact.
struct Affine {
    double a = 1, b = 0, c = 0, d = 1, e = 0, f = 0;
    bool identity = true;

    static Affine matrix(double a, double b, double c, double d, double e, double f) {
        return {a, b, c, d, e, f, false};
    }
    Eigen::Vector2d apply(const Eigen::Vector2d& p) const {
        if (identity) return p;
        return {a * p.x() + c * p.y() + e, b * p.x() + d * p.y() + f};
    }
    // This map after `inner` (inner is applied first).
    Affine after(const Affine& inner) const {
        if (identity) return inner;
        if (inner.identity) return *this;
        return matrix(a * inner.a + c * inner.b, b * inner.a + d * inner.b, a * inner.c + c * inner.d,
                      b * inner.c + d * inner.d, a * inner.e + c * inner.f + e, b * inner.e + d * inner.f + f);
    }
};

// cos and sin of an angle in degrees, exact at multiples of 90 degrees so that
// rotate(90) maps integer coordinates to integer coordinates.
inline std::pair<double, double> cos_sin_degrees(double degrees) {
    const double quarter = degrees / 90.0;
    if (quarter == std::floor(quarter) && std::fabs(quarter) < 1e9) {
        switch (((static_cast<long long>(quarter) % 4) + 4) % 4) {
            case 0: return {1.0, 0.0};
            case 1: return {0.0, 1.0};
            case 2: return {-1.0, 0.0};
            default: return {0.0, -1.0};
        }
    }
    const double radians = degrees * 3.14159265358979323846 / 180.0;
    return {std::cos(radians), std::sin(radians)};
}

inline double distance_to_segment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d ab = b - a;
    const double length2 = ab.squaredNorm();
    if (!(length2 > 0.0)) return (p - a).norm();
    const double t = std::clamp((p - a).dot(ab) / length2, 0.0, 1.0);
    return (p - (a + t * ab)).norm();
}

constexpr int kMaxSubdivisionDepth = 12;                 // at most 4096 segments per curve
constexpr std::size_t kMaxPointsPerDrawing = 2000000;    // guards memory against absurd files

// Appends the flattened cubic Bézier (without p0; p3 exactly). The curve lies
// in the convex hull of its control points, so once both inner control points
// are within `tolerance` of the chord, so is the whole curve.
inline void flatten_cubic(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& p2,
                   const Eigen::Vector2d& p3, double tolerance, int depth, std::vector<Eigen::Vector2d>& out) {
    if (depth >= kMaxSubdivisionDepth ||
        (distance_to_segment(p1, p0, p3) <= tolerance && distance_to_segment(p2, p0, p3) <= tolerance)) {
        out.push_back(p3);
        return;
    }
    // de Casteljau split at t = 1/2.
    const Eigen::Vector2d p01 = 0.5 * (p0 + p1), p12 = 0.5 * (p1 + p2), p23 = 0.5 * (p2 + p3);
    const Eigen::Vector2d p012 = 0.5 * (p01 + p12), p123 = 0.5 * (p12 + p23);
    const Eigen::Vector2d mid = 0.5 * (p012 + p123);
    flatten_cubic(p0, p01, p012, mid, tolerance, depth + 1, out);
    flatten_cubic(mid, p123, p23, p3, tolerance, depth + 1, out);
}

// ---- numbers in attributes ------------------------------------------------------------

inline bool is_svg_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f'; }
inline bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Reads one SVG number at `pos` ([+-]? (digits [. digits?] | . digits) ([eE] [+-]? digits)?).
// "-1-2" reads -1 then -2, "1.5.5" reads 1.5 then .5. Returns nullopt without
// moving when no number starts there (or it overflows: `overflow` set).
inline std::optional<double> read_number(std::string_view s, std::size_t& pos, bool* overflow = nullptr) {
    std::size_t i = pos;
    const std::size_t n = s.size();
    const std::size_t sign_pos = i;
    if (i < n && (s[i] == '+' || s[i] == '-')) ++i;
    const std::size_t mantissa = i;
    while (i < n && is_digit(s[i])) ++i;
    bool digits = i > mantissa;
    if (i < n && s[i] == '.') {
        const std::size_t fraction = ++i;
        while (i < n && is_digit(s[i])) ++i;
        digits = digits || i > fraction;
    }
    if (!digits) return std::nullopt;
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        std::size_t j = i + 1;
        if (j < n && (s[j] == '+' || s[j] == '-')) ++j;
        if (j < n && is_digit(s[j])) {
            while (j < n && is_digit(s[j])) ++j;
            i = j;
        }
    }
    // from_chars takes no leading '+'.
    const std::size_t begin = (s[sign_pos] == '+') ? sign_pos + 1 : sign_pos;
    double value = 0.0;
    auto [ptr, ec] = std::from_chars(s.data() + begin, s.data() + i, value);
    if (ec != std::errc() || ptr != s.data() + i) {
        if (overflow) *overflow = true;
        return std::nullopt;
    }
    pos = i;
    return value;
}

inline void skip_svg_space(std::string_view s, std::size_t& pos) {
    while (pos < s.size() && is_svg_space(s[pos])) ++pos;
}

// Whitespace, then at most one comma, then whitespace.
inline void skip_comma_space(std::string_view s, std::size_t& pos) {
    skip_svg_space(s, pos);
    if (pos < s.size() && s[pos] == ',') {
        ++pos;
        skip_svg_space(s, pos);
    }
}

// A list of numbers separated by whitespace and/or commas; nullopt on junk.
inline std::optional<std::vector<double>> read_number_list(std::string_view s) {
    std::vector<double> values;
    std::size_t pos = 0;
    skip_svg_space(s, pos);
    while (pos < s.size()) {
        std::optional<double> value = read_number(s, pos);
        if (!value) return std::nullopt;
        values.push_back(*value);
        skip_comma_space(s, pos);
    }
    return values;
}

inline std::string trim(std::string_view s) {
    std::size_t begin = 0, end = s.size();
    while (begin < end && is_svg_space(s[begin])) ++begin;
    while (end > begin && is_svg_space(s[end - 1])) --end;
    return std::string(s.substr(begin, end - begin));
}

inline std::string excerpt(std::string_view s, std::size_t pos) {
    const std::size_t begin = pos > 12 ? pos - 12 : 0;
    std::string text(s.substr(begin, 28));
    for (char& c : text)
        if (is_svg_space(c)) c = ' ';
    std::string quoted = "\"";
    if (begin > 0) quoted += "...";
    quoted += text;
    if (begin + 28 < s.size()) quoted += "...";
    quoted += '"';
    return quoted;
}

// transform="translate(10) rotate(30 5 5) ..." composed left to right (the
// rightmost is applied to the points first). Returns nullopt with `error` set.
inline std::optional<Affine> parse_transform(std::string_view s, std::string& error) {
    Affine result;
    std::size_t pos = 0;
    skip_svg_space(s, pos);
    while (pos < s.size()) {
        const std::size_t name_start = pos;
        while (pos < s.size() && ((s[pos] >= 'a' && s[pos] <= 'z') || (s[pos] >= 'A' && s[pos] <= 'Z'))) ++pos;
        const std::string name(s.substr(name_start, pos - name_start));
        skip_svg_space(s, pos);
        if (name.empty() || pos >= s.size() || s[pos] != '(') {
            error = "expected a transform such as translate(x y) at " + excerpt(s, name_start);
            return std::nullopt;
        }
        ++pos;
        std::vector<double> args;
        skip_svg_space(s, pos);
        while (pos < s.size() && s[pos] != ')') {
            std::optional<double> value = read_number(s, pos);
            if (!value) {
                error = "expected a number or ')' in " + name + "(...) at " + excerpt(s, pos);
                return std::nullopt;
            }
            args.push_back(*value);
            skip_comma_space(s, pos);
        }
        if (pos >= s.size()) {
            error = "missing ')' after " + name + "(";
            return std::nullopt;
        }
        ++pos;
        auto count_is = [&](std::initializer_list<std::size_t> allowed) {
            for (std::size_t count : allowed)
                if (args.size() == count) return true;
            std::string list;
            for (std::size_t count : allowed) list += (list.empty() ? "" : " or ") + std::to_string(count);
            error = name + "() takes " + list + " numbers, found " + std::to_string(args.size());
            return false;
        };
        Affine step;
        if (name == "matrix") {
            if (!count_is({6})) return std::nullopt;
            step = Affine::matrix(args[0], args[1], args[2], args[3], args[4], args[5]);
        } else if (name == "translate") {
            if (!count_is({1, 2})) return std::nullopt;
            step = Affine::matrix(1, 0, 0, 1, args[0], args.size() > 1 ? args[1] : 0.0);
        } else if (name == "scale") {
            if (!count_is({1, 2})) return std::nullopt;
            step = Affine::matrix(args[0], 0, 0, args.size() > 1 ? args[1] : args[0], 0, 0);
        } else if (name == "rotate") {
            if (!count_is({1, 3})) return std::nullopt;
            const auto [cos_a, sin_a] = cos_sin_degrees(args[0]);
            step = Affine::matrix(cos_a, sin_a, -sin_a, cos_a, 0, 0);
            if (args.size() == 3)  // rotate(a cx cy) = translate(cx cy) rotate(a) translate(-cx -cy)
                step = Affine::matrix(1, 0, 0, 1, args[1], args[2])
                           .after(step)
                           .after(Affine::matrix(1, 0, 0, 1, -args[1], -args[2]));
        } else if (name == "skewX") {
            if (!count_is({1})) return std::nullopt;
            const auto [cos_a, sin_a] = cos_sin_degrees(args[0]);
            step = Affine::matrix(1, 0, sin_a / cos_a, 1, 0, 0);
        } else if (name == "skewY") {
            if (!count_is({1})) return std::nullopt;
            const auto [cos_a, sin_a] = cos_sin_degrees(args[0]);
            step = Affine::matrix(1, sin_a / cos_a, 0, 1, 0, 0);
        } else {
            error = "unknown transform \"" + name + "\"";
            return std::nullopt;
        }
        result = result.after(step);
        skip_comma_space(s, pos);
    }
    return result;
}

// ---- path data ----------------------------------------------------------------------

struct PathResult {
    std::vector<Eigen::Vector2d> points;  // pixels
    std::string error;                    // non-empty: refused
    std::string error_fix;
    bool closed = false;
};

// Converts path data to one polyline in pixels: user coordinates go through
// `ctm`, then curves are flattened (an affine map keeps a Bézier a Bézier
// with mapped control points, so the tolerance is met in pixels).
inline PathResult convert_path(std::string_view d, const Affine& ctm, double tolerance, std::size_t& budget) {
    PathResult result;
    std::vector<std::vector<Eigen::Vector2d>> subpaths;  // pixels
    Eigen::Vector2d current(0, 0), start(0, 0), last_cubic_control(0, 0), last_quad_control(0, 0);
    std::size_t counted_subpaths = 0, finished_points = 0;  // for the point budget
    char previous = 0;  // previous command, upper case
    char command = 0;
    std::size_t pos = 0;
    auto fail = [&](const std::string& message, const std::string& fix = "") {
        result.error = message;
        result.error_fix = fix.empty() ? "correct the path data (see the SVG path syntax)" : fix;
        result.points.clear();
        return result;
    };
    auto line_to = [&](const Eigen::Vector2d& user) {
        subpaths.back().push_back(ctm.apply(user));
        current = user;
    };
    skip_svg_space(d, pos);
    while (pos < d.size()) {
        const char c = d[pos];
        const std::size_t command_pos = pos;
        if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z')) {
            command = c;
            ++pos;
        } else if (command == 0) {
            return fail("path data must start with M (moveto), found " + excerpt(d, pos));
        } else if (command == 'Z' || command == 'z') {
            return fail("numbers after Z (closepath) at " + excerpt(d, pos));
        } else if (command == 'M') {
            command = 'L';  // coordinates after a moveto are implicit linetos
        } else if (command == 'm') {
            command = 'l';
        }
        const char upper = static_cast<char>(command & ~0x20);
        const bool relative = command >= 'a';
        if (subpaths.empty() && upper != 'M') return fail("path data must start with M (moveto), found " + excerpt(d, command_pos));

        static constexpr std::array<std::pair<char, int>, 10> kArity = {
            {{'M', 2}, {'L', 2}, {'H', 1}, {'V', 1}, {'C', 6}, {'S', 4}, {'Q', 4}, {'T', 2}, {'A', 7}, {'Z', 0}}};
        int arity = -1;
        for (const auto& [letter, count] : kArity)
            if (letter == upper) arity = count;
        if (arity < 0) return fail(std::string("unknown path command '") + command + "' at " + excerpt(d, command_pos));
        if (upper == 'A')
            return fail("elliptical arcs (A/a commands) are not supported",
                        "replace the arc by Bézier curves (in Inkscape: Extensions > Modify Path > Add Nodes, or "
                        "redraw it with the Bézier tool)");
        double v[6] = {0, 0, 0, 0, 0, 0};
        for (int k = 0; k < arity; ++k) {
            skip_comma_space(d, pos);
            bool overflow = false;
            std::optional<double> value = read_number(d, pos, &overflow);
            if (!value)
                return fail(std::string(overflow ? "number out of range" : "expected a number") + " for '" + command +
                            "' at " + excerpt(d, pos));
            v[k] = *value;
        }
        // Absolute coordinates are taken as written (0 + -0 would lose the sign).
        const Eigen::Vector2d origin = current;
        auto at = [&](double x, double y) {
            return relative ? Eigen::Vector2d(origin + Eigen::Vector2d(x, y)) : Eigen::Vector2d(x, y);
        };
        switch (upper) {
            case 'M':
                current = at(v[0], v[1]);
                start = current;
                subpaths.emplace_back();
                subpaths.back().push_back(ctm.apply(current));
                break;
            case 'L': line_to(at(v[0], v[1])); break;
            case 'H': line_to({relative ? current.x() + v[0] : v[0], current.y()}); break;
            case 'V': line_to({current.x(), relative ? current.y() + v[0] : v[0]}); break;
            case 'C':
            case 'S':
            case 'Q':
            case 'T': {
                Eigen::Vector2d c1, c2, end;
                if (upper == 'C' || upper == 'S') {
                    if (upper == 'C') {
                        c1 = at(v[0], v[1]);
                        c2 = at(v[2], v[3]);
                        end = at(v[4], v[5]);
                    } else {  // first control point: the previous one reflected
                        c1 = (previous == 'C' || previous == 'S') ? Eigen::Vector2d(2.0 * current - last_cubic_control)
                                                                  : current;
                        c2 = at(v[0], v[1]);
                        end = at(v[2], v[3]);
                    }
                    last_cubic_control = c2;
                } else {
                    Eigen::Vector2d q;
                    if (upper == 'Q') {
                        q = at(v[0], v[1]);
                        end = at(v[2], v[3]);
                    } else {
                        q = (previous == 'Q' || previous == 'T') ? Eigen::Vector2d(2.0 * current - last_quad_control)
                                                                 : current;
                        end = at(v[0], v[1]);
                    }
                    last_quad_control = q;
                    // Degree elevation: the same curve as a cubic.
                    c1 = current + (2.0 / 3.0) * (q - current);
                    c2 = end + (2.0 / 3.0) * (q - end);
                }
                const Eigen::Vector2d p0 = subpaths.back().back();
                flatten_cubic(p0, ctm.apply(c1), ctm.apply(c2), ctm.apply(end), tolerance, 0, subpaths.back());
                current = end;
                break;
            }
            case 'Z':
                if (subpaths.back().size() > 1 || current != start) {
                    line_to(start);
                    result.closed = true;
                }
                // A command after Z starts a new subpath at the start point.
                subpaths.emplace_back();
                subpaths.back().push_back(ctm.apply(start));
                current = start;
                break;
        }
        previous = upper;
        if (subpaths.size() > counted_subpaths + 1) {  // a subpath was finished: count it once
            for (; counted_subpaths + 1 < subpaths.size(); ++counted_subpaths)
                finished_points += subpaths[counted_subpaths].size();
        }
        if (finished_points + subpaths.back().size() > budget)
            return fail("the path has too many points after flattening curves",
                        "simplify the drawing (fewer, flatter curves)");
        skip_svg_space(d, pos);
    }
    std::size_t drawn = 0;
    for (const auto& subpath : subpaths) {
        if (subpath.size() < 2) continue;
        if (drawn++ == 0) result.points = subpath;
    }
    if (drawn > 1)
        return fail("the path has " + std::to_string(drawn) + " subpaths (several M commands); a flow line is one stroke",
                    "split it into one path per line (in Inkscape: Path > Break Apart) and give each its own id");
    if (drawn == 0 && !subpaths.empty()) result.points = {subpaths.front().front()};
    budget -= std::min(budget, result.points.size());
    return result;
}

// Drops exact repeats (a zero-length segment, a Z back onto the start).
inline void remove_repeats(std::vector<Eigen::Vector2d>& points) {
    points.erase(std::unique(points.begin(), points.end(),
                             [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a == b; }),
                 points.end());
}

// ---- <svg> size and viewBox ------------------------------------------------------------

struct Length {
    double px = 0.0;
    bool percent = false;
    std::string unit;
};

inline std::optional<Length> parse_length(std::string_view text, std::string& error) {
    const std::string s = trim(text);
    std::size_t pos = 0;
    std::optional<double> value = read_number(s, pos);
    if (!value || !std::isfinite(*value)) {
        error = "\"" + s + "\" is not a length";
        return std::nullopt;
    }
    Length length;
    length.unit = trim(std::string_view(s).substr(pos));
    static const std::map<std::string, double> kPxPerUnit = {
        {"", 1.0}, {"px", 1.0}, {"in", 96.0}, {"cm", 96.0 / 2.54}, {"mm", 96.0 / 25.4}, {"pt", 96.0 / 72.0}, {"pc", 16.0}};
    if (length.unit == "%") {
        length.percent = true;
        return length;
    }
    auto it = kPxPerUnit.find(length.unit);
    if (it == kPxPerUnit.end()) {
        error = "unit \"" + length.unit + "\" is not supported";
        return std::nullopt;
    }
    length.px = *value * it->second;
    return length;
}

}  // namespace flowvid::formats::svg
