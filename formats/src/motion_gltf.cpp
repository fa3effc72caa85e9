#include "flowvid/formats/motion_gltf.hpp"

#include "gltf_json.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <sstream>
#include <type_traits>

namespace flowvid::formats {
namespace {
namespace fs = std::filesystem;

constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kGlbBinChunk = 0x004E4942;   // "BIN\0"
constexpr std::uintmax_t kMaxGlbBytes = 0xFFFFFFF0u;  // GLB lengths are uint32

constexpr const char* kUpAxisText = "flowvid world (x, y, z), metres, +z up, is stored as glTF (x, z, -y), +y up";
constexpr const char* kUvText = "flowvid uv (u, v), origin bottom-left, is stored as glTF TEXCOORD_0 (u, 1 - v)";
constexpr const char* kFramesText =
    "frame k = morph target k (target 0 is all zero: frame 0 is the base mesh), active alone from time k / fps";

std::string pointer(const std::string& collection, std::size_t index) {
    return "/" + collection + "/" + std::to_string(index);
}

std::string frame_name(int frame) {
    char text[32];
    std::snprintf(text, sizeof(text), "frame_%06d", frame);
    return text;
}

// ---------------------------------------------------------------------------
// Checking an in-memory animation

void check_animation(const MeshAnimation& animation, Diagnostics& diag) {
    if (!(std::isfinite(animation.fps) && animation.fps > 0.0))
        diag.error("fps", "frame rate " + std::to_string(animation.fps) + " is not positive", "give the simulation's output frames per second");
    const int frames = animation.frame_count();
    const int vertices = animation.vertex_count();
    if (frames < 1) {
        diag.error("frames_positions_m", "no frame", "add at least one frame of positions");
        return;
    }
    if (frames > kMaxMotionGltfFrames)
        diag.error("frames_positions_m",
                   std::to_string(frames) + " frames exceed the limit of " + std::to_string(kMaxMotionGltfFrames),
                   "export a shorter range, or use the vertex-animation EXR for long sequences");
    if (vertices < 3) diag.error("frames_positions_m[0]", "fewer than 3 vertices", "give the whole mesh");
    if (static_cast<long long>(frames) * vertices > kMaxMotionGltfVertexFrames)
        diag.error("frames_positions_m",
                   std::to_string(frames) + " frames x " + std::to_string(vertices) + " vertices exceed the limit of " +
                       std::to_string(kMaxMotionGltfVertexFrames),
                   "export fewer frames or a coarser mesh");
    for (int f = 0; f < frames; ++f) {
        const auto& positions = animation.frames_positions_m[f];
        const std::string field = "frames_positions_m[" + std::to_string(f) + "]";
        if (static_cast<int>(positions.size()) != vertices) {
            diag.error(field, std::to_string(positions.size()) + " positions, frame 0 has " + std::to_string(vertices),
                       "every frame gives every vertex");
            continue;
        }
        for (int v = 0; v < vertices; ++v)
            if (!positions[v].allFinite()) {
                diag.error(field + "[" + std::to_string(v) + "]", "not a finite position", "fix the simulation output");
                break;  // one message per frame is enough
            }
    }
    if (animation.triangles.empty()) diag.error("triangles", "no triangle", "give the mesh faces");
    for (std::size_t t = 0; t < animation.triangles.size(); ++t) {
        const auto& tri = animation.triangles[t];
        const std::string field = "triangles[" + std::to_string(t) + "]";
        bool in_range = true;
        for (int corner : tri) in_range = in_range && corner >= 0 && corner < vertices;
        if (!in_range) {
            diag.error(field,
                       "vertex index out of range (" + std::to_string(tri[0]) + ", " + std::to_string(tri[1]) + ", " +
                           std::to_string(tri[2]) + "; " + std::to_string(vertices) + " vertices)",
                       "index vertices from 0");
        } else if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
            diag.error(field, "uses a vertex twice (degenerate)", "remove degenerate triangles");
        }
    }
    if (!animation.uv.empty()) {
        if (static_cast<int>(animation.uv.size()) != vertices)
            diag.error("uv", std::to_string(animation.uv.size()) + " uv pairs for " + std::to_string(vertices) + " vertices",
                       "give one uv per vertex, or none");
        for (std::size_t v = 0; v < animation.uv.size(); ++v)
            if (!animation.uv[v].allFinite()) {
                diag.error("uv[" + std::to_string(v) + "]", "not finite", "fix the texture coordinates");
                break;
            }
    }
}

// ---------------------------------------------------------------------------
// Writing

tinygltf::Value to_gltf_value(const nlohmann::json& json) {
    if (json.is_object()) {
        tinygltf::Value::Object object;
        for (auto it = json.begin(); it != json.end(); ++it) object[it.key()] = to_gltf_value(it.value());
        return tinygltf::Value(std::move(object));
    }
    if (json.is_array()) {
        tinygltf::Value::Array array;
        for (const auto& item : json) array.push_back(to_gltf_value(item));
        return tinygltf::Value(std::move(array));
    }
    if (json.is_string()) return tinygltf::Value(json.get<std::string>());
    if (json.is_boolean()) return tinygltf::Value(json.get<bool>());
    if (json.is_number_integer()) return tinygltf::Value(json.get<int>());
    if (json.is_number()) return tinygltf::Value(json.get<double>());
    return tinygltf::Value();
}

// Appends raw little-endian values to the single buffer; every view is
// 4-byte aligned because everything written is 4 bytes wide.
template <class T>
int add_view(tinygltf::Model& model, const std::vector<T>& values, int target) {
    std::vector<unsigned char>& data = model.buffers[0].data;
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = values.size() * sizeof(T);
    if (target != 0) view.target = target;
    const auto* bytes = reinterpret_cast<const unsigned char*>(values.data());
    data.insert(data.end(), bytes, bytes + view.byteLength);
    model.bufferViews.push_back(view);
    return static_cast<int>(model.bufferViews.size() - 1);
}

int add_accessor(tinygltf::Model& model, int view, std::size_t byte_offset, int component, int type, std::size_t count,
                 std::vector<double> min = {}, std::vector<double> max = {}) {
    tinygltf::Accessor accessor;
    accessor.bufferView = view;
    accessor.byteOffset = byte_offset;
    accessor.componentType = component;
    accessor.type = type;
    accessor.count = count;
    accessor.minValues = std::move(min);
    accessor.maxValues = std::move(max);
    model.accessors.push_back(accessor);
    return static_cast<int>(model.accessors.size() - 1);
}

void bounds(const float* xyz, std::size_t count, std::vector<double>& min, std::vector<double>& max) {
    min.assign(3, std::numeric_limits<double>::infinity());
    max.assign(3, -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < count; ++i)
        for (int c = 0; c < 3; ++c) {
            min[c] = std::min<double>(min[c], xyz[i * 3 + c]);
            max[c] = std::max<double>(max[c], xyz[i * 3 + c]);
        }
}

tinygltf::Model build_model(const MeshAnimation& animation) {
    const int frames = animation.frame_count();
    const std::size_t vertices = static_cast<std::size_t>(animation.vertex_count());
    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = std::string("flowvid ") + FLOWVID_VERSION_STRING;
    const nlohmann::json metadata = {
        {"format", kMotionGltfFormatName}, {"version", kMotionGltfFormatVersion.to_string()},
        {"fps", animation.fps},            {"frame_count", frames},
        {"vertex_count", vertices},        {"up_axis", kUpAxisText},
        {"uv", kUvText},                   {"frames", kFramesText},
    };
    model.asset.extras = to_gltf_value({{"flowvid", metadata}});
    model.buffers.resize(1);

    std::vector<std::uint32_t> indices;
    indices.reserve(animation.triangles.size() * 3);
    for (const auto& tri : animation.triangles)
        for (int corner : tri) indices.push_back(static_cast<std::uint32_t>(corner));
    const int index_view = add_view(model, indices, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    const int index_accessor = add_accessor(model, index_view, 0, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                            TINYGLTF_TYPE_SCALAR, indices.size(), {0.0},
                                            {static_cast<double>(vertices - 1)});

    std::vector<float> base(vertices * 3);
    for (std::size_t v = 0; v < vertices; ++v) {
        const Eigen::Vector3f p = flowvid_to_gltf(animation.frames_positions_m[0][v]);
        for (int c = 0; c < 3; ++c) base[v * 3 + c] = p[c];
    }
    std::vector<double> min, max;
    bounds(base.data(), vertices, min, max);
    const int base_view = add_view(model, base, TINYGLTF_TARGET_ARRAY_BUFFER);
    const int base_accessor =
        add_accessor(model, base_view, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, vertices, min, max);

    int uv_accessor = -1;
    if (!animation.uv.empty()) {
        std::vector<float> uv(vertices * 2);
        for (std::size_t v = 0; v < vertices; ++v) {
            uv[v * 2] = animation.uv[v].x();
            uv[v * 2 + 1] = 1.0f - animation.uv[v].y();  // glTF's v runs down the image
        }
        const int uv_view = add_view(model, uv, TINYGLTF_TARGET_ARRAY_BUFFER);
        uv_accessor = add_accessor(model, uv_view, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, vertices);
    }

    // Deltas from frame 0, subtracted in double and rounded once.
    std::vector<float> deltas(static_cast<std::size_t>(frames) * vertices * 3);
    for (int f = 0; f < frames; ++f)
        for (std::size_t v = 0; v < vertices; ++v) {
            const Eigen::Vector3f p = flowvid_to_gltf(animation.frames_positions_m[f][v]);
            for (int c = 0; c < 3; ++c)
                deltas[(f * vertices + v) * 3 + c] =
                    static_cast<float>(static_cast<double>(p[c]) - static_cast<double>(base[v * 3 + c]));
        }
    const int delta_view = add_view(model, deltas, TINYGLTF_TARGET_ARRAY_BUFFER);
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    primitive.indices = index_accessor;
    primitive.attributes["POSITION"] = base_accessor;
    if (uv_accessor >= 0) primitive.attributes["TEXCOORD_0"] = uv_accessor;
    tinygltf::Value::Array target_names;
    for (int f = 0; f < frames; ++f) {
        bounds(deltas.data() + f * vertices * 3, vertices, min, max);
        const int accessor = add_accessor(model, delta_view, f * vertices * 3 * sizeof(float),
                                          TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, vertices, min, max);
        primitive.targets.push_back({{"POSITION", accessor}});
        target_names.push_back(tinygltf::Value(frame_name(f)));
    }

    tinygltf::Mesh mesh;
    mesh.name = animation.name;
    mesh.primitives.push_back(primitive);
    mesh.weights.assign(frames, 0.0);
    mesh.weights[0] = 1.0;  // without the animation, a viewer shows frame 0
    tinygltf::Value::Object mesh_extras;
    mesh_extras["targetNames"] = tinygltf::Value(std::move(target_names));  // Blender's shape-key names
    mesh.extras = tinygltf::Value(std::move(mesh_extras));
    model.meshes.push_back(mesh);

    tinygltf::Node node;
    node.name = animation.name;
    node.mesh = 0;
    model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.name = animation.name;
    scene.nodes.push_back(0);
    model.scenes.push_back(scene);
    model.defaultScene = 0;

    std::vector<float> times(frames);
    std::vector<float> weights(static_cast<std::size_t>(frames) * frames, 0.0f);
    for (int f = 0; f < frames; ++f) {
        times[f] = static_cast<float>(f / animation.fps);
        weights[static_cast<std::size_t>(f) * frames + f] = 1.0f;
    }
    const int time_view = add_view(model, times, 0);
    const int time_accessor = add_accessor(model, time_view, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR,
                                           times.size(), {times.front()}, {times.back()});
    const int weight_view = add_view(model, weights, 0);
    const int weight_accessor =
        add_accessor(model, weight_view, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, weights.size());
    tinygltf::Animation clip;
    clip.name = animation.name;
    tinygltf::AnimationSampler sampler;
    sampler.input = time_accessor;
    sampler.output = weight_accessor;
    sampler.interpolation = "STEP";
    clip.samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = 0;
    channel.target_node = 0;
    channel.target_path = "weights";
    clip.channels.push_back(channel);
    model.animations.push_back(clip);
    return model;
}

std::size_t encoded_size_bound(const MeshAnimation& animation) {
    const std::size_t frames = static_cast<std::size_t>(animation.frame_count());
    const std::size_t vertices = static_cast<std::size_t>(animation.vertex_count());
    return animation.triangles.size() * 12 + vertices * (12 + 8) + frames * vertices * 12 + frames * 4 +
           frames * frames * 4 + frames * 400 + 4096;  // JSON: roughly 400 bytes per target accessor
}

// ---------------------------------------------------------------------------
// Reading

// tinygltf must never open other files (a .glb may name external buffers or
// images by URI): these callbacks refuse every file access.
bool refuse_exists(const std::string&, void*) { return false; }
std::string keep_path(const std::string& path, void*) { return path; }
bool refuse_read(std::vector<unsigned char>*, std::string* err, const std::string& path, void*) {
    if (err) *err += "external file \"" + path + "\" not read: a flowvid motion .glb is self-contained\n";
    return false;
}
bool refuse_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err += "writing is not allowed while reading\n";
    return false;
}
bool refuse_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
    return true;  // images are not decoded: a motion file has none, and a foreign one's are irrelevant
}

