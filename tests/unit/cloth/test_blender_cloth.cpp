// Fabric preset -> Blender cloth settings (cloth/blender_cloth): the mesh
// statistics of a panel computed by hand, and each setting against the
// formula of docs/blender.md evaluated here term by term. That the numbers
// equal the Blender add-on's own mapping (core/mapping.py) is checked by
// python.addon_core (MappingTest.test_cli_mapping_equals_addon).

#include "flowvid/cloth/blender_cloth.hpp"
#include "flowvid/formats/blender_cloth_settings.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/polygon_mesh.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

using namespace flowvid;
namespace fc = flowvid::cloth;
namespace ff = flowvid::formats;
using flowvid::testing::mentions;
using flowvid::testing::source_path;
using flowvid::testing::test_data;
using flowvid::testing::validation_messages;

namespace {

std::map<std::string, double> as_map(const std::vector<std::pair<std::string, double>>& pairs) {
    return {pairs.begin(), pairs.end()};
}

// tests/data/cloth/panel_9x5.obj: 0.4 m x 0.3 m, 9 x 5 vertices, 8 x 4 quads.
constexpr int kVertices = 45;
constexpr double kArea = 0.4 * 0.3;
constexpr double kMeanEdge = (40 * 0.05 + 36 * 0.075) / 76.0;  // 40 edges along x, 36 along y
constexpr double kBoundary = 2 * (0.4 + 0.3);

}  // namespace

TEST(BlenderCloth, MeshStatisticsOfAQuadPanel) {
    const ff::PolygonMesh mesh = ff::read_polygon_mesh(test_data("cloth/panel_9x5.obj"));
    EXPECT_EQ(mesh.vertices_m.size(), 45u);
    EXPECT_EQ(mesh.faces.size(), 32u);
    const fc::BlenderMeshStats stats = fc::blender_mesh_stats(mesh);
    EXPECT_EQ(stats.vertex_count, kVertices);
    EXPECT_NEAR(stats.area_m2, kArea, 1e-12);
    EXPECT_NEAR(stats.mean_edge_length_m, kMeanEdge, 1e-12);
    EXPECT_NEAR(stats.boundary_length_m, kBoundary, 1e-12);
    EXPECT_EQ(stats.quad_fraction, 1.0);

    // Triangulated, the same panel has diagonals among its edges and no quads.
    ff::PolygonMesh triangles = mesh;
    triangles.faces.clear();
    for (const std::vector<int>& q : mesh.faces) {
        triangles.faces.push_back({q[0], q[1], q[2]});
        triangles.faces.push_back({q[0], q[2], q[3]});
    }
    const fc::BlenderMeshStats t = fc::blender_mesh_stats(triangles);
    EXPECT_NEAR(t.area_m2, kArea, 1e-12);
    EXPECT_EQ(t.quad_fraction, 0.0);
    EXPECT_NEAR(t.mean_edge_length_m, (40 * 0.05 + 36 * 0.075 + 32 * std::hypot(0.05, 0.075)) / 108.0, 1e-12);
}

