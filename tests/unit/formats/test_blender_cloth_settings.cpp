// flowvid.blender_cloth (*.blender.json written by `flowvid convert PRESET
// OUT.blender.json --mesh GARMENT`): the example reads with its values and
// writes back to the same bytes; every required field, missing or mistyped,
// is named by its JSON pointer with a fix; negative and non-finite values are
// refused, by the reader and by the writer, and a refused write keeps the
// file that was there.

#include "flowvid/formats/any_file.hpp"
#include "flowvid/formats/blender_cloth_settings.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::mentions;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string example_path() { return source_path("formats/examples/panel.blender.json"); }
nlohmann::json example() { return nlohmann::json::parse(read_text(example_path())); }

// Every problem of `document` judged strictly (what `flowvid validate` does).
std::vector<Problem> problems_of(const nlohmann::json& document, Strictness strictness = Strictness::strict) {
    Diagnostics diagnostics("x.blender.json");
    parse_blender_cloth_settings(document, diagnostics, strictness);
    return diagnostics.problems();
}

// The error naming `pointer`, if any (with its message and fix).
std::optional<Problem> error_at(const std::vector<Problem>& problems, const std::string& pointer) {
    for (const Problem& p : problems)
        if (p.severity == Problem::Severity::error && p.field == pointer) return p;
    return std::nullopt;
}

std::string listed(const std::vector<Problem>& problems) {
    std::string text;
    for (const Problem& p : problems) text += p.field + ": " + p.message + " (fix: " + p.fix + ")\n";
    return text;
}

// Every required field of the format, as JSON pointers.
std::vector<std::string> required_fields() {
    std::vector<std::string> fields = {"/format", "/version", "/preset", "/blender", "/units", "/settings", "/mesh",
                                       "/scene", "/options", "/derived", "/not_represented", "/settings/bending_model"};
    for (const BlenderClothSettingRange& range : blender_cloth_setting_ranges())
        fields.push_back(std::string("/settings/") + range.name);
    for (const char* key : {"path", "vertex_count", "mean_edge_length_m", "area_m2", "quad_fraction", "boundary_length_m"})
        fields.push_back(std::string("/mesh/") + key);
    for (const char* key : {"fps", "quality"}) fields.push_back(std::string("/scene/") + key);
    for (const char* key : {"mass_scale", "reference_speed_m_per_s", "min_quality"})
        fields.push_back(std::string("/options/") + key);
    return fields;
}

// Every number of the format (each must be >= 0, most > 0).
std::vector<std::string> numeric_fields() {
    std::vector<std::string> fields;
    for (const BlenderClothSettingRange& range : blender_cloth_setting_ranges())
        fields.push_back(std::string("/settings/") + range.name);
    for (const char* key : {"vertex_count", "mean_edge_length_m", "area_m2", "quad_fraction", "boundary_length_m"})
        fields.push_back(std::string("/mesh/") + key);
    for (const char* key : {"fps", "quality"}) fields.push_back(std::string("/scene/") + key);
    for (const char* key : {"mass_scale", "reference_speed_m_per_s", "min_quality"})
        fields.push_back(std::string("/options/") + key);
    fields.push_back("/derived/tau_s");
    fields.push_back("/derived/shear_spring_N_per_m");
    return fields;
}

}  // namespace