std::uint32_t read_u32(const std::string& bytes, std::size_t at) {
    return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at])) |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 1])) << 8 |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 2])) << 16 |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[at + 3])) << 24;
}

// The GLB container, checked before tinygltf sees it, so that a truncated or
// foreign file gets a message saying which part is wrong.
bool check_glb_container(const std::string& bytes, Diagnostics& diag) {
    if (bytes.size() < 12 || read_u32(bytes, 0) != kGlbMagic) {
        const bool text_gltf = bytes.find("\"asset\"") != std::string::npos && !bytes.empty() && bytes[0] == '{';
        diag.error("GLB header", "not a glTF binary (.glb): the file does not start with \"glTF\"",
                   text_gltf ? "this looks like a text .gltf; export it as glTF Binary (.glb)"
                             : "give a .glb written by flowvid");
        return false;
    }
    const std::uint32_t version = read_u32(bytes, 4);
    if (version != 2) {
        diag.error("GLB header", "container version " + std::to_string(version) + ", expected 2", "export as glTF 2.0");
        return false;
    }
    const std::uint32_t length = read_u32(bytes, 8);
    if (length != bytes.size()) {
        diag.error("GLB header",
                   "declares " + std::to_string(length) + " bytes but the file has " + std::to_string(bytes.size()) +
                       (length > bytes.size() ? " (truncated)" : " (trailing data)"),
                   "the file is damaged or was cut short; write it again");
        return false;
    }
    if (bytes.size() < 20 || read_u32(bytes, 16) != kGlbJsonChunk) {
        diag.error("GLB chunk 0", "the first chunk is not JSON", "the file is damaged; write it again");
        return false;
    }
    const std::uint64_t json_end = 20ull + read_u32(bytes, 12);
    if (json_end > bytes.size()) {
        diag.error("GLB chunk 0", "the JSON chunk runs past the end of the file", "the file is damaged; write it again");
        return false;
    }
    if (json_end < bytes.size()) {
        if (json_end + 8 > bytes.size() || read_u32(bytes, static_cast<std::size_t>(json_end) + 4) != kGlbBinChunk) {
            diag.error("GLB chunk 1", "the chunk after JSON is not BIN", "the file is damaged; write it again");
            return false;
        }
        if (json_end + 8 + read_u32(bytes, static_cast<std::size_t>(json_end)) > bytes.size()) {
            diag.error("GLB chunk 1", "the BIN chunk runs past the end of the file", "the file is damaged; write it again");
            return false;
        }
    }
    return true;
}

