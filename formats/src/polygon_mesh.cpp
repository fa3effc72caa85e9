#include "flowvid/formats/polygon_mesh.hpp"

#include "flowvid/formats/rigid_mesh.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <locale>
#include <sstream>

namespace flowvid::formats {
namespace {

bool ends_with(const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string lower(std::string text) {
    for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return text;
}

}  // namespace

std::optional<PolygonMesh> parse_obj_mesh(const std::string& text, Diagnostics& diagnostics) {
    PolygonMesh mesh;
    std::istringstream lines(text);
    std::string line;
    int number = 0;
    bool warned_lines = false;
    // A face may use only the vertices above it (what every exporter writes,
    // and what negative indices count back from).
    while (std::getline(lines, line)) {
        ++number;
        const std::string where = "line " + std::to_string(number);
        std::istringstream in(line);
        in.imbue(std::locale::classic());
        std::string keyword;
        if (!(in >> keyword) || keyword[0] == '#') continue;
        if (keyword == "v") {
            Eigen::Vector3d p;
            if (!(in >> p.x() >> p.y() >> p.z())) {
                diagnostics.error(where, "a vertex needs three numbers", "write v X Y Z (metres)");
                continue;
            }
            if (!p.allFinite()) diagnostics.error(where, "vertex coordinate is not finite", "fix the exported mesh");
            mesh.vertices_m.push_back(p);
        } else if (keyword == "f") {
            std::vector<int> face;
            std::string corner;
            bool ok = true;
            while (in >> corner) {
                const std::string index_text = corner.substr(0, corner.find('/'));
                char* end = nullptr;
                const long index = std::strtol(index_text.c_str(), &end, 10);
                const long count = static_cast<long>(mesh.vertices_m.size());
                const long resolved = index > 0 ? index - 1 : count + index;
                if (index_text.empty() || *end != '\0' || index == 0 || resolved < 0 || resolved >= count) {
                    diagnostics.error(where, "face corner \"" + corner + "\" does not name one of the " +
                                                 std::to_string(count) + " vertices above it",
                                      "use 1-based vertex indices (or negative ones counting back)");
                    ok = false;
                    break;
                }
                face.push_back(static_cast<int>(resolved));
            }
            if (!ok) continue;
            if (face.size() < 3) {
                diagnostics.error(where, "a face needs at least three corners", "remove the line or complete the face");
                continue;
            }
            mesh.faces.push_back(std::move(face));
        } else if (keyword == "l") {
            if (!warned_lines)
                diagnostics.warning(where, "loose edges (l lines) are ignored", "a cloth is made of faces only");
            warned_lines = true;
        }
    }
    if (mesh.faces.empty() && !diagnostics.has_errors())
        diagnostics.error("", "the mesh has no faces", "export the garment as a surface (f lines), not points or lines");
    if (diagnostics.has_errors()) return std::nullopt;
    return mesh;
}

PolygonMesh read_polygon_mesh(const std::string& path, std::vector<Problem>* warnings) {
    if (ends_with(lower(path), ".glb")) {
        const TriangleMesh triangles = read_rigid_mesh(path, warnings);
        PolygonMesh mesh;
        mesh.vertices_m = triangles.vertices_m;
        for (const std::array<int, 3>& t : triangles.triangles) mesh.faces.push_back({t[0], t[1], t[2]});
        return mesh;
    }
    if (!ends_with(lower(path), ".obj"))
        throw UsageError(path, "", "unknown mesh type", "give a Wavefront .obj (quads kept) or a glTF binary .glb");
    Diagnostics diagnostics(path);
    const std::string text = read_text_or_throw(path);
    std::optional<PolygonMesh> mesh = parse_obj_mesh(text, diagnostics);
    diagnostics.throw_if_errors();
    if (warnings) *warnings = diagnostics.warnings();
    return std::move(*mesh);
}

}  // namespace flowvid::formats
