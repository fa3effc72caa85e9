// Capture folders (capture.json version 1), the rigid-body mesh reader, the
// frame loader and SHA-256. Tiny synthetic captures live in
// tests/data/formats/capture/; the shared example captures are used when
// ../shared is present.

#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/rigid_mesh.hpp"
#include "flowvid/formats/sha256.hpp"
#include "flowvid/formats/vertex_animation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <Eigen/Dense>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

namespace fs = std::filesystem;
using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::shared_path;
using flowvid::testing::test_data;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

std::string tiny(const std::string& name) { return test_data("formats/capture/" + name); }

using flowvid::testing::mentions;

std::string errors_of(const std::vector<Problem>& problems) {
    std::string text;
    for (const Problem& p : problems)
        if (p.severity == Problem::Severity::error) text += p.to_string() + "\n";
    return text;
}

// A writable copy of a tiny capture, with capture.json replaced by `edit(json)`.
std::string edited_copy(const std::string& source, const std::string& name,
                        const std::function<void(nlohmann::json&)>& edit) {
    const std::string dir = scratch_dir("capture_" + name);
    fs::copy(tiny(source), dir, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
    nlohmann::json document = nlohmann::json::parse(read_text(dir + "/capture.json"));
    edit(document);
    fs::permissions(dir + "/capture.json", fs::perms::owner_write, fs::perm_options::add);
    write_text(dir + "/capture.json", document.dump(2));
    return dir;
}

// The messages read_capture throws for an edited tiny cloth capture.
std::string cloth_errors(const std::string& name, const std::function<void(nlohmann::json&)>& edit) {
    const std::string dir = edited_copy("tiny-cloth", name, edit);
    return validation_messages([&] { read_capture(dir); });
}

bool shared_captures_present() { return fs::is_directory(shared_path("captures")); }

std::vector<std::string> shared_capture_folders() {
    std::vector<std::string> folders;
    for (const auto& entry : fs::directory_iterator(shared_path("captures")))
        if (entry.is_directory() && fs::exists(entry.path() / "capture.json")) folders.push_back(entry.path().string());
    std::sort(folders.begin(), folders.end());
    return folders;
}

}  // namespace

// ---- SHA-256 ---------------------------------------------------------------------

