// A fabric preset as an OpenUSD physics material (formats/fabric_usda):
// values back equal to the preset's, attribute names and types as the
// deformables proposal defines them (OpenUSD-proposals pull request 111,
// proposals/physics_deformables/wp_deformable_physics.md), the usda parser.
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fabric_usda.hpp"
#include "converter_test_preset.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::mentions;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {


// The proposal's material attributes: PhysicsMaterialAPI (density, friction,
// restitution) and PhysicsSurfaceDeformableMaterialAPI, with their types.
const std::map<std::string, std::string>& proposal_surface_material_attributes() {
    static const std::map<std::string, std::string> table = {
        {"physics:dynamicFriction", "float"},       {"physics:staticFriction", "float"},
        {"physics:restitution", "float"},           {"physics:density", "float"},
        {"physics:youngsModulus", "float"},         {"physics:poissonsRatio", "float"},
        {"physics:surfaceStretchStiffness", "float"}, {"physics:surfaceShearStiffness", "float"},
        {"physics:surfaceBendStiffness", "float"},
    };
    return table;
}

double relative_difference(double a, double b) { return std::abs(a - b) / std::max(std::abs(b), 1e-300); }

}  // namespace

TEST(FabricUsda, RoundTripGivesThePresetsValues) {
    const FabricPreset preset = flowvid::testing::converter_test_preset();
    const std::string path = scratch_dir("usda_round_trip") + "/cotton.usda";
    write_fabric_usda(path, preset);
    const FabricPreset back = read_fabric_usda(path);
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        const FabricParameter& a = preset.parameters.*info.member;
        const FabricParameter& b = back.parameters.*info.member;
        EXPECT_EQ(b.value, a.value) << info.key;  // doubles printed with 17 digits come back exactly
        EXPECT_EQ(b.uncertainty, a.uncertainty) << info.key;
        EXPECT_EQ(b.range, a.range) << info.key;
    }
    EXPECT_EQ(back, preset);
    EXPECT_EQ(detect_file_kind(path), FileKind::fabric_usda);
    EXPECT_EQ(summarize_any_file(path)["name"], preset.name);
}

