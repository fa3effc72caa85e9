// Structure-aware mutations (see structure_mutator.hpp). The scanners here are
// deliberately forgiving: inputs are often already broken by earlier byte-level
// mutations, and an operation on a half-valid document is still useful.
#include "structure_mutator.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>

namespace flowvid::fuzz {

std::uint64_t MutationRandom::next() {
    std::uint64_t z = (m_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

const std::vector<std::string>& odd_json_numbers() {
    static const std::vector<std::string> numbers = {
        "1e999", "-1e999", "1e-400", "-0", "-0.0", "NaN", "-NaN", "Infinity", "-Infinity", "nan", "inf",
        "1e308", "-1e308", "1.7976931348623157e308", "5e-324", "2.2250738585072014e-308", "1e-300", "0.001",
        "1e12", "-1e12", "-384", "-1", "0", "1", "2", "3.5", "0.5", "2147483647", "2147483648", "-2147483649",
        "4294967295", "4294967296", "9007199254740993", "9223372036854775807", "9223372036854775808",
        "-9223372036854775809", "18446744073709551616", "100000000000000000000000000000", "1E+2", "00", "01",
        "1.", ".5", "1e", "--1", "0x10", "1e+99999999999"};
    return numbers;
}

const std::vector<std::string>& odd_strings() {
    // JSON string contents (already escaped where needed).
    static const std::vector<std::string> strings = {
        "../../etc/passwd", "/etc/passwd", "..", ".", "", "/", "../", "..\\\\..\\\\windows", "C:\\\\x",
        "file:///etc/passwd", "/dev/zero", "/dev/stdin", "/proc/self/mem", "~/x", "frames/%06d%06d.png",
        "frames/%999999999d.png", "frames/%s.png", "frames/%n%n%n.png", "frames/%", "%%", "%d",
        "frames/%033d.png", "frames/%-6d.png", "\\u0000", "a\\u0000b", "\\ud800", "\\udfff\\ud800", "\\n",
        " ", "capture.json", "truth/truth.json", "flowvid.capture", "flowvid.fabric", "flowvid.flowlines",
        "flowvid.fit_shard", "flowvid.particle_bank", "1.0", "9.0", "1.999999999999", "-1.0", "1", "cloth.static",
        "cloth.waving", "rigid.toss", "video.flow", "NaN", "1e999", "\\u00e9\\u4e2d"};
    return strings;
}

namespace {

constexpr std::size_t kNone = static_cast<std::size_t>(-1);

// ---- JSON scanning -----------------------------------------------------------

struct Span {
    std::size_t begin = 0;
    std::size_t end = 0;  // one past the last byte
    char type = 0;        // 's' string, 'n' number, 'l' literal, '[' array, '{' object, 'k' key
};

std::size_t string_end(const std::string& text, std::size_t quote) {
    for (std::size_t j = quote + 1; j < text.size(); ++j) {
        if (text[j] == '\\') ++j;
        else if (text[j] == '"') return j + 1;
    }
    return text.size();
}

bool is_number_char(char c) {
    return std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.' || c == 'e' || c == 'E';
}

struct JsonScan {
    std::vector<Span> values;  // in order of their start
    std::vector<Span> keys;
};

JsonScan scan_json(const std::string& text) {
    JsonScan scan;
    std::vector<std::size_t> open;
    std::size_t i = 0;
    const std::size_t n = text.size();
    while (i < n) {
        const char c = text[i];
        if (c == '"') {
            const std::size_t j = string_end(text, i);
            std::size_t k = j;
            while (k < n && std::isspace(static_cast<unsigned char>(text[k]))) ++k;
            if (k < n && text[k] == ':') scan.keys.push_back({i, j, 'k'});
            else scan.values.push_back({i, j, 's'});
            i = j;
        } else if (c == '[' || c == '{') {
            scan.values.push_back({i, n, c});
            open.push_back(scan.values.size() - 1);
            ++i;
        } else if (c == ']' || c == '}') {
            if (!open.empty()) {
                scan.values[open.back()].end = i + 1;
                open.pop_back();
            }
            ++i;
        } else if (c == '-' || std::isdigit(static_cast<unsigned char>(c))) {
            std::size_t j = i + 1;
            while (j < n && is_number_char(text[j])) ++j;
            scan.values.push_back({i, j, 'n'});
            i = j;
        } else if (std::isalpha(static_cast<unsigned char>(c))) {
            std::size_t j = i + 1;
            while (j < n && std::isalnum(static_cast<unsigned char>(text[j]))) ++j;
            scan.values.push_back({i, j, 'l'});
            i = j;
        } else {
            ++i;
        }
    }
    return scan;
}

// The first value that starts at or after `position` (kNone when none).
std::size_t value_at_or_after(const JsonScan& scan, std::size_t position) {
    const auto it = std::lower_bound(scan.values.begin(), scan.values.end(), position,
                                     [](const Span& span, std::size_t p) { return span.begin < p; });
    return it == scan.values.end() ? kNone : static_cast<std::size_t>(it - scan.values.begin());
}

std::size_t pick_of_type(const JsonScan& scan, MutationRandom& random, const char* types) {
    std::vector<std::size_t> candidates;
    for (std::size_t i = 0; i < scan.values.size(); ++i)
        if (std::strchr(types, scan.values[i].type)) candidates.push_back(i);
    return candidates.empty() ? kNone : candidates[random.below(candidates.size())];
}

void replace(std::string& text, const Span& span, const std::string& with) {
    text.replace(span.begin, span.end - span.begin, with);
}

// How many repetitions of `unit` bytes fit (at most `wanted`).
std::size_t fitting(std::size_t wanted, std::size_t unit, std::size_t size, std::size_t max_size) {
    if (unit == 0 || size >= max_size) return 0;
    return std::min(wanted, (max_size - size) / unit);
}

// A count for "many": mostly small, sometimes as many as the cases.
std::size_t many(MutationRandom& random) {
    static constexpr std::array<std::size_t, 8> counts = {2, 3, 16, 100, 1000, 10000, 100000, 500000};
    return counts[random.below(random.one_in(8) ? counts.size() : 4)];
}

std::string long_run(MutationRandom& random, char c) {
    static constexpr std::array<std::size_t, 4> lengths = {256, 4096, 65536, 1 << 20};
    return std::string(lengths[random.below(random.one_in(4) ? lengths.size() : 2)], c);
}

}  // namespace

// ---- JSON operations ---------------------------------------------------------

namespace ops {

bool json_nest_deep(std::string& text, MutationRandom& random, std::size_t max_size) {
    static constexpr std::array<std::size_t, 5> depths = {32, 1000, 10000, 100000, 1000000};
    struct Level {
        const char* open;
        const char* close;
    };
    static constexpr std::array<Level, 4> levels = {{{"[", "]"}, {"{\"a\":", "}"}, {"[0,", "]"}, {"[[", "],0]"}}};
    const Level level = levels[random.below(levels.size())];
    const std::size_t unit = std::strlen(level.open) + std::strlen(level.close);
    const std::size_t depth = fitting(depths[random.below(random.one_in(4) ? depths.size() : 2)], unit, text.size(), max_size);
    if (depth < 2) return false;
    Span target{0, text.size(), '['};
    if (!random.one_in(3)) {
        const JsonScan scan = scan_json(text);
        const std::size_t index = pick_of_type(scan, random, "snl[{");
        if (index != kNone) target = scan.values[index];
    }
    std::string opening, closing;
    opening.reserve(depth * std::strlen(level.open));
    closing.reserve(depth * std::strlen(level.close));
    for (std::size_t i = 0; i < depth; ++i) opening += level.open;
    for (std::size_t i = 0; i < depth; ++i) closing += level.close;
    text.insert(target.end, closing);
    text.insert(target.begin, opening);
    return true;
}

bool json_odd_number(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    const std::size_t index = pick_of_type(scan, random, random.one_in(4) ? "nls" : "n");
    if (index == kNone) return false;
    const std::string& number = odd_json_numbers()[random.below(odd_json_numbers().size())];
    if (text.size() + number.size() > max_size) return false;
    replace(text, scan.values[index], number);
    return true;
}

bool json_duplicate_key(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    if (scan.keys.empty()) return false;
    const Span key = scan.keys[random.below(scan.keys.size())];
    const std::size_t value = value_at_or_after(scan, key.end);
    const std::size_t member_end = value == kNone ? key.end : scan.values[value].end;
    std::string member = text.substr(key.begin, member_end - key.begin);
    if (value == kNone) member += ":0";
    if (random.one_in(2)) {  // the duplicate with another value
        const std::size_t colon = member.find(':');
        member = member.substr(0, colon + 1) + odd_json_numbers()[random.below(odd_json_numbers().size())];
    }
    member += ",";
    const std::size_t copies = fitting(many(random), member.size(), text.size(), max_size);
    if (copies == 0) return false;
    std::string inserted;
    inserted.reserve(copies * member.size());
    for (std::size_t i = 0; i < copies; ++i) inserted += member;
    text.insert(key.begin, inserted);
    return true;
}

bool json_many_keys(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    const std::size_t index = pick_of_type(scan, random, "{");
    if (index == kNone) return false;
    const Span object = scan.values[index];
    const std::size_t count = fitting(many(random), 14, text.size(), max_size);
    if (count == 0) return false;
    std::string members;
    for (std::size_t i = 0; i < count; ++i) members += "\"k" + std::to_string(i) + "\":0,";
    std::size_t after = object.begin + 1;
    while (after < text.size() && std::isspace(static_cast<unsigned char>(text[after]))) ++after;
    if (after >= text.size() || text[after] == '}') members.pop_back();
    text.insert(object.begin + 1, members);
    return true;
}

bool json_huge_array(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    const std::size_t index = pick_of_type(scan, random, "[");
    if (index == kNone) return false;
    const Span array = scan.values[index];
    std::string element = "0";
    std::size_t insert_at = array.begin + 1;
    bool empty = true;
    if (index + 1 < scan.values.size() && scan.values[index + 1].begin < array.end) {
        const Span first = scan.values[index + 1];
        element = text.substr(first.begin, first.end - first.begin);
        insert_at = first.end;
        empty = false;
    }
    const std::string unit = "," + element;
    const std::size_t copies = fitting(many(random), unit.size(), text.size(), max_size);
    if (copies == 0) return false;
    std::string inserted;
    inserted.reserve(copies * unit.size());
    for (std::size_t i = 0; i < copies; ++i) inserted += unit;
    if (empty) inserted.erase(0, 1);
    text.insert(insert_at, inserted);
    return true;
}

bool json_odd_string(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    const std::size_t index = pick_of_type(scan, random, random.one_in(4) ? "snl" : "s");
    if (index == kNone) return false;
    std::string value;
    if (random.one_in(8)) value = long_run(random, random.one_in(2) ? 'A' : '/');
    else value = odd_strings()[random.below(odd_strings().size())];
    if (text.size() + value.size() + 2 > max_size) return false;
    replace(text, scan.values[index], "\"" + value + "\"");
    return true;
}

bool json_type_swap(std::string& text, MutationRandom& random, std::size_t max_size) {
    static const std::array<const char*, 14> replacements = {
        "null", "true", "false", "[]", "{}", "\"\"", "0", "-1", "[[]]", "{\"\":{}}", "[null]", "\"x\"", "[0,0,0]", "{\"format\":0}"};
    const JsonScan scan = scan_json(text);
    const std::size_t index = pick_of_type(scan, random, "snl[{");
    if (index == kNone) return false;
    const std::string value = replacements[random.below(replacements.size())];
    if (text.size() + value.size() > max_size) return false;
    replace(text, scan.values[index], value);
    return true;
}

bool json_splice_subtree(std::string& text, MutationRandom& random, std::size_t max_size) {
    const JsonScan scan = scan_json(text);
    if (scan.values.size() < 2) return false;
    const Span to = scan.values[random.below(scan.values.size())];
    const Span from = scan.values[random.below(scan.values.size())];
    const std::string copy = text.substr(from.begin, from.end - from.begin);
    if (text.size() - (to.end - to.begin) + copy.size() > max_size) return false;
    replace(text, to, copy);
    return true;
}

}  // namespace ops

// ---- SVG / XML ---------------------------------------------------------------

namespace {

struct Tag {
    std::size_t lt = 0;         // '<'
    std::size_t name_end = 0;   // one past the element name
    std::string name;
};

std::vector<Tag> scan_start_tags(const std::string& text) {
    std::vector<Tag> tags;
    for (std::size_t i = 0; i + 1 < text.size(); ++i) {
        if (text[i] != '<' || !std::isalpha(static_cast<unsigned char>(text[i + 1]))) continue;
        std::size_t j = i + 1;
        while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j])) && text[j] != '>' && text[j] != '/') ++j;
        tags.push_back({i, j, text.substr(i + 1, j - i - 1)});
    }
    return tags;
}