TEST(Sha256, FipsTestVectors) {
    EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    EXPECT_EQ(sha256_hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, PaddingBoundaries) {
    // Lengths around the 55/56/64-byte padding edges (reference: Python hashlib).
    const std::pair<std::size_t, const char*> cases[] = {
        {55, "d5e285683cd4efc02d021a5c62014694958901005d6f71e89e0989fac77e4072"},
        {56, "04c26261370ee7541549d16dee320c723e3fd14671e66a099afe0a377c16888e"},
        {63, "75220b47218278e656f2013bb8f0c455a25eaf01e86c64924e9d48d89776d6f2"},
        {64, "7ce100971f64e7001e8fe5a51973ecdfe1ced42befe7ee8d5fd6219506b5393c"},
        {65, "9537c5fdf120482f7d58d25e9ed583f52c02b4e304ea814db1633ad565aed7e9"},
        {119, "000b48d4edf0fa7bee3c6236ecd2785baa5db4eeb8bb54341b029e0d9fa5fb0c"},
        {120, "13f05a0b594787f5ecd315edc96141bd3243203d1b7d4f0836f37308b276ba98"},
    };
    for (const auto& [length, digest] : cases) EXPECT_EQ(sha256_hex(std::string(length, 'x')), digest) << length;
}

TEST(Sha256, CaptureJsonHashIsOfTheFileBytes) {
    const Capture capture = read_capture(tiny("tiny-cloth"));
    EXPECT_EQ(capture.capture_json_sha256, sha256_hex(read_text(tiny("tiny-cloth/capture.json"))));
    EXPECT_EQ(capture.capture_json_sha256.size(), 64u);
}

// ---- Frame patterns and projection --------------------------------------------------

TEST(CapturePattern, FormatsPrintfStyle) {
    EXPECT_EQ(format_frame_pattern("frames/%06d.png", 7).value_or(""), "frames/000007.png");
    EXPECT_EQ(format_frame_pattern("f%d.jpg", 123).value_or(""), "f123.jpg");
    EXPECT_EQ(format_frame_pattern("f%4d.png", 12).value_or(""), "f  12.png");
    EXPECT_EQ(format_frame_pattern("100%%/%03d.png", 5).value_or(""), "100%/005.png");
    EXPECT_FALSE(format_frame_pattern("frames/000001.png", 1));  // no conversion
    EXPECT_FALSE(format_frame_pattern("%d_%d.png", 1));          // two
    EXPECT_FALSE(format_frame_pattern("%s.png", 1));             // not an integer
    EXPECT_FALSE(format_frame_pattern("%0999d.png", 1));         // absurd width
    EXPECT_FALSE(format_frame_pattern("%", 1));
}

TEST(CaptureCamera, ProjectsWithoutDistortion) {
    const Capture capture = read_capture(tiny("tiny-cloth"));
    ASSERT_TRUE(capture.camera);
    // World (0, 0, 0.5) is 1 m in front of the camera on its axis: the principal point.
    const Eigen::Vector2d centre = capture.camera->project({0.0, 0.0, 0.5});
    EXPECT_NEAR(centre.x(), 3.5, 1e-12);
    EXPECT_NEAR(centre.y(), 2.5, 1e-12);
    // +x world is +x image, +z world (up) is -y image; fx = 10 px at 1 m.
    const Eigen::Vector2d p = capture.camera->project({0.1, 0.0, 0.6});
    EXPECT_NEAR(p.x(), 4.5, 1e-12);
    EXPECT_NEAR(p.y(), 1.5, 1e-12);
    // Behind the camera: NaN, not a mirrored pixel.
    EXPECT_TRUE(std::isnan(capture.camera->project({0.0, -2.0, 0.5}).x()));
    const Eigen::Vector3d centre_world = capture.camera->centre_world();
    EXPECT_NEAR((centre_world - Eigen::Vector3d(0.0, -1.0, 0.5)).norm(), 0.0, 1e-12);
}

TEST(CaptureCamera, OpenCvDistortionModel) {
    CameraModel camera;
    camera.K << 100.0, 0.0, 50.0, 0.0, 200.0, 40.0, 0.0, 0.0, 1.0;
    camera.dist = {0.1, -0.05, 0.01, -0.02, 0.003};
    // Hand-evaluated OpenCV model at x' = 0.2, y' = 0.1 (r^2 = 0.05):
    // radial = 1 + 0.1*0.05 - 0.05*0.0025 + 0.003*0.000125 = 1.004875375
    // x'' = 0.2*radial + 2*0.01*0.02 - 0.02*(0.05 + 0.08) = 0.2009750750 + 0.0004 - 0.0026 = 0.198775075
    // y'' = 0.1*radial + 0.01*(0.05 + 0.02) + 2*(-0.02)*0.02 = 0.1004875375 + 0.0007 - 0.0008 = 0.1003875375
    const Eigen::Vector2d pixel = camera.project_camera_point({0.4, 0.2, 2.0});
    EXPECT_NEAR(pixel.x(), 100.0 * 0.198775075 + 50.0, 1e-9);
    EXPECT_NEAR(pixel.y(), 200.0 * 0.1003875375 + 40.0, 1e-9);
    EXPECT_TRUE(camera.has_distortion());
}

// ---- The tiny synthetic captures ----------------------------------------------------

TEST(CaptureTiny, ClothLoadsWithEveryField) {
    std::vector<Problem> warnings;
    const Capture capture = read_capture(tiny("tiny-cloth"), &warnings);
    EXPECT_TRUE(warnings.empty()) << (warnings.empty() ? "" : warnings.front().to_string());
    EXPECT_EQ(capture.kind, "cloth.waving");
    EXPECT_TRUE(capture.is_cloth());
    EXPECT_DOUBLE_EQ(capture.fps, 30.0);
    EXPECT_EQ(capture.frames.first, 1);
    EXPECT_EQ(capture.frames.count, 3);
    EXPECT_EQ(capture.frames.last(), 3);
    ASSERT_TRUE(capture.camera && capture.world && capture.projector && capture.swatch);
    EXPECT_EQ(capture.camera->width, 8);
    EXPECT_EQ(capture.camera->height, 6);
    ASSERT_TRUE(capture.world->gravity_m_per_s2);
    EXPECT_DOUBLE_EQ(capture.world->gravity_m_per_s2->z(), -9.81);
    EXPECT_EQ(capture.projector->camera.width, 16);
    EXPECT_EQ(capture.projector->pattern.axis, "rows");
    EXPECT_DOUBLE_EQ(capture.projector->pattern.period_px, 4.0);
    EXPECT_DOUBLE_EQ(capture.swatch->mass_kg, 0.0135);
    ASSERT_EQ(capture.swatch->pins.size(), 2u);
    EXPECT_EQ(capture.swatch->pins[1].uv, Eigen::Vector2d(1.0, 1.0));
    ASSERT_EQ(capture.swatch->pins[1].positions_m.size(), 3u);
    EXPECT_DOUBLE_EQ(capture.swatch->pins[1].positions_m[2].x(), 0.12);
    EXPECT_EQ(capture.source["licence"], "CC0");
    EXPECT_EQ(fs::path(capture.frame_path(2)).filename().string(), "000002.png");
}

TEST(CaptureTiny, FramesMasksAndBackgroundLoad) {
    const Capture capture = read_capture(tiny("tiny-cloth"));
    FrameSource source(capture);
    EXPECT_EQ(source.width(), 8);
    EXPECT_EQ(source.height(), 6);
    for (int n = 1; n <= 3; ++n) {
        const Image frame = source.frame(n);
        ASSERT_EQ(frame.width, 8);
        ASSERT_EQ(frame.height, 6);
        ASSERT_EQ(frame.channels, 3);
        EXPECT_EQ(frame.encoding, Image::Encoding::srgb);
        // Written as (R, G, B) = (10 n + x, 20 y, 200 + n) / 255: RGB order, top row first.
        EXPECT_FLOAT_EQ(frame.at(5, 4, 0), float(10 * n + 5) / 255.0f);
        EXPECT_FLOAT_EQ(frame.at(5, 4, 1), 80.0f / 255.0f);
        EXPECT_FLOAT_EQ(frame.at(5, 4, 2), float(200 + n) / 255.0f);
    }
    EXPECT_THROW(source.frame(0), std::out_of_range);
    EXPECT_THROW(source.frame(4), std::out_of_range);
    ASSERT_TRUE(source.has_masks());
    const Image mask = source.mask(2);
    ASSERT_EQ(mask.channels, 1);
    EXPECT_FLOAT_EQ(mask.at(2, 1), 1.0f);
    EXPECT_FLOAT_EQ(mask.at(5, 4), 1.0f);
    EXPECT_FLOAT_EQ(mask.at(1, 1), 0.0f);
    EXPECT_FLOAT_EQ(mask.at(6, 5), 0.0f);
    // The pins project onto the object.
    for (const Pin& pin : capture.swatch->pins) {
        const Eigen::Vector2d p = capture.camera->project(pin.positions_m.front());
        EXPECT_FLOAT_EQ(mask.at(int(std::lround(p.x())), int(std::lround(p.y()))), 1.0f);
    }
    ASSERT_TRUE(source.has_background());
    EXPECT_FLOAT_EQ(source.background().at(7, 5, 2), 9.0f / 255.0f);
}

TEST(CaptureTiny, ExrFramesLoadLinearAndUnchanged) {
    const std::string dir = edited_copy("tiny-cloth", "exr_frames", [](nlohmann::json& j) {
        j["frames"]["pattern"] = "frames/%06d.exr";
    });
    // An RGB float EXR of 8 x 6 pixels (the vertex-animation writer makes one).
    for (int n = 1; n <= 3; ++n) {
        VertexAnimation pixels;
        pixels.vertex_count = 8;  // width
        pixels.frame_count = 6;   // height
        for (int y = 0; y < 6; ++y)
            for (int x = 0; x < 8; ++x) pixels.positions_m.emplace_back(float(n) * 2.5f, float(x) - 0.125f, float(y) * 10.0f);
        write_vertex_animation(dir + "/frames/" + *format_frame_pattern("%06d.exr", n), pixels);
    }
    const Capture capture = read_capture(dir);
    FrameSource source(capture);
    const Image frame = source.frame(2);
    EXPECT_EQ(frame.encoding, Image::Encoding::linear);
    EXPECT_EQ(frame.width, 8);
    EXPECT_EQ(frame.height, 6);
    EXPECT_EQ(frame.at(3, 4, 0), 5.0f);     // not clamped to [0, 1]
    EXPECT_EQ(frame.at(3, 4, 1), 2.875f);
    EXPECT_EQ(frame.at(3, 4, 2), 40.0f);
    EXPECT_EQ(frame.at(0, 0, 1), -0.125f);  // not clamped either
}

TEST(CaptureTiny, RigidLoadsMeshAndMassProperties) {
    std::vector<Problem> warnings;
    const Capture capture = read_capture(tiny("tiny-rigid"), &warnings);
    EXPECT_TRUE(warnings.empty()) << (warnings.empty() ? "" : warnings.front().to_string());
    ASSERT_TRUE(capture.rigid);
    EXPECT_FALSE(capture.world->gravity_m_per_s2.has_value());
    EXPECT_EQ(capture.world->note, "unknown: world frame = camera frame");
    EXPECT_NEAR(capture.rigid->mass_kg, 500.0 * 1e-3 / 6.0, 1e-12);
    ASSERT_EQ(capture.rigid->body_mesh.vertices_m.size(), 4u);
    ASSERT_EQ(capture.rigid->body_mesh.triangles.size(), 4u);
    // The tetrahedron's volume and centroid agree with the declared mass and COM.
    const MeshVolume volume = mesh_volume(capture.rigid->body_mesh);
    EXPECT_NEAR(volume.volume_m3, 1e-3 / 6.0, 1e-9);
    EXPECT_NEAR((volume.centroid_m - capture.rigid->center_of_mass_m).norm(), 0.0, 1e-7);
}

TEST(CaptureTiny, VideoDecodesSequentiallyAndBackwards) {
    const Capture capture = read_capture(tiny("tiny-video"));
    EXPECT_TRUE(capture.is_video());
    EXPECT_FALSE(capture.camera);
    EXPECT_EQ(capture.flowlines, "flowlines.svg");
    FrameSource source(capture);
    EXPECT_EQ(source.width(), 16);
    EXPECT_EQ(source.height(), 16);
    const Image third = source.frame(3);
    const Image first = source.frame(1);  // goes back: re-opens the clip
    EXPECT_EQ(third.width, 16);
    EXPECT_EQ(first.height, 16);
    EXPECT_NE(first.pixels, third.pixels);  // testsrc moves between frames
    // A fresh source decoding forward gives identical pixels (decoding is exact).
    FrameSource fresh(capture);
    EXPECT_EQ(fresh.frame(1).pixels, first.pixels);
    EXPECT_EQ(fresh.frame(3).pixels, third.pixels);
    EXPECT_THROW(source.frame(4), std::out_of_range);
}

TEST(CaptureTiny, RoundTripThroughJson) {
    for (const char* name : {"tiny-cloth", "tiny-rigid", "tiny-video"}) {
        const Capture capture = read_capture(tiny(name));
        const nlohmann::json original = nlohmann::json::parse(read_text(tiny(std::string(name) + "/capture.json")));
        EXPECT_EQ(capture_to_json(capture), original) << name;
        Diagnostics diag("round trip");
        std::optional<Capture> again = parse_capture(capture_to_json(capture), capture.folder, diag,
                                                     Strictness::strict, CaptureFileChecks::none);
        ASSERT_TRUE(again) << errors_of(diag.problems());
        EXPECT_EQ(capture_to_json(*again), capture_to_json(capture)) << name;
    }
}

TEST(CaptureTiny, SummaryNamesTheEssentials) {
    const nlohmann::json summary = summarize_capture(read_capture(tiny("tiny-cloth")));
    EXPECT_EQ(summary["kind"], "cloth.waving");
    EXPECT_EQ(summary["frames"]["count"], 3);
    EXPECT_DOUBLE_EQ(summary["frames"]["duration_s"].get<double>(), 0.1);
    EXPECT_DOUBLE_EQ(summary["swatch"]["areal_density_kg_per_m2"].get<double>(), 0.0135 / 0.09);
    EXPECT_NEAR(summary["swatch"]["pins"][1]["max_travel_m"].get<double>(), 0.02, 1e-12);
    EXPECT_EQ(summary["capture_json_sha256"].get<std::string>().size(), 64u);
    const nlohmann::json rigid = summarize_capture(read_capture(tiny("tiny-rigid")));
    EXPECT_EQ(rigid["rigid"]["mesh_summary"]["triangles"], 4);
}

// A tiny cloth capture with 3D tracks: `rows` x `cols` points over `frames`
// frames, point (r, c) at (c, 0, r) cm plus 1 mm per frame, `gaps` NaN.
std::string capture_with_tracks(const std::string& name, int rows, int cols, int frames,
                                const std::vector<std::pair<int, int>>& gaps, bool partly_nan = false) {
    const std::string dir = edited_copy("tiny-cloth", name, [&](nlohmann::json& j) {
        j["tracks"] = {{"file", "tracks.exr"}, {"rows", rows}, {"cols", cols}};
    });
    VertexAnimation tracks;
    tracks.frame_count = frames;
    tracks.vertex_count = rows * cols;
    for (int f = 0; f < frames; ++f)
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c)
                tracks.positions_m.emplace_back(0.01f * c + 0.001f * f, 0.0f, 0.01f * r);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const auto& [frame, point] : gaps)
        tracks.positions_m[static_cast<std::size_t>(frame * rows * cols + point)] =
            partly_nan ? Eigen::Vector3f(nan, 0.0f, 0.0f) : Eigen::Vector3f::Constant(nan);
    if (!partly_nan) {
        write_vertex_animation(dir + "/tracks.exr", tracks, MissingPoints::allow_nan);
        return dir;
    }
    // The writer refuses a partly-NaN point, so this broken export is written with OpenEXR directly.
    EXPECT_FALSE(validation_messages([&] { write_vertex_animation(dir + "/x.exr", tracks, MissingPoints::allow_nan); }).empty());
    Imf::Header header(tracks.vertex_count, tracks.frame_count);
    for (const char* channel : {"R", "G", "B"}) header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
    Imf::OutputFile file((dir + "/tracks.exr").c_str(), header);
    char* base = reinterpret_cast<char*>(tracks.positions_m.data());
    Imf::FrameBuffer buffer;
    for (int c = 0; c < 3; ++c)
        buffer.insert(c == 0 ? "R" : c == 1 ? "G" : "B",
                      Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(Eigen::Vector3f),
                                 sizeof(Eigen::Vector3f) * static_cast<std::size_t>(tracks.vertex_count)));
    file.setFrameBuffer(buffer);
    file.writePixels(tracks.frame_count);
    return dir;
}

