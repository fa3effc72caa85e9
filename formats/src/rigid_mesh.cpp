#include "flowvid/formats/rigid_mesh.hpp"

#include "gltf_json.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <Eigen/Geometry>
#include <tiny_gltf.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <optional>
#include <set>

namespace flowvid::formats {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kChunkJson = 0x4E4F534A;     // "JSON"
constexpr std::uint32_t kChunkBinary = 0x004E4942;   // "BIN\0"
constexpr int kModeTriangles = 4;
constexpr std::size_t kMaxNodeDepth = 256;
// A rigid body's collision/inertia mesh: anything above this is not plausible
// and would only make a corrupt file allocate.
constexpr std::size_t kMaxMeshElements = 50'000'000;

std::uint32_t read_u32(const std::string& bytes, std::size_t offset) {
    const auto* p = reinterpret_cast<const unsigned char*>(bytes.data()) + offset;
    return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[3]) << 24);
}

// The GLB container, checked before tinygltf sees the bytes, so a truncated
// file gets a message that says so (and the parser never reads past the end).
bool check_glb_container(const std::string& bytes, Diagnostics& diag) {
    if (bytes.size() < 12) {
        diag.error("GLB header", "the file has " + std::to_string(bytes.size()) + " bytes, fewer than a GLB header (12)",
                   "the file is truncated: export the mesh again as glTF binary (.glb)");
        return false;
    }
    if (read_u32(bytes, 0) != kGlbMagic) {
        diag.error("GLB header", "not a glTF binary (the file does not start with \"glTF\")",
                   "export the mesh as glTF 2.0 binary (.glb)");
        return false;
    }
    const std::uint32_t version = read_u32(bytes, 4);
    if (version != 2) {
        diag.error("GLB header", "GLB container version " + std::to_string(version) + " (only 2 is glTF 2.0)",
                   "export the mesh as glTF 2.0 binary");
        return false;
    }
    const std::uint32_t declared = read_u32(bytes, 8);
    if (declared > bytes.size()) {
        diag.error("GLB header",
                   "the header declares " + std::to_string(declared) + " bytes but the file has " +
                       std::to_string(bytes.size()) + ": it is truncated",
                   "copy or export the mesh again");
        return false;
    }
    if (declared < 20) {
        diag.error("GLB header", "declared length " + std::to_string(declared) + " leaves no room for a JSON chunk",
                   "the file is corrupt: export the mesh again");
        return false;
    }
    std::size_t offset = 12;
    int chunk = 0;
    while (offset < declared) {
        if (declared - offset < 8) {
            diag.error("GLB chunk " + std::to_string(chunk), "chunk header cut off at byte " + std::to_string(offset),
                       "the file is corrupt: export the mesh again");
            return false;
        }
        const std::uint32_t length = read_u32(bytes, offset);
        const std::uint32_t type = read_u32(bytes, offset + 4);
        if (length > declared - offset - 8) {
            diag.error("GLB chunk " + std::to_string(chunk),
                       "chunk of " + std::to_string(length) + " bytes runs past the end of the file (byte " +
                           std::to_string(declared) + ")",
                       "the file is truncated or corrupt: export the mesh again");
            return false;
        }
        if (chunk == 0 && type != kChunkJson) {
            diag.error("GLB chunk 0", "the first chunk is not JSON", "the file is corrupt: export the mesh again");
            return false;
        }
        if (chunk == 1 && type != kChunkBinary)
            diag.warning("GLB chunk 1", "the second chunk is not BIN (ignored)", "");
        offset += 8 + std::size_t(length);
        ++chunk;
    }
    if (declared < bytes.size())
        diag.warning("GLB header", std::to_string(bytes.size() - declared) + " bytes after the declared end (ignored)",
                     "");
    return true;
}

bool skip_images(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
    return true;  // a body mesh needs no textures
}

