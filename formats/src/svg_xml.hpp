#pragma once
// A small XML tokenizer for the SVG importer (flowlines_svg.cpp): no XML
// library is available, so it reads what vector editors write (comments,
// processing instructions, DOCTYPE with internal entities, CDATA, both quote
// styles, predefined and numeric entities) and refuses malformed or truncated
// files with the line and column. Not part of the public interface.

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace flowvid::formats::svg {

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

inline bool is_xml_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
inline bool is_name_start(char c) {
    const unsigned char u = static_cast<unsigned char>(c);
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':' || u >= 0x80;
}
inline bool is_name_char(char c) { return is_name_start(c) || (c >= '0' && c <= '9') || c == '-' || c == '.'; }

inline void append_utf8(std::string& out, std::uint32_t code) {
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
inline std::string expand_character_references(const std::string& value) {
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

}  // namespace flowvid::formats::svg