TEST(CaptureTracks, GapsAndGridLoad) {
    const std::string dir = capture_with_tracks("tracks_ok", 2, 3, 3, {{0, 4}, {2, 0}});
    std::vector<Problem> warnings;
    const Capture capture = read_capture(dir, &warnings);
    EXPECT_TRUE(warnings.empty()) << (warnings.empty() ? "" : warnings.front().to_string());
    ASSERT_TRUE(capture.tracks);
    EXPECT_EQ(capture.tracks->rows, 2);
    EXPECT_EQ(capture.tracks->cols, 3);
    const std::optional<VertexAnimation> tracks = read_capture_tracks(capture);
    ASSERT_TRUE(tracks);
    EXPECT_EQ(tracks->grid_rows, 2);
    EXPECT_EQ(tracks->grid_cols, 3);
    EXPECT_DOUBLE_EQ(tracks->fps, 30.0);
    EXPECT_TRUE(tracks->position(0, 4).array().isNaN().all());
    EXPECT_FLOAT_EQ(tracks->position(1, 5).x(), 0.021f);
    const nlohmann::json summary = summarize_capture(capture);
    EXPECT_DOUBLE_EQ(summary["tracks"]["seen_share"].get<double>(), 16.0 / 18.0);
    EXPECT_EQ(capture_to_json(capture)["tracks"]["file"], "tracks.exr");
    // A capture without tracks has none to read.
    EXPECT_FALSE(read_capture_tracks(read_capture(tiny("tiny-cloth"))));
    // Simulated positions still refuse NaN: only tracks may have gaps.
    EXPECT_FALSE(validation_messages([&] { read_vertex_animation(dir + "/tracks.exr"); }).empty());
}

