#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/fabric_preset.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

namespace fs = std::filesystem;
using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string example_path() { return source_path("formats/examples/cotton.fabric.json"); }

nlohmann::json example_json() { return nlohmann::json::parse(read_text(example_path())); }

// Writes `document` to a file in a scratch folder and returns its path.
std::string write_json(const std::string& dir, const nlohmann::json& document, const std::string& name = "bad.fabric.json") {
    const std::string path = dir + "/" + name;
    write_text(path, document.dump(2));
    return path;
}

using flowvid::testing::mentions;

}  // namespace

TEST(FabricPreset, Version1_0FilesReadAsTheSameFabricWithNeutralNewParameters) {
    // 1.1 added optional parameters; a 1.0 file lacks them and must read as
    // the fabric it always was: compression as stiff as tension, no linear drag.
    std::vector<Problem> warnings;
    const FabricPreset old = read_fabric_preset(source_path("formats/examples/cotton-1.0.fabric.json"), &warnings);
    EXPECT_TRUE(warnings.empty()) << (warnings.empty() ? "" : warnings.front().to_string());
    EXPECT_EQ(old.parameters.stretch_warp_compression_ratio.value, 1.0);
    EXPECT_EQ(old.parameters.stretch_weft_compression_ratio.value, 1.0);
    EXPECT_EQ(old.parameters.drag_linear_normal_kg_per_m2_s.value, 0.0);
    EXPECT_EQ(old.parameters.hem_line_density_kg_per_m.value, 0.0);
    EXPECT_EQ(old.parameters.shear_cell_fraction.value, 0.0);  // 1.2: shear read across each triangle
    const FabricPreset current = read_fabric_preset(example_path());
    for (const FabricParameterInfo& info : fabric_parameter_table())
        EXPECT_EQ((old.parameters.*info.member).value, (current.parameters.*info.member).value) << info.key;
    // Written again, it is a 1.2 file with every parameter spelled out.
    const std::string dir = scratch_dir("fabric_upgrade");
    write_fabric_preset(dir + "/old.fabric.json", old);
    const nlohmann::json written = nlohmann::json::parse(read_text(dir + "/old.fabric.json"));
    EXPECT_EQ(written["version"], "1.2");
    EXPECT_EQ(written["parameters"]["shear_cell_fraction"]["value"], 0.0);
    EXPECT_EQ(written["parameters"]["stretch_weft_compression_ratio"]["value"], 1.0);
    EXPECT_EQ(read_fabric_preset(dir + "/old.fabric.json").parameters, old.parameters);
    // Only the parameters added after 1.0 are optional.
    nlohmann::json missing = example_json();
    missing["parameters"].erase("shear_stiffness_N_per_m");
    missing["parameters"].erase("drag_linear_normal_kg_per_m2_s");
    const std::string path = write_json(dir, missing);
    const std::string messages = validation_messages([&] { read_fabric_preset(path); });
    EXPECT_TRUE(mentions(messages, "/parameters/shear_stiffness_N_per_m")) << messages;
    EXPECT_FALSE(mentions(messages, "drag_linear_normal")) << messages;
    nlohmann::json zero_ratio = example_json();
    zero_ratio["parameters"]["stretch_warp_compression_ratio"]["value"] = 0.0;
    zero_ratio["parameters"]["stretch_warp_compression_ratio"].erase("range");
    const std::string zero_path = write_json(dir, zero_ratio, "zero.fabric.json");
    EXPECT_TRUE(mentions(validation_messages([&] { read_fabric_preset(zero_path); }),
                         "/parameters/stretch_warp_compression_ratio/value"));
}

