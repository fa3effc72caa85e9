// Vertex-animation EXR: bit-exact round trip, the captures' truth files, and
// bad input (truncated, corrupted, NaN, wrong channels, other versions) that
// must give clear errors and never crash.

#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/vertex_animation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <half.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>

namespace fs = std::filesystem;
using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::shared_path;
using flowvid::testing::source_path;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

using flowvid::testing::mentions;

// A grid animation with awkward floats (negative zero, subnormals, large and
// tiny magnitudes) so that any lossy step would show.
VertexAnimation sample_animation(int frames, int rows, int cols) {
    VertexAnimation animation;
    animation.frame_count = frames;
    animation.vertex_count = rows * cols;
    animation.grid_rows = rows;
    animation.grid_cols = cols;
    animation.fps = 29.97002997002997;
    std::mt19937 random(7);
    std::uniform_real_distribution<float> uniform(-2.0f, 2.0f);
    for (int f = 0; f < frames; ++f)
        for (int v = 0; v < animation.vertex_count; ++v)
            animation.positions_m.emplace_back(uniform(random), uniform(random), uniform(random));
    animation.positions_m[0] = Eigen::Vector3f(-0.0f, std::numeric_limits<float>::denorm_min(), 3.0e38f);
    if (animation.positions_m.size() > 1) animation.positions_m[1] = Eigen::Vector3f(1e-30f, -123456.789f, std::nextafter(1.0f, 2.0f));
    return animation;
}

// Writes an EXR directly with OpenEXR, for inputs flowvid's writer refuses.
void write_raw_exr(const std::string& path, int width, int height, const std::vector<std::string>& channels,
                   Imf::PixelType type, const std::function<float(int, int, int)>& value,
                   const std::function<void(Imf::Header&)>& edit_header = {},
                   Imf::Compression compression = Imf::NO_COMPRESSION) {
    Imf::Header header(width, height);
    header.compression() = compression;
    for (const std::string& name : channels) header.channels().insert(name, Imf::Channel(type));
    if (edit_header) edit_header(header);
    std::vector<float> data(static_cast<std::size_t>(width) * height * channels.size());
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (std::size_t c = 0; c < channels.size(); ++c)
                data[(static_cast<std::size_t>(y) * width + x) * channels.size() + c] = value(x, y, int(c));
    Imf::OutputFile file(path.c_str(), header);
    Imf::FrameBuffer buffer;
    std::vector<Imath::half> half_data;
    if (type == Imf::HALF) {
        half_data.assign(data.begin(), data.end());
        for (std::size_t c = 0; c < channels.size(); ++c)
            buffer.insert(channels[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(half_data.data() + c),
                                                  sizeof(Imath::half) * channels.size(),
                                                  sizeof(Imath::half) * channels.size() * width));
    } else {
        for (std::size_t c = 0; c < channels.size(); ++c)
            buffer.insert(channels[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(data.data() + c),
                                                  sizeof(float) * channels.size(), sizeof(float) * channels.size() * width));
    }
    file.setFrameBuffer(buffer);
    file.writePixels(height);
}

void write_rgb_exr(const std::string& path, int width, int height,
                   const std::function<void(Imf::Header&)>& edit_header = {}) {
    write_raw_exr(path, width, height, {"R", "G", "B"}, Imf::FLOAT,
                  [](int x, int y, int c) { return float(x) + 0.5f * float(y) + 0.25f * float(c); }, edit_header);
}

std::string errors_of(const std::vector<Problem>& problems) {
    std::string text;
    for (const Problem& p : problems)
        if (p.severity == Problem::Severity::error) text += p.to_string() + "\n";
    return text;
}

}  // namespace

// ---- Round trip ---------------------------------------------------------------

