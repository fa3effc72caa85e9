#include "flowvid/formats/fabric_usda.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <locale>
#include <ostream>
#include <sstream>

namespace flowvid::formats {

const UsdaAttribute* UsdaPrim::attribute(const std::string& attribute_name) const {
    for (const UsdaAttribute& a : attributes)
        if (a.name == attribute_name) return &a;
    return nullptr;
}

// ---- Reading the usda subset -------------------------------------------------
namespace {

constexpr int kMaxUsdaNesting = 64;  // prims in prims, arrays in arrays: far more than a material needs

struct Token {
    enum class Kind { end, punct, string, number, identifier, path } kind = Kind::end;
    std::string text;
    int line = 0;
};

class Tokenizer {
public:
    Tokenizer(const std::string& text, Diagnostics& diagnostics) : m_text(text), m_diag(diagnostics) {}

    // Every token up to the end; false after reporting a lexical error.
    bool run(std::vector<Token>& tokens) {
        while (true) {
            skip_space_and_comments();
            if (m_pos >= m_text.size()) {
                tokens.push_back({Token::Kind::end, "", m_line});
                return true;
            }
            std::optional<Token> token = next();
            if (!token) return false;
            tokens.push_back(*token);
        }
    }

private:
    void skip_space_and_comments() {
        while (m_pos < m_text.size()) {
            const char c = m_text[m_pos];
            if (c == '\n') ++m_line;
            if (std::isspace(static_cast<unsigned char>(c))) {
                ++m_pos;
            } else if (c == '#') {
                while (m_pos < m_text.size() && m_text[m_pos] != '\n') ++m_pos;
            } else {
                return;
            }
        }
    }

    bool error(const std::string& message, const std::string& fix) {
        m_diag.error("line " + std::to_string(m_line), message, fix);
        return false;
    }

    std::optional<Token> next() {
        const char c = m_text[m_pos];
        const int line = m_line;
        if (c == '"' || c == '\'') return string_token(line);
        if (c == '<') {
            const std::size_t close = m_text.find('>', m_pos);
            if (close == std::string::npos || m_text.find('\n', m_pos) < close) {
                error("unterminated path (no closing '>')", "write a path as </Prim/Child>");
                return std::nullopt;
            }
            Token token{Token::Kind::path, m_text.substr(m_pos + 1, close - m_pos - 1), line};
            m_pos = close + 1;
            return token;
        }
        if (std::isdigit(static_cast<unsigned char>(c)) || c == '-' || c == '+' || c == '.') {
            std::size_t end = m_pos + 1;
            while (end < m_text.size() && (std::isalnum(static_cast<unsigned char>(m_text[end])) || m_text[end] == '.' ||
                                           ((m_text[end] == '-' || m_text[end] == '+') &&
                                            (m_text[end - 1] == 'e' || m_text[end - 1] == 'E'))))
                ++end;
            Token token{Token::Kind::number, m_text.substr(m_pos, end - m_pos), line};
            m_pos = end;
            return token;
        }
        if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
            std::size_t end = m_pos + 1;
            while (end < m_text.size() && (std::isalnum(static_cast<unsigned char>(m_text[end])) || m_text[end] == '_' ||
                                           m_text[end] == ':' || m_text[end] == '.'))
                ++end;
            Token token{Token::Kind::identifier, m_text.substr(m_pos, end - m_pos), line};
            m_pos = end;
            return token;
        }
        if (std::string("()[]{}=,;").find(c) != std::string::npos) {
            ++m_pos;
            return Token{Token::Kind::punct, std::string(1, c), line};
        }
        error(std::string("unexpected character '") + c + "'", "this file is not usda text flowvid can read");
        return std::nullopt;
    }

    std::optional<Token> string_token(int line) {
        const char quote = m_text[m_pos];
        const bool triple = m_text.compare(m_pos, 3, std::string(3, quote)) == 0;
        m_pos += triple ? 3 : 1;
        std::string value;
        while (m_pos < m_text.size()) {
            const char c = m_text[m_pos];
            if (triple ? m_text.compare(m_pos, 3, std::string(3, quote)) == 0 : c == quote) {
                m_pos += triple ? 3 : 1;
                return Token{Token::Kind::string, value, line};
            }
            if (c == '\n') {
                if (!triple) break;
                ++m_line;
            }
            if (c == '\\' && m_pos + 1 < m_text.size()) {
                const char escaped = m_text[m_pos + 1];
                switch (escaped) {
                    case 'n': value += '\n'; break;
                    case 't': value += '\t'; break;
                    case 'r': value += '\r'; break;
                    default: value += escaped; break;  // \" \' \\ and anything else as itself
                }
                m_pos += 2;
                continue;
            }
            value += c;
            ++m_pos;
        }
        m_line = line;
        error("unterminated string", "close the string with its quote on the same line (or use \"\"\" for several lines)");
        return std::nullopt;
    }

