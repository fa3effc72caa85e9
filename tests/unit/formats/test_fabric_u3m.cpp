// A fabric preset as U3M 1.1 (formats/fabric_u3m): values back equal to the
// preset's, the document shaped as the U3M 1.1 schema requires
// (vizoogmbh/u3m, u3m1.1/spec/u3m_schema.json), errors naming the field.
#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "flowvid/formats/fabric_u3m.hpp"
#include "converter_test_preset.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <regex>
#include <set>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::mentions;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::set<std::string> keys_of(const nlohmann::json& object) {
    std::set<std::string> keys;
    for (auto it = object.begin(); it != object.end(); ++it) keys.insert(it.key());
    return keys;
}

}  // namespace

TEST(FabricU3m, RoundTripGivesThePresetsValues) {
    const FabricPreset preset = flowvid::testing::converter_test_preset();
    const std::string path = scratch_dir("u3m_round_trip") + "/cotton.u3m";
    write_fabric_u3m(path, preset);
    const FabricPreset back = read_fabric_u3m(path);
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        const FabricParameter& a = preset.parameters.*info.member;
        const FabricParameter& b = back.parameters.*info.member;
        EXPECT_EQ(b.value, a.value) << info.key;
        EXPECT_EQ(b.uncertainty, a.uncertainty) << info.key;
        EXPECT_EQ(b.range, a.range) << info.key;
    }
    EXPECT_EQ(back, preset);  // name, description, provenance and adapters too
    EXPECT_EQ(detect_file_kind(path), FileKind::fabric_u3m);
    EXPECT_EQ(summarize_any_file(path)["parameters"]["stretch_weft_stiffness_N_per_m"]["value"].get<double>(), 610.25);

    // Units are stated beside each value, and the schema's weight is in g/m^2.
    const nlohmann::json document = nlohmann::json::parse(read_text(path));
    for (const FabricParameterInfo& info : fabric_parameter_table())
        EXPECT_EQ(document["custom"]["flowvid"]["parameters"][info.key]["unit"], info.unit) << info.key;
    EXPECT_DOUBLE_EQ(document["material"]["physics"]["weight"].get<double>(),
                     preset.parameters.areal_density_kg_per_m2.value * 1000.0);
}

// The U3M 1.1 schema's requirements for what flowvid writes, restated as a
// table: required keys of the document, of material and of physics (each of
// these objects has additionalProperties false), and the types and units of
// the fields (u3m1.1/spec/u3m_schema.json).
TEST(FabricU3m, DocumentHasTheShapeOfTheU3m11Schema) {
    const FabricPreset preset = flowvid::testing::converter_test_preset();
    const nlohmann::json u3m = fabric_preset_to_u3m(preset);
    EXPECT_EQ(keys_of(u3m), (std::set<std::string>{"schema", "material", "custom"}));
    EXPECT_EQ(u3m["schema"], "1.1");
    ASSERT_TRUE(u3m["custom"].is_object());

    const nlohmann::json& material = u3m["material"];
    EXPECT_EQ(keys_of(material), (std::set<std::string>{"id", "name", "description", "created", "modified", "front",
                                                        "back", "side", "physics", "metadata"}));
    static const std::regex uuid4(
        "[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-4[0-9a-fA-F]{3}-[89AaBb][0-9a-fA-F]{3}-[0-9a-fA-F]{12}");
    EXPECT_TRUE(std::regex_match(material["id"].get<std::string>(), uuid4)) << material["id"];
    EXPECT_FALSE(material["name"].get<std::string>().empty());
    EXPECT_TRUE(material["description"].is_string());
    static const std::regex date_time(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?(Z|[+-]\d{2}:\d{2}))");
    EXPECT_TRUE(std::regex_match(material["created"].get<std::string>(), date_time));
    EXPECT_TRUE(std::regex_match(material["modified"].get<std::string>(), date_time));
    // No visuals: allowed because physics is not null.
    for (const char* side : {"front", "back", "side"}) EXPECT_TRUE(material[side].is_null()) << side;
    EXPECT_TRUE(material["metadata"].is_null() || material["metadata"].is_object());

    const nlohmann::json& physics = material["physics"];
    ASSERT_TRUE(physics.is_object());
    EXPECT_EQ(keys_of(physics), (std::set<std::string>{"thickness", "weight", "composition", "devices",
                                                       "material_type", "construction"}));
    EXPECT_TRUE(physics["thickness"].is_null());  // mm in U3M; not known from a fit, so not invented
    ASSERT_TRUE(physics["weight"].is_number());   // g/m^2
    EXPECT_GE(physics["weight"].get<double>(), 0.0);
    EXPECT_NEAR(physics["weight"].get<double>(), 150.0, 1e-9);
    EXPECT_TRUE(physics["composition"].is_null());
    EXPECT_EQ(keys_of(physics["devices"]), (std::set<std::string>{"fab"}));
    EXPECT_EQ(physics["devices"]["fab"], "null");  // the schema's value for "no FAB file"
    EXPECT_TRUE(physics["material_type"].is_null());
    EXPECT_TRUE(physics["construction"].is_null());

    // The id follows the preset: stable for the same preset, another for another.
    EXPECT_EQ(fabric_preset_to_u3m(preset)["material"]["id"], material["id"]);
    FabricPreset other = preset;
    other.parameters.bend_stiffness_N_m.value *= 2.0;
    EXPECT_NE(fabric_preset_to_u3m(other)["material"]["id"], material["id"]);
}

