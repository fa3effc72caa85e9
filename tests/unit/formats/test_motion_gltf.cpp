#include "flowvid/formats/motion_gltf.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
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

using flowvid::testing::mentions;

std::string example_path() { return source_path("formats/examples/example.motion.glb"); }

std::string write_text_path(const std::string& path, const std::string& text) {
    write_text(path, text);
    return path;
}

// The recipe of formats/examples/example.motion.glb: a 0.3 m square swatch,
// 5 x 5 vertices, pinned along its top edge at z = 1 m, swinging in a
// travelling wave over 8 frames at 24 fps. Vertex r * 5 + c, row 0 at v = 0
// (bottom), column 0 at u = 0, as in the captures' swatch layout.
MeshAnimation make_example_animation(int frames = 8) {
    MeshAnimation animation;
    animation.name = "swatch";
    animation.fps = 24.0;
    const int n = 5;
    const float size_m = 0.3f;
    for (int f = 0; f < frames; ++f) {
        std::vector<Eigen::Vector3f> positions;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c) {
                const float u = c / float(n - 1), v = r / float(n - 1);
                const float hang = (1.0f - v) * size_m;  // distance below the pinned top edge
                const float swing = 0.05f * std::sin(0.8f * f - 3.0f * v) * (1.0f - v);
                positions.emplace_back(u * size_m - 0.15f, swing, 1.0f - hang + 0.01f * swing);
            }
        animation.frames_positions_m.push_back(positions);
    }
    for (int r = 0; r + 1 < n; ++r)
        for (int c = 0; c + 1 < n; ++c) {
            const int a = r * n + c, b = a + 1, d = a + n, e = d + 1;
            animation.triangles.push_back({a, b, e});
            animation.triangles.push_back({a, e, d});
        }
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) animation.uv.emplace_back(c / float(n - 1), r / float(n - 1));
    return animation;
}

std::uint32_t u32(const std::string& bytes, std::size_t at) {
    std::uint32_t value;
    std::memcpy(&value, bytes.data() + at, 4);
    return value;
}

void put_u32(std::string& bytes, std::size_t at, std::uint32_t value) { std::memcpy(bytes.data() + at, &value, 4); }

// Splits a .glb into its JSON and BIN chunks, and joins them back (with the
// padding and lengths the container needs), to build damaged variants.
struct Glb {
    nlohmann::json json;
    std::string bin;
};

Glb split_glb(const std::string& bytes) {
    const std::uint32_t json_length = u32(bytes, 12);
    Glb glb;
    glb.json = nlohmann::json::parse(bytes.substr(20, json_length));
    const std::size_t bin_at = 20 + json_length;
    if (bin_at < bytes.size()) glb.bin = bytes.substr(bin_at + 8, u32(bytes, bin_at));
    return glb;
}

std::string join_glb(const Glb& glb) {
    std::string json = glb.json.dump();
    while (json.size() % 4) json += ' ';
    std::string bin = glb.bin;
    while (bin.size() % 4) bin += '\0';
    std::string bytes(12, '\0');
    bytes.replace(0, 4, "glTF");
    put_u32(bytes, 4, 2);
    std::string chunk(8, '\0');
    put_u32(chunk, 0, static_cast<std::uint32_t>(json.size()));
    put_u32(chunk, 4, 0x4E4F534A);
    bytes += chunk + json;
    if (!bin.empty()) {
        put_u32(chunk, 0, static_cast<std::uint32_t>(bin.size()));
        put_u32(chunk, 4, 0x004E4942);
        bytes += chunk + bin;
    }
    put_u32(bytes, 8, static_cast<std::uint32_t>(bytes.size()));
    return bytes;
}

std::string edited_glb(const std::string& dir, const std::string& name, const std::function<void(Glb&)>& edit) {
    const std::string good = dir + "/good_" + name;
    write_motion_gltf(good, make_example_animation());
    Glb glb = split_glb(read_text(good));
    edit(glb);
    const std::string path = dir + "/" + name;
    write_text(path, join_glb(glb));
    return path;
}

// Float32 rounding bound of a coordinate rebuilt as base + delta (see motion_gltf.hpp).
float rebuild_tolerance(float value, float base) {
    return std::ldexp(1.0f, -24) * (std::fabs(value) + std::fabs(value - base)) * 1.0001f;
}

}  // namespace