TEST(CaptureTracks, ShapeMismatchesNameTheFieldAndTheFix) {
    // The grid must match the file's columns, the file's rows the frames.
    EXPECT_NO_THROW(read_capture(capture_with_tracks("tracks_grid", 2, 3, 3, {})));
    const std::string wrong_grid_dir = edited_copy("tiny-cloth", "tracks_wrong_grid", [](nlohmann::json& j) {
        j["tracks"] = {{"file", "tracks.exr"}, {"rows", 3}, {"cols", 3}};
    });
    fs::copy_file(capture_with_tracks("tracks_source", 2, 3, 3, {}) + "/tracks.exr", wrong_grid_dir + "/tracks.exr",
                  fs::copy_options::overwrite_existing);
    const std::string wrong_grid = validation_messages([&] { read_capture(wrong_grid_dir); });
    EXPECT_TRUE(mentions(wrong_grid, "capture.json: /tracks/rows")) << wrong_grid;
    EXPECT_TRUE(mentions(wrong_grid, "6 columns (points) but the grid 3 x 3 has 9")) << wrong_grid;
    EXPECT_TRUE(mentions(wrong_grid, "fix:")) << wrong_grid;

    const std::string frames = validation_messages([&] { read_capture(capture_with_tracks("tracks_frames", 2, 3, 2, {})); });
    EXPECT_TRUE(mentions(frames, "/tracks/file")) << frames;
    EXPECT_TRUE(mentions(frames, "2 rows (frames) but the capture has 3 frames")) << frames;

    const std::string partly = validation_messages([&] { read_capture(capture_with_tracks("tracks_partly", 2, 3, 3, {{1, 2}}, true)); });
    EXPECT_TRUE(mentions(partly, "tracks.exr: pixels")) << partly;
    EXPECT_TRUE(mentions(partly, "NaN in some channels but not all")) << partly;

    const std::string missing = cloth_errors("tracks_missing", [](nlohmann::json& j) {
        j["tracks"] = {{"file", "nowhere.exr"}, {"rows", 2}, {"cols", 3}};
    });
    EXPECT_TRUE(mentions(missing, "/tracks/file")) << missing;
    EXPECT_TRUE(mentions(missing, "does not exist")) << missing;

    const std::string bad_grid = cloth_errors("tracks_bad_grid", [](nlohmann::json& j) {
        j["tracks"] = {{"file", "tracks.exr"}, {"rows", 1}, {"cols", "three"}};
    });
    EXPECT_TRUE(mentions(bad_grid, "/tracks/rows")) << bad_grid;
    EXPECT_TRUE(mentions(bad_grid, "/tracks/cols")) << bad_grid;
}

TEST(CaptureTracks, OnlyClothCapturesReadThem) {
    std::vector<Problem> warnings;
    const std::string dir = edited_copy("tiny-rigid", "tracks_rigid", [](nlohmann::json& j) {
        j["tracks"] = {{"file", "tracks.exr"}, {"rows", 2}, {"cols", 2}};
    });
    const Capture capture = read_capture(dir, &warnings);
    EXPECT_FALSE(capture.tracks);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "/tracks");
}

TEST(CaptureTiny, AcceptsTheFolderOrItsCaptureJson) {
    const Capture by_folder = read_capture(tiny("tiny-cloth"));
    const Capture by_file = read_capture(tiny("tiny-cloth/capture.json"));
    EXPECT_EQ(by_folder.capture_json_sha256, by_file.capture_json_sha256);
    EXPECT_EQ(fs::canonical(by_folder.frame_path(1)), fs::canonical(by_file.frame_path(1)));
    EXPECT_TRUE(errors_of(validate_capture_folder(tiny("tiny-cloth/capture.json"))).empty());
}

// ---- Bad input: every message names the file and the field -----------------------

TEST(CaptureBad, MalformedJsonGivesLineAndColumn) {
    const std::string dir = scratch_dir("capture_malformed");
    write_text(dir + "/capture.json", "{\n  \"format\": \"flowvid.capture\",\n  \"version\": 1,\n  \"kind\": \n}\n");
    const std::string text = validation_messages([&] { read_capture(dir); });
    EXPECT_TRUE(mentions(text, "capture.json")) << text;
    EXPECT_TRUE(mentions(text, "line 5")) << text;
    EXPECT_TRUE(mentions(text, "malformed JSON")) << text;
}

TEST(CaptureBad, MissingCaptureJsonIsAnIoError) {
    const std::string dir = scratch_dir("capture_empty_folder");
    EXPECT_THROW(read_capture(dir), IoError);
    const std::vector<Problem> problems = validate_capture_folder(dir);
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_TRUE(mentions(problems[0].to_string(), "capture.json"));
}