    const std::string& m_text;
    Diagnostics& m_diag;
    std::size_t m_pos = 0;
    int m_line = 1;
};

bool is_list_op(const std::string& word) {
    return word == "prepend" || word == "append" || word == "add" || word == "delete" || word == "reorder";
}

class Parser {
public:
    Parser(std::vector<Token> tokens, Diagnostics& diagnostics) : m_tokens(std::move(tokens)), m_diag(diagnostics) {}

    std::optional<UsdaLayer> layer() {
        UsdaLayer result;
        if (is_punct("(")) {
            std::optional<nlohmann::json> metadata = metadata_block(0);
            if (!metadata) return std::nullopt;
            result.metadata = *metadata;
        }
        while (peek().kind != Token::Kind::end) {
            std::optional<UsdaPrim> p = prim(0);
            if (!p) return std::nullopt;
            result.prims.push_back(std::move(*p));
        }
        return result;
    }

private:
    const Token& peek() const { return m_tokens[m_index]; }
    const Token& take() { return m_tokens[m_index < m_tokens.size() - 1 ? m_index++ : m_index]; }
    bool is_punct(const char* p) const { return peek().kind == Token::Kind::punct && peek().text == p; }

    bool fail(const Token& at, const std::string& message, const std::string& fix) {
        m_diag.error("line " + std::to_string(at.line), message, fix);
        return false;
    }
    bool expect(const char* p, const std::string& where) {
        if (is_punct(p)) {
            take();
            return true;
        }
        const Token& at = peek();
        return fail(at, std::string("expected '") + p + "' " + where + ", found " +
                            (at.kind == Token::Kind::end ? std::string("the end of the file") : "'" + at.text + "'"),
                    "check the brackets and quotes above this line");
    }
    bool too_deep(int depth) {
        if (depth < kMaxUsdaNesting) return false;
        fail(peek(), "nested more than " + std::to_string(kMaxUsdaNesting) + " levels deep", "flatten the file");
        return true;
    }

    // ( key = value  key = value  "doc string" ... )
    std::optional<nlohmann::json> metadata_block(int depth) {
        if (too_deep(depth) || !expect("(", "to open metadata")) return std::nullopt;
        nlohmann::json metadata = nlohmann::json::object();
        while (!is_punct(")")) {
            const Token& at = peek();
            if (at.kind == Token::Kind::string) {
                metadata["doc"] = take().text;
                continue;
            }
            if (at.kind == Token::Kind::punct && at.text == ";") {
                take();
                continue;
            }
            if (at.kind != Token::Kind::identifier) {
                fail(at, "expected a metadata name, found '" + at.text + "'", "write metadata as name = value");
                return std::nullopt;
            }
            std::string key = take().text;
            std::string list_op;
            if (is_list_op(key) && peek().kind == Token::Kind::identifier) {
                list_op = key;
                key = take().text;
            }
            if (!expect("=", "after metadata \"" + key + "\"")) return std::nullopt;
            std::optional<nlohmann::json> v = value(depth + 1);
            if (!v) return std::nullopt;
            metadata[key] = *v;
            if (!list_op.empty()) metadata[key + ":listOp"] = list_op;
        }
        take();
        return metadata;
    }