// Only the bytes inside the .glb are read: no external buffers or images, so
// a capture cannot make flowvid open arbitrary files.
bool refuse_external_file(std::vector<unsigned char>*, std::string* err, const std::string& name, void*) {
    if (err) *err += "external file \"" + name + "\" referenced; flowvid reads self-contained .glb files only\n";
    return false;
}
bool no_file_exists(const std::string&, void*) { return false; }
std::string keep_path(const std::string& path, void*) { return path; }
bool refuse_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err += "writing is not supported\n";
    return false;
}

std::string pointer(const char* array, std::size_t index) { return std::string("/") + array + "/" + std::to_string(index); }

struct AccessorData {
    const unsigned char* first = nullptr;  // first element
    std::size_t stride = 0;                // bytes between elements
    std::size_t count = 0;
    int component_type = 0;
};

// Checks that an accessor lies inside its buffer view and buffer; the caller
// states which element types it accepts.
std::optional<AccessorData> accessor_data(const tinygltf::Model& model, int index, int expected_type,
                                          std::initializer_list<int> component_types, const std::string& used_by,
                                          Diagnostics& diag) {
    if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size()) {
        diag.error(used_by, "accessor " + std::to_string(index) + " does not exist (" +
                                std::to_string(model.accessors.size()) + " accessors)",
                   "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    const tinygltf::Accessor& accessor = model.accessors[static_cast<std::size_t>(index)];
    const std::string where = pointer("accessors", static_cast<std::size_t>(index));
    bool ok = true;
    if (accessor.type != expected_type) {
        diag.error(where + "/type", "unexpected element type for " + used_by,
                   expected_type == TINYGLTF_TYPE_VEC3 ? "positions must be VEC3" : "indices must be SCALAR");
        ok = false;
    }
    bool component_ok = false;
    for (int type : component_types) component_ok = component_ok || accessor.componentType == type;
    if (!component_ok) {
        diag.error(where + "/componentType", "component type " + std::to_string(accessor.componentType) +
                                                 " is not supported for " + used_by,
                   expected_type == TINYGLTF_TYPE_VEC3 ? "export positions as float (no quantization)"
                                                        : "indices must be unsigned byte, short or int");
        ok = false;
    }
    if (accessor.sparse.isSparse) {
        diag.error(where + "/sparse", "sparse accessors are not supported", "export without sparse accessors");
        ok = false;
    }
    if (accessor.normalized && expected_type == TINYGLTF_TYPE_VEC3) {
        diag.error(where + "/normalized", "normalized (quantized) positions are not supported",
                   "export positions as float");
        ok = false;
    }
    if (accessor.count > kMaxMeshElements) {
        diag.error(where + "/count", std::to_string(accessor.count) + " elements is implausibly many",
                   "simplify the mesh");
        ok = false;
    }
    if (accessor.bufferView < 0 || static_cast<std::size_t>(accessor.bufferView) >= model.bufferViews.size()) {
        diag.error(where + "/bufferView", "missing or out of range", "the file is corrupt: export the mesh again");
        ok = false;
    }
    if (!ok) return std::nullopt;

    const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(accessor.bufferView)];
    const std::string view_where = pointer("bufferViews", static_cast<std::size_t>(accessor.bufferView));
    if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size()) {
        diag.error(view_where + "/buffer", "missing or out of range", "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    const tinygltf::Buffer& buffer = model.buffers[static_cast<std::size_t>(view.buffer)];
    const std::size_t buffer_size = buffer.data.size();
    if (view.byteOffset > buffer_size || view.byteLength > buffer_size - view.byteOffset) {
        diag.error(view_where, "bytes [" + std::to_string(view.byteOffset) + ", " +
                                   std::to_string(view.byteOffset + view.byteLength) + ") lie outside buffer " +
                                   std::to_string(view.buffer) + " (" + std::to_string(buffer_size) + " bytes)",
                   "the file is truncated or corrupt: export the mesh again");
        return std::nullopt;
    }
    const std::size_t components = expected_type == TINYGLTF_TYPE_VEC3 ? 3 : 1;
    const std::size_t component_size = accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                                       : accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                                                                                                          : 4;
    const std::size_t element_size = components * component_size;
    const std::size_t stride = view.byteStride != 0 ? view.byteStride : element_size;
    if (stride < element_size || stride > 252) {
        diag.error(view_where + "/byteStride", "stride " + std::to_string(stride) + " does not fit the " +
                                                   std::to_string(element_size) + "-byte elements",
                   "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    if (accessor.count > 0) {
        const std::size_t span = (accessor.count - 1) * stride + element_size;  // count is capped above
        if (accessor.byteOffset > view.byteLength || span > view.byteLength - accessor.byteOffset) {
            diag.error(where, std::to_string(accessor.count) + " elements from byte " +
                                  std::to_string(accessor.byteOffset) + " run past the end of buffer view " +
                                  std::to_string(accessor.bufferView) + " (" + std::to_string(view.byteLength) +
                                  " bytes)",
                       "the file is truncated or corrupt: export the mesh again");
            return std::nullopt;
        }
    }
    AccessorData data;
    data.first = buffer.data.data() + view.byteOffset + accessor.byteOffset;
    data.stride = stride;
    data.count = accessor.count;
    data.component_type = accessor.componentType;
    return data;
}

std::uint32_t read_index(const AccessorData& data, std::size_t i) {
    const unsigned char* p = data.first + i * data.stride;
    switch (data.component_type) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[0];
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8);
        default:
            return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) |
                   (std::uint32_t(p[3]) << 24);
    }
}

