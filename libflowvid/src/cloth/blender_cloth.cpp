#include "flowvid/cloth/blender_cloth.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

namespace flowvid::cloth {
namespace {

// Blender 3.4's solver constants (SIM_mass_spring.cpp), as in the add-on.
constexpr double kBlenderAirDampingScale = 0.01;  // drag = Cvi * 0.01

std::string g(double value, const char* format = "%g") {
    char text[64];
    std::snprintf(text, sizeof text, format, value);
    return text;
}

}  // namespace

BlenderMeshStats blender_mesh_stats(const formats::PolygonMesh& mesh) {
    BlenderMeshStats stats;
    stats.vertex_count = static_cast<int>(mesh.vertices_m.size());
    std::map<std::pair<int, int>, int> faces_of_edge;
    int quads = 0;
    for (const std::vector<int>& face : mesh.faces) {
        const Eigen::Vector3d& p0 = mesh.vertices_m[static_cast<std::size_t>(face[0])];
        for (std::size_t k = 1; k + 1 < face.size(); ++k)
            stats.area_m2 += 0.5 * (mesh.vertices_m[static_cast<std::size_t>(face[k])] - p0)
                                       .cross(mesh.vertices_m[static_cast<std::size_t>(face[k + 1])] - p0)
                                       .norm();
        quads += face.size() == 4;
        for (std::size_t k = 0; k < face.size(); ++k) {
            const int a = face[k], b = face[(k + 1) % face.size()];
            ++faces_of_edge[{std::min(a, b), std::max(a, b)}];
        }
    }
    double edge_total = 0.0;
    for (const auto& [edge, count] : faces_of_edge) {
        const double length = (mesh.vertices_m[static_cast<std::size_t>(edge.first)] -
                               mesh.vertices_m[static_cast<std::size_t>(edge.second)])
                                  .norm();
        edge_total += length;
        if (count == 1) stats.boundary_length_m += length;
    }
    stats.mean_edge_length_m = faces_of_edge.empty() ? 0.0 : edge_total / static_cast<double>(faces_of_edge.size());
    stats.quad_fraction = mesh.faces.empty() ? 0.0 : static_cast<double>(quads) / static_cast<double>(mesh.faces.size());
    return stats;
}

BlenderClothMapping map_preset_to_blender_cloth(const formats::FabricParameters& parameters,
                                                const BlenderMeshStats& mesh, const BlenderClothOptions& options,
                                                const std::string& mesh_name) {
    Diagnostics problems(mesh_name);
    if (!(parameters.bend_stiffness_N_m.value > 0.0))
        problems.error("/parameters/bend_stiffness_N_m/value",
                       "must be > 0 for Blender (its bending damping is a ratio to the bending stiffness)",
                       "give the preset a positive bending stiffness");
    if (mesh.vertex_count < 3 || !(mesh.mean_edge_length_m > 0.0) || !(mesh.area_m2 > 0.0))
        problems.error("", "needs faces with non-zero area and edge length (" + std::to_string(mesh.vertex_count) +
                               " vertices, mean edge " + g(mesh.mean_edge_length_m) + " m, area " + g(mesh.area_m2) +
                               " m^2)",
                       "give the garment's surface mesh, in metres");
    if (!(options.fps > 0.0)) problems.error("--fps", "must be > 0", "give the scene's frames per second, e.g. --fps 24");
    problems.throw_if_errors();

    const formats::FabricParameters& p = parameters;
    BlenderClothMapping result;
    std::vector<std::string>& notes = result.not_represented;
    const double s = options.mass_scale;
    const double L = mesh.mean_edge_length_m;
    const double n = mesh.vertex_count;
    const double time_scale = std::sqrt(1000.0) / options.fps;  // Blender falls with the scene's gravity
    const double tau = 1.0 / (options.fps * time_scale);        // seconds per unit of solver time
    const double force = s * tau * tau;                          // N -> Blender force units
    const double damping = s * tau;                              // N s/m -> Blender damping units

    auto isotropic = [&](double warp, double weft, const std::string& name, const std::string& unit) {
        const double mean = 0.5 * (warp + weft);
        if (std::abs(warp - weft) > 0.05 * std::max(mean, 1e-30))
            notes.push_back("anisotropic " + name + " (warp " + g(warp) + ", weft " + g(weft) + unit + ") averaged to " +
                            g(mean) + ": Blender's springs are isotropic");
        return mean;
    };
    const double k_stretch = isotropic(p.stretch_warp_stiffness_N_per_m.value, p.stretch_weft_stiffness_N_per_m.value,
                                       "stretch", " N/m");
    const double k_shear = p.shear_stiffness_N_per_m.value;
    const double d_stretch = isotropic(p.stretch_warp_damping_N_s_per_m.value, p.stretch_weft_damping_N_s_per_m.value,
                                       "stretch damping", " N s/m");
    const double bend = p.bend_stiffness_N_m.value;
    const double compression_ratio = isotropic(p.stretch_warp_compression_ratio.value,
                                               p.stretch_weft_compression_ratio.value, "compression ratio", "");
    const double hem = p.hem_line_density_kg_per_m.value;

    // Quad diagonals (tension-only shear springs) carry 2 k_shear and add
    // k_shear to the stretch stiffness in tension; a diagonal fibre of
    // stiffness k is a diagonal spring of k / 2 (docs/blender.md).
    const double shear_spring = 2.0 * k_shear + 0.5 * p.diagonal_tension_stiffness_N_per_m.value;
    double tension_spring = k_stretch - k_shear;
    if (tension_spring <= 0.0) {
        notes.push_back("shear stiffness exceeds stretch stiffness: tension springs set to 10% of stretch");
        tension_spring = 0.1 * k_stretch;
    }
    const double v = options.reference_speed_m_per_s;
    const double c_drag = p.drag_linear_normal_kg_per_m2_s.value +
                          p.drag_normal_kg_per_m3.value * v / (1.0 + p.drag_degradation_s2_per_m2.value * v * v);
    notes.push_back("air drag is linear and isotropic in Blender: the normal drag kN v^2/(1+kf v^2) is matched at " +
                    g(v, "%.2f") + " m/s (" + g(c_drag, "%.3g") +
                    " kg/(m^2 s)); below that speed Blender drags more, above it less; the tangential drag (" +
                    g(p.drag_tangential_kg_per_m2_s.value, "%.3g") + " kg/(m^2 s)) is replaced by the same isotropic value");
    notes.push_back("mass is uniform per vertex in Blender (the library lumps it by area, so edges are lighter there)");
    if (hem > 0.0)
        notes.push_back("the hem (" + g(hem, "%.3g") +
                        " kg per m of boundary) is spread over every vertex: Blender has no per-vertex cloth mass");
    if (mesh.quad_fraction < 0.9)
        notes.push_back("the mesh is " + g(100.0 * (1.0 - mesh.quad_fraction), "%.0f") +
                        "% triangles: the spring formulas assume quads (triangles have no shear springs in Blender); "
                        "run Calibrate for this mesh");
    notes.push_back("bending damping is approximate (Blender damps the wings' mean normal velocity)");

    const double bending = 20.0 * bend * force / (L * L);
    result.settings = {
        {"quality", static_cast<double>(std::max(options.quality, options.min_quality))},
        {"time_scale", time_scale},
        {"mass", s * (p.areal_density_kg_per_m2.value * mesh.area_m2 + hem * mesh.boundary_length_m) / n},
        {"tension_stiffness", tension_spring * force * L},
        {"compression_stiffness", compression_ratio * k_stretch * force * L},
        {"shear_stiffness", shear_spring * force * L},
        {"bending_stiffness", bending},
        {"tension_damping", d_stretch * damping},
        {"compression_damping", d_stretch * damping},
        {"shear_damping", 2.0 * p.shear_damping_N_s_per_m.value * damping},
        {"bending_damping", 0.2 * bending * (p.bend_damping_N_m_s.value / bend) / tau},
        {"air_damping", c_drag * (mesh.area_m2 / n) * damping / kBlenderAirDampingScale},
    };
    for (auto& [name, value] : result.settings) {
        for (const formats::BlenderClothSettingRange& limit : formats::blender_cloth_setting_ranges()) {
            if (name != limit.name || (value <= limit.max && value >= limit.min)) continue;
            const double clamped = std::min(std::max(value, limit.min), limit.max);
            notes.push_back(name + " = " + g(value, "%.4g") + " is outside Blender's range [" + g(limit.min) + ", " +
                            g(limit.max) + "]: set to " + g(clamped));
            value = clamped;
        }
    }
    result.derived = {
        {"tau_s", tau},
        {"mass_scale", s},
        {"force_scale", force},
        {"damping_scale", damping},
        {"linear_drag_kg_per_m2_s", c_drag},
        {"reference_speed_m_per_s", v},
        {"tension_spring_N_per_m", tension_spring},
        {"shear_spring_N_per_m", shear_spring},
    };
    return result;
}

formats::BlenderClothSettings blender_cloth_settings(const formats::FabricPreset& preset, const std::string& mesh_path,
                                                     const BlenderMeshStats& mesh, const BlenderClothOptions& options,
                                                     const BlenderClothMapping& mapping) {
    formats::BlenderClothSettings out;
    out.preset = preset.name;
    out.settings = mapping.settings;
    out.bending_model = mapping.bending_model;
    out.mesh = {mesh_path, mesh.vertex_count, mesh.mean_edge_length_m, mesh.area_m2, mesh.quad_fraction,
                mesh.boundary_length_m};
    out.scene = {options.fps, options.quality};
    out.options = {options.mass_scale, options.reference_speed_m_per_s, options.min_quality};
    out.derived = {mapping.derived.begin(), mapping.derived.end()};
    out.not_represented = mapping.not_represented;
    if (preset.adapters.count("blender"))
        out.not_represented.push_back(
            "the preset's stored Blender adapter (adapters.blender) is not applied here: these are the formula's "
            "settings; applying the preset in Blender uses a stored calibration for a similar mesh");
    return out;
}

formats::BlenderClothSettings blender_cloth_settings_for_mesh(const formats::FabricPreset& preset,
                                                              const std::string& mesh_path,
                                                              const BlenderClothOptions& options,
                                                              std::vector<Problem>* warnings) {
    const BlenderMeshStats stats = blender_mesh_stats(formats::read_polygon_mesh(mesh_path, warnings));
    return blender_cloth_settings(preset, mesh_path, stats, options,
                                  map_preset_to_blender_cloth(preset.parameters, stats, options, mesh_path));
}

}  // namespace flowvid::cloth