    std::optional<nlohmann::json> value(int depth) {
        if (too_deep(depth)) return std::nullopt;
        const Token& at = peek();
        switch (at.kind) {
            case Token::Kind::string:
            case Token::Kind::path: return nlohmann::json(take().text);
            case Token::Kind::number: {
                const Token token = take();
                return number(token);
            }
            case Token::Kind::identifier: {
                const Token token = take();
                if (token.text == "true") return nlohmann::json(true);
                if (token.text == "false") return nlohmann::json(false);
                if (token.text == "None") return nlohmann::json(nullptr);
                if (token.text == "inf" || token.text == "nan") return number(token);
                return nlohmann::json(token.text);  // a token value, e.g. "ANGULAR"
            }
            case Token::Kind::punct:
                if (at.text == "(" || at.text == "[") return sequence(at.text == "(" ? ")" : "]", depth);
                if (at.text == "{") return dictionary(depth);
                break;
            case Token::Kind::end: break;
        }
        fail(at, "expected a value, found " + (at.kind == Token::Kind::end ? std::string("the end of the file") : "'" + at.text + "'"),
             "write a number, a \"string\", a (tuple) or an [array]");
        return std::nullopt;
    }

    std::optional<nlohmann::json> number(const Token& token) {
        std::string text = token.text;
        double sign = 1.0;
        if (!text.empty() && (text[0] == '-' || text[0] == '+')) {
            sign = text[0] == '-' ? -1.0 : 1.0;
            text = text.substr(1);
        }
        if (text == "inf") return nlohmann::json(sign * std::numeric_limits<double>::infinity());
        if (text == "nan") return nlohmann::json(std::numeric_limits<double>::quiet_NaN());
        std::istringstream in(text);
        in.imbue(std::locale::classic());
        double parsed = 0.0;
        in >> parsed;
        if (in.fail() || !in.eof() || text.empty() || !(std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '.')) {
            fail(token, "\"" + token.text + "\" is not a number", "write numbers as 12, 0.5 or 2e-05");
            return std::nullopt;
        }
        return nlohmann::json(sign * parsed);
    }

    std::optional<nlohmann::json> sequence(const char* close, int depth) {
        take();
        nlohmann::json items = nlohmann::json::array();
        while (!is_punct(close)) {
            std::optional<nlohmann::json> item = value(depth + 1);
            if (!item) return std::nullopt;
            items.push_back(*item);
            if (is_punct(",")) take();
            else if (!is_punct(close)) {
                expect(close, "or ',' between values");
                return std::nullopt;
            }
        }
        take();
        return items;
    }

    // { type "key" = value ... } (customLayerData, customData)
    std::optional<nlohmann::json> dictionary(int depth) {
        take();
        nlohmann::json entries = nlohmann::json::object();
        while (!is_punct("}")) {
            if (is_punct(";") || is_punct(",")) {
                take();
                continue;
            }
            if (peek().kind != Token::Kind::identifier) {
                fail(peek(), "expected a type name in a dictionary, found '" + peek().text + "'",
                     "write dictionary entries as type \"key\" = value");
                return std::nullopt;
            }
            take();  // the entry's type
            if (is_punct("[")) {
                take();
                if (!expect("]", "after '[' in an array type")) return std::nullopt;
            }
            const Token& key = peek();
            if (key.kind != Token::Kind::string && key.kind != Token::Kind::identifier) {
                fail(key, "expected a dictionary key", "write dictionary entries as type \"key\" = value");
                return std::nullopt;
            }
            const std::string name = take().text;
            if (!expect("=", "after dictionary key \"" + name + "\"")) return std::nullopt;
            std::optional<nlohmann::json> v = value(depth + 1);
            if (!v) return std::nullopt;
            entries[name] = *v;
        }
        take();
        return entries;
    }

    std::optional<UsdaPrim> prim(int depth) {
        if (too_deep(depth)) return std::nullopt;
        const Token& start = peek();
        if (start.kind != Token::Kind::identifier ||
            (start.text != "def" && start.text != "over" && start.text != "class")) {
            fail(start, "expected a prim (def, over or class), found '" + start.text + "'",
                 "a usda layer holds prims: def Type \"Name\" { ... }");
            return std::nullopt;
        }
        UsdaPrim result;
        result.line = start.line;
        result.specifier = take().text;
        if (peek().kind == Token::Kind::identifier) result.type_name = take().text;
        if (peek().kind != Token::Kind::string) {
            fail(peek(), "expected the prim's name in quotes", "write def Material \"Fabric\" { ... }");
            return std::nullopt;
        }
        result.name = take().text;
        if (is_punct("(")) {
            std::optional<nlohmann::json> metadata = metadata_block(depth + 1);
            if (!metadata) return std::nullopt;
            result.metadata = *metadata;
        }
        if (!expect("{", "to open prim \"" + result.name + "\"")) return std::nullopt;
        while (!is_punct("}")) {
            if (peek().kind == Token::Kind::end) {
                expect("}", "to close prim \"" + result.name + "\"");
                return std::nullopt;
            }
            const std::string& word = peek().text;
            if (word == "def" || word == "over" || word == "class") {
                std::optional<UsdaPrim> child = prim(depth + 1);
                if (!child) return std::nullopt;
                result.children.push_back(std::move(*child));
            } else {
                std::optional<UsdaAttribute> a = property(depth + 1);
                if (!a) return std::nullopt;
                if (!a->type.empty()) result.attributes.push_back(std::move(*a));
            }
        }
        take();
        return result;
    }