TEST(CaptureBad, WrongFormatAndVersion) {
    std::string text = cloth_errors("wrong_format", [](nlohmann::json& j) { j["format"] = "flowvid.fabric"; });
    EXPECT_TRUE(mentions(text, "capture.json: /format: this is a \"flowvid.fabric\" file")) << text;
    text = cloth_errors("version_2", [](nlohmann::json& j) { j["version"] = 2; });
    EXPECT_TRUE(mentions(text, "capture.json: /version: capture version 2 is not supported")) << text;
    EXPECT_TRUE(mentions(text, "upgrade flowvid")) << text;
    text = cloth_errors("version_text", [](nlohmann::json& j) { j["version"] = "one"; });
    EXPECT_TRUE(mentions(text, "/version")) << text;
    text = cloth_errors("bad_kind", [](nlohmann::json& j) { j["kind"] = "cloth.flapping"; });
    EXPECT_TRUE(mentions(text, "capture.json: /kind: unknown kind \"cloth.flapping\"")) << text;
    // A newer minor, written the MAJOR.MINOR way, loads with a warning.
    const std::string dir = edited_copy("tiny-cloth", "version_1_1", [](nlohmann::json& j) { j["version"] = "1.1"; });
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_capture(dir, &warnings));
    ASSERT_FALSE(warnings.empty());
    EXPECT_EQ(warnings[0].field, "/version");
}