class MotionReader {
public:
    MotionReader(Diagnostics& diag, Strictness strictness) : m_diag(diag), m_strictness(strictness) {}

    std::optional<MeshAnimation> read(const std::string& bytes) {
        if (!check_glb_container(bytes, m_diag)) return std::nullopt;
        // Look at the JSON first: a clear message for malformed JSON (line and
        // column) and for external files, which are never opened.
        const std::uint32_t json_length = read_u32(bytes, 12);
        std::optional<nlohmann::json> document = detail::read_glb_json_chunk(bytes.substr(20, json_length), m_diag);
        if (!document) return std::nullopt;
        bool external = false;
        for (const char* collection : {"buffers", "images"}) {
            const auto found = document->find(collection);
            if (found == document->end() || !found->is_array()) continue;
            for (std::size_t i = 0; i < found->size(); ++i) {
                const nlohmann::json& item = (*found)[i];
                if (!item.is_object() || !item.contains("uri") || !item["uri"].is_string()) continue;
                if (item["uri"].get<std::string>().rfind("data:", 0) == 0) continue;  // embedded
                m_diag.error(pointer(collection, i) + "/uri", "refers to an external file, which is not read",
                             "a flowvid motion .glb is self-contained; export with everything embedded");
                external = true;
            }
        }
        if (external) return std::nullopt;
        m_document = std::move(*document);

        tinygltf::TinyGLTF loader;
        loader.SetImageLoader(refuse_image, nullptr);
        loader.SetFsCallbacks({refuse_exists, keep_path, refuse_read, refuse_write, nullptr});
        std::string err, warn;
        bool loaded = false;
        try {
            loaded = loader.LoadBinaryFromMemory(&m_model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                                 static_cast<unsigned int>(bytes.size()), "");
        } catch (const std::exception& error) {
            err = error.what();
        }
        if (!loaded) {
            m_diag.error("GLB chunk 0", "glTF cannot be parsed: " + trim(err), "the file is damaged or is not glTF 2.0");
            return std::nullopt;
        }
        if (!trim(warn).empty()) m_diag.warning("", "glTF: " + trim(warn), "");
        std::optional<double> fps;
        std::optional<std::int64_t> frames, vertex_count;
        if (!read_metadata(fps, frames, vertex_count)) return std::nullopt;
        return read_animation(*fps, static_cast<int>(*frames), static_cast<int>(*vertex_count));
    }

private:
    static std::string trim(std::string text) {
        while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
        return text;
    }

