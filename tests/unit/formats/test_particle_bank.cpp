#include "flowvid/formats/particle_bank.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputPart.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfRgbaFile.h>
#include <ImfStringAttribute.h>
#include <ImfStringVectorAttribute.h>
#include <half.h>

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
using flowvid::testing::test_data;
using flowvid::testing::validation_messages;
using flowvid::testing::write_text;

namespace {

using flowvid::testing::mentions;

std::string example_path() { return source_path("formats/examples/example.bank.exr"); }
std::string example_1_0_path() { return source_path("formats/examples/example-1.0.bank.exr"); }

// The camera of the recipe (1.1): drifting right and up by half a pixel a
// frame and turning slightly, tracked in the view of frame 6.
BankCamera example_camera(int frames) {
    BankCamera camera;
    camera.model = BankCameraModel::affine;
    camera.view_frame = 6;
    for (int f = 0; f < frames; ++f)
        camera.first_to_frame.push_back({1.0f + 0.001f * f, -0.002f * f, 0.5f * f, 0.002f * f, 1.0f + 0.001f * f, -0.25f * f});
    camera.largest_offset_px = 6.4f;
    camera.worst_correlation = 0.95f;
    return camera;
}

// The recipe of formats/examples/example.bank.exr (and, without its camera,
// of example-1.0.bank.exr): two falling-water lines,
// six particles entering every second frame, accelerating like water under
// gravity (s = 2.25 + 4 t + 0.75 t^2 px), each a soft bright blob that drifts
// down its patch and turns whiter as it falls; a drifting camera.
// Deterministic, so the kept examples can be compared with it forever.
ParticleBank make_example_bank() {
    ParticleBank bank;
    bank.patch_size_px = 8;
    bank.fps = 24.0;
    bank.clip_width_px = 64;
    bank.clip_height_px = 96;
    bank.clip_frame_count = 12;
    bank.source_clip = "synthetic example (tests/unit/formats/test_particle_bank.cpp, make_example_bank)";
    bank.dynamics = ParticleDynamics::stationary;
    bank.lines = {{"fall_left", 80.0f}, {"fall_right", 72.5f}};
    const int ps = bank.patch_size_px;
    for (int p = 0; p < 6; ++p) {
        TrackedParticle particle;
        particle.line_id = bank.lines[p % 2].id;
        particle.start_frame = 2 * p;
        const int life = std::min(6, bank.clip_frame_count - particle.start_frame);
        for (int t = 0; t < life; ++t) {
            particle.arc_length_px.push_back(2.25f + 4.0f * t + 0.75f * t * t + 0.1f * (p % 2));
            for (int y = 0; y < ps; ++y)
                for (int x = 0; x < ps; ++x) {
                    const float dx = x - 3.5f, dy = y - 3.5f - 0.3f * t;
                    const float blob = std::exp(-(dx * dx + dy * dy) / 8.0f);
                    const float foam = 0.1f * t;
                    particle.texture_rgba.push_back(0.15f + 0.6f * blob + foam);
                    particle.texture_rgba.push_back(0.35f + 0.5f * blob + foam);
                    particle.texture_rgba.push_back(0.7f + 0.25f * blob + 0.5f * foam);
                    particle.texture_rgba.push_back(1.0f);
                }
        }
        bank.particles.push_back(particle);
    }
    bank.camera = example_camera(bank.clip_frame_count);
    return bank;
}

ParticleBank without_camera(ParticleBank bank) {
    bank.camera.reset();
    return bank;
}

float as_half(float value) { return static_cast<float>(half(value)); }

// What a bank looks like after a trip through half: positions unchanged,
// texture rounded to the nearest half.
ParticleBank half_rounded(ParticleBank bank) {
    for (TrackedParticle& particle : bank.particles)
        for (float& v : particle.texture_rgba) v = as_half(v);
    return bank;
}

// The raw content of a bank file, to build damaged or foreign variants with
// OpenEXR directly (the library's writer refuses to write them).
struct RawBank {
    std::vector<Imf::Header> headers;
    std::vector<half> rgba;        // patches part, interleaved RGBA
    std::vector<float> arc;        // motion part
    std::vector<unsigned> line;
};

RawBank read_raw(const std::string& path) {
    Imf::MultiPartInputFile file(path.c_str());
    RawBank raw;
    for (int i = 0; i < file.parts(); ++i) raw.headers.push_back(file.header(i));
    {
        Imf::InputPart part(file, 0);
        const Imath::Box2i dw = part.header().dataWindow();
        const std::size_t w = dw.max.x + 1, h = dw.max.y + 1;
        raw.rgba.resize(w * h * 4);
        Imf::FrameBuffer fb;
        const char* names[4] = {"R", "G", "B", "A"};
        for (int c = 0; c < 4; ++c)
            fb.insert(names[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(raw.rgba.data() + c), 8, w * 8));
        part.setFrameBuffer(fb);
        part.readPixels(0, dw.max.y);
    }
    {
        Imf::InputPart part(file, 1);
        const Imath::Box2i dw = part.header().dataWindow();
        const std::size_t w = dw.max.x + 1, h = dw.max.y + 1;
        raw.arc.resize(w * h);
        raw.line.resize(w * h);
        Imf::FrameBuffer fb;
        fb.insert("arc_length_px.V", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(raw.arc.data()), 4, w * 4));
        fb.insert("line.V", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(raw.line.data()), 4, w * 4));
        part.setFrameBuffer(fb);
        part.readPixels(0, dw.max.y);
    }
    return raw;
}

