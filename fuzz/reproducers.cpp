#include "reproducers.hpp"

namespace flowvid::fuzz {

namespace {

Bytes bytes_of(const std::string& text) { return Bytes(text.begin(), text.end()); }

std::string repeat(const std::string& unit, std::size_t count) {
    std::string out;
    out.reserve(unit.size() * count);
    for (std::size_t i = 0; i < count; ++i) out += unit;
    return out;
}

}  // namespace

std::vector<Reproducer> generated_reproducers() {
    std::vector<Reproducer> cases;

    // '[' * 100000 + ']' * 100000 in a .fabric.json: stack overflow.
    cases.push_back({"fabric_json", "deep_nesting_100000.fabric.json", "'['*100000+']'*100000 in a .fabric.json",
                     bytes_of(std::string(100000, '[') + std::string(100000, ']'))});
    // The same depth inside a valid-looking document, as objects.
    cases.push_back({"flowlines_json", "deep_objects_100000.flowlines.json",
                     "100000 nested objects in a flow-line set's description",
                     bytes_of("{\"format\":\"flowvid.flowlines\",\"version\":\"1.0\",\"description\":" +
                              repeat("{\"a\":", 100000) + "0" + std::string(100000, '}') + "}")});

    // 300 000 attributes on one <path>.
    {
        std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"64\" height=\"48\">"
                          "<g id=\"input\"><path id=\"in0\" d=\"M1 1 L10 10\"";
        for (int i = 0; i < 300000; ++i) svg += " a" + std::to_string(i) + "=\"1\"";
        svg += "/></g></svg>";
        cases.push_back({"flowlines_svg", "attributes_300000.svg", "300 000 attributes on one SVG <path>", bytes_of(svg)});
    }

    // One 100 KB entity used 10 000 times: entity amplification (1 GB expanded).
    {
        std::string body = "M0 0";
        while (body.size() < 100000) body += " L1 1";
        const std::string svg = "<?xml version=\"1.0\"?><!DOCTYPE svg [<!ENTITY big \"" + body +
                                "\">]><svg xmlns=\"http://www.w3.org/2000/svg\" width=\"64\" height=\"48\">"
                                "<g id=\"input\"><path id=\"in0\" d=\"" + repeat("&big;", 10000) + "\"/></g></svg>";
        cases.push_back({"flowlines_svg", "entity_100kb_x_10000.svg", "one 100 KB SVG entity used 10 000 times",
                         bytes_of(svg)});
    }
    // Billion laughs: 10 levels of 10 references (10^10 expansions of 3 bytes).
    {
        std::string doctype = "<!DOCTYPE svg [<!ENTITY e0 \"L1 1\">";
        for (int level = 1; level <= 10; ++level)
            doctype += "<!ENTITY e" + std::to_string(level) + " \"" + repeat("&e" + std::to_string(level - 1) + ";", 10) + "\">";
        doctype += "]>";
        const std::string svg = doctype + "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"64\" height=\"48\">"
                                          "<g id=\"input\"><path id=\"in0\" d=\"M0 0 &e10;\"/></g></svg>";
        cases.push_back({"flowlines_svg", "billion_laughs.svg", "nested entities (10 levels x 10 references)", bytes_of(svg)});
    }

    // 100 000 input + 100 000 output lines: a quadratic `from` lookup.
    {
        std::string json = "{\"format\":\"flowvid.flowlines\",\"version\":\"1.0\",\"image\":{\"width\":1920,\"height\":1080,"
                           "\"pixel_convention\":\"opencv\"},\"inputs\":[";
        for (int i = 0; i < 100000; ++i)
            json += (i ? "," : "") + std::string("{\"id\":\"in") + std::to_string(i) + "\",\"points\":[[1,1],[10,10]]}";
        json += "],\"outputs\":[";
        // Each output names an input near the end, so a linear search walks them all.
        for (int i = 0; i < 100000; ++i)
            json += (i ? "," : "") + std::string("{\"id\":\"out") + std::to_string(i) + "\",\"from\":\"in" +
                    std::to_string(99999 - (i % 1000)) + "\",\"points\":[[1,1],[10,10]]}";
        json += "]}";
        cases.push_back({"flowlines_json", "lines_100000_in_100000_out.flowlines.json",
                         "100 000 input + 100 000 output flow lines", bytes_of(json)});
    }

    // 500 000 duplicate fit-shard parameters.
    {
        std::string json = "{\"format\":\"flowvid.fit_shard\",\"version\":\"1.0\",\"kind\":\"cloth\",\"request\":"
                           "{\"software\":\"flowvid 0.1.0\",\"captures\":[{\"path\":\"c\",\"capture_json_sha256\":\"" +
                           std::string(64, 'a') + "\"}],\"options\":{}},\"fingerprint_sha256\":\"" + std::string(64, 'b') +
                           "\",\"shard\":{\"index\":1,\"count\":1},\"result\":{\"parameters\":[";
        for (int i = 0; i < 500000; ++i) json += (i ? "," : "") + std::string("{\"name\":\"bend_stiffness_N_m\",\"value\":1}");
        json += "],\"error\":1,\"evaluations\":1,\"status\":\"converged\"}}";
        cases.push_back({"fit_shard", "parameters_500000_duplicates.fit_shard.json", "500 000 duplicate fit-shard parameters",
                         bytes_of(json)});
    }

    // A 1 MB string where a file name is expected.
    cases.push_back({"capture_json", "frames_pattern_1mb.json", "a 1 MB frame pattern",
                     bytes_of("{\"format\":\"flowvid.capture\",\"version\":1,\"kind\":\"video.flow\",\"fps\":25,"
                              "\"frames\":{\"pattern\":\"" + std::string(1 << 20, 'A') + "%06d.png\",\"first\":1,\"count\":3},"
                              "\"flowlines\":\"flowlines.svg\"}")});
    return cases;
}

}  // namespace flowvid::fuzz