TEST(BlenderClothSettings, ExampleLoadsWithItsValuesAndValidates) {
    std::vector<Problem> warnings;
    const BlenderClothSettings s = read_blender_cloth_settings(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty()) << listed(warnings);
    EXPECT_EQ(s.preset, "cotton (example)");
    EXPECT_EQ(s.mesh.path, "tests/data/cloth/panel_9x5.obj");
    EXPECT_EQ(s.mesh.vertex_count, 45);
    EXPECT_NEAR(s.mesh.area_m2, 0.4 * 0.3, 1e-12);
    EXPECT_NEAR(s.mesh.mean_edge_length_m, (40 * 0.05 + 36 * 0.075) / 76.0, 1e-12);
    EXPECT_NEAR(s.mesh.boundary_length_m, 1.4, 1e-12);
    EXPECT_EQ(s.mesh.quad_fraction, 1.0);
    EXPECT_EQ(s.scene.fps, 24.0);
    EXPECT_EQ(s.scene.quality, 0);
    EXPECT_EQ(s.options.mass_scale, 1000.0);
    EXPECT_EQ(s.options.min_quality, 10);
    EXPECT_EQ(s.bending_model, "ANGULAR");
    // Every setting, in the add-on's order, quality raised to the minimum.
    ASSERT_EQ(s.settings.size(), blender_cloth_setting_ranges().size());
    for (std::size_t i = 0; i < s.settings.size(); ++i) EXPECT_EQ(s.settings[i].first, blender_cloth_setting_ranges()[i].name);
    EXPECT_EQ(s.setting("quality"), 10.0);
    EXPECT_NEAR(*s.setting("time_scale"), std::sqrt(1000.0) / 24.0, 1e-12);
    EXPECT_NEAR(*s.setting("mass"), 1000.0 * 0.15 * 0.12 / 45.0, 1e-12);  // cotton: 0.15 kg/m^2
    EXPECT_FALSE(s.setting("pin_stiffness"));
    EXPECT_NEAR(s.derived.at("tau_s"), 1.0 / std::sqrt(1000.0), 1e-15);
    EXPECT_EQ(s.not_represented.size(), 4u);

    EXPECT_TRUE(validate_blender_cloth_settings_file(example_path(), Strictness::strict).empty());
    EXPECT_EQ(detect_file_kind(example_path()), FileKind::blender_cloth_settings);
    EXPECT_TRUE(validate_any_file(example_path()).empty());
    const nlohmann::json summary = summarize_any_file(example_path());
    EXPECT_EQ(summary["kind"], "Blender cloth settings");
    EXPECT_EQ(summary["format"], "flowvid.blender_cloth");
    EXPECT_EQ(summary["vertex_count"], 45);
    EXPECT_EQ(summary["settings"]["quality"], 10);
    EXPECT_EQ(summary["settings"]["bending_model"], "ANGULAR");
    EXPECT_EQ(summary["not_represented"], 4);
    EXPECT_STREQ(file_kind_name(FileKind::blender_cloth_settings), "Blender cloth settings");
}

TEST(BlenderClothSettings, RoundTripIsEqualAndBitExact) {
    const std::string dir = scratch_dir("blender_cloth_round_trip");
    const BlenderClothSettings s = read_blender_cloth_settings(example_path());
    write_blender_cloth_settings(dir + "/panel.blender.json", s);
    EXPECT_EQ(read_text(dir + "/panel.blender.json"), read_text(example_path()));
    EXPECT_TRUE(read_blender_cloth_settings(dir + "/panel.blender.json") == s);

    // Built by hand (as the mapping does): every field comes back.
    BlenderClothSettings made;
    made.preset = "linen";
    for (const BlenderClothSettingRange& range : blender_cloth_setting_ranges())
        made.settings.emplace_back(range.name, range.integer ? 12.0 : 0.25 + 0.5 * static_cast<double>(made.settings.size()));
    made.bending_model = "LINEAR";
    made.mesh = {"garment.obj", 1234, 0.0125, 0.75, 0.5, 2.5};
    made.scene = {25.0, 12};
    made.options = {500.0, 0.75, 8};
    made.derived = {{"tau_s", 0.04}, {"force_scale", 2.0}};
    made.not_represented = {"first note", "second note"};
    write_blender_cloth_settings(dir + "/made.blender.json", made);
    const BlenderClothSettings back = read_blender_cloth_settings(dir + "/made.blender.json");
    EXPECT_TRUE(back == made);
    EXPECT_EQ(back.mesh.vertex_count, 1234);
    EXPECT_EQ(back.setting("air_damping"), 0.25 + 0.5 * 11);
    EXPECT_EQ(nlohmann::json::parse(read_text(dir + "/made.blender.json"))["settings"]["quality"].type(),
              nlohmann::json::value_t::number_unsigned);
}