TEST(VertexAnimation, RoundTripIsBitExact) {
    const std::string dir = scratch_dir("vat_round_trip");
    const VertexAnimation animation = sample_animation(7, 5, 6);
    const std::string path = dir + "/anim.exr";
    write_vertex_animation(path, animation);
    std::vector<Problem> warnings;
    const VertexAnimation back = read_vertex_animation(path, &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(back.frame_count, 7);
    EXPECT_EQ(back.vertex_count, 30);
    EXPECT_EQ(back.grid_rows, 5);
    EXPECT_EQ(back.grid_cols, 6);
    EXPECT_EQ(back.fps, animation.fps);
    ASSERT_EQ(back.positions_m.size(), animation.positions_m.size());
    // Bit-exact, including the sign of zero and subnormals.
    EXPECT_EQ(std::memcmp(back.positions_m.data(), animation.positions_m.data(),
                          animation.positions_m.size() * sizeof(Eigen::Vector3f)),
              0);
    EXPECT_TRUE(back == animation);
    EXPECT_TRUE(std::signbit(back.positions_m[0].x()));
    // Layout: row = frame, column = vertex.
    EXPECT_EQ(back.position(3, 17), animation.positions_m[3 * 30 + 17]);
    // No temporary files are left beside it.
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(VertexAnimation, WriterStoresTheFlowvidAttributesAndFloatChannels) {
    const std::string dir = scratch_dir("vat_attributes");
    write_vertex_animation(dir + "/anim.exr", sample_animation(2, 3, 4));
    Imf::InputFile file((dir + "/anim.exr").c_str());
    const Imf::Header& header = file.header();
    ASSERT_NE(header.findTypedAttribute<Imf::StringAttribute>("flowvid.format"), nullptr);
    EXPECT_EQ(header.findTypedAttribute<Imf::StringAttribute>("flowvid.format")->value(), "flowvid.vertex_animation");
    EXPECT_EQ(header.findTypedAttribute<Imf::StringAttribute>("flowvid.version")->value(), "1.0");
    EXPECT_EQ(header.findTypedAttribute<Imf::DoubleAttribute>("flowvid.fps")->value(), 29.97002997002997);
    EXPECT_EQ(header.findTypedAttribute<Imf::IntAttribute>("flowvid.grid_rows")->value(), 3);
    EXPECT_EQ(header.findTypedAttribute<Imf::IntAttribute>("flowvid.grid_cols")->value(), 4);
    for (const char* name : {"R", "G", "B"}) {
        ASSERT_NE(header.channels().findChannel(name), nullptr);
        EXPECT_EQ(header.channels().findChannel(name)->type, Imf::FLOAT);
    }
    EXPECT_EQ(header.dataWindow().max.x, 11);  // 12 vertices
    EXPECT_EQ(header.dataWindow().max.y, 1);   // 2 frames
}

TEST(VertexAnimation, WithoutGridOrFps) {
    const std::string dir = scratch_dir("vat_plain");
    VertexAnimation animation = sample_animation(3, 2, 2);
    animation.grid_rows.reset();
    animation.grid_cols.reset();
    animation.fps = 0.0;
    write_vertex_animation(dir + "/plain.exr", animation);
    const VertexAnimation back = read_vertex_animation(dir + "/plain.exr");
    EXPECT_FALSE(back.grid_rows);
    EXPECT_EQ(back.fps, 0.0);
    EXPECT_TRUE(back == animation);
}

TEST(VertexAnimation, ReadsFilesWithoutFlowvidAttributes) {
    const std::string dir = scratch_dir("vat_foreign");
    write_rgb_exr(dir + "/foreign.exr", 5, 3);
    std::vector<Problem> warnings;
    const VertexAnimation animation = read_vertex_animation(dir + "/foreign.exr", &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(animation.frame_count, 3);
    EXPECT_EQ(animation.vertex_count, 5);
    EXPECT_EQ(animation.position(2, 4), Eigen::Vector3f(4.0f + 1.0f, 4.0f + 1.0f + 0.25f, 4.0f + 1.0f + 0.5f));
    EXPECT_EQ(animation.fps, 0.0);
}

TEST(VertexAnimation, SummaryReportsSizeAndMotion) {
    VertexAnimation animation;
    animation.frame_count = 2;
    animation.vertex_count = 2;
    animation.fps = 10.0;
    animation.positions_m = {{0, 0, 0}, {1, 0, 0}, {0, 0, 0.5f}, {1, 2, 0}};
    const nlohmann::json summary = summarize_vertex_animation(animation);
    EXPECT_EQ(summary["frames"], 2);
    EXPECT_EQ(summary["vertices"], 2);
    EXPECT_DOUBLE_EQ(summary["duration_s"].get<double>(), 0.2);
    EXPECT_DOUBLE_EQ(summary["max_displacement_from_first_frame_m"].get<double>(), 2.0);
    EXPECT_DOUBLE_EQ(summary["bbox_max_m"][1].get<double>(), 2.0);
}

TEST(VertexAnimation, ExampleOfVersion1_0Loads) {
    // Kept forever: the fuzz seed written by the first writer (3 frames, 2 x 3 grid, 30 fps).
    std::vector<Problem> warnings;
    const VertexAnimation example =
        read_vertex_animation(source_path("fuzz/corpus/vertex_animation/grid_2x3_3frames.exr"), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(example.frame_count, 3);
    EXPECT_EQ(example.vertex_count, 6);
    EXPECT_EQ(example.grid_rows, 2);
    EXPECT_EQ(example.grid_cols, 3);
    EXPECT_EQ(example.fps, 30.0);
    for (int f = 0; f < 3; ++f)
        for (int v = 0; v < 6; ++v)
            EXPECT_EQ(example.position(f, v),
                      Eigen::Vector3f(0.1f * float(v % 3), 0.01f * float(f), 1.2f - 0.1f * float(v / 3)));
}

// ---- The captures' truth files ------------------------------------------------

TEST(VertexAnimationTruth, WavingCaptureTruthMatchesThePins) {
    const std::string folder = shared_path("captures/cloth-cotton-waving-1");
    if (!fs::exists(folder)) GTEST_SKIP() << "no ../shared/captures";
    const VertexAnimation truth = read_vertex_animation(folder + "/truth/positions.exr");
    EXPECT_EQ(truth.frame_count, 50);
    EXPECT_EQ(truth.vertex_count, 576);
    EXPECT_FALSE(truth.grid_rows);  // the file has no flowvid attributes
    EXPECT_EQ(truth.fps, 0.0);
    const Capture capture = read_capture(folder);
    ASSERT_TRUE(capture.swatch);
    // Pinned corners: uv (0,1) -> vertex 23*24 + 0, uv (1,1) -> 23*24 + 23.
    const int pinned[2] = {23 * 24 + 0, 23 * 24 + 23};
    for (int p = 0; p < 2; ++p) {
        ASSERT_EQ(capture.swatch->pins[static_cast<std::size_t>(p)].uv, Eigen::Vector2d(p, 1.0));
        for (int f = 0; f < truth.frame_count; ++f) {
            const Eigen::Vector3d expected = capture.swatch->pins[static_cast<std::size_t>(p)].positions_m[static_cast<std::size_t>(f)];
            EXPECT_LT((truth.position(f, pinned[p]).cast<double>() - expected).norm(), 1e-4) << "pin " << p << " frame " << f;
        }
    }
    // Plausible cloth: hangs below the pins (z = 1.2 m) by at most its height,
    // and neighbouring vertices are about 0.30 / 23 m apart.
    for (const Eigen::Vector3f& p : truth.positions_m) {
        EXPECT_GT(p.z(), 1.2f - 0.35f);
        EXPECT_LT(p.z(), 1.2f + 0.05f);
    }
    double edge_sum = 0.0;
    for (int c = 0; c + 1 < 24; ++c) edge_sum += (truth.position(0, c + 1) - truth.position(0, c)).norm();
    EXPECT_NEAR(edge_sum / 23.0, 0.30 / 23.0, 0.30 / 23.0 * 0.1);
}

TEST(VertexAnimationTruth, EveryClothCaptureHasReadableTruth) {
    if (!fs::exists(shared_path("captures"))) GTEST_SKIP() << "no ../shared/captures";
    int checked = 0;
    for (const auto& entry : fs::directory_iterator(shared_path("captures"))) {
        const std::string exr = (entry.path() / "truth/positions.exr").string();
        if (!fs::exists(exr)) continue;
        EXPECT_TRUE(validate_vertex_animation_file(exr, Strictness::strict).empty()) << exr;
        const Capture capture = read_capture(entry.path().string());
        const std::optional<VertexAnimation> truth = read_capture_truth_positions(capture);
        ASSERT_TRUE(truth) << exr;
        EXPECT_EQ(truth->frame_count, capture.frames.count) << exr;
        EXPECT_EQ(truth->vertex_count, 576) << exr;
        EXPECT_EQ(truth->grid_rows.value_or(0), 24) << exr;
        EXPECT_EQ(truth->grid_cols.value_or(0), 24) << exr;
        EXPECT_EQ(truth->fps, capture.fps) << exr;
        ++checked;
    }
    EXPECT_EQ(checked, 9);
}

// ---- Bad input ----------------------------------------------------------------

TEST(VertexAnimationBad, MissingFileAndNotAnExr) {
    const std::string dir = scratch_dir("vat_missing");
    EXPECT_THROW(read_vertex_animation(dir + "/none.exr"), IoError);
    write_text(dir + "/text.exr", "this is not an image");
    const std::string text = validation_messages([&] { read_vertex_animation(dir + "/text.exr"); });
    EXPECT_TRUE(mentions(text, "text.exr: not an OpenEXR file")) << text;
}

TEST(VertexAnimationBad, TruncatedFilesGiveClearErrors) {
    const std::string dir = scratch_dir("vat_truncated");
    // Uncompressed and compressed variants: truncation shows differently.
    write_rgb_exr(dir + "/plain.exr", 40, 10);
    write_vertex_animation(dir + "/zip.exr", sample_animation(10, 5, 8));
    for (const char* name : {"plain.exr", "zip.exr"}) {
        const std::string bytes = read_text(dir + "/" + name);
        for (std::size_t cut : {std::size_t(6), std::size_t(40), std::size_t(200), bytes.size() / 2, bytes.size() - 1}) {
            const std::string path = dir + "/cut.exr";
            write_text(path, bytes.substr(0, cut));
            const std::string text = validation_messages([&] { read_vertex_animation(path); });
            EXPECT_TRUE(mentions(text, "cut.exr: ")) << name << " cut at " << cut << ": " << text;
            EXPECT_TRUE(mentions(text, "header") || mentions(text, "pixels")) << name << " cut at " << cut << ": " << text;
            EXPECT_TRUE(mentions(text, "truncated") || mentions(text, "corrupt")) << text;
        }
    }
}

TEST(VertexAnimationBad, CorruptedBytesNeverCrash) {
    const std::string dir = scratch_dir("vat_corrupt");
    write_vertex_animation(dir + "/zip.exr", sample_animation(6, 4, 5));
    write_rgb_exr(dir + "/plain.exr", 20, 6);
    std::mt19937 random(2024);
    int refused = 0, total = 0;
    for (const char* name : {"zip.exr", "plain.exr"}) {
        const std::string good = read_text(dir + "/" + name);
        for (int trial = 0; trial < 300; ++trial) {
            std::string bytes = good;
            const int flips = 1 + int(random() % 6);
            for (int i = 0; i < flips; ++i) {
                const std::size_t at = random() % bytes.size();
                bytes[at] = static_cast<char>(random() % 3 == 0 ? 0xff : (bytes[at] ^ (1 << (random() % 8))));
            }
            ++total;
            // Every corruption is either read (flipped pixel bits can still be
            // valid floats) or refused with problems; nothing else escapes.
            std::vector<Problem> problems;
            ASSERT_NO_THROW(problems = validate_vertex_animation_bytes(bytes, name, Strictness::lenient));
            if (!errors_of(problems).empty()) ++refused;
            try {
                read_vertex_animation_from_memory(bytes, name);
            } catch (const ValidationError&) {
            }
        }
    }
    EXPECT_GT(refused, total / 10);  // the corruptions are not all harmless
}

TEST(VertexAnimationBad, NanValuesAreNamed) {
    const std::string dir = scratch_dir("vat_nan");
    write_raw_exr(dir + "/nan.exr", 6, 4, {"R", "G", "B"}, Imf::FLOAT, [](int x, int y, int c) {
        return (x == 5 && y == 2 && c == 1) || (x == 0 && y == 3) ? std::numeric_limits<float>::quiet_NaN() : 1.0f;
    });
    const std::string text = validation_messages([&] { read_vertex_animation(dir + "/nan.exr"); });
    EXPECT_TRUE(mentions(text, "nan.exr: pixels: 4 NaN or infinite value(s), the first at frame row 2, vertex 5, channel G"))
        << text;
    write_raw_exr(dir + "/inf.exr", 2, 2, {"R", "G", "B"}, Imf::FLOAT,
                  [](int, int, int c) { return c == 2 ? std::numeric_limits<float>::infinity() : 0.0f; });
    EXPECT_TRUE(mentions(validation_messages([&] { read_vertex_animation(dir + "/inf.exr"); }), "inf.exr: pixels: 4 NaN"));
}

TEST(VertexAnimationBad, WrongChannels) {
    const std::string dir = scratch_dir("vat_channels");
    write_raw_exr(dir + "/gray.exr", 4, 2, {"Y"}, Imf::FLOAT, [](int, int, int) { return 0.5f; });
    std::string text = validation_messages([&] { read_vertex_animation(dir + "/gray.exr"); });
    for (const char* channel : {"R", "G", "B"})
        EXPECT_TRUE(mentions(text, std::string("gray.exr: channel ") + channel + ": missing")) << text;
    write_raw_exr(dir + "/half.exr", 4, 2, {"R", "G", "B"}, Imf::HALF, [](int, int, int) { return 0.5f; });
    text = validation_messages([&] { read_vertex_animation(dir + "/half.exr"); });
    EXPECT_TRUE(mentions(text, "half.exr: channel R: is half, positions need float32")) << text;
    // An extra channel: a warning when reading, an error under strict validation.
    write_raw_exr(dir + "/rgba.exr", 4, 2, {"R", "G", "B", "A"}, Imf::FLOAT, [](int, int, int) { return 0.5f; });
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_vertex_animation(dir + "/rgba.exr", &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "channel A");
    EXPECT_TRUE(mentions(errors_of(validate_vertex_animation_file(dir + "/rgba.exr", Strictness::strict)),
                         "rgba.exr: channel A: extra channel"));
}

TEST(VertexAnimationBad, VersionsAndAttributes) {
    const std::string dir = scratch_dir("vat_versions");
    auto with = [&](const std::string& name, const std::function<void(Imf::Header&)>& edit) {
        write_rgb_exr(dir + "/" + name, 6, 2, edit);
        return dir + "/" + name;
    };
    std::string path = with("v2.exr", [](Imf::Header& h) {
        h.insert("flowvid.format", Imf::StringAttribute("flowvid.vertex_animation"));
        h.insert("flowvid.version", Imf::StringAttribute("2.0"));
    });
    std::string text = validation_messages([&] { read_vertex_animation(path); });
    EXPECT_TRUE(mentions(text, "v2.exr: attribute flowvid.version: version 2.0 is not supported")) << text;
    path = with("v1_4.exr", [](Imf::Header& h) {
        h.insert("flowvid.format", Imf::StringAttribute("flowvid.vertex_animation"));
        h.insert("flowvid.version", Imf::StringAttribute("1.4"));
    });
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_vertex_animation(path, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "attribute flowvid.version");
    path = with("bank.exr", [](Imf::Header& h) {
        h.insert("flowvid.format", Imf::StringAttribute("flowvid.particle_bank"));
        h.insert("flowvid.version", Imf::StringAttribute("1.0"));
    });
    text = validation_messages([&] { read_vertex_animation(path); });
    EXPECT_TRUE(mentions(text, "bank.exr: attribute flowvid.format: this is a \"flowvid.particle_bank\" file")) << text;
    path = with("grid.exr", [](Imf::Header& h) {
        h.insert("flowvid.grid_rows", Imf::IntAttribute(4));
        h.insert("flowvid.grid_cols", Imf::IntAttribute(2));
        h.insert("flowvid.fps", Imf::DoubleAttribute(-3.0));
    });
    text = validation_messages([&] { read_vertex_animation(path); });
    EXPECT_TRUE(mentions(text, "grid.exr: attribute flowvid.grid_rows: grid 4 x 2 = 8 vertices, but the image has 6 columns"))
        << text;
    EXPECT_TRUE(mentions(text, "grid.exr: attribute flowvid.fps: must be a finite number > 0")) << text;
}

TEST(VertexAnimationBad, ImplausibleSizeIsRefusedBeforeAllocating) {
    const std::string dir = scratch_dir("vat_huge");
    write_rgb_exr(dir + "/small.exr", 4, 2);
    std::string bytes = read_text(dir + "/small.exr");
    // Patch the dataWindow's max.x to 2^30 - 1 vertices.
    const std::size_t at = bytes.find("dataWindow");
    ASSERT_NE(at, std::string::npos);
    const std::size_t value = at + std::strlen("dataWindow") + 1 + std::strlen("box2i") + 1 + 4;
    const std::int32_t huge = (1 << 30) - 1;
    std::memcpy(&bytes[value + 8], &huge, 4);
    const std::vector<Problem> problems = validate_vertex_animation_bytes(bytes, "huge.exr", Strictness::lenient);
    EXPECT_TRUE(mentions(errors_of(problems), "huge.exr: data window: the header declares"))
        << errors_of(problems);
}

TEST(VertexAnimationBad, WriterValidatesFirstAndKeepsTheOldFile) {
    const std::string dir = scratch_dir("vat_writer");
    const std::string path = dir + "/anim.exr";
    write_vertex_animation(path, sample_animation(2, 2, 2));
    const std::string before = read_text(path);
    VertexAnimation bad = sample_animation(2, 2, 2);
    bad.positions_m[5].y() = std::numeric_limits<float>::quiet_NaN();
    std::string text = validation_messages([&] { write_vertex_animation(path, bad); });
    EXPECT_TRUE(mentions(text, "anim.exr: positions_m: 1 NaN or infinite value(s), the first at frame row 1, vertex 1, channel G"))
        << text;
    bad = sample_animation(2, 2, 2);
    bad.positions_m.pop_back();
    bad.grid_cols = 3;
    text = validation_messages([&] { write_vertex_animation(path, bad); });
    EXPECT_TRUE(mentions(text, "anim.exr: positions_m: holds 7 positions")) << text;
    EXPECT_TRUE(mentions(text, "anim.exr: grid_rows: grid 2 x 3 does not have vertex_count = 4 vertices")) << text;
    EXPECT_EQ(read_text(path), before);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
    EXPECT_THROW(write_vertex_animation(dir + "/no/such/folder/a.exr", sample_animation(1, 1, 1)), IoError);
}