TEST(CaptureBad, MissingKindSpecificBlocks) {
    std::string text = cloth_errors("no_blocks", [](nlohmann::json& j) {
        j.erase("camera");
        j.erase("swatch");
        j.erase("projector");
        j.erase("world");
    });
    for (const char* field : {"/camera: missing", "/swatch: missing", "/projector: missing", "/world: missing"})
        EXPECT_TRUE(mentions(text, std::string("capture.json: ") + field)) << field << "\n" << text;
    text = cloth_errors("rigid_without_rigid", [](nlohmann::json& j) { j["kind"] = "rigid.toss"; });
    EXPECT_TRUE(mentions(text, "capture.json: /rigid: missing")) << text;
    text = cloth_errors("video_without_flowlines", [](nlohmann::json& j) { j["kind"] = "video.flow"; });
    EXPECT_TRUE(mentions(text, "capture.json: /flowlines: missing")) << text;
    // The other kinds' blocks are ignored with a warning, not an error.
    std::vector<Problem> warnings;
    const std::string dir = edited_copy("tiny-cloth", "extra_block", [](nlohmann::json& j) {
        j["rigid"] = {{"mesh", "x.glb"}};
    });
    EXPECT_NO_THROW(read_capture(dir, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "/rigid");
}

TEST(CaptureBad, NegativeNullAndStringMasses) {
    std::string text = cloth_errors("negative_mass", [](nlohmann::json& j) { j["swatch"]["mass_kg"] = -0.01; });
    EXPECT_TRUE(mentions(text, "capture.json: /swatch/mass_kg: value -0.01 is out of range")) << text;
    // JSON cannot hold NaN: writers produce null.
    text = cloth_errors("nan_mass", [](nlohmann::json& j) {
        j["swatch"]["mass_kg"] = std::numeric_limits<double>::quiet_NaN();
    });
    EXPECT_TRUE(mentions(text, "capture.json: /swatch/mass_kg: expected a number")) << text;
    EXPECT_TRUE(mentions(text, "NaN")) << text;
    const std::string dir = edited_copy("tiny-rigid", "rigid_bad", [](nlohmann::json& j) {
        j["rigid"]["mass_kg"] = 0.0;
        j["rigid"]["inertia_body"][0][1] = 1.0;  // not symmetric
    });
    text = validation_messages([&] { read_capture(dir); });
    EXPECT_TRUE(mentions(text, "capture.json: /rigid/mass_kg: value 0 is out of range")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /rigid/inertia_body: not symmetric")) << text;
}

TEST(CaptureBad, InertiaMustBePhysical) {
    auto with_inertia = [](const std::string& name, const Eigen::Matrix3d& I) {
        const std::string dir = edited_copy("tiny-rigid", name, [&](nlohmann::json& j) {
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) j["rigid"]["inertia_body"][r][c] = I(r, c);
        });
        return validation_messages([&] { read_capture(dir); });
    };
    std::string text = with_inertia("inertia_negative", Eigen::Vector3d(1e-3, -1e-3, 1e-3).asDiagonal());
    EXPECT_TRUE(mentions(text, "/rigid/inertia_body: not positive definite")) << text;
    text = with_inertia("inertia_triangle", Eigen::Vector3d(1e-3, 1e-3, 5e-3).asDiagonal());
    EXPECT_TRUE(mentions(text, "/rigid/inertia_body: principal moments")) << text;
    EXPECT_TRUE(mentions(text, "triangle inequality")) << text;
}

TEST(CaptureBad, CameraMustBeRigidAndCalibrated) {
    std::string text = cloth_errors("scaled_rotation", [](nlohmann::json& j) {
        j["camera"]["camera_from_world"][0][0] = 1.01;
    });
    EXPECT_TRUE(mentions(text, "capture.json: /camera/camera_from_world: the rotation part is not orthonormal")) << text;
    text = cloth_errors("reflection", [](nlohmann::json& j) {
        for (int c = 0; c < 3; ++c) j["camera"]["camera_from_world"][0][c] = -j["camera"]["camera_from_world"][0][c].get<double>();
    });
    EXPECT_TRUE(mentions(text, "capture.json: /camera/camera_from_world: the rotation part has determinant -1")) << text;
    text = cloth_errors("last_row", [](nlohmann::json& j) { j["camera"]["camera_from_world"][3][0] = 0.5; });
    EXPECT_TRUE(mentions(text, "capture.json: /camera/camera_from_world/3: the last row must be [0, 0, 0, 1]")) << text;
    text = cloth_errors("bad_K", [](nlohmann::json& j) {
        j["camera"]["K"][0][0] = -5.0;
        j["camera"]["K"][2][2] = 2.0;
        j["camera"]["dist"] = {0.0, 0.0, 0.0};
    });
    EXPECT_TRUE(mentions(text, "capture.json: /camera/K/0/0: focal length fx = -5 must be > 0")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /camera/K/2: the last row must be [0, 0, 1]")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /camera/dist: expected 5 numbers, found 3")) << text;
    text = cloth_errors("projector_bad", [](nlohmann::json& j) {
        j["projector"]["pattern"]["axis"] = "diagonal";
        j["projector"]["pattern"]["period_px"] = 0;
    });
    EXPECT_TRUE(mentions(text, "capture.json: /projector/pattern/axis: unknown axis \"diagonal\"")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /projector/pattern/period_px: value 0 is out of range")) << text;
}

TEST(CaptureBad, PinPositionsMustMatchTheFrameCount) {
    std::string text = cloth_errors("pin_count", [](nlohmann::json& j) {
        j["swatch"]["pins"][1]["positions"].erase(2);
    });
    EXPECT_TRUE(mentions(text, "capture.json: /swatch/pins/1/positions: has 2 positions but frames.count is 3")) << text;
    text = cloth_errors("pin_uv", [](nlohmann::json& j) {
        j["swatch"]["pins"][0]["uv"] = {0.0, 1.5};
        j["swatch"]["pins"][1]["positions"][0] = {0.1, 0.0};
    });
    EXPECT_TRUE(mentions(text, "capture.json: /swatch/pins/0/uv/1: value 1.5 is out of range")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /swatch/pins/1/positions/0: expected [x, y, z]")) << text;
}

TEST(CaptureBad, MissingFramesAndReferencedFiles) {
    const std::string dir = edited_copy("tiny-cloth", "missing_files", [](nlohmann::json& j) {
        j["background"] = "no_background.png";
    });
    fs::remove(dir + "/frames/000002.png");
    fs::remove(dir + "/masks/000003.png");
    const std::string text = validation_messages([&] { read_capture(dir); });
    EXPECT_TRUE(mentions(text, "capture.json: /frames/pattern: 1 of the 3 frame files checked do not exist: "
                               "\"frames/000002.png\"")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /masks: 1 of the 3 mask files checked do not exist: \"masks/000003.png\""))
        << text;
    EXPECT_TRUE(mentions(text, "capture.json: /background: background image \"no_background.png\" does not exist"))
        << text;
}

TEST(CaptureBad, FrameSizeMustMatchTheCamera) {
    const std::string text = cloth_errors("camera_size", [](nlohmann::json& j) { j["camera"]["width"] = 10; });
    EXPECT_TRUE(mentions(text, "capture.json: /frames/pattern: frame 1 file \"frames/000001.png\" is 8 x 6 pixels but "
                               "/camera says 10 x 6")) << text;
    EXPECT_TRUE(mentions(text, "/background: background image \"background.png\" is 8 x 6")) << text;
}

TEST(CaptureBad, EveryProblemIsReportedAtOnce) {
    const std::string dir = edited_copy("tiny-cloth", "many", [](nlohmann::json& j) {
        j["fps"] = 0;
        j["swatch"]["width_m"] = "wide";
        j["camera"]["camera_from_world"][1][1] = 3.0;
        j["projector"]["pattern"]["type"] = "checkerboard";
        j["frames"]["count"] = 4;  // frame 4 and the pins' 4th position are missing
        j["colour"] = "blue";      // unknown key: an error under validate
    });
    const std::vector<Problem> problems = validate_capture_folder(dir, Strictness::strict);
    const std::string text = errors_of(problems);
    for (const char* field : {"/fps", "/swatch/width_m", "/camera/camera_from_world", "/projector/pattern/type",
                              "/swatch/pins/0/positions", "/swatch/pins/1/positions", "/frames/pattern", "/colour"})
        EXPECT_TRUE(mentions(text, std::string("capture.json: ") + field + ":")) << field << "\n" << text;
    // Reading is lenient about the unknown key: a warning.
    std::vector<Problem> lenient = validate_capture_folder(dir, Strictness::lenient);
    EXPECT_FALSE(mentions(errors_of(lenient), "/colour")) << errors_of(lenient);
}

TEST(CaptureBad, BrokenMeshIsReportedWithItsFile) {
    const std::string dir = edited_copy("tiny-rigid", "broken_mesh", [](nlohmann::json&) {});
    const std::string glb = read_text(dir + "/body.glb");
    fs::permissions(dir + "/body.glb", fs::perms::owner_write, fs::perm_options::add);
    write_text(dir + "/body.glb", glb.substr(0, glb.size() - 30));
    const std::string text = validation_messages([&] { read_capture(dir); });
    EXPECT_TRUE(mentions(text, "body.glb: GLB header: the header declares")) << text;
    EXPECT_TRUE(mentions(text, "capture.json: /rigid/mesh: mesh \"body.glb\" is not a valid glTF binary")) << text;
}

TEST(CaptureBad, VideoShorterThanFramesCount) {
    const std::string dir = edited_copy("tiny-video", "short_video", [](nlohmann::json& j) { j["frames"]["count"] = 9; });
    const std::string text = validation_messages([&] { read_capture(dir); });
    EXPECT_TRUE(mentions(text, "capture.json: /frames/count: frames 1..9 are asked for but video \"clip.mp4\" has 3 frames"))
        << text;
}

// ---- Rigid meshes built in memory ----------------------------------------------------

namespace {

// A GLB from a glTF JSON and its binary chunk.
std::string make_glb(const nlohmann::json& gltf, std::string binary) {
    std::string json = gltf.dump();
    while (json.size() % 4) json += ' ';
    while (binary.size() % 4) binary += '\0';
    std::string out;
    auto u32 = [&](std::uint32_t v) {
        for (int i = 0; i < 4; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
    };
    u32(0x46546C67);
    u32(2);
    u32(static_cast<std::uint32_t>(12 + 8 + json.size() + 8 + binary.size()));
    u32(static_cast<std::uint32_t>(json.size()));
    u32(0x4E4F534A);
    out += json;
    u32(static_cast<std::uint32_t>(binary.size()));
    u32(0x004E4942);
    out += binary;
    return out;
}

// One triangle (3 float vertices, uint16 indices) under a node with `node_extra`.
std::string triangle_glb(const nlohmann::json& node_extra, float nan_at = 0.0f, std::uint16_t last_index = 2) {
    const float vertices[9] = {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, nan_at};
    const std::uint16_t indices[3] = {0, 1, last_index};
    std::string binary(reinterpret_cast<const char*>(vertices), sizeof vertices);
    binary.append(reinterpret_cast<const char*>(indices), sizeof indices);
    nlohmann::json node = {{"mesh", 0}};
    node.update(node_extra);
    const nlohmann::json gltf = {
        {"asset", {{"version", "2.0"}}},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {node}},
        {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"indices", 1}}}}}}},
        {"accessors",
         {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}},
          {{"bufferView", 1}, {"componentType", 5123}, {"count", 3}, {"type", "SCALAR"}}}},
        {"bufferViews",
         {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 36}}, {{"buffer", 0}, {"byteOffset", 36}, {"byteLength", 6}}}},
        {"buffers", {{{"byteLength", 44}}}}};
    return make_glb(gltf, binary);
}

