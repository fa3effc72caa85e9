#pragma once
// Fabric preset -> Blender cloth settings for a given mesh: the library's
// home of the mapping the Blender add-on applies (blender_addon/flowvid_blender/
// core/mapping.py, map_preset; derivation in docs/blender.md). The two are
// kept equal by python.addon_core (MappingTest.test_cli_mapping_equals_addon),
// which maps the same preset and mesh both ways and compares every setting.
//
// Only the documented formula: a Blender calibration stored in the preset
// (adapters.blender, written by the add-on's Calibrate) needs Blender to check
// and is applied by the add-on, not here (noted in the result when present).

#include "flowvid/formats/blender_cloth_settings.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/polygon_mesh.hpp"

#include <string>
#include <utility>
#include <vector>

namespace flowvid::cloth {

// The garment as Blender's cloth sees it (after the object's scale), as the
// add-on's fabric.mesh_stats measures it: every vertex, every edge of the faces.
struct BlenderMeshStats {
    int vertex_count = 0;
    double mean_edge_length_m = 0.0;  // mean edge length (Blender's avg_spring_len)
    double area_m2 = 0.0;
    double quad_fraction = 1.0;       // faces with 4 corners / all faces
    double boundary_length_m = 0.0;   // edges of one face only: where a hem lies
};
BlenderMeshStats blender_mesh_stats(const formats::PolygonMesh& mesh);

struct BlenderClothOptions {
    double fps = 24.0;                   // scene frames per second (Blender's default scene: 24)
    int quality = 0;                     // the object's substeps per frame; raised to min_quality
    double mass_scale = 1000.0;          // Blender mass unit = 1 g (any value gives the same motion)
    double reference_speed_m_per_s = 0.5;  // where quadratic drag is matched by Blender's linear drag
    int min_quality = 10;
};

struct BlenderClothMapping {
    // ClothSettings name -> value, in the add-on's order, clamped to Blender 3.4's hard limits
    // (formats::blender_cloth_setting_ranges(), what the settings file accepts).
    std::vector<std::pair<std::string, double>> settings;
    std::string bending_model = "ANGULAR";
    std::vector<std::string> not_represented;                // what Blender cannot express, each clamp
    std::vector<std::pair<std::string, double>> derived;     // tau, spring constants, ...
};

// Throws ValidationError naming the preset field or the mesh when the mapping
// cannot use them (e.g. zero bending stiffness, a mesh without area).
BlenderClothMapping map_preset_to_blender_cloth(const formats::FabricParameters& parameters,
                                                const BlenderMeshStats& mesh, const BlenderClothOptions& options,
                                                const std::string& mesh_name = "mesh");

// The settings file flowvid convert writes (formats/blender_cloth_settings,
// "flowvid.blender_cloth"): the mapping with the preset's name, the mesh
// (`mesh_path` as given), the options, and a note when the preset carries a
// Blender calibration that this formula does not apply.
formats::BlenderClothSettings blender_cloth_settings(const formats::FabricPreset& preset, const std::string& mesh_path,
                                                     const BlenderMeshStats& mesh, const BlenderClothOptions& options,
                                                     const BlenderClothMapping& mapping);

// Reads the mesh, measures it, maps the preset: what `flowvid convert PRESET
// OUT.blender.json --mesh GARMENT` writes. Throws IoError / ValidationError
// naming the mesh (its line) or the preset field; the mesh's warnings go to
// `warnings` when given.
formats::BlenderClothSettings blender_cloth_settings_for_mesh(const formats::FabricPreset& preset,
                                                              const std::string& mesh_path,
                                                              const BlenderClothOptions& options,
                                                              std::vector<Problem>* warnings = nullptr);

}  // namespace flowvid::cloth