TEST(BlenderCloth, SettingsFollowTheDocumentedFormula) {
    ff::FabricPreset preset = ff::read_fabric_preset(source_path("formats/examples/cotton.fabric.json"));
    ff::FabricParameters& p = preset.parameters;
    p.stretch_weft_stiffness_N_per_m.value = 600.0;  // anisotropic: averaged to 700
    p.hem_line_density_kg_per_m.value = 0.002;
    p.diagonal_tension_stiffness_N_per_m.value = 40.0;
    p.drag_linear_normal_kg_per_m2_s.value = 0.05;
    const fc::BlenderMeshStats mesh = fc::blender_mesh_stats(ff::read_polygon_mesh(test_data("cloth/panel_9x5.obj")));
    fc::BlenderClothOptions options;
    options.fps = 25.0;
    options.quality = 4;
    const fc::BlenderClothMapping mapping = fc::map_preset_to_blender_cloth(p, mesh, options);
    std::map<std::string, double> s = as_map(mapping.settings);

    const double tau = 1.0 / std::sqrt(1000.0);  // Blender's gravity is real in this time unit
    const double mass_scale = 1000.0, force = mass_scale * tau * tau, damping = mass_scale * tau;
    const double L = kMeanEdge, k_stretch = 700.0, k_shear = 80.0;
    EXPECT_EQ(s["quality"], 10.0);  // raised to the minimum
    EXPECT_NEAR(s["time_scale"], std::sqrt(1000.0) / 25.0, 1e-12);
    EXPECT_NEAR(s["mass"], mass_scale * (0.15 * kArea + 0.002 * kBoundary) / kVertices, 1e-12);
    EXPECT_NEAR(s["tension_stiffness"], (k_stretch - k_shear) * force * L, 1e-12);
    EXPECT_NEAR(s["compression_stiffness"], 1.0 * k_stretch * force * L, 1e-12);
    EXPECT_NEAR(s["shear_stiffness"], (2 * k_shear + 0.5 * 40.0) * force * L, 1e-12);
    const double bending = 20.0 * 2e-5 * force / (L * L);
    EXPECT_NEAR(s["bending_stiffness"], bending, 1e-12);
    EXPECT_NEAR(s["tension_damping"], 0.5 * damping, 1e-12);
    EXPECT_NEAR(s["shear_damping"], 2 * 0.05 * damping, 1e-12);
    EXPECT_NEAR(s["bending_damping"], 0.2 * bending * (1e-7 / 2e-5) / tau, 1e-12);
    const double c_drag = 0.05 + 0.6 * 0.5 / (1 + 0.1 * 0.25);
    EXPECT_NEAR(s["air_damping"], c_drag * (kArea / kVertices) * damping / 0.01, 1e-12);
    EXPECT_EQ(mapping.bending_model, "ANGULAR");
    bool anisotropy_noted = false;
    for (const std::string& note : mapping.not_represented) anisotropy_noted |= mentions(note, "anisotropic stretch");
    EXPECT_TRUE(anisotropy_noted);
}

TEST(BlenderCloth, OutOfRangeSettingsAreClampedAndSaid) {
    ff::FabricPreset preset = ff::read_fabric_preset(source_path("formats/examples/cotton.fabric.json"));
    preset.parameters.stretch_warp_stiffness_N_per_m.value = 1e9;
    preset.parameters.stretch_weft_stiffness_N_per_m.value = 1e9;
    const fc::BlenderMeshStats mesh = fc::blender_mesh_stats(ff::read_polygon_mesh(test_data("cloth/panel_9x5.obj")));
    const fc::BlenderClothMapping mapping = fc::map_preset_to_blender_cloth(preset.parameters, mesh, {});
    EXPECT_EQ(as_map(mapping.settings)["tension_stiffness"], 10000.0);
    bool said = false;
    for (const std::string& note : mapping.not_represented) said |= mentions(note, "tension_stiffness = ");
    EXPECT_TRUE(said);
}

TEST(BlenderCloth, UnusableInputNamesTheFieldAndTheFix) {
    ff::FabricPreset preset = ff::read_fabric_preset(source_path("formats/examples/cotton.fabric.json"));
    const fc::BlenderMeshStats mesh = fc::blender_mesh_stats(ff::read_polygon_mesh(test_data("cloth/panel_9x5.obj")));
    preset.parameters.bend_stiffness_N_m.value = 0.0;
    std::string messages = validation_messages([&] { fc::map_preset_to_blender_cloth(preset.parameters, mesh, {}, "x.obj"); });
    EXPECT_TRUE(mentions(messages, "/parameters/bend_stiffness_N_m/value")) << messages;

    ff::PolygonMesh flat;
    flat.vertices_m = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 0, 0)};
    flat.faces = {{0, 1, 2}};
    preset.parameters.bend_stiffness_N_m.value = 2e-5;
    messages = validation_messages(
        [&] { fc::map_preset_to_blender_cloth(preset.parameters, fc::blender_mesh_stats(flat), {}, "flat.obj"); });
    EXPECT_TRUE(mentions(messages, "flat.obj")) << messages;
    EXPECT_TRUE(mentions(messages, "non-zero area")) << messages;

    Diagnostics diagnostics("bad.obj");
    EXPECT_FALSE(ff::parse_obj_mesh("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n", diagnostics));
    ASSERT_TRUE(diagnostics.has_errors());
    EXPECT_EQ(diagnostics.problems()[0].field, "line 4");
    EXPECT_TRUE(mentions(diagnostics.problems()[0].message, "\"7\"")) << diagnostics.problems()[0].message;
}