    // [custom] [uniform] type[[]] name [= value] [( metadata )]; rel name [= <path>]
    std::optional<UsdaAttribute> property(int depth) {
        UsdaAttribute a;
        a.line = peek().line;
        if (peek().kind != Token::Kind::identifier) {
            fail(peek(), "expected an attribute, found '" + peek().text + "'",
                 "write attributes as type name = value, e.g. float physics:density = 150");
            return std::nullopt;
        }
        bool relationship = false;
        while (peek().kind == Token::Kind::identifier &&
               (peek().text == "custom" || peek().text == "uniform" || peek().text == "varying" || peek().text == "config")) {
            const std::string word = take().text;
            a.custom = a.custom || word == "custom";
            a.uniform = a.uniform || word == "uniform";
        }
        if (peek().kind != Token::Kind::identifier) {
            fail(peek(), "expected a type name", "write attributes as type name = value");
            return std::nullopt;
        }
        a.type = take().text;
        relationship = a.type == "rel";
        if (is_punct("[")) {
            take();
            if (!expect("]", "after '[' in an array type")) return std::nullopt;
            a.type += "[]";
        }
        if (peek().kind != Token::Kind::identifier) {
            fail(peek(), "expected the attribute's name after its type \"" + a.type + "\"",
                 "write attributes as type name = value");
            return std::nullopt;
        }
        const Token& name = peek();
        a.name = take().text;
        const std::size_t dot = a.name.find('.');
        if (dot != std::string::npos) {
            fail(name, "\"" + a.name + "\": time samples and connections are not read by flowvid",
                 "give the attribute one default value: " + a.type + " " + a.name.substr(0, dot) + " = ...");
            return std::nullopt;
        }
        if (is_punct("=")) {
            take();
            std::optional<nlohmann::json> v = value(depth + 1);
            if (!v) return std::nullopt;
            a.value = *v;
        }
        if (is_punct("(")) {
            std::optional<nlohmann::json> metadata = metadata_block(depth + 1);
            if (!metadata) return std::nullopt;
            a.metadata = *metadata;
        }
        if (relationship) a.type.clear();  // relationships are not attributes: skipped by the caller
        return a;
    }

    std::vector<Token> m_tokens;
    std::size_t m_index = 0;
    Diagnostics& m_diag;
};

}  // namespace

std::optional<UsdaLayer> parse_usda(const std::string& text, Diagnostics& diagnostics) {
    const std::size_t first_line_end = text.find('\n');
    const std::string first_line = text.substr(0, first_line_end);
    if (first_line.rfind("#usda 1.0", 0) != 0) {
        diagnostics.error("line 1", "not usda text (the first line is not \"#usda 1.0\")",
                          "give a .usda file (binary .usdc/.usd files are not read; usdcat converts them)");
        return std::nullopt;
    }
    std::vector<Token> tokens;
    Tokenizer tokenizer(text, diagnostics);
    if (!tokenizer.run(tokens)) return std::nullopt;
    Parser parser(std::move(tokens), diagnostics);
    return parser.layer();
}