    bool read_metadata(std::optional<double>& fps, std::optional<std::int64_t>& frames,
                       std::optional<std::int64_t>& vertex_count) {
        const nlohmann::json* extras = nullptr;
        if (m_document.contains("asset") && m_document["asset"].is_object() && m_document["asset"].contains("extras"))
            extras = &m_document["asset"]["extras"];
        if (!extras || !extras->is_object() || !extras->contains("flowvid")) {
            m_diag.error("/asset/extras/flowvid",
                         "a glTF file without a flowvid animation (asset.extras.flowvid is missing)",
                         "give a .glb written by flowvid's motion export; other glTF files are not motion exports");
            return false;
        }
        const std::size_t before = m_diag.problems().size();
        JsonView extras_view(*extras, "/asset/extras", m_diag, m_strictness);
        std::optional<JsonView> root = extras_view.object("flowvid");
        if (!root) return false;
        const bool known_format =
            check_format_header(*root, kMotionGltfFormatName, kMotionGltfFormatVersion).has_value();
        if (!known_format) return false;
        root->check_known_keys({"format", "version", "fps", "frame_count", "vertex_count", "up_axis", "uv", "frames"});
        fps = root->number("fps", NumberRange::positive("frames/s"));
        frames = root->integer("frame_count", 1, kMaxMotionGltfFrames);
        vertex_count = root->integer("vertex_count", 3, kMaxMotionGltfVertexFrames);
        for (std::size_t i = before; i < m_diag.problems().size(); ++i)
            if (m_diag.problems()[i].severity == Problem::Severity::error) return false;
        if (*frames * *vertex_count > kMaxMotionGltfVertexFrames) {
            m_diag.error("/asset/extras/flowvid/vertex_count", "frames x vertices exceed the limit of " +
                                                                   std::to_string(kMaxMotionGltfVertexFrames),
                         "the file is damaged or too large for this flowvid");
            return false;
        }
        return true;
    }

