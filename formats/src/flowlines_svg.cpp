// SVG import and export of flow-line sets. No XML library is available, so a
// small XML tokenizer lives here; it reads what vector editors write (comments,
// processing instructions, DOCTYPE with internal entities, CDATA, both quote
// styles, predefined and numeric entities) and refuses malformed or truncated
// files with the line and column. The rules are in formats/specs/flowlines.md.

#include "flowvid/formats/flowlines.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <ostream>
#include <set>
#include <string_view>

namespace flowvid::formats {
namespace {

// ---- XML tokenizer ------------------------------------------------------------------

// Most text that references to declared entities may produce in one file.
constexpr std::size_t kMaxEntityExpansionBytes = std::size_t{8} << 20;

struct XmlAttribute {
    std::string name;
    std::string value;
};

struct XmlEvent {
    enum class Kind { start, end, text, done, failed };
    Kind kind = Kind::done;
    std::string name;
    std::vector<XmlAttribute> attributes;
    std::size_t line = 0;
    std::string text;

    const std::string* attribute(std::string_view key) const {
        for (const XmlAttribute& a : attributes)
            if (a.name == key) return &a.value;
        return nullptr;
    }
};

bool is_xml_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
bool is_name_start(char c) {
    const unsigned char u = static_cast<unsigned char>(c);
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':' || u >= 0x80;
}
bool is_name_char(char c) { return is_name_start(c) || (c >= '0' && c <= '9') || c == '-' || c == '.'; }

void append_utf8(std::string& out, std::uint32_t code) {
    if (code < 0x80) {
        out += static_cast<char>(code);
    } else if (code < 0x800) {
        out += static_cast<char>(0xC0 | (code >> 6));
        out += static_cast<char>(0x80 | (code & 0x3F));
    } else if (code < 0x10000) {
        out += static_cast<char>(0xE0 | (code >> 12));
        out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (code & 0x3F));
    } else {
        out += static_cast<char>(0xF0 | (code >> 18));
        out += static_cast<char>(0x80 | ((code >> 12) & 0x3F));
        out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (code & 0x3F));
    }
}

// Character references in an entity's value are replaced when it is declared
// (XML 1.0, 4.5); other references stay as written.
std::string expand_character_references(const std::string& value) {
    std::string out;
    for (std::size_t i = 0; i < value.size(); ++i) {
        const std::size_t semi = value.find(';', i);
        if (value.compare(i, 2, "&#") == 0 && semi != std::string::npos && semi - i <= 12) {
            const bool hex = i + 2 < semi && (value[i + 2] == 'x' || value[i + 2] == 'X');
            const std::size_t first = i + (hex ? 3 : 2);
            std::uint32_t code = 0;
            auto [ptr, ec] = std::from_chars(value.data() + first, value.data() + semi, code, hex ? 16 : 10);
            if (first < semi && ec == std::errc() && ptr == value.data() + semi && code > 0 && code <= 0x10FFFF &&
                !(code >= 0xD800 && code <= 0xDFFF)) {
                append_utf8(out, code);
                i = semi;
                continue;
            }
        }
        out += value[i];
    }
    return out;
}