float read_float(const unsigned char* p) {
    // glTF is little endian, as is every platform flowvid builds on.
    float value;
    std::memcpy(&value, p, sizeof value);
    return value;
}

// The node's local transform: its matrix (column-major) or T * R * S.
std::optional<Eigen::Affine3d> node_transform(const tinygltf::Node& node, const std::string& where, Diagnostics& diag) {
    Eigen::Affine3d transform = Eigen::Affine3d::Identity();
    if (!node.matrix.empty()) {
        if (node.matrix.size() != 16) {
            diag.error(where + "/matrix", "must have 16 numbers", "the file is corrupt: export the mesh again");
            return std::nullopt;
        }
        Eigen::Matrix4d m;
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) m(r, c) = node.matrix[static_cast<std::size_t>(c * 4 + r)];
        if (!m.allFinite() || m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
            diag.error(where + "/matrix", "not a finite affine transform", "export with plain node transforms");
            return std::nullopt;
        }
        transform.matrix() = m;
        return transform;
    }
    if (!node.translation.empty() && node.translation.size() != 3) {
        diag.error(where + "/translation", "must have 3 numbers", "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    if (!node.rotation.empty() && node.rotation.size() != 4) {
        diag.error(where + "/rotation", "must have 4 numbers (x, y, z, w)", "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    if (!node.scale.empty() && node.scale.size() != 3) {
        diag.error(where + "/scale", "must have 3 numbers", "the file is corrupt: export the mesh again");
        return std::nullopt;
    }
    Eigen::Vector3d translation = Eigen::Vector3d::Zero();
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
    Eigen::Vector3d scale = Eigen::Vector3d::Ones();
    if (!node.translation.empty()) translation = {node.translation[0], node.translation[1], node.translation[2]};
    if (!node.rotation.empty()) rotation = Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
    if (!node.scale.empty()) scale = {node.scale[0], node.scale[1], node.scale[2]};
    if (!translation.allFinite() || !rotation.coeffs().allFinite() || !scale.allFinite() || rotation.norm() < 1e-12) {
        diag.error(where, "non-finite or degenerate transform", "export with plain node transforms");
        return std::nullopt;
    }
    transform = Eigen::Translation3d(translation) * rotation.normalized() * Eigen::Scaling(scale);
    return transform;
}

void append_mesh(const tinygltf::Model& model, std::size_t mesh_index, const Eigen::Affine3d& transform,
                 TriangleMesh& out, Diagnostics& diag) {
    const tinygltf::Mesh& mesh = model.meshes[mesh_index];
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
        const tinygltf::Primitive& primitive = mesh.primitives[p];
        const std::string where = pointer("meshes", mesh_index) + "/primitives/" + std::to_string(p);
        if (primitive.mode != -1 && primitive.mode != kModeTriangles) {
            diag.warning(where + "/mode", "primitive mode " + std::to_string(primitive.mode) +
                                              " is not triangles (skipped)",
                         "export the body as a triangulated mesh");
            continue;
        }
        if (!primitive.targets.empty())
            diag.warning(where + "/targets", "morph targets are ignored (a rigid body has one shape)", "");
        auto position = primitive.attributes.find("POSITION");
        if (position == primitive.attributes.end()) {
            diag.error(where + "/attributes", "no POSITION attribute", "export the mesh with vertex positions");
            continue;
        }
        std::optional<AccessorData> positions =
            accessor_data(model, position->second, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT},
                          where + "/attributes/POSITION", diag);
        if (!positions) continue;
        const std::size_t base = out.vertices_m.size();
        if (base + positions->count > kMaxMeshElements) {
            diag.error(where, "too many vertices in total", "simplify the mesh");
            return;
        }
        std::size_t non_finite = 0;
        for (std::size_t i = 0; i < positions->count; ++i) {
            const unsigned char* p3 = positions->first + i * positions->stride;
            const Eigen::Vector3d local(read_float(p3), read_float(p3 + 4), read_float(p3 + 8));
            if (!local.allFinite()) ++non_finite;
            out.vertices_m.push_back(transform * local);
        }
        if (non_finite > 0)
            diag.error(pointer("accessors", static_cast<std::size_t>(position->second)),
                       std::to_string(non_finite) + " vertex position(s) are NaN or infinite",
                       "fix the mesh in the modelling tool and export again");

        const std::size_t vertex_count = positions->count;
        std::vector<std::uint32_t> indices;
        if (primitive.indices >= 0) {
            std::optional<AccessorData> index_data = accessor_data(
                model, primitive.indices, TINYGLTF_TYPE_SCALAR,
                {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                where + "/indices", diag);
            if (!index_data) continue;
            std::size_t out_of_range = 0;
            indices.reserve(index_data->count);
            for (std::size_t i = 0; i < index_data->count; ++i) {
                const std::uint32_t index = read_index(*index_data, i);
                if (index >= vertex_count) ++out_of_range;
                indices.push_back(index);
            }
            if (out_of_range > 0) {
                diag.error(pointer("accessors", static_cast<std::size_t>(primitive.indices)),
                           std::to_string(out_of_range) + " index(es) are >= the vertex count " +
                               std::to_string(vertex_count),
                           "the file is corrupt: export the mesh again");
                continue;
            }
        } else {
            indices.resize(vertex_count);
            for (std::size_t i = 0; i < vertex_count; ++i) indices[i] = static_cast<std::uint32_t>(i);
        }
        if (indices.size() % 3 != 0) {
            diag.error(where + "/indices", std::to_string(indices.size()) + " indices is not a multiple of 3",
                       "the file is corrupt: export the mesh again");
            continue;
        }
        for (std::size_t i = 0; i < indices.size(); i += 3)
            out.triangles.push_back({static_cast<int>(base + indices[i]), static_cast<int>(base + indices[i + 1]),
                                     static_cast<int>(base + indices[i + 2])});
    }
}

}  // namespace