    // Checks an accessor's declaration and that its bytes lie inside its
    // buffer view and buffer, then returns its values as floats (or indices).
    template <class Out>
    std::optional<std::vector<Out>> read_accessor(int index, const std::string& used_by, int type, std::size_t count,
                                                  bool indices = false) {
        if (index < 0 || static_cast<std::size_t>(index) >= m_model.accessors.size()) {
            m_diag.error(used_by, "refers to accessor " + std::to_string(index) + ", which does not exist",
                         "the file is damaged; write it again");
            return std::nullopt;
        }
        const tinygltf::Accessor& accessor = m_model.accessors[index];
        const std::string field = pointer("accessors", index);
        const int components = type == TINYGLTF_TYPE_SCALAR ? 1 : type == TINYGLTF_TYPE_VEC2 ? 2 : 3;
        std::size_t component_size = 4;
        if (accessor.sparse.isSparse) {
            m_diag.error(field, "sparse accessors are not used by flowvid motion files", "write the file with flowvid");
            return std::nullopt;
        }
        if (accessor.type != type) {
            m_diag.error(field + "/type", "wrong element type for " + used_by, "write the file with flowvid");
            return std::nullopt;
        }
        if (indices) {
            switch (accessor.componentType) {
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: component_size = 1; break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: component_size = 2; break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: component_size = 4; break;
                default:
                    m_diag.error(field + "/componentType", "indices must be unsigned integers", "write the file with flowvid");
                    return std::nullopt;
            }
        } else if (accessor.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || accessor.normalized) {
            m_diag.error(field + "/componentType", "expected float components for " + used_by, "write the file with flowvid");
            return std::nullopt;
        }
        if (count != std::numeric_limits<std::size_t>::max() && accessor.count != count) {
            m_diag.error(field + "/count",
                         std::to_string(accessor.count) + " elements, expected " + std::to_string(count) + " for " + used_by,
                         "the counts in the file disagree; write it again");
            return std::nullopt;
        }
        if (accessor.bufferView < 0 || static_cast<std::size_t>(accessor.bufferView) >= m_model.bufferViews.size()) {
            m_diag.error(field + "/bufferView", "missing or out of range", "the file is damaged; write it again");
            return std::nullopt;
        }
        const tinygltf::BufferView& view = m_model.bufferViews[accessor.bufferView];
        const std::string view_field = pointer("bufferViews", accessor.bufferView);
        if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= m_model.buffers.size()) {
            m_diag.error(view_field + "/buffer", "missing or out of range", "the file is damaged; write it again");
            return std::nullopt;
        }
        const std::vector<unsigned char>& data = m_model.buffers[view.buffer].data;
        const std::size_t element_size = component_size * components;
        const std::size_t stride = view.byteStride == 0 ? element_size : view.byteStride;
        if (stride < element_size || stride > 252 || stride % component_size != 0) {
            m_diag.error(view_field + "/byteStride", "invalid stride " + std::to_string(view.byteStride),
                         "the file is damaged; write it again");
            return std::nullopt;
        }
        // All in 64-bit with explicit overflow guards: counts come from the file.
        const std::uint64_t view_end = static_cast<std::uint64_t>(view.byteOffset) + view.byteLength;
        if (view.byteOffset > data.size() || view.byteLength > data.size() || view_end > data.size()) {
            m_diag.error(view_field, "lies outside its buffer (" + std::to_string(data.size()) + " bytes)",
                         "the file is damaged or truncated; write it again");
            return std::nullopt;
        }
        if (accessor.count == 0) {
            m_diag.error(field + "/count", "empty accessor", "the file is damaged; write it again");
            return std::nullopt;
        }
        if (accessor.count > data.size() || accessor.byteOffset > view.byteLength ||
            static_cast<std::uint64_t>(accessor.byteOffset) + (accessor.count - 1) * static_cast<std::uint64_t>(stride) +
                    element_size > view.byteLength) {
            m_diag.error(field, "its " + std::to_string(accessor.count) + " elements run past the end of " + view_field,
                         "the file is damaged or truncated; write it again");
            return std::nullopt;
        }
        std::vector<Out> values(accessor.count * components);
        const unsigned char* base = data.data() + view.byteOffset + accessor.byteOffset;
        for (std::size_t i = 0; i < accessor.count; ++i)
            for (int c = 0; c < components; ++c) {
                const unsigned char* at = base + i * stride + c * component_size;
                if (component_size == 4) {
                    if constexpr (std::is_same_v<Out, float>) std::memcpy(&values[i * components + c], at, 4);
                    else {
                        std::uint32_t value;
                        std::memcpy(&value, at, 4);
                        values[i * components + c] = static_cast<Out>(value);
                    }
                } else if (component_size == 2) {
                    std::uint16_t value;
                    std::memcpy(&value, at, 2);
                    values[i * components + c] = static_cast<Out>(value);
                } else {
                    values[i * components + c] = static_cast<Out>(*at);
                }
            }
        if constexpr (std::is_same_v<Out, float>) {
            for (std::size_t i = 0; i < values.size(); ++i)
                if (!std::isfinite(values[i])) {
                    m_diag.error(field, "element " + std::to_string(i / components) + " is not finite (" + used_by + ")",
                                 "fix the data and export again");
                    return std::nullopt;
                }
        }
        return values;
    }

    std::optional<MeshAnimation> read_animation(double fps, int frames, int vertices) {
        // The animation: the first one with a weights channel.
        const tinygltf::Animation* clip = nullptr;
        std::size_t clip_index = 0;
        for (std::size_t a = 0; a < m_model.animations.size() && !clip; ++a)
            for (const tinygltf::AnimationChannel& channel : m_model.animations[a].channels)
                if (channel.target_path == "weights") {
                    clip = &m_model.animations[a];
                    clip_index = a;
                    break;
                }
        if (!clip) {
            m_diag.error("/animations", "no animation of morph-target weights", "write the file with flowvid's motion export");
            return std::nullopt;
        }
        const std::string clip_field = pointer("animations", clip_index);
        std::size_t channel_index = 0;
        while (clip->channels[channel_index].target_path != "weights") ++channel_index;
        const tinygltf::AnimationChannel& channel = clip->channels[channel_index];
        const std::string channel_field = clip_field + "/channels/" + std::to_string(channel_index);
        if (channel.target_node < 0 || static_cast<std::size_t>(channel.target_node) >= m_model.nodes.size()) {
            m_diag.error(channel_field + "/target/node", "refers to no node", "the file is damaged; write it again");
            return std::nullopt;
        }
        if (channel.sampler < 0 || static_cast<std::size_t>(channel.sampler) >= clip->samplers.size()) {
            m_diag.error(channel_field + "/sampler", "refers to no sampler", "the file is damaged; write it again");
            return std::nullopt;
        }
        const tinygltf::Node& node = m_model.nodes[channel.target_node];
        const std::string node_field = pointer("nodes", channel.target_node);
        if (node.mesh < 0 || static_cast<std::size_t>(node.mesh) >= m_model.meshes.size()) {
            m_diag.error(node_field + "/mesh", "the animated node has no mesh", "the file is damaged; write it again");
            return std::nullopt;
        }
        const tinygltf::Mesh& mesh = m_model.meshes[node.mesh];
        const std::string mesh_field = pointer("meshes", node.mesh);
        if (mesh.primitives.size() != 1) {
            m_diag.error(mesh_field + "/primitives",
                         std::to_string(mesh.primitives.size()) + " primitives, expected exactly 1",
                         "write the file with flowvid's motion export");
            return std::nullopt;
        }
        const tinygltf::Primitive& primitive = mesh.primitives[0];
        const std::string primitive_field = mesh_field + "/primitives/0";
        bool ok = true;
        if (primitive.mode != TINYGLTF_MODE_TRIANGLES) {
            m_diag.error(primitive_field + "/mode", "not TRIANGLES (4)", "export triangles");
            ok = false;
        }
        if (primitive.targets.size() != static_cast<std::size_t>(frames)) {
            m_diag.error(primitive_field + "/targets",
                         std::to_string(primitive.targets.size()) + " morph targets for " + std::to_string(frames) +
                             " frames (asset.extras.flowvid.frame_count)",
                         "the counts disagree; write the file again");
            ok = false;
        }
        const auto position = primitive.attributes.find("POSITION");
        if (position == primitive.attributes.end()) {
            m_diag.error(primitive_field + "/attributes/POSITION", "missing", "write the file with flowvid");
            ok = false;
        }
        if (primitive.indices < 0) {
            m_diag.error(primitive_field + "/indices", "missing (flowvid writes indexed triangles)", "write the file with flowvid");
            ok = false;
        }
        if (!ok) return std::nullopt;

        MeshAnimation animation;
        animation.name = node.name.empty() ? mesh.name : node.name;
        animation.fps = fps;
        const auto base = read_accessor<float>(position->second, primitive_field + "/attributes/POSITION", TINYGLTF_TYPE_VEC3,
                                               static_cast<std::size_t>(vertices));
        const auto indices = read_accessor<std::uint32_t>(primitive.indices, primitive_field + "/indices",
                                                          TINYGLTF_TYPE_SCALAR, std::numeric_limits<std::size_t>::max(), true);
        std::optional<std::vector<float>> uv;
        const auto texcoord = primitive.attributes.find("TEXCOORD_0");
        if (texcoord != primitive.attributes.end())
            uv = read_accessor<float>(texcoord->second, primitive_field + "/attributes/TEXCOORD_0", TINYGLTF_TYPE_VEC2,
                                      static_cast<std::size_t>(vertices));
        if (!base || !indices || (texcoord != primitive.attributes.end() && !uv)) return std::nullopt;
        if (indices->size() % 3 != 0) {
            m_diag.error(pointer("accessors", primitive.indices) + "/count",
                         std::to_string(indices->size()) + " indices, not a multiple of 3", "the file is damaged; write it again");
            return std::nullopt;
        }
        for (std::size_t i = 0; i < indices->size(); i += 3) {
            std::array<int, 3> tri{};
            for (int c = 0; c < 3; ++c) {
                const std::uint32_t corner = (*indices)[i + c];
                if (corner >= static_cast<std::uint32_t>(vertices)) {
                    m_diag.error(pointer("accessors", primitive.indices),
                                 "triangle " + std::to_string(i / 3) + " uses vertex " + std::to_string(corner) + " of " +
                                     std::to_string(vertices),
                                 "the file is damaged; write it again");
                    return std::nullopt;
                }
                tri[c] = static_cast<int>(corner);
            }
            animation.triangles.push_back(tri);
        }
        if (uv) {
            animation.uv.resize(vertices);
            for (int v = 0; v < vertices; ++v) animation.uv[v] = {(*uv)[v * 2], 1.0f - (*uv)[v * 2 + 1]};
        }

        if (!check_timing(*clip, channel, clip_field, fps, frames)) return std::nullopt;

        animation.frames_positions_m.resize(frames);
        for (int f = 0; f < frames; ++f) {
            const std::string target_field = primitive_field + "/targets/" + std::to_string(f) + "/POSITION";
            const auto found = primitive.targets[f].find("POSITION");
            if (found == primitive.targets[f].end()) {
                m_diag.error(target_field, "missing", "every morph target moves POSITION");
                return std::nullopt;
            }
            const auto delta = read_accessor<float>(found->second, target_field, TINYGLTF_TYPE_VEC3, vertices);
            if (!delta) return std::nullopt;
            std::vector<Eigen::Vector3f>& positions = animation.frames_positions_m[f];
            positions.resize(vertices);
            for (int v = 0; v < vertices; ++v) {
                Eigen::Vector3f p;
                for (int c = 0; c < 3; ++c) p[c] = (*base)[v * 3 + c] + (*delta)[v * 3 + c];
                if (!p.allFinite()) {
                    m_diag.error(target_field, "vertex " + std::to_string(v) + " is not finite at frame " + std::to_string(f),
                                 "fix the data and export again");
                    return std::nullopt;
                }
                positions[v] = gltf_to_flowvid(p);
            }
        }
        return animation;
    }

    // Keyframe k must be at time k / fps and switch on target k alone.
    bool check_timing(const tinygltf::Animation& clip, const tinygltf::AnimationChannel& channel,
                      const std::string& clip_field, double fps, int frames) {
        const tinygltf::AnimationSampler& sampler = clip.samplers[channel.sampler];
        const std::string sampler_field = clip_field + "/samplers/" + std::to_string(channel.sampler);
        if (sampler.interpolation != "STEP" && sampler.interpolation != "LINEAR") {
            m_diag.error(sampler_field + "/interpolation", quoted(sampler.interpolation) + " is not STEP or LINEAR",
                         "flowvid writes STEP");
            return false;
        }
        const auto times = read_accessor<float>(sampler.input, sampler_field + "/input", TINYGLTF_TYPE_SCALAR,
                                                static_cast<std::size_t>(frames));
        const auto weights = read_accessor<float>(sampler.output, sampler_field + "/output", TINYGLTF_TYPE_SCALAR,
                                                  static_cast<std::size_t>(frames) * frames);
        if (!times || !weights) return false;
        for (int k = 0; k < frames; ++k) {
            const double expected = k / fps;
            if (std::fabs((*times)[k] - expected) > 1e-3 / fps) {
                m_diag.error(pointer("accessors", sampler.input),
                             "keyframe " + std::to_string(k) + " is at " + std::to_string((*times)[k]) + " s, expected " +
                                 std::to_string(expected) + " s (frame / fps)",
                             "keyframes are one per frame at asset.extras.flowvid.fps");
                return false;
            }
            for (int t = 0; t < frames; ++t) {
                const float w = (*weights)[static_cast<std::size_t>(k) * frames + t];
                if (std::fabs(w - (t == k ? 1.0f : 0.0f)) > 1e-6f) {
                    m_diag.error(pointer("accessors", sampler.output),
                                 "keyframe " + std::to_string(k) + " gives target " + std::to_string(t) + " weight " +
                                     std::to_string(w) + "; flowvid motion switches on target k alone at frame k",
                                 "this reader reads one-target-per-frame animations written by flowvid");
                    return false;
                }
            }
        }
        return true;
    }

    static std::string quoted(const std::string& text) { return "\"" + text + "\""; }

    Diagnostics& m_diag;
    Strictness m_strictness;
    nlohmann::json m_document;  // the JSON chunk as parsed before tinygltf
    tinygltf::Model m_model;
};