void write_raw(const std::string& path, const RawBank& raw) {
    Imf::MultiPartOutputFile file(path.c_str(), raw.headers.data(), static_cast<int>(raw.headers.size()));
    {
        Imf::OutputPart part(file, 0);
        const Imath::Box2i dw = part.header().dataWindow();
        const std::size_t w = dw.max.x + 1;
        Imf::FrameBuffer fb;
        const char* names[4] = {"R", "G", "B", "A"};
        for (int c = 0; c < 4; ++c)
            fb.insert(names[c], Imf::Slice(Imf::HALF, const_cast<char*>(reinterpret_cast<const char*>(raw.rgba.data() + c)), 8, w * 8));
        part.setFrameBuffer(fb);
        part.writePixels(dw.max.y + 1);
    }
    {
        Imf::OutputPart part(file, 1);
        const Imath::Box2i dw = part.header().dataWindow();
        const std::size_t w = dw.max.x + 1;
        Imf::FrameBuffer fb;
        fb.insert("arc_length_px.V", Imf::Slice(Imf::FLOAT, const_cast<char*>(reinterpret_cast<const char*>(raw.arc.data())), 4, w * 4));
        fb.insert("line.V", Imf::Slice(Imf::UINT, const_cast<char*>(reinterpret_cast<const char*>(raw.line.data())), 4, w * 4));
        part.setFrameBuffer(fb);
        part.writePixels(dw.max.y + 1);
    }
}

// Writes the example bank, lets `edit` change its raw content, writes the
// result to dir/name and returns its path.
std::string edited_bank(const std::string& dir, const std::string& name, const std::function<void(RawBank&)>& edit) {
    const std::string good = dir + "/good_" + name;
    write_particle_bank(good, make_example_bank());
    RawBank raw = read_raw(good);
    edit(raw);
    const std::string path = dir + "/" + name;
    write_raw(path, raw);
    return path;
}

std::string bytes_of(const std::string& path) { return read_text(path); }

std::string write_bytes(const std::string& path, const std::string& bytes) {
    write_text(path, bytes);
    return path;
}

// Offset of the first pixel chunk: walks the attributes of every part header
// (name, type, size, value) to the end of the headers, where the chunk offset
// tables begin; the first entry points at the first chunk written.
std::size_t first_data_byte(const std::string& bytes) {
    std::size_t at = 8;  // magic number and version field
    auto read_cstring = [&]() {
        const std::size_t end = bytes.find('\0', at);
        std::string text = bytes.substr(at, end - at);
        at = end + 1;
        return text;
    };
    while (at < bytes.size() && bytes[at] != '\0') {  // one part header per iteration
        while (at < bytes.size()) {
            const std::string name = read_cstring();
            if (name.empty()) break;
            read_cstring();  // type
            std::int32_t size;
            std::memcpy(&size, bytes.data() + at, 4);
            at += 4 + static_cast<std::size_t>(size);
        }
    }
    std::uint64_t first_chunk;
    std::memcpy(&first_chunk, bytes.data() + at + 1, 8);
    return static_cast<std::size_t>(first_chunk);
}

void plain_rgba_exr(const std::string& path) {
    const int w = 4, h = 3;
    std::vector<Imf::Rgba> pixels(w * h, Imf::Rgba(0.5f, 0.25f, 0.125f, 1.0f));
    Imf::RgbaOutputFile file(path.c_str(), w, h, Imf::WRITE_RGBA);
    file.setFrameBuffer(pixels.data(), 1, w);
    file.writePixels(h);
}

// Rewrites the kept example files from the recipe (run once per format
// version, with FLOWVID_REGENERATE_EXAMPLES=1; see formats/specs/particle_bank.md).
void regenerate_kept_files() {
    const ParticleBank bank = make_example_bank();
    write_particle_bank(source_path("formats/examples/example.bank.exr"), bank);
    const std::string corpus = source_path("fuzz/corpus/particle_bank");
    const std::string data = source_path("tests/data/formats/bank");
    fs::create_directories(corpus);
    fs::create_directories(data);
    const std::string valid = bytes_of(example_path());
    write_bytes(corpus + "/valid.bank.exr", valid);
    write_bytes(corpus + "/truncated.bank.exr", valid.substr(0, valid.size() / 2));
    std::string header_flipped = valid;
    header_flipped[valid.find("dataWindow") + 30] ^= 0x40;  // inside the patches part's data window
    write_bytes(corpus + "/header_flipped.bank.exr", header_flipped);
    std::string data_flipped = valid;
    for (std::size_t i = first_data_byte(valid) + 200; i < valid.size(); i += 97) data_flipped[i] ^= 0x5a;
    write_bytes(corpus + "/data_flipped.bank.exr", data_flipped);
    plain_rgba_exr(data + "/plain_rgba.exr");
    const std::string scratch = scratch_dir("bank_regenerate");
    fs::copy_file(edited_bank(scratch, "v2.bank.exr",
                              [](RawBank& raw) { raw.headers[0].insert("flowvid.version", Imf::StringAttribute("2.0")); }),
                  data + "/version_2_0.bank.exr", fs::copy_options::overwrite_existing);
}

}  // namespace

TEST(ParticleBank, RegenerateKeptFilesWhenAsked) {
    if (!std::getenv("FLOWVID_REGENERATE_EXAMPLES")) GTEST_SKIP() << "set FLOWVID_REGENERATE_EXAMPLES=1 to rewrite them";
    regenerate_kept_files();
}