// A pull tokenizer: next() returns start tags (self-closing ones are followed
// by their end), end tags and text until done; the first syntax error is
// recorded ("line L, column C") and every later call returns failed.
class XmlTokenizer {
public:
    XmlTokenizer(const std::string& text, Diagnostics& diagnostics) : m_text(text), m_diag(diagnostics) {
        m_line_starts.push_back(0);
        for (std::size_t i = 0; i < text.size(); ++i)
            if (text[i] == '\n') m_line_starts.push_back(i + 1);
        if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) m_pos = 3;  // UTF-8 byte-order mark
    }

    std::size_t line_of(std::size_t pos) const {
        return static_cast<std::size_t>(std::upper_bound(m_line_starts.begin(), m_line_starts.end(), pos) -
                                        m_line_starts.begin());
    }

    XmlEvent next() {
        XmlEvent event;
        if (m_failed) return failed();
        if (m_pending_end) {
            m_pending_end = false;
            event.kind = XmlEvent::Kind::end;
            event.name = m_open.back().first;
            event.line = m_open.back().second;
            pop_open();
            return event;
        }
        const std::size_t n = m_text.size();
        while (true) {
            if (m_pos >= n) {
                if (!m_open.empty())
                    return fail(n, "the file ends inside <" + m_open.back().first + "> opened at line " +
                                       std::to_string(m_open.back().second),
                                "the file is truncated or a closing tag is missing: save the drawing again");
                if (!m_root_seen) return fail(n, "no XML element found", "this is not an SVG file");
                event.kind = XmlEvent::Kind::done;
                return event;
            }
            if (m_text[m_pos] != '<') {
                const std::size_t start = m_pos;
                const std::size_t end = std::min(m_text.find('<', m_pos), n);
                m_pos = end;
                if (m_open.empty()) {
                    for (std::size_t i = start; i < end; ++i)
                        if (!is_xml_space(m_text[i]))
                            return fail(i, "text outside the <svg> element", "this is not a well-formed SVG file");
                    continue;
                }
                std::optional<std::string> decoded = decode(start, end);
                if (!decoded) return failed();
                event.kind = XmlEvent::Kind::text;
                event.text = std::move(*decoded);
                event.line = line_of(start);
                return event;
            }
            if (starts_with("<!--")) {
                const std::size_t end = m_text.find("-->", m_pos + 4);
                if (end == std::string::npos)
                    return fail(m_pos, "unterminated comment", "close the comment with -->, or the file is truncated");
                m_pos = end + 3;
                continue;
            }
            if (starts_with("<?")) {
                const std::size_t end = m_text.find("?>", m_pos + 2);
                if (end == std::string::npos)
                    return fail(m_pos, "unterminated processing instruction", "close it with ?>, or the file is truncated");
                m_pos = end + 2;
                continue;
            }
            if (starts_with("<![CDATA[")) {
                if (m_open.empty()) return fail(m_pos, "CDATA outside the <svg> element", "remove it");
                const std::size_t end = m_text.find("]]>", m_pos + 9);
                if (end == std::string::npos)
                    return fail(m_pos, "unterminated CDATA section", "close it with ]]>, or the file is truncated");
                event.kind = XmlEvent::Kind::text;
                event.text = m_text.substr(m_pos + 9, end - m_pos - 9);
                event.line = line_of(m_pos);
                m_pos = end + 3;
                return event;
            }
            if (starts_with("<!DOCTYPE")) {
                if (m_root_seen) return fail(m_pos, "<!DOCTYPE> inside the document", "move it before <svg>");
                if (!parse_doctype()) return failed();
                continue;
            }
            if (starts_with("<!")) return fail(m_pos, "unknown markup declaration", "remove it");
            if (starts_with("</")) return end_tag();
            return start_tag();
        }
    }