// [begin, end) of every attribute value's content (inside the quotes).
std::vector<Span> scan_attribute_values(const std::string& text) {
    std::vector<Span> values;
    for (std::size_t i = 0; i + 1 < text.size(); ++i) {
        if (text[i] != '=' || (text[i + 1] != '"' && text[i + 1] != '\'')) continue;
        const char quote = text[i + 1];
        const std::size_t close = text.find(quote, i + 2);
        if (close == std::string::npos) break;
        values.push_back({i + 2, close, 'a'});
        i = close;
    }
    return values;
}

// Where a DOCTYPE goes: before the root element (after any <?xml ...?>).
std::size_t doctype_position(const std::string& text) {
    const std::size_t svg = text.find("<svg");
    return svg == std::string::npos ? 0 : svg;
}

// One value fits (`need` more bytes) or nothing is done.
bool room_for(const std::string& text, std::size_t need, std::size_t max_size) { return text.size() + need <= max_size; }

}  // namespace

namespace ops {

bool svg_many_attributes(std::string& text, MutationRandom& random, std::size_t max_size) {
    const std::vector<Tag> tags = scan_start_tags(text);
    if (tags.empty()) return false;
    // Prefer the elements the reader interprets.
    std::vector<Tag> preferred;
    for (const Tag& tag : tags)
        if (tag.name == "path" || tag.name == "g" || tag.name == "svg" || tag.name == "polyline" || tag.name == "line")
            preferred.push_back(tag);
    const std::vector<Tag>& pool = preferred.empty() || random.one_in(4) ? tags : preferred;
    const Tag tag = pool[random.below(pool.size())];
    static const std::array<const char*, 6> duplicates = {" d=\"M0 0L1 1\"", " id=\"x\"", " transform=\"scale(2)\"",
                                                          " class=\"input\"", " style=\"stroke:red\"", " xmlns=\"\""};
    const int style = static_cast<int>(random.below(3));
    const std::string duplicate = duplicates[random.below(duplicates.size())];
    const std::size_t unit = style == 0 ? 14 : duplicate.size();
    const std::size_t count = fitting(many(random), unit, text.size(), max_size);
    if (count == 0) return false;
    std::string attributes;
    for (std::size_t i = 0; i < count; ++i) {
        if (style == 0) attributes += " a" + std::to_string(i) + "=\"1\"";
        else if (style == 1) attributes += duplicate;
        else attributes += i % 2 ? duplicate : " a" + std::to_string(i) + "=\"1\"";
    }
    if (text.size() + attributes.size() > max_size) return false;
    text.insert(tag.name_end, attributes);
    return true;
}

bool svg_entity_amplification(std::string& text, MutationRandom& random, std::size_t max_size) {
    std::string declarations;
    std::string reference;
    switch (random.below(5)) {
        case 0: {  // billion laughs: levels x fan-out
            const std::size_t levels = 3 + random.below(7);
            const std::size_t fan_out = 4 + random.below(7);
            declarations = "<!ENTITY e0 \"M0 0 L1 1 \">";
            for (std::size_t level = 1; level <= levels; ++level) {
                declarations += "<!ENTITY e" + std::to_string(level) + " \"";
                for (std::size_t k = 0; k < fan_out; ++k) declarations += "&e" + std::to_string(level - 1) + ";";
                declarations += "\">";
            }
            reference = "&e" + std::to_string(levels) + ";";
            break;
        }
        case 1: {  // one big entity used many times (the 100 KB x 10 000)
            std::string body;
            const std::size_t length = std::min<std::size_t>(random.one_in(2) ? 100000 : 1000, max_size / 2);
            while (body.size() + 10 <= length) body += "L1 1 L2 2 ";
            declarations = "<!ENTITY big \"M0 0 " + body + "\">";
            const std::size_t uses = 1 + fitting(random.one_in(2) ? 10000 : 10, 5, text.size() + declarations.size(), max_size);
            for (std::size_t k = 0; k < uses; ++k) reference += "&big;";
            break;
        }
        case 2:  // recursive
            declarations = "<!ENTITY a \"&b;\"><!ENTITY b \"&a;\">";
            reference = "&a;";
            break;
        case 3:  // external: must never be read
            declarations = random.one_in(2) ? "<!ENTITY x SYSTEM \"file:///etc/passwd\">" : "<!ENTITY x SYSTEM \"../../etc/passwd\">";
            reference = "&x;";
            break;
        default:  // parameter entities and an undefined one
            declarations = "<!ENTITY % p \"<!ENTITY q 'M0 0 L1 1'>\"> %p;";
            reference = random.one_in(2) ? "&q;" : "&undefined;";
    }
    std::string doctype = "<!DOCTYPE svg [" + declarations + "]>";
    const std::size_t existing = text.find("<!DOCTYPE");
    std::size_t bracket = existing == std::string::npos ? std::string::npos : text.find('[', existing);
    std::vector<Span> values = scan_attribute_values(text);
    if (!room_for(text, doctype.size() + reference.size(), max_size)) return false;
    // The reference first (it is after the DOCTYPE, so positions stay valid).
    if (!values.empty()) {
        // Prefer path data: that is where a drawing's bytes go.
        std::vector<Span> path_data;
        for (const Span& value : values)
            if (value.begin >= 3 && text.compare(value.begin - 3, 3, "d=\"") == 0) path_data.push_back(value);
        const std::vector<Span>& pool = path_data.empty() ? values : path_data;
        const Span value = pool[random.below(pool.size())];
        text.replace(value.begin, value.end - value.begin, reference);
    } else {
        const std::size_t gt = text.find('>', doctype_position(text));
        text.insert(gt == std::string::npos ? text.size() : gt + 1, reference);
    }
    if (bracket != std::string::npos && bracket < doctype_position(text)) text.insert(bracket + 1, declarations);
    else text.insert(doctype_position(text), doctype);
    return true;
}

bool svg_many_elements(std::string& text, MutationRandom& random, std::size_t max_size) {
    const std::vector<Tag> tags = scan_start_tags(text);
    std::vector<Span> elements;
    for (const Tag& tag : tags) {
        if (tag.name == "svg") continue;
        const std::size_t gt = text.find('>', tag.name_end);
        if (gt == std::string::npos) continue;
        if (text[gt - 1] == '/') {
            elements.push_back({tag.lt, gt + 1, 'e'});
        } else {
            const std::size_t close = text.find("</" + tag.name, gt);
            const std::size_t close_gt = close == std::string::npos ? close : text.find('>', close);
            if (close_gt != std::string::npos) elements.push_back({tag.lt, close_gt + 1, 'e'});
        }
    }
    std::string element;
    std::size_t at = 0;
    if (elements.empty()) {
        element = "<path d=\"M0 0 L1 1\"/>";
        const std::size_t svg = text.find("<svg");
        const std::size_t gt = svg == std::string::npos ? svg : text.find('>', svg);
        at = gt == std::string::npos ? text.size() : gt + 1;
    } else {
        const Span chosen = elements[random.below(elements.size())];
        element = text.substr(chosen.begin, chosen.end - chosen.begin);
        at = chosen.end;
    }
    const std::size_t copies = fitting(many(random), element.size(), text.size(), max_size);
    if (copies == 0) return false;
    std::string inserted;
    inserted.reserve(copies * element.size());
    for (std::size_t i = 0; i < copies; ++i) inserted += element;
    text.insert(at, inserted);
    return true;
}

bool svg_nest_deep(std::string& text, MutationRandom& random, std::size_t max_size) {
    static constexpr std::array<std::size_t, 5> depths = {32, 1000, 10000, 100000, 1000000};
    const bool transformed = random.one_in(2);
    const std::string open = transformed ? "<g transform=\"scale(2)\">" : "<g>";
    const std::string close = "</g>";
    const std::size_t depth =
        fitting(depths[random.below(random.one_in(4) ? depths.size() : 2)], open.size() + close.size(), text.size(), max_size);
    if (depth < 2) return false;
    const std::size_t svg = text.find("<svg");
    const std::size_t gt = svg == std::string::npos ? std::string::npos : text.find('>', svg);
    const std::size_t start = gt == std::string::npos ? 0 : gt + 1;
    std::size_t end = text.rfind("</svg");
    if (end == std::string::npos || end < start) end = text.size();
    std::string opening, closing;
    for (std::size_t i = 0; i < depth; ++i) opening += open;
    for (std::size_t i = 0; i < depth; ++i) closing += close;
    text.insert(end, closing);
    text.insert(start, opening);
    return true;
}

bool svg_odd_number(std::string& text, MutationRandom& random, std::size_t max_size) {
    static const std::array<const char*, 26> numbers = {
        "1e999", "-1e999", "1e308", "-1e308", "nan", "NaN", "inf", "-inf", "Infinity", "1e-400", "-0", "0",
        "1e12", "-384", "4294967296", "9e99999", "0x10", ".", "-", "1e", "..5", "1e308 1e308", "5e-324",
        "-.e-", "1e-300", "0.001"};
    std::vector<Span> spans;
    for (const Span& value : scan_attribute_values(text)) {
        for (std::size_t i = value.begin; i < value.end;) {
            const char c = text[i];
            if (std::isdigit(static_cast<unsigned char>(c)) || ((c == '-' || c == '.') && i + 1 < value.end &&
                                                                 std::isdigit(static_cast<unsigned char>(text[i + 1])))) {
                std::size_t j = i + 1;
                while (j < value.end && is_number_char(text[j]) && !(text[j] == '-' && text[j - 1] != 'e' && text[j - 1] != 'E'))
                    ++j;
                spans.push_back({i, j, 'n'});
                i = j;
            } else {
                ++i;
            }
        }
    }
    if (spans.empty()) return false;
    const Span span = spans[random.below(spans.size())];
    const std::string number = numbers[random.below(numbers.size())];
    if (!room_for(text, number.size(), max_size)) return false;
    text.replace(span.begin, span.end - span.begin, number);
    return true;
}

bool svg_odd_attribute(std::string& text, MutationRandom& random, std::size_t max_size) {
    static const std::array<const char*, 24> values = {
        "../../etc/passwd", "file:///etc/passwd", "matrix(1e308 0 0 1e308 0 0)", "matrix(0 0 0 0 0 0)", "scale(0)",
        "rotate(nan)", "translate(1e999)", "skewX(90)", "matrix(1 2 3)", "M", "M 1e308 1e308 L -1e308 -1e308",
        "M0 0 C", "M0 0 A 1 1 0 1 1 1e308 0", "Z Z Z", "m0 0 q", "&#0;", "&#x110000;", "&#99999999999;", "&unknown;",
        "&amp;&lt;&gt;", "", " ", "M0,0,,,,1,1", "M0 0 H nan V inf"};
    const std::vector<Span> spans = scan_attribute_values(text);
    if (spans.empty()) return false;
    const Span span = spans[random.below(spans.size())];
    std::string value;
    if (random.one_in(6)) {
        const std::size_t repeats = fitting(many(random), 6, text.size(), max_size);
        value = "M0 0";
        for (std::size_t i = 0; i < repeats; ++i) value += " L1 1";
    } else {
        value = values[random.below(values.size())];
    }
    if (!room_for(text, value.size(), max_size)) return false;
    text.replace(span.begin, span.end - span.begin, value);
    return true;
}

bool svg_markup_noise(std::string& text, MutationRandom& random, std::size_t max_size) {
    static const std::array<const char*, 20> pieces = {
        "<!--", "-->", "<![CDATA[", "]]>", "<?xml version='1.0'?>", "</svg>", "<svg>", "<", ">", "&", "\"", "'",
        "", "\xff\xfe", "<!DOCTYPE svg>", "<!ENTITY", "<?pi x?>", "</g>", "<g>", "<path d='M0 0 L1 1'/>"};
    if (random.one_in(4)) {  // truncate at a tag boundary
        std::vector<std::size_t> positions;
        for (std::size_t i = 0; i < text.size(); ++i)
            if (text[i] == '<') positions.push_back(i);
        if (positions.empty()) return false;
        text.resize(positions[random.below(positions.size())]);
        return true;
    }
    const std::size_t index = random.below(pieces.size());
    const std::string piece = index == 12 ? std::string(1, '\0') : std::string(pieces[index]);
    if (!room_for(text, piece.size(), max_size)) return false;
    text.insert(random.below(text.size() + 1), piece);
    return true;
}

}  // namespace ops