TEST(FabricPreset, ExampleOfVersion1_1Loads) {
    std::vector<Problem> warnings;
    const FabricPreset preset = read_fabric_preset(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(preset.name, "cotton (example)");
    EXPECT_DOUBLE_EQ(preset.parameters.areal_density_kg_per_m2.value, 0.15);
    ASSERT_TRUE(preset.parameters.bend_stiffness_N_m.uncertainty.has_value());
    EXPECT_DOUBLE_EQ(*preset.parameters.bend_stiffness_N_m.uncertainty, 4.0e-6);
    EXPECT_EQ(preset.provenance.captures.size(), 2u);
    ASSERT_EQ(preset.adapters.count("blender"), 1u);
    EXPECT_EQ(preset.adapters.at("blender").settings["quality"], 5);
}

TEST(FabricPreset, RoundTripIsBitExact) {
    const std::string dir = scratch_dir("fabric_round_trip");
    FabricPreset preset = read_fabric_preset(example_path());
    // Values with full double precision must survive text serialisation exactly.
    std::mt19937_64 random(42);
    std::uniform_real_distribution<double> log_uniform(-9.0, 4.0);
    for (const FabricParameterInfo& info : fabric_parameter_table()) {
        FabricParameter& p = preset.parameters.*info.member;
        p.value = std::pow(10.0, log_uniform(random));
        p.uncertainty = p.value * 0.123456789012345;
        p.range = std::array<double, 2>{p.value / 3.0, p.value * 7.0};
    }
    preset.provenance.seed = 18446744073709551557ull >> 1;
    const std::string first = dir + "/a.fabric.json";
    const std::string second = dir + "/b.fabric.json";
    write_fabric_preset(first, preset);
    const FabricPreset reread = read_fabric_preset(first);
    EXPECT_EQ(reread, preset);
    for (const FabricParameterInfo& info : fabric_parameter_table())
        EXPECT_EQ((reread.parameters.*info.member).value, (preset.parameters.*info.member).value) << info.key;
    write_fabric_preset(second, reread);
    EXPECT_EQ(read_text(first), read_text(second));
}

TEST(FabricPreset, MalformedJsonNamesLineAndColumn) {
    const std::string dir = scratch_dir("fabric_malformed");
    const std::string path = dir + "/broken.fabric.json";
    write_text(path, "{\n  \"format\": \"flowvid.fabric\",\n  \"version\": \"1.0\"\n  \"name\": \"x\"\n}\n");
    const std::string messages = validation_messages([&] { read_fabric_preset(path); });
    EXPECT_TRUE(mentions(messages, path)) << messages;
    EXPECT_TRUE(mentions(messages, "line 4")) << messages;
    EXPECT_TRUE(mentions(messages, "malformed JSON")) << messages;
}

TEST(FabricPreset, WrongFormatNameIsRefused) {
    const std::string dir = scratch_dir("fabric_wrong_format");
    nlohmann::json document = example_json();
    document["format"] = "flowvid.flowlines";
    const std::string path = write_json(dir, document);
    const std::string messages = validation_messages([&] { read_fabric_preset(path); });
    EXPECT_TRUE(mentions(messages, path + ": /format")) << messages;
    EXPECT_TRUE(mentions(messages, "flowvid.flowlines")) << messages;
}

TEST(FabricPreset, OtherMajorVersionIsRefusedNewerMinorWarns) {
    const std::string dir = scratch_dir("fabric_versions");
    nlohmann::json document = example_json();
    document["version"] = "2.0";
    const std::string major_path = write_json(dir, document, "major.fabric.json");
    const std::string messages = validation_messages([&] { read_fabric_preset(major_path); });
    EXPECT_TRUE(mentions(messages, major_path + ": /version")) << messages;
    EXPECT_TRUE(mentions(messages, "not supported")) << messages;

    document["version"] = "1.7";
    document["parameters"]["future_parameter"] = {{"value", 1.0}};
    const std::string minor_path = write_json(dir, document, "minor.fabric.json");
    std::vector<Problem> warnings;
    const FabricPreset preset = read_fabric_preset(minor_path, &warnings);
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0].field, "/version");
    EXPECT_EQ(warnings[1].field, "/parameters/future_parameter");
    EXPECT_DOUBLE_EQ(preset.parameters.areal_density_kg_per_m2.value, 0.15);

    // Under `flowvid validate` an unknown key is an error, not a warning.
    const std::vector<Problem> strict = validate_fabric_preset_file(minor_path, Strictness::strict);
    bool unknown_is_error = false;
    for (const Problem& p : strict)
        unknown_is_error |= p.field == "/parameters/future_parameter" && p.severity == Problem::Severity::error;
    EXPECT_TRUE(unknown_is_error);
}