// ---- Writing -------------------------------------------------------------------
namespace {

std::string quoted(const std::string& text) {
    std::string out = "\"";
    for (char c : text) {
        switch (c) {
            case '"': out += "\\\""; break;
            case '\\': out += "\\\\"; break;
            case '\n': out += "\\n"; break;
            case '\r': out += "\\r"; break;
            case '\t': out += "\\t"; break;
            default: out += c; break;
        }
    }
    return out + "\"";
}

// The shortest of 15, 16 or 17 significant digits that reads back as the same double.
std::string format_double(double value) {
    char text[40];
    for (int digits = 15; digits <= 17; ++digits) {
        std::snprintf(text, sizeof text, "%.*g", digits, value);
        if (std::strtod(text, nullptr) == value) break;
    }
    return text;
}

// The proposal's attributes are float: written with the digits that bring the float back.
std::string format_float(double value) {
    char text[40];
    std::snprintf(text, sizeof text, "%.9g", static_cast<double>(static_cast<float>(value)));
    return text;
}

struct StandardAttribute {
    const char* name;
    const char* unit;  // in the proposal's words, for the doc
    double value;      // SI
    std::string doc;
};

std::vector<StandardAttribute> standard_attributes(const FabricParameters& p) {
    const double warp = p.stretch_warp_stiffness_N_per_m.value;
    const double weft = p.stretch_weft_stiffness_N_per_m.value;
    std::string stretch_doc = "N/m (force/distance). ";
    stretch_doc += warp == weft ? "The preset is isotropic: warp = weft."
                                : "Mean of warp (" + format_double(warp) + ") and weft (" + format_double(weft) +
                                      "): the proposal's surface stiffness is isotropic; flowvid:stretch_*_stiffness_N_per_m "
                                      "keep both.";
    return {
        {"physics:density", "mass/distance^3",
         p.areal_density_kg_per_m2.value / kUsdDefaultShellThicknessM,
         "kg/m^3. flowvid:areal_density_kg_per_m2 (" + format_double(p.areal_density_kg_per_m2.value) +
             " kg/m^2) over the proposal's default shell thickness of 1e-3 m; if you author physics:thicknesses, "
             "set this to the areal density divided by that thickness."},
        {"physics:surfaceStretchStiffness", "force/distance", 0.5 * (warp + weft), stretch_doc},
        {"physics:surfaceShearStiffness", "force/distance", p.shear_stiffness_N_per_m.value,
         "N/m (force/distance): in-plane shear, per rest area as in the preset."},
        {"physics:surfaceBendStiffness", "force*distance", p.bend_stiffness_N_m.value,
         "N m (force*distance): the plate bending stiffness."},
    };
}

}  // namespace

std::string fabric_preset_to_usda(const FabricPreset& preset) {
    std::ostringstream out;
    out.imbue(std::locale::classic());
    out << "#usda 1.0\n"
        << "(\n"
        << "    doc = " << quoted("Fabric preset \"" + preset.name + "\" written by flowvid " FLOWVID_VERSION_STRING
                                  " as a physics material of the OpenUSD deformable-body proposal "
                                  "(OpenUSD-proposals pull request 111). SI units: metersPerUnit = 1, kilogramsPerUnit = 1. "
                                  "flowvid: attributes hold every preset parameter with its uncertainty and range.")
        << "\n"
        << "    defaultPrim = " << quoted(kFabricUsdaPrimName) << "\n"
        << "    metersPerUnit = 1\n"
        << "    kilogramsPerUnit = 1\n"
        << "    customLayerData = {\n"
        << "        string \"flowvid:format\" = " << quoted(kFabricFormatName) << "\n"
        << "        string \"flowvid:version\" = " << quoted(kFabricFormatVersion.to_string()) << "\n"
        << "    }\n"
        << ")\n\n"
        << "def Material " << quoted(kFabricUsdaPrimName) << " (\n"
        << "    prepend apiSchemas = [\"PhysicsMaterialAPI\", \"PhysicsSurfaceDeformableMaterialAPI\"]\n"
        << ")\n"
        << "{\n";
    for (const StandardAttribute& a : standard_attributes(preset.parameters))
        out << "    float " << a.name << " = " << format_float(a.value) << " (\n        doc = " << quoted(a.doc)
            << "\n    )\n";
    out << "\n"
        << "    custom string flowvid:name = " << quoted(preset.name) << "\n";
    if (!preset.description.empty()) out << "    custom string flowvid:description = " << quoted(preset.description) << "\n";
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        const FabricParameter& p = preset.parameters.*info.member;
        const std::string name = std::string(kFabricUsdaNamespace) + info.key;
        out << "    custom double " << name << " = " << format_double(p.value) << " (\n        doc = "
            << quoted(std::string(info.unit) + ": " + info.meaning) << "\n    )\n";
        if (p.uncertainty) out << "    custom double " << name << ":uncertainty = " << format_double(*p.uncertainty) << "\n";
        if (p.range)
            out << "    custom double2 " << name << ":range = (" << format_double((*p.range)[0]) << ", "
                << format_double((*p.range)[1]) << ")\n";
    }
    // Provenance and adapters are structured: kept as the preset's own JSON.
    nlohmann::json document = fabric_preset_to_json(preset);
    out << "    custom string flowvid:provenance = " << quoted(document["provenance"].dump()) << "\n";
    if (document.contains("adapters"))
        out << "    custom string flowvid:adapters = " << quoted(document["adapters"].dump()) << "\n";
    out << "}\n";
    return out.str();
}