// The schema check: every physics: attribute is one the proposal defines for
// a surface deformable material, with the proposal's type, not custom; the
// four flowvid maps are there with the preset's values in the units the layer
// states; everything else is a custom flowvid: attribute.
TEST(FabricUsda, AttributesFollowTheDeformablesProposal) {
    const FabricPreset preset = flowvid::testing::converter_test_preset();
    Diagnostics diagnostics("cotton.usda");
    const std::optional<UsdaLayer> layer = parse_usda(fabric_preset_to_usda(preset), diagnostics);
    ASSERT_TRUE(layer) << diagnostics.problems().front().to_string();
    EXPECT_FALSE(diagnostics.has_errors());

    EXPECT_EQ(layer->metadata["metersPerUnit"], 1.0);
    EXPECT_EQ(layer->metadata["kilogramsPerUnit"], 1.0);
    EXPECT_EQ(layer->metadata["defaultPrim"], "Fabric");
    ASSERT_EQ(layer->prims.size(), 1u);
    const UsdaPrim& material = layer->prims[0];
    EXPECT_EQ(material.specifier, "def");
    EXPECT_EQ(material.type_name, "Material");
    EXPECT_EQ(material.name, "Fabric");
    const nlohmann::json schemas = material.metadata["apiSchemas"];
    EXPECT_NE(std::find(schemas.begin(), schemas.end(), "PhysicsSurfaceDeformableMaterialAPI"), schemas.end());
    EXPECT_NE(std::find(schemas.begin(), schemas.end(), "PhysicsMaterialAPI"), schemas.end());

    std::map<std::string, double> physics;
    for (const UsdaAttribute& a : material.attributes) {
        if (a.name.rfind("physics:", 0) == 0) {
            const auto expected = proposal_surface_material_attributes().find(a.name);
            ASSERT_NE(expected, proposal_surface_material_attributes().end()) << a.name << " is not in the proposal";
            EXPECT_EQ(a.type, expected->second) << a.name;
            EXPECT_FALSE(a.custom) << a.name;
            ASSERT_TRUE(a.value.is_number()) << a.name;
            physics[a.name] = a.value.get<double>();
        } else {
            EXPECT_EQ(a.name.rfind("flowvid:", 0), 0u) << a.name << ": outside the proposal, so in flowvid:";
            EXPECT_TRUE(a.custom) << a.name;
        }
    }
    const FabricParameters& p = preset.parameters;
    const double float_precision = 1e-7;  // the proposal's attributes are float
    ASSERT_EQ(physics.size(), 4u);
    EXPECT_LT(relative_difference(physics["physics:surfaceStretchStiffness"],
                                  0.5 * (p.stretch_warp_stiffness_N_per_m.value + p.stretch_weft_stiffness_N_per_m.value)),
              float_precision);
    EXPECT_LT(relative_difference(physics["physics:surfaceShearStiffness"], p.shear_stiffness_N_per_m.value), float_precision);
    EXPECT_LT(relative_difference(physics["physics:surfaceBendStiffness"], p.bend_stiffness_N_m.value), float_precision);
    // kg/m^3 over the proposal's default shell thickness of 1 mm.
    EXPECT_LT(relative_difference(physics["physics:density"], p.areal_density_kg_per_m2.value / 1e-3), float_precision);

    // Damping and drag live in flowvid:, in double, with uncertainty and range.
    const UsdaAttribute* drag = material.attribute("flowvid:drag_normal_kg_per_m3");
    ASSERT_NE(drag, nullptr);
    EXPECT_EQ(drag->type, "double");
    EXPECT_EQ(drag->value.get<double>(), p.drag_normal_kg_per_m3.value);
    const UsdaAttribute* uncertainty = material.attribute("flowvid:drag_normal_kg_per_m3:uncertainty");
    ASSERT_NE(uncertainty, nullptr);
    EXPECT_EQ(uncertainty->value.get<double>(), *p.drag_normal_kg_per_m3.uncertainty);
    const UsdaAttribute* range = material.attribute("flowvid:stretch_warp_damping_N_s_per_m:range");
    ASSERT_NE(range, nullptr);
    EXPECT_EQ(range->type, "double2");
    EXPECT_EQ(range->value, nlohmann::json::array({0.0, 100.0}));
}

TEST(FabricUsda, ParserReadsTheUsdaSubsetAndNamesTheLineOfAMistake) {
    const std::string text = R"(#usda 1.0
(
    """A layer doc
over two lines"""
    metersPerUnit = 0.01
    customLayerData = {
        string "a" = "b"
        double[] "list" = [1, 2.5]
    }
)

# a comment
def Xform "World" (
    kind = "group"
)
{
    float3 xformOp:translate = (1, -2e-3, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    rel material:binding = </World/Cloth>
    def Mesh "Cloth" (
        prepend apiSchemas = ["PhysicsSurfaceDeformableSimAPI"]
    )
    {
        int[] faceVertexCounts = [3, 3]
        float physics:youngsModulus = -inf
        bool flag = true
    }
}
)";
    Diagnostics diagnostics("test.usda");
    const std::optional<UsdaLayer> layer = parse_usda(text, diagnostics);
    ASSERT_TRUE(layer) << diagnostics.problems().front().to_string();
    EXPECT_EQ(layer->metadata["doc"], "A layer doc\nover two lines");
    EXPECT_EQ(layer->metadata["metersPerUnit"], 0.01);
    EXPECT_EQ(layer->metadata["customLayerData"]["list"], nlohmann::json::array({1.0, 2.5}));
    ASSERT_EQ(layer->prims.size(), 1u);
    const UsdaPrim& world = layer->prims[0];
    EXPECT_EQ(world.type_name, "Xform");
    EXPECT_EQ(world.metadata["kind"], "group");
    EXPECT_EQ(world.attribute("xformOp:translate")->value, nlohmann::json::array({1.0, -2e-3, 3.0}));
    EXPECT_EQ(world.attribute("xformOpOrder")->type, "token[]");
    EXPECT_TRUE(world.attribute("xformOpOrder")->uniform);
    EXPECT_EQ(world.attribute("material:binding"), nullptr);  // a relationship, not an attribute
    ASSERT_EQ(world.children.size(), 1u);
    const UsdaPrim& cloth = world.children[0];
    EXPECT_EQ(cloth.metadata["apiSchemas:listOp"], "prepend");
    EXPECT_EQ(cloth.attribute("physics:youngsModulus")->value.get<double>(), -std::numeric_limits<double>::infinity());
    EXPECT_EQ(cloth.attribute("physics:youngsModulus")->line, 25);
    EXPECT_EQ(cloth.attribute("flag")->value, true);

    Diagnostics broken("broken.usda");
    EXPECT_FALSE(parse_usda("#usda 1.0\ndef Material \"M\"\n{\n    float physics:density = \n}\n", broken));
    ASSERT_TRUE(broken.has_errors());
    EXPECT_EQ(broken.problems()[0].field, "line 5");

    Diagnostics not_usda("model.usd");
    EXPECT_FALSE(parse_usda("PXR-USDC binary", not_usda));
    EXPECT_TRUE(mentions(not_usda.problems()[0].fix, "usdcat"));

    // Hostile nesting is refused, not recursed into until the stack ends.
    Diagnostics deep("deep.usda");
    EXPECT_FALSE(parse_usda("#usda 1.0\ndef \"A\" {\n    double[] x = " + std::string(100000, '[') + "\n}\n", deep));
    EXPECT_TRUE(mentions(deep.problems()[0].message, "nested")) << deep.problems()[0].message;
}