TEST(BlenderClothSettings, EveryRequiredFieldMissingIsNamedWithItsFix) {
    for (const std::string& field : required_fields()) {
        nlohmann::json document = example();
        const nlohmann::json::json_pointer pointer(field);
        document[pointer.parent_pointer()].erase(pointer.back());
        const std::vector<Problem> problems = problems_of(document);
        const std::optional<Problem> problem = error_at(problems, field);
        ASSERT_TRUE(problem.has_value()) << field << " missing:\n" << listed(problems);
        EXPECT_EQ(problem->message, "missing") << field;
        EXPECT_FALSE(problem->fix.empty()) << field;
        EXPECT_TRUE(mentions(problem->fix, pointer.back())) << field << ": " << problem->fix;
    }
}

TEST(BlenderClothSettings, EveryRequiredFieldMistypedIsNamedWithItsFix) {
    for (const std::string& field : required_fields()) {
        nlohmann::json document = example();
        const nlohmann::json::json_pointer pointer(field);
        // A string where anything else belongs; a number where a string or array belongs.
        const bool text = document[pointer].is_string();
        document[pointer] = text ? nlohmann::json(7) : nlohmann::json("seven");
        const std::vector<Problem> problems = problems_of(document);
        const std::optional<Problem> problem = error_at(problems, field);
        ASSERT_TRUE(problem.has_value()) << field << " mistyped:\n" << listed(problems);
        EXPECT_TRUE(mentions(problem->message, text ? "found number" : "found string") ||
                    mentions(problem->message, "expected"))
            << field << ": " << problem->message;
        EXPECT_FALSE(problem->fix.empty()) << field;
    }
    // A fractional substep count, an unknown bending model.
    nlohmann::json document = example();
    document["settings"]["quality"] = 10.5;
    EXPECT_TRUE(error_at(problems_of(document), "/settings/quality").has_value());
    document = example();
    document["settings"]["bending_model"] = "SPRING";
    const std::optional<Problem> model = error_at(problems_of(document), "/settings/bending_model");
    ASSERT_TRUE(model.has_value());
    EXPECT_TRUE(mentions(model->fix, "ANGULAR")) << model->fix;
    document = example();
    document["not_represented"][1] = 3;
    EXPECT_TRUE(error_at(problems_of(document), "/not_represented/1").has_value());
}