namespace {

void find_fabric_prim(const std::vector<UsdaPrim>& prims, const std::string& path, const UsdaPrim*& found,
                      std::string& found_path) {
    for (const UsdaPrim& prim : prims) {
        if (found) return;
        const std::string here = path + "/" + prim.name;
        if (prim.attribute(std::string(kFabricUsdaNamespace) + "areal_density_kg_per_m2")) {
            found = &prim;
            found_path = here;
            return;
        }
        find_fabric_prim(prim.children, here, found, found_path);
    }
}

// "/parameters/KEY/value" -> "/Fabric.flowvid:KEY"; "/provenance/x" -> "/Fabric.flowvid:provenance (JSON /x)".
std::string usda_field(const std::string& prim_path, const std::string& pointer) {
    std::vector<std::string> parts;
    std::size_t start = 1;
    while (start <= pointer.size() && !pointer.empty()) {
        const std::size_t slash = pointer.find('/', start);
        parts.push_back(pointer.substr(start, slash == std::string::npos ? std::string::npos : slash - start));
        if (slash == std::string::npos) break;
        start = slash + 1;
    }
    const std::string ns = prim_path + "." + kFabricUsdaNamespace;
    if (parts.size() >= 2 && parts[0] == "parameters") {
        std::string field = ns + parts[1];
        if (parts.size() >= 3 && parts[2] != "value") field += ":" + parts[2];
        return field;
    }
    if (!parts.empty() && (parts[0] == "provenance" || parts[0] == "adapters")) {
        const std::string rest = pointer.substr(1 + parts[0].size());
        return ns + parts[0] + (rest.empty() ? "" : " (JSON " + rest + ")");
    }
    if (!parts.empty()) return ns + parts[0];
    return prim_path;
}

}  // namespace

