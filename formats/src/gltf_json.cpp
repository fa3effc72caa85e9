#include "gltf_json.hpp"

#include "flowvid/formats/json_fields.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

namespace flowvid::formats::detail {
namespace {

constexpr const char* kChunkField = "GLB chunk 0 (JSON), ";
constexpr double kMaxGltfInteger = std::numeric_limits<std::int32_t>::max();

class IndexChecker {
public:
    explicit IndexChecker(Diagnostics& diag) : m_diag(diag) {}

    // `value[key]`, when present, must be a whole number in [0, 2^31 - 1].
    void check(const nlohmann::json& value, const std::string& pointer, const char* key) {
        if (!value.is_object()) return;
        const auto found = value.find(key);
        if (found == value.end()) return;
        check_number(*found, json_pointer_child(pointer, key));
    }

    void check_number(const nlohmann::json& value, const std::string& pointer) {
        const bool whole = value.is_number_integer() || value.is_number_unsigned() ||
                           (value.is_number_float() && std::floor(value.get<double>()) == value.get<double>());
        if (whole) {
            const double number = value.get<double>();
            if (number >= 0.0 && number <= kMaxGltfInteger) return;
        }
        std::string shown = value.is_number() || value.is_boolean() ? value.dump() : std::string(value.type_name());
        if (shown.size() > 24) shown = shown.substr(0, 24) + "...";
        m_diag.error(kChunkField + pointer, "must be a whole number from 0 to 2147483647, found " + shown,
                     "the file is damaged: export or write it again");
    }

    // Every value of an object (mesh attributes, morph targets).
    void check_all_values(const nlohmann::json& value, const std::string& pointer) {
        if (!value.is_object()) return;
        for (auto it = value.begin(); it != value.end(); ++it) check_number(it.value(), json_pointer_child(pointer, it.key()));
    }

    void check_all_elements(const nlohmann::json& value, const std::string& pointer) {
        if (!value.is_array()) return;
        for (std::size_t i = 0; i < value.size(); ++i) check_number(value[i], json_pointer_child(pointer, i));
    }

    // Calls visit(item, pointer) for each element of document[collection].
    template <class Visit>
    static void each(const nlohmann::json& parent, const std::string& pointer, const char* collection, Visit visit) {
        if (!parent.is_object()) return;
        const auto found = parent.find(collection);
        if (found == parent.end() || !found->is_array()) return;
        const std::string base = json_pointer_child(pointer, collection);
        for (std::size_t i = 0; i < found->size(); ++i) visit((*found)[i], json_pointer_child(base, i));
    }

private:
    Diagnostics& m_diag;
};

void check_index_fields(const nlohmann::json& document, Diagnostics& diag) {
    IndexChecker c(diag);
    c.check(document, "", "scene");
    IndexChecker::each(document, "", "buffers", [&](const nlohmann::json& b, const std::string& p) { c.check(b, p, "byteLength"); });
    IndexChecker::each(document, "", "bufferViews", [&](const nlohmann::json& v, const std::string& p) {
        for (const char* key : {"buffer", "byteOffset", "byteLength", "byteStride", "target"}) c.check(v, p, key);
    });
    IndexChecker::each(document, "", "accessors", [&](const nlohmann::json& a, const std::string& p) {
        for (const char* key : {"bufferView", "byteOffset", "count", "componentType"}) c.check(a, p, key);
        if (a.is_object() && a.contains("sparse") && a["sparse"].is_object()) {
            const nlohmann::json& sparse = a["sparse"];
            const std::string sp = json_pointer_child(p, "sparse");
            c.check(sparse, sp, "count");
            for (const char* part : {"indices", "values"})
                if (sparse.contains(part))
                    for (const char* key : {"bufferView", "byteOffset", "componentType"})
                        c.check(sparse[part], json_pointer_child(sp, part), key);
        }
    });
    IndexChecker::each(document, "", "meshes", [&](const nlohmann::json& mesh, const std::string& mp) {
        IndexChecker::each(mesh, mp, "primitives", [&](const nlohmann::json& primitive, const std::string& pp) {
            for (const char* key : {"indices", "material", "mode"}) c.check(primitive, pp, key);
            if (primitive.is_object() && primitive.contains("attributes"))
                c.check_all_values(primitive["attributes"], json_pointer_child(pp, "attributes"));
            IndexChecker::each(primitive, pp, "targets",
                               [&](const nlohmann::json& target, const std::string& tp) { c.check_all_values(target, tp); });
        });
    });
    IndexChecker::each(document, "", "nodes", [&](const nlohmann::json& node, const std::string& p) {
        for (const char* key : {"mesh", "camera", "skin"}) c.check(node, p, key);
        if (node.is_object() && node.contains("children")) c.check_all_elements(node["children"], json_pointer_child(p, "children"));
    });
    IndexChecker::each(document, "", "scenes", [&](const nlohmann::json& scene, const std::string& p) {
        if (scene.is_object() && scene.contains("nodes")) c.check_all_elements(scene["nodes"], json_pointer_child(p, "nodes"));
    });
    IndexChecker::each(document, "", "animations", [&](const nlohmann::json& animation, const std::string& ap) {
        IndexChecker::each(animation, ap, "samplers", [&](const nlohmann::json& sampler, const std::string& p) {
            c.check(sampler, p, "input");
            c.check(sampler, p, "output");
        });
        IndexChecker::each(animation, ap, "channels", [&](const nlohmann::json& channel, const std::string& p) {
            c.check(channel, p, "sampler");
            if (channel.is_object() && channel.contains("target")) c.check(channel["target"], json_pointer_child(p, "target"), "node");
        });
    });
}

}  // namespace

std::optional<nlohmann::json> read_glb_json_chunk(const std::string& json_text, Diagnostics& diag) {
    Diagnostics json_diag(diag.file());
    std::optional<nlohmann::json> document = parse_json_text(json_text, json_diag);
    for (Problem problem : json_diag.problems()) {
        problem.field = kChunkField + problem.field;
        diag.merge({problem});
    }
    if (!document) return std::nullopt;
    if (!document->is_object()) {
        diag.error("GLB chunk 0 (JSON)", "the glTF JSON is not an object", "the file is damaged; write it again");
        return std::nullopt;
    }
    Diagnostics index_diag(diag.file());
    check_index_fields(*document, index_diag);
    diag.merge(index_diag.problems());
    if (index_diag.has_errors()) return std::nullopt;
    return document;
}

}  // namespace flowvid::formats::detail