TEST(FabricUsda, BadFilesNameTheAttributeAndTheFix) {
    const std::string dir = scratch_dir("usda_bad");
    const std::string good = fabric_preset_to_usda(flowvid::testing::converter_test_preset());
    auto replaced = [&](const std::string& from, const std::string& to) {
        std::string text = good;
        const std::size_t at = text.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        return text.replace(at, from.size(), to);
    };

    write_text(dir + "/negative.usda", replaced("custom double flowvid:shear_stiffness_N_per_m = 80",
                                                "custom double flowvid:shear_stiffness_N_per_m = -80"));
    std::string messages = validation_messages([&] { read_fabric_usda(dir + "/negative.usda"); });
    EXPECT_TRUE(mentions(messages, dir + "/negative.usda")) << messages;
    EXPECT_TRUE(mentions(messages, "/Fabric.flowvid:shear_stiffness_N_per_m")) << messages;

    write_text(dir + "/string.usda", replaced("custom double flowvid:bend_damping_N_m_s = 1e-07",
                                              "custom double flowvid:bend_damping_N_m_s = \"small\""));
    messages = validation_messages([&] { read_fabric_usda(dir + "/string.usda"); });
    EXPECT_TRUE(mentions(messages, "flowvid:bend_damping_N_m_s (line ")) << messages;
    EXPECT_TRUE(mentions(messages, "expected a number")) << messages;

    // A proposal attribute edited in a DCC: read with the flowvid: values and a warning naming it.
    const std::string edited = dir + "/edited.usda";
    std::string text = good;
    const std::size_t at = text.find("float physics:surfaceBendStiffness = ");
    ASSERT_NE(at, std::string::npos);
    const std::size_t end = text.find(' ', at + 38);
    write_text(edited, text.replace(at, end - at, "float physics:surfaceBendStiffness = 0.5"));
    std::vector<Problem> warnings;
    const FabricPreset back = read_fabric_usda(edited, &warnings);
    EXPECT_EQ(back.parameters.bend_stiffness_N_m.value, flowvid::testing::converter_test_preset().parameters.bend_stiffness_N_m.value);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_TRUE(mentions(warnings[0].field, "physics:surfaceBendStiffness")) << warnings[0].field;

    write_text(dir + "/other.usda", "#usda 1.0\ndef Material \"M\"\n{\n    float physics:density = 1000\n}\n");
    messages = validation_messages([&] { read_fabric_usda(dir + "/other.usda"); });
    EXPECT_TRUE(mentions(messages, "flowvid convert")) << messages;
}