std::optional<TriangleMesh> parse_rigid_mesh_glb(const std::string& bytes, Diagnostics& diag) {
    if (!check_glb_container(bytes, diag)) return std::nullopt;
    if (bytes.size() > std::numeric_limits<unsigned int>::max()) {
        diag.error("GLB header", "files over 4 GiB are not supported", "simplify the mesh");
        return std::nullopt;
    }
    // flowvid reads the JSON first (nesting limit, indices that fit tinygltf's ints).
    if (!detail::read_glb_json_chunk(bytes.substr(20, read_u32(bytes, 12)), diag)) return std::nullopt;

    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&skip_images, nullptr);
    tinygltf::FsCallbacks callbacks{&no_file_exists, &keep_path, &refuse_external_file, &refuse_write, nullptr};
    loader.SetFsCallbacks(callbacks);
    tinygltf::Model model;
    std::string error_text, warning_text;
    bool loaded = false;
    try {
        loaded = loader.LoadBinaryFromMemory(&model, &error_text, &warning_text,
                                             reinterpret_cast<const unsigned char*>(bytes.data()),
                                             static_cast<unsigned int>(bytes.size()), "");
    } catch (const std::exception& error) {
        error_text = error.what();
    }
    if (!loaded) {
        while (!error_text.empty() && (error_text.back() == '\n' || error_text.back() == ' ')) error_text.pop_back();
        diag.error("glTF", "cannot parse the glTF content: " + (error_text.empty() ? std::string("unknown error") : error_text),
                   "the file is corrupt or not glTF 2.0: export the mesh again as .glb");
        return std::nullopt;
    }

    TriangleMesh mesh;
    if (model.meshes.empty()) {
        diag.error("/meshes", "the file has no mesh", "export the body's mesh into the .glb");
        return std::nullopt;
    }
    if (!model.skins.empty()) diag.warning("/skins", "skins are ignored (a rigid body does not deform)", "");

    // Which nodes to draw: the default scene's (or the first scene's) roots;
    // without scenes, every node that is nobody's child.
    std::vector<int> roots;
    if (!model.scenes.empty()) {
        std::size_t scene = 0;
        if (model.defaultScene >= 0 && static_cast<std::size_t>(model.defaultScene) < model.scenes.size())
            scene = static_cast<std::size_t>(model.defaultScene);
        roots = model.scenes[scene].nodes;
    } else {
        std::vector<bool> is_child(model.nodes.size(), false);
        for (const tinygltf::Node& node : model.nodes)
            for (int child : node.children)
                if (child >= 0 && static_cast<std::size_t>(child) < model.nodes.size())
                    is_child[static_cast<std::size_t>(child)] = true;
        for (std::size_t i = 0; i < model.nodes.size(); ++i)
            if (!is_child[i]) roots.push_back(static_cast<int>(i));
    }

    if (model.nodes.empty()) {
        for (std::size_t m = 0; m < model.meshes.size(); ++m)
            append_mesh(model, m, Eigen::Affine3d::Identity(), mesh, diag);
    } else {
        std::set<int> visited;
        std::function<void(int, const Eigen::Affine3d&, std::size_t)> visit =
            [&](int index, const Eigen::Affine3d& parent, std::size_t depth) {
                if (index < 0 || static_cast<std::size_t>(index) >= model.nodes.size()) {
                    diag.error("/nodes", "node " + std::to_string(index) + " does not exist",
                               "the file is corrupt: export the mesh again");
                    return;
                }
                if (!visited.insert(index).second || depth > kMaxNodeDepth) {
                    diag.error(pointer("nodes", static_cast<std::size_t>(index)),
                               "the node hierarchy has a cycle or is too deep", "the file is corrupt: export again");
                    return;
                }
                const tinygltf::Node& node = model.nodes[static_cast<std::size_t>(index)];
                const std::string where = pointer("nodes", static_cast<std::size_t>(index));
                std::optional<Eigen::Affine3d> local = node_transform(node, where, diag);
                if (!local) return;
                const Eigen::Affine3d world = parent * *local;
                if (node.mesh >= 0) {
                    if (static_cast<std::size_t>(node.mesh) >= model.meshes.size())
                        diag.error(where + "/mesh", "mesh " + std::to_string(node.mesh) + " does not exist",
                                   "the file is corrupt: export the mesh again");
                    else append_mesh(model, static_cast<std::size_t>(node.mesh), world, mesh, diag);
                }
                for (int child : node.children) visit(child, world, depth + 1);
            };
        for (int root : roots) visit(root, Eigen::Affine3d::Identity(), 0);
    }
    if (diag.has_errors()) return std::nullopt;
    if (mesh.triangles.empty()) {
        diag.error("/meshes", "no triangles found in the scene", "export the body as a triangulated mesh");
        return std::nullopt;
    }
    std::size_t degenerate = 0;
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d& a = mesh.vertices_m[static_cast<std::size_t>(t[0])];
        const Eigen::Vector3d& b = mesh.vertices_m[static_cast<std::size_t>(t[1])];
        const Eigen::Vector3d& c = mesh.vertices_m[static_cast<std::size_t>(t[2])];
        if ((b - a).cross(c - a).norm() <= 1e-18) ++degenerate;
    }
    if (degenerate > 0)
        diag.warning("/meshes", std::to_string(degenerate) + " degenerate (zero-area) triangle(s)",
                     "clean the mesh (merge by distance) before export");
    return mesh;
}