TEST(ParticleBank, ExampleOfVersion1_0LoadsAndMatchesItsRecipe) {
    // Written by 1.0 and kept as it was: no camera (readers estimate it again).
    std::vector<Problem> warnings;
    const ParticleBank old = read_particle_bank(example_1_0_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_FALSE(old.camera.has_value());
    EXPECT_EQ(old, half_rounded(without_camera(make_example_bank())));
    EXPECT_TRUE(validate_particle_bank_file(example_1_0_path(), Strictness::strict).empty());
}

TEST(ParticleBank, ExampleOfVersion1_1LoadsAndMatchesItsRecipe) {
    std::vector<Problem> warnings;
    const ParticleBank bank = read_particle_bank(example_path(), &warnings);
    EXPECT_TRUE(warnings.empty());
    EXPECT_EQ(bank, half_rounded(make_example_bank()));
    ASSERT_TRUE(bank.camera.has_value());
    EXPECT_EQ(bank.camera->first_to_frame.size(), 12u);
    EXPECT_EQ(bank.camera->first_to_frame[11][2], 5.5f);  // floats, bit for bit
    EXPECT_EQ(bank.particles.size(), 6u);
    EXPECT_EQ(bank.particles[5].life_frames(), 2);
    EXPECT_EQ(bank.particles[5].start_frame, 10);
    EXPECT_EQ(bank.particles[3].line_id, "fall_right");
    EXPECT_LT(fs::file_size(example_path()), 16u * 1024u) << "keep the example small";
}

TEST(ParticleBank, RoundTripIsBitExactForPositionsAndHalfExactForTextures) {
    const std::string dir = scratch_dir("bank_round_trip");
    ParticleBank bank = make_example_bank();
    bank.dynamics = ParticleDynamics::non_stationary;
    // Positions with every mantissa bit used, textures that are not halves.
    std::mt19937 random(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (TrackedParticle& particle : bank.particles) {
        for (float& s : particle.arc_length_px) s = std::nextafter(s * 0.999f + unit(random) * 1e-3f, 100.0f);
        for (float& v : particle.texture_rgba) v = unit(random) * 3.0f - 0.5f;
    }
    const std::string path = dir + "/round.bank.exr";
    write_particle_bank(path, bank);
    const ParticleBank reread = read_particle_bank(path);
    ASSERT_EQ(reread.particles.size(), bank.particles.size());
    for (std::size_t p = 0; p < bank.particles.size(); ++p) {
        const TrackedParticle& a = bank.particles[p];
        const TrackedParticle& b = reread.particles[p];
        EXPECT_EQ(b.line_id, a.line_id);
        EXPECT_EQ(b.start_frame, a.start_frame);
        ASSERT_EQ(b.arc_length_px.size(), a.arc_length_px.size());
        EXPECT_EQ(std::memcmp(a.arc_length_px.data(), b.arc_length_px.data(), a.arc_length_px.size() * sizeof(float)), 0)
            << "positions must be bit-exact (float32 as stored), particle " << p;
        ASSERT_EQ(b.texture_rgba.size(), a.texture_rgba.size());
        for (std::size_t i = 0; i < a.texture_rgba.size(); ++i)
            ASSERT_EQ(b.texture_rgba[i], as_half(a.texture_rgba[i])) << "particle " << p << " value " << i;
    }
    EXPECT_EQ(reread, half_rounded(bank));
    // Writing what was read gives the same bytes (the writer is deterministic).
    const std::string again = dir + "/again.bank.exr";
    write_particle_bank(again, reread);
    EXPECT_EQ(bytes_of(again), bytes_of(path));
}

TEST(ParticleBank, HeaderAndLayoutDescribeTheBank) {
    Imf::MultiPartInputFile file(example_path().c_str());
    ASSERT_EQ(file.parts(), 2);
    const Imf::Header& patches = file.header(0);
    const Imf::Header& motion = file.header(1);
    EXPECT_EQ(patches.name(), "patches");
    EXPECT_EQ(motion.name(), "motion");
    EXPECT_EQ(patches.typedAttribute<Imf::StringAttribute>("flowvid.format").value(), "flowvid.particle_bank");
    EXPECT_EQ(patches.typedAttribute<Imf::StringAttribute>("flowvid.version").value(), "1.1");
    EXPECT_EQ(patches.typedAttribute<Imf::StringAttribute>("flowvid.camera_model").value(), "affine");
    EXPECT_EQ(patches.typedAttribute<Imf::IntAttribute>("flowvid.camera_view_frame").value(), 6);
    EXPECT_EQ(patches.typedAttribute<Imf::FloatVectorAttribute>("flowvid.camera_first_to_frame_px").value().size(), 12u * 6u);
    EXPECT_EQ(patches.typedAttribute<Imf::IntAttribute>("flowvid.patch_size_px").value(), 8);
    EXPECT_EQ(patches.typedAttribute<Imf::IntAttribute>("flowvid.particle_count").value(), 6);
    EXPECT_EQ(patches.typedAttribute<Imf::IntAttribute>("flowvid.clip_frame_count").value(), 12);
    EXPECT_EQ(patches.typedAttribute<Imf::StringVectorAttribute>("flowvid.line_ids").value(),
              (std::vector<std::string>{"fall_left", "fall_right"}));
    EXPECT_EQ(patches.typedAttribute<Imf::FloatVectorAttribute>("flowvid.line_lengths_px").value(),
              (std::vector<float>{80.0f, 72.5f}));
    // Atlas: 12 frames x 8 px wide, 6 particles x 8 px high, half RGBA.
    EXPECT_EQ(patches.dataWindow().max, Imath::V2i(95, 47));
    for (const char* c : {"R", "G", "B", "A"}) EXPECT_EQ(patches.channels()[c].type, Imf::HALF) << c;
    EXPECT_EQ(motion.dataWindow().max, Imath::V2i(11, 5));
    EXPECT_EQ(motion.channels()["arc_length_px.V"].type, Imf::FLOAT);
    EXPECT_EQ(motion.channels()["line.V"].type, Imf::UINT);
    // Blender's multilayer reader takes only channel names whose last token is
    // one letter ("R", "line.V") and refuses the whole file otherwise.
    for (const Imf::Header* header : {&patches, &motion})
        for (auto it = header->channels().begin(); it != header->channels().end(); ++it) {
            const std::string name = it.name();
            const std::size_t dot = name.rfind('.');
            EXPECT_EQ(name.size() - (dot == std::string::npos ? 0 : dot + 1), 1u) << name;
        }

    // Particle 2 (line fall_left) starts at frame 4: its first patch sits at
    // column 4; before it the row is transparent.
    const RawBank raw = read_raw(example_path());
    const ParticleBank bank = make_example_bank();
    const std::size_t w = 96;
    auto pixel = [&](int x, int y, int c) { return static_cast<float>(raw.rgba[(y * w + x) * 4 + c]); };
    const int x0 = 4 * 8, y0 = 2 * 8;
    for (int c = 0; c < 4; ++c) {
        EXPECT_EQ(pixel(x0 + 3, y0 + 5, c), as_half(bank.particles[2].texture_rgba[(5 * 8 + 3) * 4 + c])) << c;
        EXPECT_EQ(pixel(x0 - 1, y0 + 5, c), 0.0f) << "transparent before the particle is born";
    }
    EXPECT_EQ(raw.line[2 * 12 + 4], 1u);  // 1 + index of fall_left
    EXPECT_EQ(raw.line[2 * 12 + 3], 0u);
    EXPECT_EQ(raw.arc[2 * 12 + 5], bank.particles[2].arc_length_px[1]);
}

TEST(ParticleBank, OpensInOiiotoolWithTwoNamedSubimages) {
    if (std::system("oiiotool --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "oiiotool is not installed";
    const std::string dir = scratch_dir("bank_oiiotool");
    const std::string out = dir + "/info.txt";
    const std::string command = "oiiotool --info -v -a \"" + example_path() + "\" > \"" + out + "\" 2>&1";
    ASSERT_EQ(std::system(command.c_str()), 0) << read_text(out);
    std::string info_spaced = read_text(out), info;
    for (char c : info_spaced)  // oiiotool aligns sizes with runs of spaces
        if (c != ' ' || info.empty() || info.back() != ' ') info += c;
    EXPECT_TRUE(mentions(info, "subimage 0: 96 x 48, 4 channel, half")) << info;
    EXPECT_TRUE(mentions(info, "subimage 1: 12 x 6, 2 channel, float/uint")) << info;
    EXPECT_TRUE(mentions(info, "name: \"patches\"")) << info;
    EXPECT_TRUE(mentions(info, "name: \"motion\"")) << info;
    EXPECT_TRUE(mentions(info, "flowvid.format: \"flowvid.particle_bank\"")) << info;
    EXPECT_TRUE(mentions(info, "flowvid.version: \"1.1\"")) << info;
    EXPECT_TRUE(mentions(info, "arc_length_px.V")) << info;
}

TEST(ParticleBank, WriterRefusesInvalidBanksAndKeepsThePreviousFile) {
    const std::string dir = scratch_dir("bank_writer_refuses");
    const std::string path = dir + "/bank.exr";
    write_particle_bank(path, make_example_bank());
    const std::string before = bytes_of(path);

    ParticleBank bank = make_example_bank();
    bank.particles[1].arc_length_px[2] = std::numeric_limits<float>::quiet_NaN();
    bank.particles[2].line_id = "no_such_line";
    bank.particles[3].start_frame = 9;  // lives 6 frames: past the 12-frame clip
    bank.particles[4].texture_rgba.pop_back();
    bank.particles[0].texture_rgba[5] = 1e6f;  // beyond half
    bank.lines.push_back({"fall_left", 10.0f});
    bank.fps = 0.0;
    const std::string messages = validation_messages([&] { write_particle_bank(path, bank); });
    EXPECT_TRUE(mentions(messages, path)) << messages;
    EXPECT_TRUE(mentions(messages, "particles[1].arc_length_px: frame of life 2 has value nan")) << messages;
    EXPECT_TRUE(mentions(messages, "particles[2].line_id: unknown line \"no_such_line\"")) << messages;
    EXPECT_TRUE(mentions(messages, "particles[3].arc_length_px: the particle lives until frame 14")) << messages;
    EXPECT_TRUE(mentions(messages, "particles[4].texture_rgba: texture holds")) << messages;
    EXPECT_TRUE(mentions(messages, "particles[0].texture_rgba: frame of life 0 has value 1000000")) << messages;
    EXPECT_TRUE(mentions(messages, "lines[2].id: line id \"fall_left\" appears twice")) << messages;
    EXPECT_TRUE(mentions(messages, "fps: frame rate")) << messages;
    EXPECT_EQ(bytes_of(path), before) << "a refused write must not touch the previous file";
    for (const auto& entry : fs::directory_iterator(dir))
        EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();

    ParticleBank empty = make_example_bank();
    empty.particles.clear();
    EXPECT_TRUE(mentions(validation_messages([&] { write_particle_bank(path, empty); }), "particles: the bank holds no particle"));
}

TEST(ParticleBank, TruncatedFilesAreRefusedNamingFileAndPart) {
    const std::string dir = scratch_dir("bank_truncated");
    const std::string valid = bytes_of(example_path());
    // Cut in half (inside the pixel data), inside the headers, and just before the end.
    const std::size_t data_start = first_data_byte(valid);
    struct Cut { std::size_t size; const char* expected; };
    for (const Cut& cut : {Cut{valid.size() / 2, "part \""}, Cut{data_start / 2, "header"},
                           Cut{valid.size() - 3, "part \""}, Cut{3, "not an OpenEXR file"}}) {
        const std::string path = write_bytes(dir + "/cut_" + std::to_string(cut.size) + ".bank.exr", valid.substr(0, cut.size));
        const std::string messages = validation_messages([&] { read_particle_bank(path); });
        EXPECT_TRUE(mentions(messages, path)) << messages;
        EXPECT_TRUE(mentions(messages, cut.expected)) << "cut at " << cut.size << ": " << messages;
        EXPECT_FALSE(validate_particle_bank_file(path, Strictness::strict).empty());
    }
    // The kept corpus file: cut in half.
    const std::string messages =
        validation_messages([&] { read_particle_bank(source_path("fuzz/corpus/particle_bank/truncated.bank.exr")); });
    EXPECT_TRUE(mentions(messages, "truncated.bank.exr")) << messages;
}

TEST(ParticleBank, FlippedBytesAreRefusedNamingFileAndPart) {
    const std::string header_path = source_path("fuzz/corpus/particle_bank/header_flipped.bank.exr");
    std::string messages = validation_messages([&] { read_particle_bank(header_path); });
    EXPECT_TRUE(mentions(messages, header_path)) << messages;
    EXPECT_TRUE(mentions(messages, "part \"patches\" dataWindow") || mentions(messages, "header")) << messages;

    const std::string data_path = source_path("fuzz/corpus/particle_bank/data_flipped.bank.exr");
    messages = validation_messages([&] { read_particle_bank(data_path); });
    EXPECT_TRUE(mentions(messages, data_path)) << messages;
    EXPECT_TRUE(mentions(messages, "part \"patches\"") || mentions(messages, "part \"motion\"")) << messages;
}

TEST(ParticleBank, RandomDamageNeverCrashesOrEscapes) {
    // A small in-test fuzz run (the fuzz replay does more): every damaged copy
    // is either refused with problems naming the file, or still a valid bank.
    const std::string dir = scratch_dir("bank_random_damage");
    const std::string valid = bytes_of(example_path());
    std::mt19937 random(2026);
    int refused = 0;
    for (int i = 0; i < 300; ++i) {
        std::string bytes = valid;
        const int edits = 1 + static_cast<int>(random() % 3);
        for (int e = 0; e < edits; ++e) {
            if (random() % 4 == 0) bytes.resize(random() % bytes.size());
            else if (!bytes.empty()) bytes[random() % bytes.size()] ^= static_cast<char>(1 + random() % 255);
        }
        const std::string path = write_bytes(dir + "/damaged.bank.exr", bytes);
        std::vector<Problem> problems;
        ASSERT_NO_THROW(problems = validate_particle_bank_file(path, Strictness::lenient)) << "mutation " << i;
        bool has_error = false;
        for (const Problem& problem : problems) {
            EXPECT_EQ(problem.file, path);
            has_error = has_error || problem.severity == Problem::Severity::error;
        }
        if (has_error) ++refused;
        else EXPECT_NO_THROW(read_particle_bank(path)) << "mutation " << i;
    }
    EXPECT_GT(refused, 150) << "most damage must be detected";
}

TEST(ParticleBank, WrongFormatAndVersionsAreJudgedByTheirAttribute) {
    const std::string dir = scratch_dir("bank_versions");
    const std::string other = edited_bank(dir, "other.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.format", Imf::StringAttribute("flowvid.vertex_animation"));
    });
    std::string messages = validation_messages([&] { read_particle_bank(other); });
    EXPECT_TRUE(mentions(messages, other + ": part \"patches\" attribute \"flowvid.format\": this is a \"flowvid.vertex_animation\" file"))
        << messages;

    const std::string v2 = test_data("formats/bank/version_2_0.bank.exr");
    messages = validation_messages([&] { read_particle_bank(v2); });
    EXPECT_TRUE(mentions(messages, v2 + ": part \"patches\" attribute \"flowvid.version\": version 2.0 is not supported"))
        << messages;

    const std::string v11 = edited_bank(dir, "v12.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.version", Imf::StringAttribute("1.2"));
        raw.headers[0].insert("flowvid.future_thing", Imf::IntAttribute(3));
    });
    std::vector<Problem> warnings;
    const ParticleBank bank = read_particle_bank(v11, &warnings);
    EXPECT_EQ(bank, half_rounded(make_example_bank()));
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0].field, "part \"patches\" attribute \"flowvid.version\"");
    EXPECT_TRUE(mentions(warnings[0].message, "newer than 1.1"));
    EXPECT_EQ(warnings[1].field, "part \"patches\" attribute \"flowvid.future_thing\"");
    // `flowvid validate` is strict: the unknown attribute becomes an error.
    const std::vector<Problem> strict = validate_particle_bank_file(v11, Strictness::strict);
    bool unknown_is_error = false;
    for (const Problem& p : strict)
        unknown_is_error = unknown_is_error || (p.severity == Problem::Severity::error && mentions(p.field, "future_thing"));
    EXPECT_TRUE(unknown_is_error);

    const std::string garbled = edited_bank(dir, "garbled.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.version", Imf::StringAttribute("one"));
    });
    EXPECT_TRUE(mentions(validation_messages([&] { read_particle_bank(garbled); }), "\"one\" is not MAJOR.MINOR"));
}