TEST(BlenderClothSettings, NegativeAndNonFiniteValuesAreRefused) {
    for (const std::string& field : numeric_fields()) {
        nlohmann::json document = example();
        const nlohmann::json::json_pointer pointer(field);
        ASSERT_TRUE(document.contains(pointer)) << field;
        document[pointer] = -1;
        const std::optional<Problem> negative = error_at(problems_of(document), field);
        ASSERT_TRUE(negative.has_value()) << field << " = -1:\n" << listed(problems_of(document));
        EXPECT_TRUE(mentions(negative->message, "out of range")) << field << ": " << negative->message;
        EXPECT_TRUE(mentions(negative->fix, "use ")) << field << ": " << negative->fix;
        // NaN and infinity are null in JSON.
        document[pointer] = nullptr;
        const std::optional<Problem> null = error_at(problems_of(document), field);
        ASSERT_TRUE(null.has_value()) << field << " = null";
    }
    // Beyond Blender's limits, and zero where it must be positive.
    nlohmann::json document = example();
    document["settings"]["air_damping"] = 12.0;
    const std::optional<Problem> air = error_at(problems_of(document), "/settings/air_damping");
    ASSERT_TRUE(air.has_value());
    EXPECT_TRUE(mentions(air->fix, "[0, 10]")) << air->fix;
    document = example();
    document["scene"]["fps"] = 0.0;
    EXPECT_TRUE(error_at(problems_of(document), "/scene/fps").has_value());
    document = example();
    document["mesh"]["quad_fraction"] = 1.5;
    EXPECT_TRUE(error_at(problems_of(document), "/mesh/quad_fraction").has_value());

    // The writer names a non-finite value by its field before it becomes null.
    const std::string dir = scratch_dir("blender_cloth_nan");
    BlenderClothSettings s = read_blender_cloth_settings(example_path());
    s.settings[2].second = std::numeric_limits<double>::quiet_NaN();  // mass
    s.derived["tau_s"] = std::numeric_limits<double>::infinity();
    const std::string path = dir + "/nan.blender.json";
    const std::string messages = validation_messages([&] { write_blender_cloth_settings(path, s); });
    EXPECT_TRUE(mentions(messages, path + ": /settings/mass: not finite")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /derived/tau_s: not finite")) << messages;
    EXPECT_TRUE(mentions(messages, "(fix: ")) << messages;
    EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(BlenderClothSettings, FailedWriteKeepsThePreviousFile) {
    const std::string dir = scratch_dir("blender_cloth_keep");
    const std::string path = dir + "/panel.blender.json";
    const BlenderClothSettings good = read_blender_cloth_settings(example_path());
    write_blender_cloth_settings(path, good);
    const std::string before = read_text(path);

    BlenderClothSettings bad = good;
    bad.settings[1].second = -std::numeric_limits<double>::infinity();  // time_scale
    EXPECT_TRUE(mentions(validation_messages([&] { write_blender_cloth_settings(path, bad); }), "/settings/time_scale"));
    EXPECT_EQ(read_text(path), before);

    bad = good;
    bad.settings.erase(bad.settings.begin() + 2);  // no mass
    bad.mesh.area_m2 = -0.5;
    const std::string messages = validation_messages([&] { write_blender_cloth_settings(path, bad); });
    EXPECT_TRUE(mentions(messages, path + ": /settings/mass: missing")) << messages;
    EXPECT_TRUE(mentions(messages, path + ": /mesh/area_m2: value -0.5 is out of range")) << messages;
    EXPECT_EQ(read_text(path), before);

    bad = good;
    bad.settings.emplace_back("pin_stiffness", 1.0);  // not a setting the file holds
    EXPECT_TRUE(mentions(validation_messages([&] { write_blender_cloth_settings(path, bad); }), "/settings/pin_stiffness"));
    EXPECT_EQ(read_text(path), before);
    EXPECT_TRUE(read_blender_cloth_settings(path) == good);
}

TEST(BlenderClothSettings, VersionsAndUnknownKeys) {
    nlohmann::json document = example();
    document["version"] = "1.3";
    std::vector<Problem> problems = problems_of(document);
    ASSERT_EQ(problems.size(), 1u) << listed(problems);
    EXPECT_EQ(problems[0].severity, Problem::Severity::warning);
    EXPECT_EQ(problems[0].field, "/version");
    document["version"] = "2.0";
    EXPECT_TRUE(error_at(problems_of(document), "/version").has_value());
    document = example();
    document["format"] = "flowvid.fabric";
    EXPECT_TRUE(error_at(problems_of(document), "/format").has_value());

    // Unknown keys: errors for validate, warnings for readers.
    document = example();
    document["settings"]["pin_stiffness"] = 1.0;
    document["mesh"]["colour"] = "red";
    EXPECT_TRUE(error_at(problems_of(document), "/settings/pin_stiffness").has_value());
    EXPECT_TRUE(error_at(problems_of(document), "/mesh/colour").has_value());
    problems = problems_of(document, Strictness::lenient);
    EXPECT_EQ(problems.size(), 2u) << listed(problems);
    for (const Problem& p : problems) EXPECT_EQ(p.severity, Problem::Severity::warning) << p.field;

    // A file named *.blender.json is judged as one even without its "format".
    const std::string dir = scratch_dir("blender_cloth_by_name");
    document = example();
    document.erase("format");
    write_text(dir + "/bare.blender.json", document.dump(2));
    EXPECT_EQ(detect_file_kind(dir + "/bare.blender.json"), FileKind::blender_cloth_settings);
    problems = validate_any_file(dir + "/bare.blender.json");
    ASSERT_EQ(problems.size(), 1u) << listed(problems);
    EXPECT_EQ(problems[0].field, "/format");
    EXPECT_EQ(problems[0].file, dir + "/bare.blender.json");
}