TEST(BlenderCloth, SettingsFileHoldsTheMappingAndReadsBack) {
    const ff::FabricPreset preset = ff::read_fabric_preset(source_path("formats/examples/cotton.fabric.json"));
    const std::string mesh_path = test_data("cloth/panel_9x5.obj");
    const fc::BlenderMeshStats mesh = fc::blender_mesh_stats(ff::read_polygon_mesh(mesh_path));
    fc::BlenderClothOptions options;
    options.fps = 30.0;
    options.quality = 14;
    const fc::BlenderClothMapping mapping = fc::map_preset_to_blender_cloth(preset.parameters, mesh, options);
    const ff::BlenderClothSettings s = fc::blender_cloth_settings_for_mesh(preset, mesh_path, options);

    EXPECT_EQ(s.preset, "cotton (example)");
    EXPECT_EQ(s.mesh.path, mesh_path);
    EXPECT_EQ(s.mesh.vertex_count, kVertices);
    EXPECT_NEAR(s.mesh.mean_edge_length_m, kMeanEdge, 1e-12);
    EXPECT_NEAR(s.mesh.boundary_length_m, kBoundary, 1e-12);
    EXPECT_EQ(s.scene.fps, 30.0);
    EXPECT_EQ(s.scene.quality, 14);
    EXPECT_EQ(s.options.min_quality, 10);
    EXPECT_EQ(s.settings, mapping.settings);
    ASSERT_EQ(s.settings.size(), ff::blender_cloth_setting_ranges().size());
    for (std::size_t i = 0; i < s.settings.size(); ++i) EXPECT_EQ(s.settings[i].first, ff::blender_cloth_setting_ranges()[i].name);
    EXPECT_EQ(s.setting("quality"), 14.0);
    EXPECT_NEAR(*s.setting("time_scale"), std::sqrt(1000.0) / 30.0, 1e-12);
    EXPECT_EQ(s.derived.size(), mapping.derived.size());
    EXPECT_EQ(s.derived.at("tension_spring_N_per_m"), as_map(mapping.derived)["tension_spring_N_per_m"]);
    // The example preset carries a Blender calibration: said, not applied.
    ASSERT_EQ(s.not_represented.size(), mapping.not_represented.size() + 1);
    EXPECT_TRUE(mentions(s.not_represented.back(), "adapters.blender"));
    ff::FabricPreset bare = preset;
    bare.adapters.clear();
    EXPECT_EQ(fc::blender_cloth_settings(bare, mesh_path, mesh, options, mapping).not_represented, mapping.not_represented);

    // The file holds exactly this, and the bundled example is this mapping at 24 fps.
    const std::string path = flowvid::testing::scratch_dir("blender_cloth_file") + "/panel.blender.json";
    ff::write_blender_cloth_settings(path, s);
    EXPECT_TRUE(ff::read_blender_cloth_settings(path) == s);
    ff::BlenderClothSettings example = ff::read_blender_cloth_settings(source_path("formats/examples/panel.blender.json"));
    example.mesh.path = mesh_path;
    EXPECT_TRUE(fc::blender_cloth_settings_for_mesh(preset, mesh_path, {}) == example)
        << "formats/examples/panel.blender.json is stale: write it again with flowvid convert (formats/specs/blender_cloth_settings.md)";

    // A mesh the mapping cannot use is named.
    const std::string flat = flowvid::testing::scratch_dir("blender_cloth_flat") + "/flat.obj";
    flowvid::testing::write_text(flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    const std::string messages = validation_messages([&] { fc::blender_cloth_settings_for_mesh(preset, flat, {}); });
    EXPECT_TRUE(mentions(messages, "flat.obj")) << messages;
    EXPECT_TRUE(mentions(messages, "non-zero area")) << messages;
}