TEST(ParticleBank, TheCameraRoundTripsAndAStillOneHasNoMaps) {
    const std::string dir = scratch_dir("bank_camera");
    for (const BankCameraModel model : {BankCameraModel::still, BankCameraModel::translation, BankCameraModel::affine}) {
        ParticleBank bank = make_example_bank();
        if (model == BankCameraModel::still) {
            bank.camera = BankCamera();
            bank.camera->untrusted = true;  // the firelight case: frames as filmed
            bank.camera->largest_offset_px = 3.25f;
            bank.camera->worst_correlation = 0.5f;
        } else
            bank.camera->model = model;
        const std::string path = dir + "/" + to_string(model) + ".bank.exr";
        write_particle_bank(path, bank);
        const ParticleBank reread = read_particle_bank(path);
        EXPECT_EQ(reread, half_rounded(bank)) << to_string(model);
        EXPECT_TRUE(validate_particle_bank_file(path, Strictness::strict).empty()) << to_string(model);
    }
    // A bank written without a camera reads as one (a 1.0 bank's content).
    write_particle_bank(dir + "/none.bank.exr", without_camera(make_example_bank()));
    EXPECT_FALSE(read_particle_bank(dir + "/none.bank.exr").camera.has_value());
    const nlohmann::json summary = summarize_particle_bank(read_particle_bank(example_path()));
    EXPECT_EQ(summary["camera"]["model"], "affine");
    EXPECT_EQ(summary["camera"]["view_frame"], 6);
}