TEST(MotionGltf, RegenerateKeptFilesWhenAsked) {
    if (!std::getenv("FLOWVID_REGENERATE_EXAMPLES")) GTEST_SKIP() << "set FLOWVID_REGENERATE_EXAMPLES=1 to rewrite them";
    write_motion_gltf(example_path(), make_example_animation());
}

TEST(MotionGltf, ExampleOfVersion1_0LoadsAndMatchesItsRecipe) {
    std::vector<Problem> warnings;
    const MeshAnimation animation = read_motion_gltf(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    const MeshAnimation recipe = make_example_animation();
    EXPECT_EQ(animation.name, "swatch");
    EXPECT_EQ(animation.fps, 24.0);
    EXPECT_EQ(animation.triangles, recipe.triangles);
    ASSERT_EQ(animation.frame_count(), 8);
    ASSERT_EQ(animation.vertex_count(), 25);
    double worst_m = 0.0;
    for (int f = 0; f < 8; ++f)
        for (int v = 0; v < 25; ++v)
            worst_m = std::max<double>(worst_m, (animation.frames_positions_m[f][v] - recipe.frames_positions_m[f][v]).cwiseAbs().maxCoeff());
    EXPECT_LE(worst_m, 1e-6);
    EXPECT_LT(fs::file_size(example_path()), 16u * 1024u) << "keep the example small";
}

TEST(MotionGltf, RoundTripWithinFloat32Rounding) {
    const std::string dir = scratch_dir("motion_round_trip");
    MeshAnimation animation = make_example_animation(30);
    // Coordinates up to a few metres with every mantissa bit used.
    std::mt19937 random(11);
    std::uniform_real_distribution<float> metres(-4.0f, 4.0f);
    for (auto& frame : animation.frames_positions_m)
        for (auto& p : frame) p += Eigen::Vector3f(metres(random), metres(random), metres(random)) * 0.5f;
    const std::string path = dir + "/round.glb";
    write_motion_gltf(path, animation);
    const MeshAnimation reread = read_motion_gltf(path);
    EXPECT_EQ(reread.name, animation.name);
    EXPECT_EQ(reread.fps, animation.fps);
    EXPECT_EQ(reread.triangles, animation.triangles);
    ASSERT_EQ(reread.frame_count(), animation.frame_count());
    ASSERT_EQ(reread.vertex_count(), animation.vertex_count());
    EXPECT_EQ(reread.frames_positions_m[0], animation.frames_positions_m[0]) << "frame 0 is the base mesh: exact";
    double worst_m = 0.0;
    for (int f = 0; f < animation.frame_count(); ++f)
        for (int v = 0; v < animation.vertex_count(); ++v)
            for (int c = 0; c < 3; ++c) {
                const float written = animation.frames_positions_m[f][v][c];
                const float read = reread.frames_positions_m[f][v][c];
                const float base = animation.frames_positions_m[0][v][c];
                ASSERT_LE(std::fabs(read - written), rebuild_tolerance(written, base))
                    << "frame " << f << " vertex " << v << " axis " << c;
                worst_m = std::max<double>(worst_m, std::fabs(read - written));
            }
    EXPECT_LE(worst_m, 1e-6) << "coordinates within 5 m of the origin come back within 1e-6 m";
    ASSERT_EQ(reread.uv.size(), animation.uv.size());
    for (std::size_t v = 0; v < animation.uv.size(); ++v)
        EXPECT_LE((reread.uv[v] - animation.uv[v]).cwiseAbs().maxCoeff(), std::ldexp(1.0f, -24)) << v;
}

TEST(MotionGltf, FileFollowsGltfConventions) {
    const Glb glb = split_glb(read_text(example_path()));
    const nlohmann::json& json = glb.json;
    EXPECT_EQ(json["asset"]["version"], "2.0");
    EXPECT_EQ(json["asset"]["extras"]["flowvid"]["format"], "flowvid.motion");
    EXPECT_EQ(json["asset"]["extras"]["flowvid"]["version"], "1.0");
    EXPECT_EQ(json["asset"]["extras"]["flowvid"]["fps"], 24.0);
    const nlohmann::json& primitive = json["meshes"][0]["primitives"][0];
    EXPECT_EQ(primitive["mode"], 4);
    ASSERT_EQ(primitive["targets"].size(), 8u);
    EXPECT_EQ(json["meshes"][0]["extras"]["targetNames"][7], "frame_000007");
    const nlohmann::json& sampler = json["animations"][0]["samplers"][0];
    EXPECT_EQ(sampler["interpolation"], "STEP");
    EXPECT_EQ(json["animations"][0]["channels"][0]["target"]["path"], "weights");
    EXPECT_EQ(json["accessors"][sampler["output"].get<int>()]["count"], 64);
    EXPECT_NEAR(json["accessors"][sampler["input"].get<int>()]["max"][0].get<double>(), 7.0 / 24.0, 1e-7);

    // +z up becomes +y up: the pinned top edge (flowvid z = 1 m) is at glTF y = 1,
    // and flowvid y (the swing, toward the camera) is glTF -z.
    const nlohmann::json& position = json["accessors"][primitive["attributes"]["POSITION"].get<int>()];
    EXPECT_NEAR(position["max"][1].get<double>(), 1.0, 1e-6);
    EXPECT_NEAR(position["min"][1].get<double>(), 0.7, 1e-6);
    const MeshAnimation recipe = make_example_animation();
    const int view = position["bufferView"];
    float first[3];
    std::memcpy(first, glb.bin.data() + json["bufferViews"][view].value("byteOffset", 0), 12);
    const Eigen::Vector3f p0 = recipe.frames_positions_m[0][0];
    EXPECT_EQ(first[0], p0.x());
    EXPECT_EQ(first[1], p0.z());
    EXPECT_EQ(first[2], -p0.y());
    EXPECT_EQ(gltf_to_flowvid(flowvid_to_gltf(p0)), p0);
}

TEST(MotionGltf, WriterRefusesInvalidAnimationsAndKeepsThePreviousFile) {
    const std::string dir = scratch_dir("motion_writer_refuses");
    const std::string path = dir + "/motion.glb";
    write_motion_gltf(path, make_example_animation());
    const std::string before = read_text(path);
    MeshAnimation animation = make_example_animation();
    animation.frames_positions_m[3][7].y() = std::numeric_limits<float>::quiet_NaN();
    animation.frames_positions_m[5].pop_back();
    animation.triangles.push_back({0, 1, 99});
    animation.triangles.push_back({2, 2, 3});
    animation.uv.pop_back();
    animation.fps = -1.0;
    const std::string messages = validation_messages([&] { write_motion_gltf(path, animation); });
    EXPECT_TRUE(mentions(messages, path + ": frames_positions_m[3][7]: not a finite position")) << messages;
    EXPECT_TRUE(mentions(messages, "frames_positions_m[5]: 24 positions, frame 0 has 25")) << messages;
    EXPECT_TRUE(mentions(messages, "triangles[32]: vertex index out of range")) << messages;
    EXPECT_TRUE(mentions(messages, "triangles[33]: uses a vertex twice")) << messages;
    EXPECT_TRUE(mentions(messages, "uv: 24 uv pairs for 25 vertices")) << messages;
    EXPECT_TRUE(mentions(messages, "fps: frame rate")) << messages;
    EXPECT_EQ(read_text(path), before);

    MeshAnimation too_long = make_example_animation(1);
    too_long.frames_positions_m.resize(kMaxMotionGltfFrames + 1, too_long.frames_positions_m[0]);
    EXPECT_TRUE(mentions(validation_messages([&] { write_motion_gltf(path, too_long); }), "exceed the limit"));
}

TEST(MotionGltf, TruncatedOrForeignFilesAreRefusedNamingFileAndElement) {
    const std::string dir = scratch_dir("motion_bad_files");
    const std::string valid = read_text(example_path());
    const std::string half = write_text_path(dir + "/half.glb", valid.substr(0, valid.size() / 2));
    std::string messages = validation_messages([&] { read_motion_gltf(half); });
    EXPECT_TRUE(mentions(messages, half + ": GLB header: declares " + std::to_string(valid.size()) + " bytes but the file has"))
        << messages;
    EXPECT_TRUE(mentions(messages, "(truncated)")) << messages;

    const std::string text = write_text_path(dir + "/scene.glb", "{\"asset\": {\"version\": \"2.0\"}}");
    messages = validation_messages([&] { read_motion_gltf(text); });
    EXPECT_TRUE(mentions(messages, text + ": GLB header: not a glTF binary")) << messages;
    EXPECT_TRUE(mentions(messages, "export it as glTF Binary")) << messages;

    const std::string png = write_text_path(dir + "/image.glb", "\x89PNG\r\n\x1a\n0000000000000");
    EXPECT_TRUE(mentions(validation_messages([&] { read_motion_gltf(png); }), "not a glTF binary"));

    // A perfectly good glTF that is not a flowvid motion export.
    const std::string foreign = edited_glb(dir, "foreign.glb", [](Glb& glb) { glb.json["asset"].erase("extras"); });
    messages = validation_messages([&] { read_motion_gltf(foreign); });
    EXPECT_TRUE(mentions(messages, foreign + ": /asset/extras/flowvid: a glTF file without a flowvid animation")) << messages;

    const std::string broken_json = edited_glb(dir, "broken_json.glb", [](Glb&) {});
    std::string bytes = read_text(broken_json);
    bytes[21] = '[';  // the JSON chunk no longer parses
    write_text(broken_json, bytes);
    messages = validation_messages([&] { read_motion_gltf(broken_json); });
    EXPECT_TRUE(mentions(messages, broken_json + ": GLB chunk 0 (JSON), line 1, column 2: malformed JSON")) << messages;
}

TEST(MotionGltf, InconsistentContentNamesTheGltfElement) {
    const std::string dir = scratch_dir("motion_inconsistent");
    const std::string frames = edited_glb(dir, "frames.glb", [](Glb& glb) { glb.json["asset"]["extras"]["flowvid"]["frame_count"] = 9; });
    std::string messages = validation_messages([&] { read_motion_gltf(frames); });
    EXPECT_TRUE(mentions(messages, frames + ": /meshes/0/primitives/0/targets: 8 morph targets for 9 frames")) << messages;

    const std::string count = edited_glb(dir, "count.glb", [](Glb& glb) {
        const int accessor = glb.json["meshes"][0]["primitives"][0]["targets"][3]["POSITION"];
        glb.json["accessors"][accessor]["count"] = 1000;
    });
    messages = validation_messages([&] { read_motion_gltf(count); });
    EXPECT_TRUE(mentions(messages, "/count: 1000 elements, expected 25 for /meshes/0/primitives/0/targets/3/POSITION")) << messages;

    const std::string outside = edited_glb(dir, "outside.glb", [](Glb& glb) {
        const int accessor = glb.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"];
        glb.json["accessors"][accessor]["byteOffset"] = 1 << 20;
    });
    messages = validation_messages([&] { read_motion_gltf(outside); });
    EXPECT_TRUE(mentions(messages, "run past the end of /bufferViews/")) << messages;

    const std::string nan = edited_glb(dir, "nan.glb", [](Glb& glb) {
        const int accessor = glb.json["meshes"][0]["primitives"][0]["targets"][2]["POSITION"];
        const int view = glb.json["accessors"][accessor]["bufferView"];
        const std::size_t at = glb.json["bufferViews"][view].value("byteOffset", 0) +
                               glb.json["accessors"][accessor].value("byteOffset", 0) + 4 * 12 + 4;
        const float not_a_number = std::numeric_limits<float>::quiet_NaN();
        std::memcpy(glb.bin.data() + at, &not_a_number, 4);
    });
    messages = validation_messages([&] { read_motion_gltf(nan); });
    EXPECT_TRUE(mentions(messages, "element 4 is not finite (/meshes/0/primitives/0/targets/2/POSITION)")) << messages;

    const std::string blend = edited_glb(dir, "blend.glb", [](Glb& glb) {
        glb.json["animations"][0]["samplers"][0]["interpolation"] = "CUBICSPLINE";
    });
    EXPECT_TRUE(mentions(validation_messages([&] { read_motion_gltf(blend); }),
                         "/animations/0/samplers/0/interpolation: \"CUBICSPLINE\" is not STEP or LINEAR"));

    const std::string v2 = edited_glb(dir, "v2.glb", [](Glb& glb) { glb.json["asset"]["extras"]["flowvid"]["version"] = "2.0"; });
    EXPECT_TRUE(mentions(validation_messages([&] { read_motion_gltf(v2); }),
                         v2 + ": /asset/extras/flowvid/version: version 2.0 is not supported"));

    const std::string v11 = edited_glb(dir, "v11.glb", [](Glb& glb) {
        glb.json["asset"]["extras"]["flowvid"]["version"] = "1.1";
        glb.json["asset"]["extras"]["flowvid"]["wind_m_per_s"] = 3;
    });
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_motion_gltf(v11, &warnings));
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0].field, "/asset/extras/flowvid/version");
    EXPECT_EQ(warnings[1].field, "/asset/extras/flowvid/wind_m_per_s");
    bool strict_error = false;
    for (const Problem& p : validate_motion_gltf_file(v11, Strictness::strict))
        strict_error = strict_error || (p.severity == Problem::Severity::error && mentions(p.field, "wind_m_per_s"));
    EXPECT_TRUE(strict_error);

    const std::string external = edited_glb(dir, "external.glb", [](Glb& glb) { glb.json["buffers"][0]["uri"] = "/etc/passwd"; });
    messages = validation_messages([&] { read_motion_gltf(external); });
    EXPECT_TRUE(mentions(messages, external + ": /buffers/0/uri: refers to an external file, which is not read")) << messages;
}