TriangleMesh read_rigid_mesh(const std::string& path, std::vector<Problem>* warnings) {
    const std::string bytes = read_text_file(path);
    Diagnostics diag(path);
    std::optional<TriangleMesh> mesh = parse_rigid_mesh_glb(bytes, diag);
    diag.throw_if_errors();
    if (warnings) *warnings = diag.warnings();
    return std::move(*mesh);
}

std::vector<Problem> validate_rigid_mesh_file(const std::string& path, Strictness) {
    Diagnostics diag(path);
    std::string bytes;
    try {
        bytes = read_text_file(path);
    } catch (const IoError& error) {
        diag.error(error.field(), error.message(), error.fix());
        return diag.problems();
    }
    parse_rigid_mesh_glb(bytes, diag);
    return diag.problems();
}

MeshVolume mesh_volume(const TriangleMesh& mesh) {
    // Sum of signed tetrahedra (origin, a, b, c).
    MeshVolume result;
    Eigen::Vector3d moment = Eigen::Vector3d::Zero();
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d& a = mesh.vertices_m[static_cast<std::size_t>(t[0])];
        const Eigen::Vector3d& b = mesh.vertices_m[static_cast<std::size_t>(t[1])];
        const Eigen::Vector3d& c = mesh.vertices_m[static_cast<std::size_t>(t[2])];
        const double volume = a.dot(b.cross(c)) / 6.0;
        result.volume_m3 += volume;
        moment += volume * (a + b + c) / 4.0;
    }
    if (std::abs(result.volume_m3) > 0.0) result.centroid_m = moment / result.volume_m3;
    return result;
}

nlohmann::json summarize_rigid_mesh(const TriangleMesh& mesh) {
    nlohmann::json summary = {{"format", "glTF 2.0 binary"},
                              {"vertices", mesh.vertices_m.size()},
                              {"triangles", mesh.triangles.size()}};
    if (!mesh.vertices_m.empty()) {
        Eigen::Vector3d lo = mesh.vertices_m.front(), hi = lo;
        for (const Eigen::Vector3d& v : mesh.vertices_m) {
            lo = lo.cwiseMin(v);
            hi = hi.cwiseMax(v);
        }
        summary["bbox_min_m"] = {lo.x(), lo.y(), lo.z()};
        summary["bbox_max_m"] = {hi.x(), hi.y(), hi.z()};
        const MeshVolume volume = mesh_volume(mesh);
        summary["volume_m3"] = volume.volume_m3;
        summary["centroid_m"] = {volume.centroid_m.x(), volume.centroid_m.y(), volume.centroid_m.z()};
    }
    return summary;
}

}  // namespace flowvid::formats