std::string read_glb_bytes(const std::string& path) {
    std::error_code ec;
    if (fs::exists(path, ec) && !fs::is_directory(path, ec)) {
        const std::uintmax_t size = fs::file_size(path, ec);
        if (!ec && size > kMaxGlbBytes)
            throw IoError(path, "", "larger than a GLB can be (4 GiB)", "give a .glb written by flowvid");
    }
    return read_text_file(path);  // throws IoError naming the file
}

}  // namespace

void check_mesh_animation(const MeshAnimation& animation, Diagnostics& diagnostics) {
    check_animation(animation, diagnostics);
}

MeshAnimation read_motion_gltf(const std::string& path, std::vector<Problem>* warnings) {
    const std::string bytes = read_glb_bytes(path);
    Diagnostics diagnostics(path);
    std::optional<MeshAnimation> animation = MotionReader(diagnostics, Strictness::lenient).read(bytes);
    diagnostics.throw_if_errors();
    if (warnings) *warnings = diagnostics.warnings();
    return *animation;
}

void write_motion_gltf(const std::string& path, const MeshAnimation& animation) {
    Diagnostics diagnostics(path);
    check_animation(animation, diagnostics);
    diagnostics.throw_if_errors();
    if (encoded_size_bound(animation) > kMaxGlbBytes)
        throw ValidationError({Problem{Problem::Severity::error, path, "frames_positions_m",
                                       "the animation is too large for a GLB (4 GiB)", "export fewer frames"}});
    const tinygltf::Model model = build_model(animation);
    write_file_atomically(path, [&](std::ostream& out) {
        tinygltf::TinyGLTF writer;
        if (!writer.WriteGltfSceneToStream(&model, out, false, true))
            throw IoError(path, "", "tinygltf could not encode the glTF binary", "report this as a flowvid bug");
    });
}