TEST(FabricPreset, EveryBadValueIsReportedWithItsField) {
    const std::string dir = scratch_dir("fabric_bad_values");
    nlohmann::json document = example_json();
    document["parameters"]["areal_density_kg_per_m2"]["value"] = nullptr;        // what NaN becomes in JSON
    document["parameters"]["shear_stiffness_N_per_m"]["value"] = -5.0;           // negative
    document["parameters"]["bend_stiffness_N_m"]["value"] = 1.0;                 // outside its own range
    document["parameters"]["drag_normal_kg_per_m3"]["uncertainty"] = -0.1;       // negative uncertainty
    document["parameters"]["stretch_warp_stiffness_N_per_m"]["range"] = {5.0, 1.0};
    document["parameters"].erase("drag_tangential_kg_per_m2_s");
    document["provenance"]["captures"][0]["capture_json_sha256"] = "xyz";
    document["provenance"]["created_utc"] = "yesterday";
    const std::string path = write_json(dir, document);
    const std::string messages = validation_messages([&] { read_fabric_preset(path); });
    for (const char* field : {"/parameters/areal_density_kg_per_m2/value", "/parameters/shear_stiffness_N_per_m/value",
                              "/parameters/bend_stiffness_N_m/value", "/parameters/drag_normal_kg_per_m3/uncertainty",
                              "/parameters/stretch_warp_stiffness_N_per_m/range", "/parameters/drag_tangential_kg_per_m2_s",
                              "/provenance/captures/0/capture_json_sha256", "/provenance/created_utc"})
        EXPECT_TRUE(mentions(messages, path + ": " + std::string(field))) << field << "\n" << messages;
    EXPECT_TRUE(mentions(messages, "NaN or infinity")) << messages;
}

TEST(FabricPreset, FittedPresetNeedsItsProvenance) {
    const std::string dir = scratch_dir("fabric_provenance");
    nlohmann::json document = example_json();
    document["provenance"].erase("captures");
    document["provenance"].erase("seed");
    const std::string path = write_json(dir, document);
    const std::string messages = validation_messages([&] { read_fabric_preset(path); });
    EXPECT_TRUE(mentions(messages, path + ": /provenance/captures: missing")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /provenance/seed: missing")) << messages;

    // A hand-made preset needs no fit details.
    nlohmann::json manual = example_json();
    manual["provenance"] = {{"method", "manual"}, {"created_utc", "2026-01-02T03:04:05Z"}};
    EXPECT_NO_THROW(read_fabric_preset(write_json(dir, manual, "manual.fabric.json")));
}

TEST(FabricPreset, MissingFileIsAnIoErrorNamingIt) {
    const std::string path = scratch_dir("fabric_missing") + "/nowhere.fabric.json";
    try {
        read_fabric_preset(path);
        FAIL() << "no exception";
    } catch (const IoError& error) {
        EXPECT_EQ(error.file(), path);
        EXPECT_TRUE(mentions(error.what(), "no such file"));
    }
}

TEST(FabricPreset, WritingNaNIsRefusedAndLeavesThePreviousFile) {
    const std::string dir = scratch_dir("fabric_write_nan");
    const std::string path = dir + "/keep.fabric.json";
    FabricPreset preset = read_fabric_preset(example_path());
    write_fabric_preset(path, preset);
    const std::string before = read_text(path);
    preset.parameters.bend_stiffness_N_m.value = std::numeric_limits<double>::quiet_NaN();
    const std::string messages = validation_messages([&] { write_fabric_preset(path, preset); });
    EXPECT_TRUE(mentions(messages, path + ": /parameters/bend_stiffness_N_m/value")) << messages;
    EXPECT_EQ(read_text(path), before);
}

TEST(AtomicWrite, WriterThatFailsHalfWayLeavesThePreviousFileIntact) {
    const std::string dir = scratch_dir("atomic_interrupted");
    const std::string path = dir + "/data.txt";
    write_file_atomically(path, [](std::ostream& out) { out << "previous good content\n"; });

    // The writer dies after writing part of the new content.
    EXPECT_THROW(write_file_atomically(path,
                                       [](std::ostream& out) {
                                           out << "half of the new";
                                           throw std::runtime_error("simulated crash");
                                       }),
                 std::runtime_error);
    EXPECT_EQ(read_text(path), "previous good content\n");

    // The stream itself fails (as on a full disk): an IoError naming the file.
    try {
        write_file_atomically(path, [](std::ostream& out) {
            out << "partial";
            out.setstate(std::ios::badbit);
        });
        FAIL() << "no exception";
    } catch (const IoError& error) {
        EXPECT_EQ(error.file(), path);
    }
    EXPECT_EQ(read_text(path), "previous good content\n");

    // No temporary files are left behind.
    int entries = 0;
    for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++entries;
    EXPECT_EQ(entries, 1);
}

TEST(AtomicWrite, MissingFolderIsAnIoError) {
    const std::string path = scratch_dir("atomic_missing_folder") + "/no/such/folder/file.txt";
    EXPECT_THROW(write_file_atomically(path, [](std::ostream& out) { out << "x"; }), IoError);
}