std::string mesh_errors(const std::string& bytes) {
    Diagnostics diag("test.glb");
    parse_rigid_mesh_glb(bytes, diag);
    return errors_of(diag.problems());
}

}  // namespace

TEST(RigidMesh, ReadsTheStoredTetrahedron) {
    const TriangleMesh mesh = read_rigid_mesh(tiny("tiny-rigid/body.glb"));
    ASSERT_EQ(mesh.vertices_m.size(), 4u);
    EXPECT_EQ(mesh.vertices_m[3], Eigen::Vector3d(0.0, 0.0, double(0.1f)));  // as stored, no y-up conversion
    EXPECT_EQ(mesh.triangles[0], (std::array<int, 3>{0, 2, 1}));
    EXPECT_GT(mesh_volume(mesh).volume_m3, 0.0);  // outward winding
    const nlohmann::json summary = summarize_rigid_mesh(mesh);
    EXPECT_EQ(summary["vertices"], 4);
    EXPECT_NEAR(summary["bbox_max_m"][2].get<double>(), 0.1, 1e-7);
}

TEST(RigidMesh, AppliesNodeTransforms) {
    Diagnostics diag("test.glb");
    // Translate by (1, 2, 3) after rotating 90 degrees about z and scaling x2.
    const std::optional<TriangleMesh> mesh = parse_rigid_mesh_glb(
        triangle_glb({{"translation", {1.0, 2.0, 3.0}},
                      {"rotation", {0.0, 0.0, std::sqrt(0.5), std::sqrt(0.5)}},
                      {"scale", {2.0, 2.0, 2.0}}}),
        diag);
    ASSERT_TRUE(mesh) << errors_of(diag.problems());
    // Vertex (1, 0, 0) -> scaled (2, 0, 0) -> rotated (0, 2, 0) -> translated (1, 4, 3).
    EXPECT_NEAR((mesh->vertices_m[1] - Eigen::Vector3d(1.0, 4.0, 3.0)).norm(), 0.0, 1e-12);
    Diagnostics diag_matrix("test.glb");
    const std::optional<TriangleMesh> moved = parse_rigid_mesh_glb(
        triangle_glb({{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 6, 7, 1}}}), diag_matrix);
    ASSERT_TRUE(moved) << errors_of(diag_matrix.problems());
    EXPECT_EQ(moved->vertices_m[0], Eigen::Vector3d(5.0, 6.0, 7.0));
}

TEST(RigidMesh, BadFilesGiveClearErrors) {
    const std::string good = triangle_glb(nlohmann::json::object());
    ASSERT_TRUE(mesh_errors(good).empty()) << mesh_errors(good);
    EXPECT_TRUE(mentions(mesh_errors(good.substr(0, 8)), "test.glb: GLB header: the file has 8 bytes"));
    EXPECT_TRUE(mentions(mesh_errors(good.substr(0, good.size() - 4)), "test.glb: GLB header: the header declares"));
    EXPECT_TRUE(mentions(mesh_errors("PK\x03\x04 not a glb at all"), "not a glTF binary"));
    std::string text = mesh_errors(triangle_glb(nlohmann::json::object(), std::numeric_limits<float>::quiet_NaN()));
    EXPECT_TRUE(mentions(text, "test.glb: /accessors/0: 1 vertex position(s) are NaN or infinite")) << text;
    text = mesh_errors(triangle_glb(nlohmann::json::object(), 0.0f, 7));
    EXPECT_TRUE(mentions(text, "test.glb: /accessors/1: 1 index(es) are >= the vertex count 3")) << text;
    // Corrupt JSON inside a well-formed container.
    std::string corrupt = good;
    corrupt[22] = '#';
    EXPECT_TRUE(mentions(mesh_errors(corrupt), "test.glb: glTF: cannot parse the glTF content")) << mesh_errors(corrupt);
    EXPECT_THROW(read_rigid_mesh(tiny("tiny-rigid/missing.glb")), IoError);
}

TEST(RigidMesh, MutatedInputsNeverCrash) {
    // A small deterministic fuzz run: every mutation is either read or refused.
    const std::string good = triangle_glb({{"translation", {1.0, 2.0, 3.0}}});
    std::uint32_t state = 12345;
    auto next = [&] { return state = state * 1664525u + 1013904223u; };
    for (int i = 0; i < 400; ++i) {
        std::string bytes = good;
        for (int e = 0; e < 1 + int(next() % 4); ++e) {
            const std::size_t at = next() % bytes.size();
            switch (next() % 3) {
                case 0: bytes[at] = static_cast<char>(bytes[at] ^ (1 << (next() % 8))); break;
                case 1: bytes.resize(at); break;
                default: bytes[at] = '\xff'; break;
            }
            if (bytes.empty()) break;
        }
        Diagnostics diag("fuzz.glb");
        EXPECT_NO_THROW(parse_rigid_mesh_glb(bytes, diag));
    }
}

// ---- The shared example captures --------------------------------------------------

TEST(CaptureShared, EveryExampleValidatesWithoutErrors) {
    if (!shared_captures_present()) GTEST_SKIP() << "no ../shared/captures";
    const std::vector<std::string> folders = shared_capture_folders();
    EXPECT_GE(folders.size(), 13u);
    for (const std::string& folder : folders) {
        const std::vector<Problem> problems = validate_capture_folder(folder, Strictness::strict);
        EXPECT_TRUE(problems.empty()) << folder << "\n" << (problems.empty() ? "" : problems.front().to_string());
        std::vector<Problem> warnings;
        Capture capture;
        ASSERT_NO_THROW(capture = read_capture(folder, &warnings)) << folder;
        EXPECT_TRUE(warnings.empty()) << folder;
        EXPECT_EQ(capture.capture_json_sha256, sha256_hex(read_text(folder + "/capture.json"))) << folder;
        // The parsed content is the file's content.
        EXPECT_EQ(capture_to_json(capture), nlohmann::json::parse(read_text(folder + "/capture.json"))) << folder;
    }
}