TEST(FabricU3m, BadFilesNameTheFieldAndTheFix) {
    const std::string dir = scratch_dir("u3m_bad");
    const nlohmann::json good = fabric_preset_to_u3m(flowvid::testing::converter_test_preset());

    nlohmann::json wrong_unit = good;
    wrong_unit["custom"]["flowvid"]["parameters"]["bend_stiffness_N_m"]["unit"] = "uN m";
    write_text(dir + "/unit.u3m", wrong_unit.dump());
    std::string messages = validation_messages([&] { read_fabric_u3m(dir + "/unit.u3m"); });
    EXPECT_TRUE(mentions(messages, "/custom/flowvid/parameters/bend_stiffness_N_m/unit")) << messages;
    EXPECT_TRUE(mentions(messages, "N m")) << messages;

    nlohmann::json negative = good;
    negative["custom"]["flowvid"]["parameters"]["shear_stiffness_N_per_m"]["value"] = -3.0;
    write_text(dir + "/negative.u3m", negative.dump());
    messages = validation_messages([&] { read_fabric_u3m(dir + "/negative.u3m"); });
    EXPECT_TRUE(mentions(messages, dir + "/negative.u3m")) << messages;
    EXPECT_TRUE(mentions(messages, "/custom/flowvid/parameters/shear_stiffness_N_per_m/value")) << messages;

    nlohmann::json foreign = good;
    foreign["custom"] = {{"another_company", {{"stretch", 1}}}};
    write_text(dir + "/foreign.u3m", foreign.dump());
    messages = validation_messages([&] { read_fabric_u3m(dir + "/foreign.u3m"); });
    EXPECT_TRUE(mentions(messages, "/custom/flowvid")) << messages;
    EXPECT_TRUE(mentions(messages, "flowvid convert")) << messages;

    nlohmann::json old = good;
    old["schema"] = "1.0";
    write_text(dir + "/old.u3m", old.dump());
    messages = validation_messages([&] { read_fabric_u3m(dir + "/old.u3m"); });
    EXPECT_TRUE(mentions(messages, "/schema")) << messages;

    // An edited weight is read (the preset's value wins) with a warning naming it.
    nlohmann::json edited = good;
    edited["material"]["physics"]["weight"] = 200.0;
    write_text(dir + "/edited.u3m", edited.dump());
    std::vector<Problem> warnings;
    const FabricPreset back = read_fabric_u3m(dir + "/edited.u3m", &warnings);
    EXPECT_EQ(back.parameters.areal_density_kg_per_m2.value, 0.15);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "/material/physics/weight");
}

TEST(FabricU3m, AFailedWriteLeavesThePreviousFile) {
    const std::string path = scratch_dir("u3m_atomic") + "/cotton.u3m";
    write_fabric_u3m(path, flowvid::testing::converter_test_preset());
    const std::string before = read_text(path);
    FabricPreset broken = flowvid::testing::converter_test_preset();
    broken.parameters.shear_stiffness_N_per_m.value = std::numeric_limits<double>::quiet_NaN();
    const std::string messages = validation_messages([&] { write_fabric_u3m(path, broken); });
    EXPECT_TRUE(mentions(messages, "shear_stiffness_N_per_m")) << messages;
    EXPECT_EQ(read_text(path), before);
}