// ---- Binary ------------------------------------------------------------------

namespace {

std::uint32_t load_u32(const Bytes& bytes, std::size_t at) {
    return static_cast<std::uint32_t>(bytes[at]) | static_cast<std::uint32_t>(bytes[at + 1]) << 8 |
           static_cast<std::uint32_t>(bytes[at + 2]) << 16 | static_cast<std::uint32_t>(bytes[at + 3]) << 24;
}

void store_le(Bytes& bytes, std::size_t at, std::uint64_t value, std::size_t width) {
    for (std::size_t i = 0; i < width && at + i < bytes.size(); ++i) bytes[at + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

std::uint64_t odd_integer(MutationRandom& random) {
    static constexpr std::array<std::uint64_t, 18> values = {
        0, 1, 2, 0xffffffffULL, 0x7fffffffULL, 0x80000000ULL, static_cast<std::uint32_t>(-384), 0xffffffffffffffffULL,
        1000000000000ULL, 0x100000000ULL, 0xffffULL, 0x10000ULL, 0x7fffffffffffffffULL, 0x8000000000000000ULL,
        static_cast<std::uint64_t>(-384), 3, 0x40000000ULL, 0xfffffffeULL};
    return values[random.below(values.size())];
}

std::string glb_key_number(MutationRandom& random) {
    static const std::array<const char*, 14> numbers = {"-384", "1e12", "-1", "4294967295", "4294967296", "2147483647",
                                                        "2147483648", "1e999", "0", "3.5", "9007199254740993", "-0",
                                                        "1e308", "NaN"};
    return numbers[random.below(numbers.size())];
}

// Replaces the number after one of glTF's index or size keys.
bool gltf_key_value(std::string& json, MutationRandom& random) {
    static const std::array<const char*, 16> keys = {
        "\"byteOffset\"", "\"byteLength\"", "\"count\"", "\"bufferView\"", "\"buffer\"", "\"indices\"", "\"POSITION\"",
        "\"mesh\"", "\"componentType\"", "\"byteStride\"", "\"scene\"", "\"nodes\"", "\"accessor\"", "\"sampler\"",
        "\"input\"", "\"output\""};
    std::vector<std::size_t> found;
    for (const char* key : keys)
        for (std::size_t at = json.find(key); at != std::string::npos; at = json.find(key, at + 1)) found.push_back(at + std::strlen(key));
    if (found.empty()) return false;
    std::size_t at = found[random.below(found.size())];
    while (at < json.size() && (json[at] == ':' || std::isspace(static_cast<unsigned char>(json[at])) || json[at] == '[')) ++at;
    std::size_t end = at;
    while (end < json.size() && is_number_char(json[end])) ++end;
    if (end == at) return false;
    json.replace(at, end - at, glb_key_number(random));
    return true;
}

bool json_operation(std::string& text, MutationRandom& random, std::size_t max_size, std::string& name);

}  // namespace

namespace ops {

bool binary_odd_integer(Bytes& bytes, MutationRandom& random, std::size_t max_size) {
    if (bytes.size() < 4) return false;
    const std::size_t width = random.one_in(3) ? 8 : 4;
    if (bytes.size() < width) return false;
    std::size_t at = random.below(bytes.size() - width + 1);
    if (random.one_in(2)) at &= ~static_cast<std::size_t>(3);
    store_le(bytes, at, odd_integer(random), width);
    return true;
}

bool glb_mutate(Bytes& bytes, MutationRandom& random, std::size_t max_size) {
    if (bytes.size() < 20 || std::memcmp(bytes.data(), "glTF", 4) != 0) return binary_odd_integer(bytes, random, max_size);
    const std::size_t json_length = std::min<std::size_t>(load_u32(bytes, 12), bytes.size() - 20);
    if (random.one_in(5)) {  // the container itself: total length, chunk lengths, the BIN chunk header
        static constexpr std::array<std::size_t, 4> fields = {4, 8, 12, 16};
        std::size_t at = fields[random.below(fields.size())];
        if (random.one_in(3) && 20 + json_length + 8 <= bytes.size()) at = 20 + json_length + random.below(2) * 4;
        store_le(bytes, at, odd_integer(random), 4);
        return true;
    }
    std::string json(bytes.begin() + 20, bytes.begin() + static_cast<std::ptrdiff_t>(20 + json_length));
    const Bytes rest(bytes.begin() + static_cast<std::ptrdiff_t>(20 + json_length), bytes.end());
    const std::size_t room = max_size > bytes.size() ? max_size - bytes.size() + json.size() : json.size();
    std::string name;
    const bool changed = random.one_in(2) ? gltf_key_value(json, random) : json_operation(json, random, room, name);
    if (!changed) return false;
    if (!random.one_in(8))
        while (json.size() % 4) json += ' ';
    if (20 + json.size() + rest.size() > max_size) return false;
    Bytes out(bytes.begin(), bytes.begin() + 20);
    out.insert(out.end(), json.begin(), json.end());
    out.insert(out.end(), rest.begin(), rest.end());
    if (!random.one_in(8)) {  // usually a consistent container, so the JSON gets parsed
        store_le(out, 8, out.size(), 4);
        store_le(out, 12, json.size(), 4);
    }
    bytes = std::move(out);
    return true;
}

bool exr_mutate(Bytes& bytes, MutationRandom& random, std::size_t max_size) {
    struct Attribute {
        std::size_t name = 0;
        std::string type;
        std::size_t size_at = 0;  // the int32 size
        std::size_t value = 0;
        std::size_t size = 0;
    };
    std::vector<Attribute> attributes;
    std::size_t header_end = 0;
    if (bytes.size() > 8 && bytes[0] == 0x76 && bytes[1] == 0x2f && bytes[2] == 0x31 && bytes[3] == 0x01) {
        std::size_t at = 8;
        int empty_names = 0;
        while (at < bytes.size() && attributes.size() < 1000) {
            const auto nul = std::find(bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.end(), 0);
            if (nul == bytes.end()) break;
            const std::size_t name_end = static_cast<std::size_t>(nul - bytes.begin());
            if (name_end == at) {  // end of a header (multi-part: another may follow, two in a row end them)
                ++at;
                header_end = at;
                if (++empty_names == 2 || (load_u32(bytes, 4) & 0x1000) == 0) break;
                continue;
            }
            empty_names = 0;
            const auto type_nul = std::find(nul + 1, bytes.end(), 0);
            if (type_nul == bytes.end()) break;
            const std::size_t type_end = static_cast<std::size_t>(type_nul - bytes.begin());
            if (type_end + 5 > bytes.size()) break;
            Attribute attribute;
            attribute.name = at;
            attribute.type.assign(reinterpret_cast<const char*>(bytes.data() + name_end + 1), type_end - name_end - 1);
            attribute.size_at = type_end + 1;
            attribute.size = load_u32(bytes, attribute.size_at);
            attribute.value = attribute.size_at + 4;
            if (attribute.value + attribute.size > bytes.size()) break;
            attributes.push_back(attribute);
            at = attribute.value + attribute.size;
        }
    }
    if (attributes.empty()) return binary_odd_integer(bytes, random, max_size);
    if (header_end && header_end + 8 <= bytes.size() && random.one_in(6)) {  // the offset table
        const std::size_t entries = std::min<std::size_t>((bytes.size() - header_end) / 8, 64);
        store_le(bytes, header_end + 8 * random.below(entries), odd_integer(random), 8);
        return true;
    }
    const Attribute attribute = attributes[random.below(attributes.size())];
    switch (random.below(5)) {
        case 0: {  // an odd size
            static constexpr std::array<std::uint32_t, 7> sizes = {0xffffffffu, 0, 0x7fffffffu, 0x80000000u, 1u << 30, 1, 4};
            std::uint32_t size = sizes[random.below(sizes.size())];
            if (random.one_in(3)) size = static_cast<std::uint32_t>(attribute.size + (random.one_in(2) ? 1 : -1));
            store_le(bytes, attribute.size_at, size, 4);
            return true;
        }
        case 1:  // an odd integer inside the value (box2i corners, ints, chlist pixel types)
            if (attribute.size < 4) return false;
            store_le(bytes, attribute.value + (random.below(attribute.size / 4) * 4), odd_integer(random), 4);
            return true;
        case 2: {  // duplicate the attribute
            const Bytes copy(bytes.begin() + static_cast<std::ptrdiff_t>(attribute.name),
                             bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value + attribute.size));
            const std::size_t copies = fitting(random.one_in(4) ? 1000 : 1, copy.size(), bytes.size(), max_size);
            if (copies == 0) return false;
            for (std::size_t i = 0; i < copies; ++i)
                bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value + attribute.size), copy.begin(), copy.end());
            return true;
        }
        default: {  // a string value: its JSON mutated, or an odd string (size kept consistent)
            if (attribute.type != "string") return binary_odd_integer(bytes, random, max_size);
            std::string value(bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value),
                              bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value + attribute.size));
            std::string name;
            const std::size_t room = max_size > bytes.size() ? max_size - bytes.size() + value.size() : value.size();
            bool changed = false;
            if (value.find_first_of("{[") != std::string::npos && !random.one_in(4)) changed = json_operation(value, random, room, name);
            if (!changed) value = odd_strings()[random.below(odd_strings().size())];
            Bytes out(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value));
            out.insert(out.end(), value.begin(), value.end());
            out.insert(out.end(), bytes.begin() + static_cast<std::ptrdiff_t>(attribute.value + attribute.size), bytes.end());
            if (out.size() > max_size) return false;
            store_le(out, attribute.size_at, value.size(), 4);
            bytes = std::move(out);
            return true;
        }
    }
}

}  // namespace ops