TEST(ParticleBank, ACameraThatCannotBeTheClipsIsRefusedNamingTheAttribute) {
    const std::string dir = scratch_dir("bank_bad_camera");
    const auto attribute = [](const std::string& name) { return "part \"patches\" attribute \"flowvid." + name + "\""; };
    const std::string short_maps = edited_bank(dir, "short.exr", [](RawBank& raw) {
        std::vector<float> maps = raw.headers[0].typedAttribute<Imf::FloatVectorAttribute>("flowvid.camera_first_to_frame_px").value();
        maps.resize(maps.size() - 6);
        raw.headers[0].insert("flowvid.camera_first_to_frame_px", Imf::FloatVectorAttribute(maps));
    });
    std::string messages = validation_messages([&] { read_particle_bank(short_maps); });
    EXPECT_TRUE(mentions(messages, short_maps + ": " + attribute("camera_first_to_frame_px") + ": 11 maps for 12 source frames"))
        << messages;

    const std::string ragged = edited_bank(dir, "ragged.exr", [](RawBank& raw) {
        std::vector<float> maps = raw.headers[0].typedAttribute<Imf::FloatVectorAttribute>("flowvid.camera_first_to_frame_px").value();
        maps.pop_back();
        raw.headers[0].insert("flowvid.camera_first_to_frame_px", Imf::FloatVectorAttribute(maps));
    });
    EXPECT_TRUE(mentions(validation_messages([&] { read_particle_bank(ragged); }), "71 values are not whole maps of 6"));

    const std::string flipped = edited_bank(dir, "flipped.exr", [](RawBank& raw) {
        std::vector<float> maps = raw.headers[0].typedAttribute<Imf::FloatVectorAttribute>("flowvid.camera_first_to_frame_px").value();
        maps[3 * 6 + 0] = -1.0f;  // frame 3 mirrored
        raw.headers[0].insert("flowvid.camera_first_to_frame_px", Imf::FloatVectorAttribute(maps));
    });
    messages = validation_messages([&] { read_particle_bank(flipped); });
    EXPECT_TRUE(mentions(messages, attribute("camera_first_to_frame_px") + ": map of frame 3 flips or collapses")) << messages;

    const std::string partial = edited_bank(dir, "partial.exr", [](RawBank& raw) {
        raw.headers[0].erase("flowvid.camera_view_frame");
        raw.headers[0].insert("flowvid.camera_model", Imf::StringAttribute("zoom"));
    });
    messages = validation_messages([&] { read_particle_bank(partial); });
    EXPECT_TRUE(mentions(messages, attribute("camera_view_frame") + ": missing while other flowvid.camera_* attributes are present"))
        << messages;
    EXPECT_TRUE(mentions(messages, "remove every flowvid.camera_* attribute")) << messages;

    const std::string model = edited_bank(dir, "model.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.camera_model", Imf::StringAttribute("zoom"));
        raw.headers[0].insert("flowvid.camera_view_frame", Imf::IntAttribute(12));
    });
    messages = validation_messages([&] { read_particle_bank(model); });
    EXPECT_TRUE(mentions(messages, attribute("camera_model") + ": unknown camera model \"zoom\"")) << messages;

    const std::string view = edited_bank(dir, "view.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.camera_view_frame", Imf::IntAttribute(12));
        raw.headers[0].insert("flowvid.camera_worst_correlation", Imf::FloatAttribute(1.5f));
    });
    messages = validation_messages([&] { read_particle_bank(view); });
    EXPECT_TRUE(mentions(messages, attribute("camera_view_frame") + ": view frame 12 is outside the clip (0..11)")) << messages;
    EXPECT_TRUE(mentions(messages, attribute("camera_worst_correlation") + ": correlation 1.5")) << messages;

    // The writer names the struct's members.
    ParticleBank bank = make_example_bank();
    bank.camera->first_to_frame.pop_back();
    bank.camera->untrusted = true;
    messages = validation_messages([&] { write_particle_bank(dir + "/refused.bank.exr", bank); });
    EXPECT_TRUE(mentions(messages, "camera.first_to_frame: 11 maps for 12 source frames")) << messages;
    EXPECT_TRUE(mentions(messages, "camera.untrusted: an untrusted estimate with the moving model \"affine\"")) << messages;
    EXPECT_FALSE(fs::exists(dir + "/refused.bank.exr"));
}