TEST(CaptureShared, KnownFactsOfTheExamples) {
    if (!shared_captures_present()) GTEST_SKIP() << "no ../shared/captures";
    const Capture waving = read_capture(shared_path("captures/cloth-cotton-waving-1"));
    EXPECT_EQ(waving.kind, "cloth.waving");
    EXPECT_EQ(waving.frames.count, 50);
    EXPECT_DOUBLE_EQ(waving.fps, 30.0);
    ASSERT_TRUE(waving.swatch && waving.camera && waving.projector);
    ASSERT_EQ(waving.swatch->pins.size(), 2u);
    EXPECT_EQ(waving.swatch->pins[0].positions_m.size(), 50u);
    EXPECT_EQ(waving.swatch->pins[1].positions_m.size(), 50u);
    EXPECT_NEAR(waving.camera->K(0, 0), 586.6666666667, 1e-9);
    EXPECT_EQ(waving.camera->width, 480);
    EXPECT_EQ(waving.camera->height, 360);
    EXPECT_DOUBLE_EQ(waving.swatch->width_m, 0.30);
    EXPECT_DOUBLE_EQ(waving.projector->pattern.period_px, 16.0);

    const Capture toss = read_capture(shared_path("captures/rigid-toss-major"));
    ASSERT_TRUE(toss.rigid);
    EXPECT_DOUBLE_EQ(toss.rigid->mass_kg, 0.972);
    EXPECT_FALSE(toss.world->gravity_m_per_s2.has_value());
    EXPECT_EQ(toss.rigid->body_mesh.vertices_m.size(), 16u);  // truth.json's glb_roundtrip check
    EXPECT_EQ(toss.rigid->body_mesh.triangles.size(), 24u);
    // Uniform density 500 kg/m^3 (README): the mesh's volume gives the declared mass.
    EXPECT_NEAR(mesh_volume(toss.rigid->body_mesh).volume_m3 * 500.0, 0.972, 0.972 * 1e-4);
    EXPECT_NEAR((mesh_volume(toss.rigid->body_mesh).centroid_m - toss.rigid->center_of_mass_m).norm(), 0.0, 1e-6);
}

TEST(CaptureShared, VideoClipsDecodeToTheirLastFrame) {
    if (!shared_captures_present()) GTEST_SKIP() << "no ../shared/captures";
    const std::pair<const char*, int> clips[] = {{"video-waterfall-cascade", 120}, {"video-fire-pot", 200}};
    for (const auto& [name, frames] : clips) {
        const Capture capture = read_capture(shared_path(std::string("captures/") + name));
        EXPECT_EQ(capture.frames.count, frames) << name;
        const VideoInfo info = read_video_info(capture.resolve(capture.frames.video));
        EXPECT_EQ(info.width, 640);
        EXPECT_EQ(info.height, 360);
        EXPECT_EQ(info.frame_count, frames) << name;
        FrameSource source(capture);
        const Image first = source.frame(1);
        const Image last = source.frame(frames);
        EXPECT_EQ(first.width, 640);
        EXPECT_EQ(first.height, 360);
        EXPECT_EQ(last.width, 640);
        EXPECT_EQ(last.height, 360);
        EXPECT_NE(first.pixels, last.pixels) << name;
    }
}

TEST(CaptureShared, TruthProjectsOntoTheMasks) {
    if (!shared_captures_present()) GTEST_SKIP() << "no ../shared/captures";
    for (const char* name : {"cloth-cotton-waving-1", "cloth-silk-static-1"}) {
        const Capture capture = read_capture(shared_path(std::string("captures/") + name));
        const std::optional<VertexAnimation> truth = read_capture_truth_positions(capture);
        ASSERT_TRUE(truth) << name;
        ASSERT_EQ(truth->grid_rows.value_or(0), 24);
        FrameSource source(capture);
        for (int frame : {1, capture.frames.count / 2, capture.frames.count}) {
            const Image mask = source.mask(frame);
            int on_mask = 0, on_dilated = 0;
            auto object = [&](int x, int y) {
                return x >= 0 && y >= 0 && x < mask.width && y < mask.height && mask.at(x, y) > 0.5f;
            };
            for (int v = 0; v < truth->vertex_count; ++v) {
                const Eigen::Vector2d p = capture.camera->project(truth->position(frame - 1, v).cast<double>());
                const int x = int(std::lround(p.x())), y = int(std::lround(p.y()));
                if (object(x, y)) ++on_mask;
                bool near = false;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) near = near || object(x + dx, y + dy);
                if (near) ++on_dilated;
            }
            // truth.json's check (frame 1, render camera): every vertex lands on the
            // 1-px-dilated mask. Undilated, boundary vertices fall half outside.
            EXPECT_GE(on_dilated, truth->vertex_count * 99 / 100) << name << " frame " << frame;
            EXPECT_GE(on_mask, truth->vertex_count * 85 / 100) << name << " frame " << frame;
        }
    }
    // Rigid captures have no vertex truth.
    EXPECT_FALSE(read_capture_truth_positions(read_capture(shared_path("captures/rigid-toss-major"))));
}

TEST(CaptureTruth, ATruthJsonThatIsNotAnObjectOrHalfAGridIsRefusedNotIgnored) {
    const std::string dir = edited_copy("tiny-cloth", "truth_shape", [](nlohmann::json&) {});
    const Capture capture = read_capture(dir);
    VertexAnimation truth;
    truth.frame_count = capture.frames.count;
    truth.vertex_count = 4;
    truth.positions_m.assign(static_cast<std::size_t>(truth.frame_count * truth.vertex_count), Eigen::Vector3f::Zero());
    fs::create_directories(dir + "/truth");
    write_vertex_animation(dir + "/truth/positions.exr", truth);

    write_text(dir + "/truth/truth.json", R"({"rows": 2, "cols": 2})");
    const std::optional<VertexAnimation> good = read_capture_truth_positions(capture);
    ASSERT_TRUE(good.has_value());
    EXPECT_EQ(good->grid_rows.value_or(0), 2);

    write_text(dir + "/truth/truth.json", "[1, 2]");
    const std::string array = validation_messages([&] { read_capture_truth_positions(capture); });
    EXPECT_TRUE(mentions(array, "truth.json")) << array;
    EXPECT_TRUE(mentions(array, "not a JSON object")) << array;

    write_text(dir + "/truth/truth.json", R"({"rows": 2})");
    const std::string half = validation_messages([&] { read_capture_truth_positions(capture); });
    EXPECT_TRUE(mentions(half, "/cols")) << half;
}