// ---- Dispatch ----------------------------------------------------------------

namespace {

struct NamedTextOperation {
    const char* name;
    bool (*run)(std::string&, MutationRandom&, std::size_t);
    int weight;
};

bool run_weighted(const std::vector<NamedTextOperation>& operations, std::string& text, MutationRandom& random,
                  std::size_t max_size, std::string& name) {
    int total = 0;
    for (const NamedTextOperation& op : operations) total += op.weight;
    // A few tries: an operation may not apply (no number, no room).
    for (int attempt = 0; attempt < 4; ++attempt) {
        int pick = static_cast<int>(random.below(static_cast<std::size_t>(total)));
        for (const NamedTextOperation& op : operations) {
            if ((pick -= op.weight) >= 0) continue;
            if (op.run(text, random, max_size)) {
                name = op.name;
                return true;
            }
            break;
        }
    }
    return false;
}

bool json_operation(std::string& text, MutationRandom& random, std::size_t max_size, std::string& name) {
    static const std::vector<NamedTextOperation> operations = {
        {"json_odd_number", ops::json_odd_number, 6},   {"json_nest_deep", ops::json_nest_deep, 1},
        {"json_duplicate_key", ops::json_duplicate_key, 2}, {"json_many_keys", ops::json_many_keys, 1},
        {"json_huge_array", ops::json_huge_array, 2},   {"json_odd_string", ops::json_odd_string, 4},
        {"json_type_swap", ops::json_type_swap, 4},     {"json_splice_subtree", ops::json_splice_subtree, 3}};
    return run_weighted(operations, text, random, max_size, name);
}

bool svg_operation(std::string& text, MutationRandom& random, std::size_t max_size, std::string& name) {
    static const std::vector<NamedTextOperation> operations = {
        {"svg_many_attributes", ops::svg_many_attributes, 2}, {"svg_entity_amplification", ops::svg_entity_amplification, 2},
        {"svg_many_elements", ops::svg_many_elements, 2},     {"svg_nest_deep", ops::svg_nest_deep, 1},
        {"svg_odd_number", ops::svg_odd_number, 5},           {"svg_odd_attribute", ops::svg_odd_attribute, 4},
        {"svg_markup_noise", ops::svg_markup_noise, 2}};
    return run_weighted(operations, text, random, max_size, name);
}

}  // namespace

std::string structure_mutate(Bytes& bytes, InputKind kind, std::size_t max_size, std::uint64_t seed) {
    MutationRandom random(seed);
    const std::size_t rounds = random.one_in(4) ? 1 + random.below(3) : 1;
    std::string applied;
    for (std::size_t round = 0; round < rounds; ++round) {
        std::string name;
        bool changed = false;
        if (kind == InputKind::json || kind == InputKind::svg) {
            std::string text(bytes.begin(), bytes.end());
            changed = kind == InputKind::json ? json_operation(text, random, max_size, name)
                                              : svg_operation(text, random, max_size, name);
            if (changed) bytes.assign(text.begin(), text.end());
        } else if (kind == InputKind::glb) {
            changed = ops::glb_mutate(bytes, random, max_size);
            name = "glb";
        } else {
            changed = ops::exr_mutate(bytes, random, max_size);
            name = "exr";
        }
        if (changed) applied += (applied.empty() ? "" : "+") + name;
    }
    return applied;
}

}  // namespace flowvid::fuzz