TEST(ParticleBank, PlainRgbaExrIsNotABank) {
    const std::string path = test_data("formats/bank/plain_rgba.exr");
    const std::string messages = validation_messages([&] { read_particle_bank(path); });
    EXPECT_TRUE(mentions(messages, path + ": part \"patches\" attribute \"flowvid.format\": not a flowvid particle bank"))
        << messages;
    const std::string text = scratch_dir("bank_text") + "/notes.exr";
    write_text(text, "this is not an image at all");
    EXPECT_TRUE(mentions(validation_messages([&] { read_particle_bank(text); }), "not an OpenEXR file"));
}

TEST(ParticleBank, BadValuesInTheFileAreReportedAllAtOnce) {
    const std::string dir = scratch_dir("bank_bad_values");
    const std::string path = edited_bank(dir, "bad.exr", [](RawBank& raw) {
        raw.arc[1 * 12 + 4] = std::numeric_limits<float>::quiet_NaN();  // particle 1, frame 4 (its 3rd)
        raw.arc[3 * 12 + 7] = 500.0f;                                    // particle 3: beyond its 72.5 px line
        raw.rgba[(2 * 8 * 96 + 5 * 8) * 4] = half(std::numeric_limits<float>::infinity());  // particle 2 texture
    });
    const std::string messages = validation_messages([&] { read_particle_bank(path); });
    EXPECT_TRUE(mentions(messages, path + ": part \"motion\" channel \"arc_length_px.V\" row 1 (particle 1): frame of life 2 has value nan"))
        << messages;
    EXPECT_TRUE(mentions(messages, "channel \"arc_length_px.V\" row 3 (particle 3): frame of life 1 has value 500")) << messages;
    EXPECT_TRUE(mentions(messages, "part \"patches\" patch row 2 (particle 2): frame of life 1 has value inf")) << messages;
}