std::vector<Problem> validate_motion_gltf_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    std::string bytes;
    try {
        bytes = read_glb_bytes(path);
    } catch (const IoError& error) {
        diagnostics.error(error.field(), error.message(), error.fix());
        return diagnostics.problems();
    }
    MotionReader(diagnostics, strictness).read(bytes);
    return diagnostics.problems();
}

nlohmann::json summarize_motion_gltf(const MeshAnimation& animation) {
    nlohmann::json summary = {
        {"format", kMotionGltfFormatName},
        {"version", kMotionGltfFormatVersion.to_string()},
        {"name", animation.name},
        {"fps", animation.fps},
        {"frame_count", animation.frame_count()},
        {"vertex_count", animation.vertex_count()},
        {"triangle_count", animation.triangles.size()},
        {"has_uv", !animation.uv.empty()},
        {"duration_s", animation.frame_count() > 0 ? (animation.frame_count() - 1) / animation.fps : 0.0},
    };
    if (animation.frame_count() > 0 && animation.vertex_count() > 0) {
        Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
        Eigen::Vector3f hi = -lo;
        double max_displacement = 0.0;
        for (const auto& frame : animation.frames_positions_m)
            for (std::size_t v = 0; v < frame.size(); ++v) {
                lo = lo.cwiseMin(frame[v]);
                hi = hi.cwiseMax(frame[v]);
                if (v < animation.frames_positions_m[0].size())
                    max_displacement = std::max<double>(max_displacement, (frame[v] - animation.frames_positions_m[0][v]).norm());
            }
        summary["bounding_box_m"] = {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}};
        summary["max_displacement_from_frame0_m"] = max_displacement;
    }
    return summary;
}

}  // namespace flowvid::formats