TEST(MotionGltf, RandomDamageNeverCrashesOrEscapes) {
    const std::string dir = scratch_dir("motion_random_damage");
    const std::string valid = read_text(example_path());
    std::mt19937 random(99);
    int refused = 0;
    for (int i = 0; i < 300; ++i) {
        std::string bytes = valid;
        const int edits = 1 + static_cast<int>(random() % 3);
        for (int e = 0; e < edits; ++e) {
            if (random() % 4 == 0) bytes.resize(random() % bytes.size());
            else if (!bytes.empty()) bytes[random() % bytes.size()] ^= static_cast<char>(1 + random() % 255);
        }
        const std::string path = dir + "/damaged.glb";
        write_text(path, bytes);
        std::vector<Problem> problems;
        ASSERT_NO_THROW(problems = validate_motion_gltf_file(path, Strictness::lenient)) << "mutation " << i;
        bool has_error = false;
        for (const Problem& problem : problems) {
            EXPECT_EQ(problem.file, path);
            has_error = has_error || problem.severity == Problem::Severity::error;
        }
        if (has_error) ++refused;
        else EXPECT_NO_THROW(read_motion_gltf(path)) << "mutation " << i;
    }
    EXPECT_GT(refused, 100);
}

TEST(MotionGltf, MissingFileIsAnIoErrorNamingIt) {
    const std::string path = scratch_dir("motion_missing") + "/absent.glb";
    try {
        read_motion_gltf(path);
        FAIL() << "expected IoError";
    } catch (const IoError& error) {
        EXPECT_EQ(error.file(), path);
    }
}

TEST(MotionGltf, SummaryReportsCountsAndExtent) {
    const nlohmann::json summary = summarize_motion_gltf(read_motion_gltf(example_path()));
    EXPECT_EQ(summary["format"], "flowvid.motion");
    EXPECT_EQ(summary["frame_count"], 8);
    EXPECT_EQ(summary["vertex_count"], 25);
    EXPECT_EQ(summary["triangle_count"], 32);
    EXPECT_EQ(summary["has_uv"], true);
    EXPECT_NEAR(summary["duration_s"].get<double>(), 7.0 / 24.0, 1e-12);
    EXPECT_NEAR(summary["bounding_box_m"]["max"][2].get<double>(), 1.0, 1e-3);
    EXPECT_NEAR(summary["bounding_box_m"]["min"][0].get<double>(), -0.15, 1e-6);
    EXPECT_GT(summary["max_displacement_from_frame0_m"].get<double>(), 0.01);
    EXPECT_LT(summary["max_displacement_from_frame0_m"].get<double>(), 0.11);
}