TEST(ParticleBank, InconsistentCountsAndTracksAreRefused) {
    const std::string dir = scratch_dir("bank_counts");
    const std::string count = edited_bank(dir, "count.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.particle_count", Imf::IntAttribute(7));
    });
    std::string messages = validation_messages([&] { read_particle_bank(count); });
    EXPECT_TRUE(mentions(messages, count + ": part \"patches\" dataWindow: is (0,0)-(95,47), expected (0,0)-(95,55)")) << messages;
    EXPECT_TRUE(mentions(messages, "part \"motion\" dataWindow")) << messages;

    const std::string lines = edited_bank(dir, "lines.exr", [](RawBank& raw) {
        raw.headers[0].insert("flowvid.line_lengths_px", Imf::FloatVectorAttribute({80.0f}));
        raw.headers[0].erase("flowvid.patch_size_px");
        raw.headers[0].insert("flowvid.patch_size_px", Imf::StringAttribute("8"));
    });
    messages = validation_messages([&] { read_particle_bank(lines); });
    EXPECT_TRUE(mentions(messages, "attribute \"flowvid.line_lengths_px\": 1 lengths for 2 line ids")) << messages;
    EXPECT_TRUE(mentions(messages, "attribute \"flowvid.patch_size_px\": has type string, expected int")) << messages;

    const std::string tracks = edited_bank(dir, "tracks.exr", [](RawBank& raw) {
        raw.line[0 * 12 + 2] = 0;  // particle 0: gap in its life
        raw.line[1 * 12 + 4] = 1;  // particle 1 (line 2) jumps to line 1
        raw.line[4 * 12 + 9] = 9;  // particle 4 on a line that does not exist
        for (int f = 0; f < 12; ++f) raw.line[5 * 12 + f] = 0;  // particle 5 never alive
    });
    messages = validation_messages([&] { read_particle_bank(tracks); });
    EXPECT_TRUE(mentions(messages, "channel \"line.V\" row 0 (particle 0): the life has a gap")) << messages;
    EXPECT_TRUE(mentions(messages, "row 1 (particle 1): the particle changes line at frame 4")) << messages;
    EXPECT_TRUE(mentions(messages, "row 4 (particle 4): the particle changes line")) << messages;
    EXPECT_TRUE(mentions(messages, "row 5 (particle 5): the particle is never alive")) << messages;

    const std::string channels = edited_bank(dir, "channels.exr", [](RawBank& raw) {
        raw.headers[1].channels().insert("extra", Imf::Channel(Imf::HALF));
    });
    // The extra channel is written as zeros by OpenEXR (no slice): tolerated with a warning.
    std::vector<Problem> warnings;
    EXPECT_NO_THROW(read_particle_bank(channels, &warnings));
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_EQ(warnings[0].field, "part \"motion\" channel \"extra\"");
}