std::optional<FabricPreset> parse_fabric_usda(const std::string& text, Diagnostics& diagnostics, Strictness strictness) {
    std::optional<UsdaLayer> layer = parse_usda(text, diagnostics);
    if (!layer) return std::nullopt;
    const UsdaPrim* prim = nullptr;
    std::string prim_path;
    find_fabric_prim(layer->prims, "", prim, prim_path);
    if (!prim) {
        diagnostics.error("", "no prim carries flowvid:areal_density_kg_per_m2: this is not a fabric preset written by flowvid",
                          "flowvid reads back the .usda files it wrote (flowvid convert PRESET.fabric.json OUT.usda)");
        return std::nullopt;
    }

    // The preset document from the flowvid: attributes.
    nlohmann::json document = nlohmann::json::object();
    std::string version = kFabricFormatVersion.to_string();
    if (layer->metadata.contains("customLayerData") && layer->metadata["customLayerData"].is_object() &&
        layer->metadata["customLayerData"].contains("flowvid:version") &&
        layer->metadata["customLayerData"]["flowvid:version"].is_string())
        version = layer->metadata["customLayerData"]["flowvid:version"].get<std::string>();
    document["format"] = kFabricFormatName;
    document["version"] = version;
    nlohmann::json parameters = nlohmann::json::object();
    const std::string ns = kFabricUsdaNamespace;
    bool types_ok = true;
    auto field_of = [&](const UsdaAttribute& a) { return prim_path + "." + a.name + " (line " + std::to_string(a.line) + ")"; };
    for (const UsdaAttribute& a : prim->attributes) {
        if (a.name.rfind(ns, 0) != 0) continue;
        const std::string rest = a.name.substr(ns.size());
        if (rest == "name" || rest == "description") {
            if (!a.value.is_string()) {
                diagnostics.error(field_of(a), "expected a string", "write custom string " + a.name + " = \"...\"");
                types_ok = false;
            } else {
                document[rest] = a.value;
            }
            continue;
        }
        if (rest == "provenance" || rest == "adapters") {
            Diagnostics inner(diagnostics.file());
            std::optional<nlohmann::json> parsed =
                a.value.is_string() ? parse_json_text(a.value.get<std::string>(), inner) : std::nullopt;
            if (!parsed) {
                diagnostics.error(field_of(a), "expected a string holding the preset's " + rest + " as JSON",
                                  "write it back as flowvid convert wrote it, or convert the preset again");
                types_ok = false;
            } else {
                document[rest] = *parsed;
            }
            continue;
        }
        std::string key = rest;
        std::string part = "value";
        for (const char* suffix : {":uncertainty", ":range"}) {
            const std::string s = suffix;
            if (key.size() > s.size() && key.compare(key.size() - s.size(), s.size(), s) == 0) {
                key = key.substr(0, key.size() - s.size());
                part = s.substr(1);
            }
        }
        const bool range = part == "range";
        const bool numeric = range ? (a.value.is_array() && a.value.size() == 2 && a.value[0].is_number() &&
                                      a.value[1].is_number())
                                   : a.value.is_number();
        if (!numeric) {
            diagnostics.error(field_of(a), range ? "expected two numbers (min, max)" : "expected a number",
                              range ? "write custom double2 " + a.name + " = (min, max)"
                                    : "write custom double " + a.name + " = VALUE");
            types_ok = false;
            continue;
        }
        parameters[key][part] = a.value;
    }
    document["parameters"] = parameters;
    if (!types_ok) return std::nullopt;

    Diagnostics inner(diagnostics.file());
    std::optional<FabricPreset> preset = parse_fabric_preset(document, inner, strictness);
    std::vector<Problem> problems = inner.problems();
    for (Problem& problem : problems) problem.field = usda_field(prim_path, problem.field);
    diagnostics.merge(problems);
    if (diagnostics.has_errors() || !preset) return std::nullopt;

    // The proposal's attributes in the layer's units (USD's fallbacks: 0.01 m and 1 kg per unit).
    auto unit = [&](const char* key, double fallback) {
        return layer->metadata.contains(key) && layer->metadata[key].is_number() ? layer->metadata[key].get<double>()
                                                                                 : fallback;
    };
    const double m = unit("metersPerUnit", 0.01);
    const double kg = unit("kilogramsPerUnit", 1.0);
    const std::vector<StandardAttribute> expected = standard_attributes(preset->parameters);
    const double to_si[] = {kg / (m * m * m), kg, kg, kg * m * m};  // density, stretch, shear, bend (time in s)
    for (std::size_t i = 0; i < expected.size(); ++i) {
        const UsdaAttribute* a = prim->attribute(expected[i].name);
        if (!a || !a->value.is_number()) continue;
        const double si = a->value.get<double>() * to_si[i];
        if (std::abs(si - expected[i].value) > 1e-6 * std::abs(expected[i].value))
            diagnostics.warning(prim_path + "." + a->name + " (line " + std::to_string(a->line) + ")",
                                format_double(si) + " (SI) disagrees with the flowvid: parameters, which give " +
                                    format_double(expected[i].value) + "; the flowvid: values are used",
                                "edit the flowvid: attributes (SI) to change the fabric, then convert again");
    }
    return preset;
}

void write_fabric_usda(const std::string& path, const FabricPreset& preset) {
    check_fabric_preset_before_writing(path, preset);  // finite values, valid ranges, naming the preset field
    const std::string text = fabric_preset_to_usda(preset);
    Diagnostics check(path);
    parse_fabric_usda(text, check, Strictness::strict);
    check.throw_if_errors();
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

FabricPreset read_fabric_usda(const std::string& path, std::vector<Problem>* warnings) {
    Diagnostics diagnostics(path);
    const std::string text = read_text_or_throw(path);
    std::optional<FabricPreset> preset = parse_fabric_usda(text, diagnostics, Strictness::lenient);
    diagnostics.throw_if_errors();
    if (!preset) throw ValidationError({Problem{Problem::Severity::error, path, "", "could not be read", ""}});
    if (warnings) *warnings = diagnostics.warnings();
    return std::move(*preset);
}

std::vector<Problem> validate_fabric_usda_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    if (std::optional<std::string> text = read_text_reporting(path, diagnostics))
        parse_fabric_usda(*text, diagnostics, strictness);
    return diagnostics.problems();
}

}  // namespace flowvid::formats