private:
    bool starts_with(const char* prefix) const { return m_text.compare(m_pos, std::strlen(prefix), prefix) == 0; }

    XmlEvent failed() {
        m_failed = true;
        XmlEvent event;
        event.kind = XmlEvent::Kind::failed;
        return event;
    }

    XmlEvent fail(std::size_t pos, const std::string& message, const std::string& fix) {
        report(pos, message, fix);
        return failed();
    }

    void report(std::size_t pos, const std::string& message, const std::string& fix) {
        const std::size_t line = line_of(pos);
        const std::size_t column = pos - m_line_starts[line - 1] + 1;
        m_diag.error("line " + std::to_string(line) + ", column " + std::to_string(column), "malformed XML: " + message,
                     fix);
        m_failed = true;
    }

    void pop_open() {
        m_open.pop_back();
        if (m_open.empty()) m_root_done = true;
    }

    bool skip_space() {
        const std::size_t start = m_pos;
        while (m_pos < m_text.size() && is_xml_space(m_text[m_pos])) ++m_pos;
        return m_pos > start;
    }

    std::string name() {
        const std::size_t start = m_pos;
        if (m_pos < m_text.size() && is_name_start(m_text[m_pos])) {
            ++m_pos;
            while (m_pos < m_text.size() && is_name_char(m_text[m_pos])) ++m_pos;
        }
        return m_text.substr(start, m_pos - start);
    }

    // Replaces entity and character references in m_text[begin, end).
    std::optional<std::string> decode(std::size_t begin, std::size_t end) {
        std::string out;
        out.reserve(end - begin);
        for (std::size_t i = begin; i < end; ++i) {
            if (m_text[i] != '&') {
                out += m_text[i];
                continue;
            }
            const std::size_t semi = m_text.find(';', i + 1);
            if (semi == std::string::npos || semi >= end || semi - i > 40) {
                report(i, "'&' that starts no entity", "write a literal & as &amp;");
                return std::nullopt;
            }
            const std::string entity = m_text.substr(i + 1, semi - i - 1);
            if (!entity.empty() && entity[0] == '#') {
                const bool hex = entity.size() > 1 && (entity[1] == 'x' || entity[1] == 'X');
                const std::string digits = entity.substr(hex ? 2 : 1);
                std::uint32_t code = 0;
                auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), code, hex ? 16 : 10);
                if (digits.empty() || ec != std::errc() || ptr != digits.data() + digits.size() || code == 0 ||
                    code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) {
                    report(i, "invalid character reference &" + entity + ";", "write a valid Unicode code point");
                    return std::nullopt;
                }
                append_utf8(out, code);
            } else if (entity == "amp") {
                out += '&';
            } else if (entity == "lt") {
                out += '<';
            } else if (entity == "gt") {
                out += '>';
            } else if (entity == "quot") {
                out += '"';
            } else if (entity == "apos") {
                out += '\'';
            } else if (auto it = m_entities.find(entity); it != m_entities.end()) {
                // Not expanded again, so no nested bombs; the total is bounded
                // too, or one large entity used many times fills the memory.
                m_entity_bytes += it->second.size();
                if (m_entity_bytes > kMaxEntityExpansionBytes) {
                    report(i, "entity references expand to more than " +
                                  std::to_string(kMaxEntityExpansionBytes >> 20) + " MiB in all",
                           "flow-line SVGs need no entities: write the text out (save the drawing again)");
                    return std::nullopt;
                }
                out += it->second;
            } else {
                report(i, "unknown entity &" + entity + ";", "write & as &amp;, or declare the entity in the DOCTYPE");
                return std::nullopt;
            }
            i = semi;
        }
        return out;
    }

    // Skips a quoted literal at m_pos; returns false (reported) when unterminated.
    bool skip_quoted() {
        const char quote = m_text[m_pos];
        const std::size_t end = m_text.find(quote, m_pos + 1);
        if (end == std::string::npos) {
            report(m_pos, "unterminated quoted string", "close the quote, or the file is truncated");
            return false;
        }
        m_pos = end + 1;
        return true;
    }

    bool skip_to_declaration_end() {
        while (m_pos < m_text.size() && m_text[m_pos] != '>') {
            if (m_text[m_pos] == '"' || m_text[m_pos] == '\'') {
                if (!skip_quoted()) return false;
            } else {
                ++m_pos;
            }
        }
        if (m_pos >= m_text.size()) {
            report(m_pos, "unterminated declaration in <!DOCTYPE>", "the file is truncated");
            return false;
        }
        ++m_pos;
        return true;
    }

    // <!DOCTYPE name ... [ internal subset ]>: general entities declared in the
    // internal subset (Adobe Illustrator writes some) are kept for decode().
    bool parse_doctype() {
        const std::size_t start = m_pos;
        m_pos += 9;
        const std::size_t n = m_text.size();
        while (m_pos < n) {
            const char c = m_text[m_pos];
            if (c == '"' || c == '\'') {
                if (!skip_quoted()) return false;
            } else if (c == '>') {
                ++m_pos;
                return true;
            } else if (c == '[') {
                ++m_pos;
                while (true) {
                    if (m_pos >= n) {
                        report(start, "unterminated <!DOCTYPE> internal subset", "the file is truncated");
                        return false;
                    }
                    if (starts_with("<!--")) {
                        const std::size_t end = m_text.find("-->", m_pos + 4);
                        if (end == std::string::npos) {
                            report(m_pos, "unterminated comment", "the file is truncated");
                            return false;
                        }
                        m_pos = end + 3;
                    } else if (starts_with("<!ENTITY")) {
                        m_pos += 8;
                        skip_space();
                        if (m_pos < n && m_text[m_pos] != '%') {
                            const std::string entity = name();
                            skip_space();
                            if (!entity.empty() && m_pos < n && (m_text[m_pos] == '"' || m_text[m_pos] == '\'')) {
                                const char quote = m_text[m_pos];
                                const std::size_t end = m_text.find(quote, m_pos + 1);
                                if (end == std::string::npos) {
                                    report(m_pos, "unterminated entity value", "the file is truncated");
                                    return false;
                                }
                                m_entities.emplace(entity,
                                                   expand_character_references(m_text.substr(m_pos + 1, end - m_pos - 1)));
                                m_pos = end + 1;
                            }
                        }
                        if (!skip_to_declaration_end()) return false;
                    } else if (m_text[m_pos] == '"' || m_text[m_pos] == '\'') {
                        if (!skip_quoted()) return false;
                    } else if (m_text[m_pos] == ']') {
                        ++m_pos;
                        break;
                    } else {
                        ++m_pos;
                    }
                }
            } else {
                ++m_pos;
            }
        }
        report(start, "unterminated <!DOCTYPE>", "close it with >, or the file is truncated");
        return false;
    }

    XmlEvent end_tag() {
        const std::size_t start = m_pos;
        m_pos += 2;
        const std::string tag = name();
        skip_space();
        if (m_pos >= m_text.size()) return fail(start, "the file ends inside </" + tag + ">", "the file is truncated");
        if (tag.empty() || m_text[m_pos] != '>') return fail(m_pos, "malformed end tag", "write </name>");
        ++m_pos;
        if (m_open.empty() || m_open.back().first != tag)
            return fail(start,
                        "</" + tag + "> does not match " +
                            (m_open.empty() ? std::string("any open element")
                                            : "<" + m_open.back().first + "> opened at line " +
                                                  std::to_string(m_open.back().second)),
                        "close elements in the reverse order they were opened");
        XmlEvent event;
        event.kind = XmlEvent::Kind::end;
        event.name = tag;
        event.line = m_open.back().second;
        pop_open();
        return event;
    }

    XmlEvent start_tag() {
        const std::size_t start = m_pos;
        if (m_root_done) return fail(start, "a second element after </svg>", "keep one <svg> element per file");
        ++m_pos;
        XmlEvent event;
        event.kind = XmlEvent::Kind::start;
        event.line = line_of(start);
        event.name = name();
        if (event.name.empty()) return fail(m_pos, "expected an element name after '<'", "write a literal < as &lt;");
        bool self_closing = false;
        std::set<std::string, std::less<>> seen_names;  // a set: a tag with many attributes stays linear
        while (true) {
            skip_space();
            if (m_pos >= m_text.size())
                return fail(start, "the file ends inside the tag <" + event.name + ">", "the file is truncated");
            const char c = m_text[m_pos];
            if (c == '>') {
                ++m_pos;
                break;
            }
            if (c == '/') {
                if (m_pos + 1 >= m_text.size() || m_text[m_pos + 1] != '>')
                    return fail(m_pos, "'/' not followed by '>' in <" + event.name + ">", "write /> to close the tag");
                m_pos += 2;
                self_closing = true;
                break;
            }
            const std::size_t attribute_pos = m_pos;
            XmlAttribute attribute;
            attribute.name = name();
            if (attribute.name.empty())
                return fail(m_pos, std::string("unexpected character '") + c + "' in <" + event.name + ">",
                            "write attributes as name=\"value\"");
            skip_space();
            if (m_pos >= m_text.size() || m_text[m_pos] != '=')
                return fail(m_pos, "attribute " + attribute.name + " has no value", "write " + attribute.name + "=\"...\"");
            ++m_pos;
            skip_space();
            if (m_pos >= m_text.size() || (m_text[m_pos] != '"' && m_text[m_pos] != '\''))
                return fail(m_pos, "the value of " + attribute.name + " is not quoted", "quote it with \" or '");
            const char quote = m_text[m_pos];
            const std::size_t end = m_text.find(quote, m_pos + 1);
            if (end == std::string::npos)
                return fail(m_pos, "the value of " + attribute.name + " is not closed", "the file is truncated");
            std::optional<std::string> value = decode(m_pos + 1, end);
            if (!value) return failed();
            m_pos = end + 1;
            if (!seen_names.insert(attribute.name).second)
                return fail(attribute_pos, "attribute " + attribute.name + " appears twice in <" + event.name + ">",
                            "keep one");
            attribute.value = std::move(*value);
            event.attributes.push_back(std::move(attribute));
        }
        if (m_root_seen && m_open.empty()) return fail(start, "a second root element", "keep one <svg> element per file");
        m_root_seen = true;
        m_open.emplace_back(event.name, event.line);
        m_pending_end = self_closing;
        return event;
    }

    const std::string& m_text;
    Diagnostics& m_diag;
    std::vector<std::size_t> m_line_starts;
    std::size_t m_pos = 0;
    std::vector<std::pair<std::string, std::size_t>> m_open;  // element name, line
    std::map<std::string, std::string> m_entities;
    std::size_t m_entity_bytes = 0;  // characters produced by declared entities so far
    bool m_pending_end = false;
    bool m_root_seen = false;
    bool m_root_done = false;
    bool m_failed = false;
};

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
std::pair<double, double> cos_sin_degrees(double degrees) {
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

double distance_to_segment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
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
void flatten_cubic(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1, const Eigen::Vector2d& p2,
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

bool is_svg_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Reads one SVG number at `pos` ([+-]? (digits [. digits?] | . digits) ([eE] [+-]? digits)?).
// "-1-2" reads -1 then -2, "1.5.5" reads 1.5 then .5. Returns nullopt without
// moving when no number starts there (or it overflows: `overflow` set).
std::optional<double> read_number(std::string_view s, std::size_t& pos, bool* overflow = nullptr) {
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

void skip_svg_space(std::string_view s, std::size_t& pos) {
    while (pos < s.size() && is_svg_space(s[pos])) ++pos;
}

// Whitespace, then at most one comma, then whitespace.
void skip_comma_space(std::string_view s, std::size_t& pos) {
    skip_svg_space(s, pos);
    if (pos < s.size() && s[pos] == ',') {
        ++pos;
        skip_svg_space(s, pos);
    }
}

// A list of numbers separated by whitespace and/or commas; nullopt on junk.
std::optional<std::vector<double>> read_number_list(std::string_view s) {
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

std::string trim(std::string_view s) {
    std::size_t begin = 0, end = s.size();
    while (begin < end && is_svg_space(s[begin])) ++begin;
    while (end > begin && is_svg_space(s[end - 1])) --end;
    return std::string(s.substr(begin, end - begin));
}

std::string excerpt(std::string_view s, std::size_t pos) {
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
std::optional<Affine> parse_transform(std::string_view s, std::string& error) {
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
PathResult convert_path(std::string_view d, const Affine& ctm, double tolerance, std::size_t& budget) {
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
void remove_repeats(std::vector<Eigen::Vector2d>& points) {
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

std::optional<Length> parse_length(std::string_view text, std::string& error) {
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