TEST(ParticleBank, HugeDeclaredSizesAreRefusedBeforeAllocating) {
    // A small file whose header declares 100 particles alive for 100 frames in
    // 1024-px patches: 16 GB of texture. The patches part has no pixel data.
    const std::string dir = scratch_dir("bank_huge");
    const std::string path = dir + "/huge.bank.exr";
    const int ps = 1024, frames = 100, count = 100;
    const Imath::Box2i atlas(Imath::V2i(0, 0), Imath::V2i(frames * ps - 1, count * ps - 1));
    Imf::Header patches(atlas, atlas);
    patches.setName("patches");
    patches.setType(Imf::SCANLINEIMAGE);
    for (const char* c : {"R", "G", "B", "A"}) patches.channels().insert(c, Imf::Channel(Imf::HALF));
    patches.insert("flowvid.format", Imf::StringAttribute("flowvid.particle_bank"));
    patches.insert("flowvid.version", Imf::StringAttribute("1.0"));
    patches.insert("flowvid.patch_size_px", Imf::IntAttribute(ps));
    patches.insert("flowvid.clip_frame_count", Imf::IntAttribute(frames));
    patches.insert("flowvid.particle_count", Imf::IntAttribute(count));
    patches.insert("flowvid.line_count", Imf::IntAttribute(1));
    patches.insert("flowvid.clip_width_px", Imf::IntAttribute(640));
    patches.insert("flowvid.clip_height_px", Imf::IntAttribute(480));
    patches.insert("flowvid.fps", Imf::DoubleAttribute(30.0));
    patches.insert("flowvid.dynamics", Imf::StringAttribute("stationary"));
    patches.insert("flowvid.line_ids", Imf::StringVectorAttribute({"a"}));
    patches.insert("flowvid.line_lengths_px", Imf::FloatVectorAttribute({100.0f}));
    Imf::Header motion(atlas, Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(frames - 1, count - 1)));
    motion.setName("motion");
    motion.setType(Imf::SCANLINEIMAGE);
    motion.channels().insert("arc_length_px.V", Imf::Channel(Imf::FLOAT));
    motion.channels().insert("line.V", Imf::Channel(Imf::UINT));
    {
        const Imf::Header headers[2] = {patches, motion};
        Imf::MultiPartOutputFile file(path.c_str(), headers, 2);
        Imf::OutputPart part(file, 1);
        std::vector<float> arc(frames * count, 1.0f);
        std::vector<unsigned> line(frames * count, 1u);
        Imf::FrameBuffer fb;
        fb.insert("arc_length_px.V", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(arc.data()), 4, frames * 4));
        fb.insert("line.V", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(line.data()), 4, frames * 4));
        part.setFrameBuffer(fb);
        part.writePixels(count);
    }
    ASSERT_LT(fs::file_size(path), 200u * 1024u);
    const std::string messages = validation_messages([&] { read_particle_bank(path); });
    EXPECT_TRUE(mentions(messages, path + ": part \"patches\" dataWindow: the header declares")) << messages;
    EXPECT_TRUE(mentions(messages, "bytes of decoded data")) << messages;
}

TEST(ParticleBank, MissingFileIsAnIoErrorNamingIt) {
    const std::string path = scratch_dir("bank_missing") + "/absent.bank.exr";
    try {
        read_particle_bank(path);
        FAIL() << "expected IoError";
    } catch (const IoError& error) {
        EXPECT_EQ(error.file(), path);
        EXPECT_TRUE(mentions(error.what(), "no such file"));
    }
    const std::vector<Problem> problems = validate_particle_bank_file(path, Strictness::strict);
    ASSERT_EQ(problems.size(), 1u);
    EXPECT_EQ(problems[0].file, path);
}

TEST(ParticleBank, SummaryReportsCountsLivesAndSpeeds) {
    const nlohmann::json summary = summarize_particle_bank(read_particle_bank(example_path()));
    EXPECT_EQ(summary["format"], "flowvid.particle_bank");
    EXPECT_EQ(summary["version"], "1.1");
    EXPECT_EQ(summary["particle_count"], 6);
    EXPECT_EQ(summary["line_count"], 2);
    EXPECT_EQ(summary["lines"][0]["id"], "fall_left");
    EXPECT_EQ(summary["lines"][0]["particle_count"], 3);
    EXPECT_EQ(summary["life_frames"]["min"], 2);
    EXPECT_EQ(summary["life_frames"]["max"], 6);
    EXPECT_EQ(summary["life_frames"]["total"], 30);
    // Speeds 4 + 0.75 (2t + 1) px/frame: the fastest step (t = 4 -> 5) is 10.75 px.
    EXPECT_NEAR(summary["speed_px_per_frame"]["max"].get<double>(), 10.75, 1e-5);
    EXPECT_EQ(summary["clip"]["frame_count"], 12);
    EXPECT_EQ(summary["dynamics"], "stationary");
}
