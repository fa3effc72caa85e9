#include "flowvid/formats/particle_bank.hpp"

#include "exr_preflight.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/capture.hpp"

#include <ImathBox.h>
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
#include <ImfStringAttribute.h>
#include <ImfStringVectorAttribute.h>
#include <half.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <map>
#include <optional>
#include <set>

namespace flowvid::formats {

const char* to_string(ParticleDynamics dynamics) {
    return dynamics == ParticleDynamics::stationary ? "stationary" : "non_stationary";
}

const char* to_string(BankCameraModel model) {
    switch (model) {
        case BankCameraModel::still: return "still";
        case BankCameraModel::translation: return "translation";
        case BankCameraModel::affine: return "affine";
    }
    return "?";
}

namespace {
namespace fs = std::filesystem;

constexpr const char* kPatchesPart = "patches";
constexpr const char* kMotionPart = "motion";
// "<quantity>.V" (layer = quantity, channel V = value): Blender's multilayer
// reader accepts only one-letter channel tokens and refuses the whole file on
// a plain name like "line"; with these it lists them as passes.
constexpr const char* kArcLengthChannel = "arc_length_px.V";
constexpr const char* kLineChannel = "line.V";
constexpr const char* kRgbaChannels[4] = {"R", "G", "B", "A"};

// Attribute names (all on part "patches" unless noted).
constexpr const char* kAttrFormat = "flowvid.format";
constexpr const char* kAttrVersion = "flowvid.version";
constexpr const char* kAttrPatchSize = "flowvid.patch_size_px";
constexpr const char* kAttrFps = "flowvid.fps";
constexpr const char* kAttrClipWidth = "flowvid.clip_width_px";
constexpr const char* kAttrClipHeight = "flowvid.clip_height_px";
constexpr const char* kAttrFrameCount = "flowvid.clip_frame_count";
constexpr const char* kAttrParticleCount = "flowvid.particle_count";
constexpr const char* kAttrLineCount = "flowvid.line_count";
constexpr const char* kAttrSourceClip = "flowvid.source_clip";
constexpr const char* kAttrDynamics = "flowvid.dynamics";
constexpr const char* kAttrLineIds = "flowvid.line_ids";
constexpr const char* kAttrLineLengths = "flowvid.line_lengths_px";
// The camera (1.1): all present, or none.
constexpr const char* kAttrCameraModel = "flowvid.camera_model";
constexpr const char* kAttrCameraUntrusted = "flowvid.camera_untrusted";
constexpr const char* kAttrCameraViewFrame = "flowvid.camera_view_frame";
constexpr const char* kAttrCameraMaps = "flowvid.camera_first_to_frame_px";
constexpr const char* kAttrCameraLargestOffset = "flowvid.camera_largest_offset_px";
constexpr const char* kAttrCameraWorstCorrelation = "flowvid.camera_worst_correlation";
constexpr const char* kAttrUnits = "flowvid.units";    // informative, both parts
constexpr const char* kAttrLayout = "flowvid.layout";  // informative, both parts

constexpr int kMaxClipSidePx = 1 << 16;
constexpr float kHalfMax = 65504.0f;

constexpr const char* kUnitsText =
    "arc_length_px: pixels along the flow line from its start, float32; time: frames of the source clip "
    "(atlas column f = frame f, 0 = first frame), fps in flowvid.fps; texture: linear RGBA, associated alpha";
constexpr const char* kPatchesLayoutText =
    "atlas of patch_size_px squares: row p = particle p, column f = source frame f; "
    "transparent (all zero) where the particle is not alive";
constexpr const char* kMotionLayoutText =
    "one pixel per particle (row) and source frame (column): line.V = 1 + index into flowvid.line_ids "
    "where the particle is alive, 0 elsewhere; arc_length_px.V = its position there (0 elsewhere)";

std::string quoted(const std::string& text) { return "\"" + text + "\""; }

std::string attribute_field(const char* part, const std::string& attribute) {
    return "part " + quoted(part) + " attribute " + quoted(attribute);
}

std::string channel_field(const char* part, const std::string& channel) {
    return "part " + quoted(part) + " channel " + quoted(channel);
}

// Names the fields of a bank either as struct members (writer) or as the
// places in the file they come from (reader), so a message points where the
// user has to look.
struct FieldNames {
    bool in_file = false;

    std::string bank(const char* member, const char* attribute) const {
        return in_file ? attribute_field(kPatchesPart, attribute) : std::string(member);
    }
    std::string line(std::size_t index, const char* member) const {
        if (in_file)
            return attribute_field(kPatchesPart, std::string(member) == "id" ? kAttrLineIds : kAttrLineLengths) + "[" +
                   std::to_string(index) + "]";
        return "lines[" + std::to_string(index) + "]." + member;
    }
    std::string camera(const char* member, const char* attribute) const {
        return in_file ? attribute_field(kPatchesPart, attribute) : "camera." + std::string(member);
    }
    std::string particle(std::size_t index, const char* member) const {
        const std::string i = std::to_string(index);
        if (!in_file) return "particles[" + i + "]." + member;
        const std::string what(member);
        if (what == "texture_rgba") return "part " + quoted(kPatchesPart) + " patch row " + i + " (particle " + i + ")";
        if (what == "arc_length_px") return channel_field(kMotionPart, kArcLengthChannel) + " row " + i + " (particle " + i + ")";
        return channel_field(kMotionPart, kLineChannel) + " row " + i + " (particle " + i + ")";
    }
};

void check_lines(const std::vector<BankFlowLine>& lines, Diagnostics& diag, const FieldNames& names) {
    if (lines.empty())
        diag.error(names.bank("lines", kAttrLineIds), "the bank names no flow line",
                   "add the input flow lines the particles were tracked on");
    std::set<std::string> seen;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const BankFlowLine& line = lines[i];
        if (line.id.empty())
            diag.error(names.line(i, "id"), "empty line id", "use the id of the SVG path the line was drawn as");
        else if (!seen.insert(line.id).second)
            diag.error(names.line(i, "id"), "line id " + quoted(line.id) + " appears twice", "give every line its own id");
        if (!(std::isfinite(line.length_px) && line.length_px > 0.0f))
            diag.error(names.line(i, "length_px"), "line length " + std::to_string(line.length_px) + " px is not positive",
                       "write the arc length of the line in pixels");
    }
}

void check_scalars(const ParticleBank& bank, Diagnostics& diag, const FieldNames& names) {
    if (bank.patch_size_px < 1 || bank.patch_size_px > kMaxBankPatchSizePx)
        diag.error(names.bank("patch_size_px", kAttrPatchSize),
                   "patch size " + std::to_string(bank.patch_size_px) + " px is outside 1.." +
                       std::to_string(kMaxBankPatchSizePx),
                   "the thesis uses 24 (100 for flames)");
    if (!(std::isfinite(bank.fps) && bank.fps > 0.0))
        diag.error(names.bank("fps", kAttrFps), "frame rate " + std::to_string(bank.fps) + " is not positive",
                   "write the source clip's frames per second");
    if (bank.clip_width_px < 1 || bank.clip_width_px > kMaxClipSidePx)
        diag.error(names.bank("clip_width_px", kAttrClipWidth), "clip width " + std::to_string(bank.clip_width_px) + " px is not in 1..65536",
                   "write the width of the source frames");
    if (bank.clip_height_px < 1 || bank.clip_height_px > kMaxClipSidePx)
        diag.error(names.bank("clip_height_px", kAttrClipHeight), "clip height " + std::to_string(bank.clip_height_px) + " px is not in 1..65536",
                   "write the height of the source frames");
    if (bank.clip_frame_count < 1 || bank.clip_frame_count > kMaxBankFrameCount)
        diag.error(names.bank("clip_frame_count", kAttrFrameCount),
                   "frame count " + std::to_string(bank.clip_frame_count) + " is outside 1.." + std::to_string(kMaxBankFrameCount),
                   "write the number of source frames the particles were tracked in");
    else if (static_cast<long long>(bank.clip_frame_count) * bank.patch_size_px > kMaxBankAtlasWidthPx)
        diag.error(names.bank("clip_frame_count", kAttrFrameCount),
                   "the atlas would be " + std::to_string(static_cast<long long>(bank.clip_frame_count) * bank.patch_size_px) +
                       " px wide (limit " + std::to_string(kMaxBankAtlasWidthPx) + ")",
                   "split the clip into several banks");
}

void check_camera(const ParticleBank& bank, Diagnostics& diag, const FieldNames& names) {
    if (!bank.camera) return;
    const BankCamera& camera = *bank.camera;
    const bool still = camera.model == BankCameraModel::still;
    const std::string maps = names.camera("first_to_frame", kAttrCameraMaps);
    if (camera.untrusted && !still)
        diag.error(names.camera("untrusted", kAttrCameraUntrusted),
                   "an untrusted estimate with the moving model " + quoted(to_string(camera.model)),
                   "an untrusted estimate leaves the frames as filmed: write the model \"still\"");
    if (still && !camera.first_to_frame.empty())
        diag.error(maps, "a still camera with " + std::to_string(camera.first_to_frame.size()) + " maps",
                   "write no map for a still camera, or its model (translation or affine)");
    if (still && camera.view_frame != 0)
        diag.error(names.camera("view_frame", kAttrCameraViewFrame),
                   "a still camera's view is frame " + std::to_string(camera.view_frame), "write 0");
    if (!still && camera.first_to_frame.size() != static_cast<std::size_t>(std::max(bank.clip_frame_count, 0)))
        diag.error(maps,
                   std::to_string(camera.first_to_frame.size()) + " maps for " + std::to_string(bank.clip_frame_count) +
                       " source frames",
                   "write one map per source frame (6 values each: a11 a12 tx a21 a22 ty)");
    if (!still && (camera.view_frame < 0 || camera.view_frame >= bank.clip_frame_count))
        diag.error(names.camera("view_frame", kAttrCameraViewFrame),
                   "view frame " + std::to_string(camera.view_frame) + " is outside the clip (0.." +
                       std::to_string(bank.clip_frame_count - 1) + ")",
                   "count frames from 0 at the clip's first frame");
    for (std::size_t f = 0; f < camera.first_to_frame.size(); ++f) {
        const std::array<float, 6>& m = camera.first_to_frame[f];
        const bool finite = std::all_of(m.begin(), m.end(), [](float v) { return std::isfinite(v); });
        // The view is carried back to the first frame by the inverse: a
        // camera's drift keeps the picture's orientation.
        const double determinant = static_cast<double>(m[0]) * m[4] - static_cast<double>(m[1]) * m[3];
        if (!finite || !(determinant > 0.0)) {
            diag.error(maps,
                       "map of frame " + std::to_string(f) +
                           (finite ? " flips or collapses the picture (determinant " + std::to_string(determinant) + ")"
                                   : " is not finite"),
                       "track the clip again: each map is a drift of the camera (near the identity)");
            break;
        }
    }
    if (!(std::isfinite(camera.largest_offset_px) && camera.largest_offset_px >= 0.0f))
        diag.error(names.camera("largest_offset_px", kAttrCameraLargestOffset),
                   "largest offset " + std::to_string(camera.largest_offset_px) + " px is not a distance",
                   "write the largest corner drift in pixels (0 or more)");
    if (!(std::isfinite(camera.worst_correlation) && std::fabs(camera.worst_correlation) <= 1.0f))
        diag.error(names.camera("worst_correlation", kAttrCameraWorstCorrelation),
                   "correlation " + std::to_string(camera.worst_correlation) + " is outside -1..1",
                   "write the estimate's lowest correlation coefficient");
}

// Reports the first offending value of a list and how many more there are,
// rather than thousands of near-identical lines.
template <class Predicate>
void report_first_bad(const std::vector<float>& values, Predicate bad, Diagnostics& diag, const std::string& field,
                      const std::string& what_is_wrong, const std::string& fix, std::size_t group = 1,
                      const char* unit_name = "sample") {
    std::size_t first = values.size(), count = 0;
    for (std::size_t i = 0; i < values.size(); ++i) {
        if (!bad(values[i])) continue;
        if (count++ == 0) first = i;
    }
    if (count == 0) return;
    std::string message = unit_name + std::string(" ") + std::to_string(first / group) + " has value " +
                          std::to_string(values[first]) + ": " + what_is_wrong;
    if (count > 1) message += " (" + std::to_string(count - 1) + " more values like it)";
    diag.error(field, message, fix);
}

void check_particle(const ParticleBank& bank, std::size_t index, const std::map<std::string, float>& line_lengths,
                    Diagnostics& diag, const FieldNames& names) {
    const TrackedParticle& particle = bank.particles[index];
    const auto line = line_lengths.find(particle.line_id);
    if (line == line_lengths.end())
        diag.error(names.particle(index, "line_id"), "unknown line " + quoted(particle.line_id),
                   "use the id of one of the bank's lines");
    const int life = particle.life_frames();
    if (life < 1)
        diag.error(names.particle(index, "arc_length_px"), "the particle lives for no frame",
                   "drop it or give it at least one position");
    if (particle.start_frame < 0 || particle.start_frame >= bank.clip_frame_count)
        diag.error(names.particle(index, "start_frame"),
                   "start frame " + std::to_string(particle.start_frame) + " is outside the clip (0.." +
                       std::to_string(bank.clip_frame_count - 1) + ")",
                   "count frames from 0 at the clip's first frame");
    else if (static_cast<long long>(particle.start_frame) + life > bank.clip_frame_count)
        diag.error(names.particle(index, "arc_length_px"),
                   "the particle lives until frame " + std::to_string(static_cast<long long>(particle.start_frame) + life - 1) +
                       ", after the clip's last frame " + std::to_string(bank.clip_frame_count - 1),
                   "shorten its track or raise clip_frame_count");
    const float length_px = line == line_lengths.end() ? std::numeric_limits<float>::infinity() : line->second;
    report_first_bad(
        particle.arc_length_px, [](float s) { return !std::isfinite(s); }, diag, names.particle(index, "arc_length_px"),
        "not a finite position", "track the particle again; positions must be finite pixels along the line",
        1, "frame of life");
    report_first_bad(
        particle.arc_length_px, [&](float s) { return std::isfinite(s) && (s < 0.0f || s > length_px); }, diag,
        names.particle(index, "arc_length_px"),
        "outside the line (0.." + std::to_string(length_px) + " px)", "clamp positions to the line's arc length",
        1, "frame of life");
    const std::size_t expected = static_cast<std::size_t>(std::max(life, 0)) * bank.patch_size_px * bank.patch_size_px * 4;
    if (bank.patch_size_px >= 1 && particle.texture_rgba.size() != expected) {
        diag.error(names.particle(index, "texture_rgba"),
                   "texture holds " + std::to_string(particle.texture_rgba.size()) + " values, expected " +
                       std::to_string(expected) + " (life x patch x patch x 4)",
                   "store one RGBA patch per frame of life");
        return;
    }
    const std::size_t per_frame = static_cast<std::size_t>(std::max(bank.patch_size_px, 1)) * bank.patch_size_px * 4;
    report_first_bad(
        particle.texture_rgba, [](float v) { return !std::isfinite(v); }, diag, names.particle(index, "texture_rgba"),
        "not a finite colour", "fix the texture; NaN and infinity are not allowed", per_frame, "frame of life");
    report_first_bad(
        particle.texture_rgba, [](float v) { return std::isfinite(v) && std::fabs(v) > kHalfMax; }, diag,
        names.particle(index, "texture_rgba"), "beyond the half-float range (65504)",
        "scale the texture down; it is stored as half", per_frame, "frame of life");
}

void check_bank(const ParticleBank& bank, Diagnostics& diag, const FieldNames& names, bool check_scalars_and_lines) {
    if (check_scalars_and_lines) {
        check_scalars(bank, diag, names);
        check_lines(bank.lines, diag, names);
        check_camera(bank, diag, names);
        if (bank.particles.empty())
            diag.error(names.bank("particles", kAttrParticleCount), "the bank holds no particle",
                       "track at least one particle");
        if (bank.particles.size() > static_cast<std::size_t>(kMaxBankParticleCount))
            diag.error(names.bank("particles", kAttrParticleCount),
                       std::to_string(bank.particles.size()) + " particles exceed the limit of " +
                           std::to_string(kMaxBankParticleCount),
                       "split the bank");
        if (static_cast<long long>(bank.particles.size()) * std::max(bank.patch_size_px, 1) >
            std::numeric_limits<int>::max())
            diag.error(names.bank("particles", kAttrParticleCount), "the atlas would be taller than OpenEXR allows",
                       "split the bank");
    }
    std::map<std::string, float> line_lengths;
    for (const BankFlowLine& line : bank.lines) line_lengths.emplace(line.id, line.length_px);
    for (std::size_t i = 0; i < bank.particles.size(); ++i) check_particle(bank, i, line_lengths, diag, names);
}

// ---------------------------------------------------------------------------
// Writing

Imath::Box2i window(long long width, long long height) {
    return Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(static_cast<int>(width - 1), static_cast<int>(height - 1)));
}

void write_bank_exr(const std::string& temp_path, const ParticleBank& bank) {
    const int ps = bank.patch_size_px;
    const int frames = bank.clip_frame_count;
    const int count = static_cast<int>(bank.particles.size());
    const long long atlas_width = static_cast<long long>(frames) * ps;
    const long long atlas_height = static_cast<long long>(count) * ps;

    // displayWindow is shared by all parts of a multi-part file: both use the atlas.
    Imf::Header patches(window(atlas_width, atlas_height), window(atlas_width, atlas_height), 1.0f, Imath::V2f(0, 0),
                        1.0f, Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
    patches.setName(kPatchesPart);
    patches.setType(Imf::SCANLINEIMAGE);
    for (const char* name : kRgbaChannels) patches.channels().insert(name, Imf::Channel(Imf::HALF));
    patches.insert(kAttrFormat, Imf::StringAttribute(kParticleBankFormatName));
    patches.insert(kAttrVersion, Imf::StringAttribute(kParticleBankFormatVersion.to_string()));
    patches.insert(kAttrPatchSize, Imf::IntAttribute(ps));
    patches.insert(kAttrFps, Imf::DoubleAttribute(bank.fps));
    patches.insert(kAttrClipWidth, Imf::IntAttribute(bank.clip_width_px));
    patches.insert(kAttrClipHeight, Imf::IntAttribute(bank.clip_height_px));
    patches.insert(kAttrFrameCount, Imf::IntAttribute(frames));
    patches.insert(kAttrParticleCount, Imf::IntAttribute(count));
    patches.insert(kAttrLineCount, Imf::IntAttribute(static_cast<int>(bank.lines.size())));
    patches.insert(kAttrSourceClip, Imf::StringAttribute(bank.source_clip));
    patches.insert(kAttrDynamics, Imf::StringAttribute(to_string(bank.dynamics)));
    Imf::StringVector ids;
    Imf::FloatVector lengths;
    for (const BankFlowLine& line : bank.lines) {
        ids.push_back(line.id);
        lengths.push_back(line.length_px);
    }
    patches.insert(kAttrLineIds, Imf::StringVectorAttribute(ids));
    patches.insert(kAttrLineLengths, Imf::FloatVectorAttribute(lengths));
    if (bank.camera) {
        const BankCamera& camera = *bank.camera;
        patches.insert(kAttrCameraModel, Imf::StringAttribute(to_string(camera.model)));
        patches.insert(kAttrCameraUntrusted, Imf::IntAttribute(camera.untrusted ? 1 : 0));
        patches.insert(kAttrCameraViewFrame, Imf::IntAttribute(camera.view_frame));
        Imf::FloatVector maps;
        for (const std::array<float, 6>& m : camera.first_to_frame) maps.insert(maps.end(), m.begin(), m.end());
        patches.insert(kAttrCameraMaps, Imf::FloatVectorAttribute(maps));
        patches.insert(kAttrCameraLargestOffset, Imf::FloatAttribute(camera.largest_offset_px));
        patches.insert(kAttrCameraWorstCorrelation, Imf::FloatAttribute(camera.worst_correlation));
    }
    patches.insert(kAttrUnits, Imf::StringAttribute(kUnitsText));
    patches.insert(kAttrLayout, Imf::StringAttribute(kPatchesLayoutText));

    Imf::Header motion(window(atlas_width, atlas_height), window(frames, count), 1.0f, Imath::V2f(0, 0), 1.0f,
                       Imf::INCREASING_Y, Imf::ZIP_COMPRESSION);
    motion.setName(kMotionPart);
    motion.setType(Imf::SCANLINEIMAGE);
    motion.channels().insert(kArcLengthChannel, Imf::Channel(Imf::FLOAT));
    motion.channels().insert(kLineChannel, Imf::Channel(Imf::UINT));
    motion.insert(kAttrUnits, Imf::StringAttribute(kUnitsText));
    motion.insert(kAttrLayout, Imf::StringAttribute(kMotionLayoutText));

    std::map<std::string, unsigned> line_number;
    for (std::size_t i = 0; i < bank.lines.size(); ++i) line_number[bank.lines[i].id] = static_cast<unsigned>(i + 1);

    const Imf::Header headers[2] = {patches, motion};
    Imf::MultiPartOutputFile file(temp_path.c_str(), headers, 2);

    {
        // One atlas scanline at a time: yStride 0 makes every y read the same row buffer.
        Imf::OutputPart part(file, 0);
        std::vector<half> row(static_cast<std::size_t>(atlas_width) * 4);
        Imf::FrameBuffer buffer;
        for (int c = 0; c < 4; ++c)
            buffer.insert(kRgbaChannels[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(row.data() + c), 4 * sizeof(half), 0));
        part.setFrameBuffer(buffer);
        for (int p = 0; p < count; ++p) {
            const TrackedParticle& particle = bank.particles[p];
            for (int y = 0; y < ps; ++y) {
                std::fill(row.begin(), row.end(), half(0.0f));
                for (int life = 0; life < particle.life_frames(); ++life) {
                    const std::size_t column = static_cast<std::size_t>(particle.start_frame + life) * ps;
                    const float* source = particle.texture_rgba.data() + (static_cast<std::size_t>(life) * ps + y) * ps * 4;
                    for (std::size_t i = 0; i < static_cast<std::size_t>(ps) * 4; ++i) row[column * 4 + i] = half(source[i]);
                }
                part.writePixels(1);
            }
        }
    }
    {
        Imf::OutputPart part(file, 1);
        std::vector<float> arc(static_cast<std::size_t>(frames) * count, 0.0f);
        std::vector<unsigned> line(arc.size(), 0u);
        for (int p = 0; p < count; ++p) {
            const TrackedParticle& particle = bank.particles[p];
            for (int life = 0; life < particle.life_frames(); ++life) {
                const std::size_t at = static_cast<std::size_t>(p) * frames + particle.start_frame + life;
                arc[at] = particle.arc_length_px[life];
                line[at] = line_number.at(particle.line_id);
            }
        }
        Imf::FrameBuffer buffer;
        const Imath::Box2i data_window = window(frames, count);
        buffer.insert(kArcLengthChannel, Imf::Slice::Make(Imf::FLOAT, arc.data(), data_window));
        buffer.insert(kLineChannel, Imf::Slice::Make(Imf::UINT, line.data(), data_window));
        part.setFrameBuffer(buffer);
        part.writePixels(count);
    }
}

// ---------------------------------------------------------------------------
// Reading

// Reads one typed attribute; reports it missing or of the wrong type.
template <class Attribute>
const Attribute* find_attribute(const Imf::Header& header, const char* part, const char* name, const char* type_name,
                                Diagnostics& diag, bool required = true) {
    if (const Attribute* attribute = header.findTypedAttribute<Attribute>(name)) return attribute;
    auto it = header.find(name);
    if (it != header.end())
        diag.error(attribute_field(part, name),
                   std::string("has type ") + it.attribute().typeName() + ", expected " + type_name,
                   "write it as " + std::string(type_name) + " (see formats/specs/particle_bank.md)");
    else if (required)
        diag.error(attribute_field(part, name), "missing", "every particle bank carries it (see formats/specs/particle_bank.md)");
    return nullptr;
}

std::optional<int> int_attribute(const Imf::Header& header, const char* name, long long min, long long max,
                                 Diagnostics& diag) {
    const auto* attribute = find_attribute<Imf::IntAttribute>(header, kPatchesPart, name, "int", diag);
    if (!attribute) return std::nullopt;
    const int value = attribute->value();
    if (value < min || value > max) {
        diag.error(attribute_field(kPatchesPart, name),
                   "value " + std::to_string(value) + " is outside " + std::to_string(min) + ".." + std::to_string(max),
                   "see formats/specs/particle_bank.md for its meaning");
        return std::nullopt;
    }
    return value;
}

void check_unknown_attributes(const Imf::Header& header, const char* part, std::initializer_list<const char*> known,
                              Diagnostics& diag, Strictness strictness) {
    for (auto it = header.begin(); it != header.end(); ++it) {
        const std::string name = it.name();
        if (name.rfind("flowvid.", 0) != 0) continue;  // standard and foreign attributes are fine
        bool found = false;
        for (const char* k : known) found = found || name == k;
        if (found) continue;
        const std::string fix = "remove it or correct its spelling (formats/specs/particle_bank.md lists the attributes)";
        if (strictness == Strictness::strict) diag.error(attribute_field(part, name), "unknown attribute", fix);
        else diag.warning(attribute_field(part, name), "unknown attribute (ignored)", fix);
    }
}

// Checks that a part has exactly the channels it should (extra channels are
// tolerated with a warning unless strict) and the expected data window.
bool check_part_layout(const Imf::Header& header, const char* part,
                       const std::vector<std::pair<const char*, Imf::PixelType>>& channels, long long width,
                       long long height, Diagnostics& diag, Strictness strictness) {
    bool ok = true;
    static const std::map<Imf::PixelType, const char*> type_names = {
        {Imf::UINT, "uint"}, {Imf::HALF, "half"}, {Imf::FLOAT, "float"}};
    for (const auto& [name, type] : channels) {
        const Imf::Channel* channel = header.channels().findChannel(name);
        if (!channel) {
            diag.error(channel_field(part, name), "missing", "a particle bank writes it (see formats/specs/particle_bank.md)");
            ok = false;
        } else if (channel->type != type) {
            const auto found = type_names.find(channel->type);
            diag.error(channel_field(part, name),
                       std::string("is ") + (found == type_names.end() ? "of an unknown type" : found->second) +
                           ", expected " + type_names.at(type),
                       "write the bank with flowvid");
            ok = false;
        } else if (channel->xSampling != 1 || channel->ySampling != 1) {
            diag.error(channel_field(part, name), "is subsampled", "write every pixel (sampling 1)");
            ok = false;
        }
    }
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
        bool known = false;
        for (const auto& channel : channels) known = known || std::string(it.name()) == channel.first;
        if (known) continue;
        if (strictness == Strictness::strict)
            diag.error(channel_field(part, it.name()), "unexpected channel", "remove it");
        else
            diag.warning(channel_field(part, it.name()), "unexpected channel (ignored)", "remove it");
    }
    const Imath::Box2i& data = header.dataWindow();
    const long long found_width = static_cast<long long>(data.max.x) - data.min.x + 1;
    const long long found_height = static_cast<long long>(data.max.y) - data.min.y + 1;
    if (data.min.x != 0 || data.min.y != 0 || found_width != width || found_height != height) {
        diag.error("part " + quoted(part) + " dataWindow",
                   "is (" + std::to_string(data.min.x) + "," + std::to_string(data.min.y) + ")-(" +
                       std::to_string(data.max.x) + "," + std::to_string(data.max.y) + "), expected (0,0)-(" +
                       std::to_string(width - 1) + "," + std::to_string(height - 1) + ") from the counts and patch size",
                   "the counts in the header and the image size disagree; write the bank again");
        ok = false;
    }
    return ok;
}

bool has_exr_magic(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    unsigned char magic[4] = {0, 0, 0, 0};
    in.read(reinterpret_cast<char*>(magic), 4);
    return in.gcount() == 4 && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

// Throws IoError when the file cannot be read at all; returns its size.
std::uintmax_t require_readable_file(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError(path, "", "no such file", "check the path");
    if (fs::is_directory(path, ec)) throw IoError(path, "", "is a folder, not a file", "name a file inside it");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path, "", "cannot open the file", "check permissions");
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec) throw IoError(path, "", "cannot read the file size: " + ec.message(), "check the file system");
    return size;
}

class BankReader {
public:
    BankReader(const std::string& path, std::uintmax_t file_size, Diagnostics& diag, Strictness strictness)
        : m_path(path), m_file_size(file_size), m_diag(diag), m_strictness(strictness) {}

    std::optional<ParticleBank> read() {
        if (!has_exr_magic(m_path)) {
            m_diag.error("", "not an OpenEXR file (its first bytes are not the EXR magic number 76 2f 31 01)",
                         "a particle bank is a multi-part OpenEXR file written by flowvid");
            return std::nullopt;
        }
        // Refuse headers whose declared sizes the file cannot hold before
        // OpenEXR allocates its tables from them.
        if (!detail::preflight_exr(detail::read_file_head(m_path, 1 << 16), m_file_size, m_diag,
                                   static_cast<std::uint64_t>(kMaxBankDecodedBytesPerFileByte)))
            return std::nullopt;
        // OpenEXR reports damage with Iex exceptions (and sometimes std ones):
        // every one becomes a problem naming the stage that failed.
        std::string stage = "header";
        try {
            Imf::MultiPartInputFile file(m_path.c_str());
            std::optional<ParticleBank> bank = read_headers(file);
            if (!bank) return std::nullopt;
            stage = "part " + quoted(kMotionPart) + " pixels";
            if (!read_motion(file, *bank)) return std::nullopt;
            stage = "part " + quoted(kPatchesPart) + " pixels";
            if (!read_patches(file, *bank, stage)) return std::nullopt;
            FieldNames names{true};
            check_bank(*bank, m_diag, names, false);
            if (m_diag.has_errors()) return std::nullopt;
            return bank;
        } catch (const std::bad_alloc&) {
            m_diag.error(stage, "not enough memory to decode it", "the file declares more data than it holds; write it again");
        } catch (const std::exception& error) {
            m_diag.error(stage, std::string("OpenEXR cannot read it: ") + error.what(),
                         "the file is damaged or truncated; write it again from its source");
        } catch (...) {
            m_diag.error(stage, "OpenEXR failed with an unknown exception", "the file is damaged; write it again");
        }
        return std::nullopt;
    }

private:
    std::optional<ParticleBank> read_headers(const Imf::MultiPartInputFile& file) {
        for (int i = 0; i < file.parts(); ++i) {
            const Imf::Header& header = file.header(i);
            const std::string name = header.hasName() ? header.name() : std::string();
            if (name == kPatchesPart && m_patches < 0) m_patches = i;
            else if (name == kMotionPart && m_motion < 0) m_motion = i;
            else if (name == kPatchesPart || name == kMotionPart)
                m_diag.error("part " + quoted(name), "appears twice", "a bank has exactly one part of each name");
        }
        if (m_patches < 0) {
            // Say what the file is instead, when it says so.
            for (int i = 0; i < file.parts(); ++i) {
                const auto* format = file.header(i).findTypedAttribute<Imf::StringAttribute>(kAttrFormat);
                if (format && format->value() != kParticleBankFormatName) {
                    m_diag.error(attribute_field(file.header(i).hasName() ? file.header(i).name().c_str() : "0", kAttrFormat),
                                 "this is a " + quoted(format->value()) + " file, not " + quoted(kParticleBankFormatName),
                                 "use the command or reader for " + format->value());
                    return std::nullopt;
                }
            }
            m_diag.error(attribute_field(kPatchesPart, kAttrFormat),
                         "not a flowvid particle bank: no part " + quoted(kPatchesPart) + " carrying " + kAttrFormat +
                             " (a plain OpenEXR image?)",
                         "give a bank written by flowvid (formats/specs/particle_bank.md)");
            return std::nullopt;
        }
        const Imf::Header& patches = file.header(m_patches);
        if (!check_format(patches)) return std::nullopt;
        if (m_motion < 0)
            m_diag.error("part " + quoted(kMotionPart), "missing", "a bank has parts \"patches\" and \"motion\"; write it again");

        ParticleBank bank;
        const std::optional<int> patch = int_attribute(patches, kAttrPatchSize, 1, kMaxBankPatchSizePx, m_diag);
        const std::optional<int> frames = int_attribute(patches, kAttrFrameCount, 1, kMaxBankFrameCount, m_diag);
        const std::optional<int> particles = int_attribute(patches, kAttrParticleCount, 1, kMaxBankParticleCount, m_diag);
        const std::optional<int> line_count = int_attribute(patches, kAttrLineCount, 1, std::numeric_limits<int>::max(), m_diag);
        const std::optional<int> width = int_attribute(patches, kAttrClipWidth, 1, kMaxClipSidePx, m_diag);
        const std::optional<int> height = int_attribute(patches, kAttrClipHeight, 1, kMaxClipSidePx, m_diag);
        if (const auto* fps = find_attribute<Imf::DoubleAttribute>(patches, kPatchesPart, kAttrFps, "double", m_diag)) {
            bank.fps = fps->value();
            if (!(std::isfinite(bank.fps) && bank.fps > 0.0))
                m_diag.error(attribute_field(kPatchesPart, kAttrFps), "frame rate " + std::to_string(bank.fps) + " is not positive",
                             "write the source clip's frames per second");
        }
        if (const auto* source = find_attribute<Imf::StringAttribute>(patches, kPatchesPart, kAttrSourceClip, "string", m_diag, false))
            bank.source_clip = source->value();
        if (const auto* dynamics = find_attribute<Imf::StringAttribute>(patches, kPatchesPart, kAttrDynamics, "string", m_diag)) {
            if (dynamics->value() == "stationary") bank.dynamics = ParticleDynamics::stationary;
            else if (dynamics->value() == "non_stationary") bank.dynamics = ParticleDynamics::non_stationary;
            else
                m_diag.error(attribute_field(kPatchesPart, kAttrDynamics), "unknown dynamics " + quoted(dynamics->value()),
                             "use \"stationary\" or \"non_stationary\"");
        }
        const auto* ids = find_attribute<Imf::StringVectorAttribute>(patches, kPatchesPart, kAttrLineIds, "stringvector", m_diag);
        const auto* lengths = find_attribute<Imf::FloatVectorAttribute>(patches, kPatchesPart, kAttrLineLengths, "floatvector", m_diag);
        if (ids && lengths) {
            if (ids->value().size() != lengths->value().size())
                m_diag.error(attribute_field(kPatchesPart, kAttrLineLengths),
                             std::to_string(lengths->value().size()) + " lengths for " + std::to_string(ids->value().size()) + " line ids",
                             "write one length per line");
            else if (line_count && ids->value().size() != static_cast<std::size_t>(*line_count))
                m_diag.error(attribute_field(kPatchesPart, kAttrLineIds),
                             std::to_string(ids->value().size()) + " line ids, but " + kAttrLineCount + " is " +
                                 std::to_string(*line_count),
                             "the counts disagree; write the bank again");
            else {
                for (std::size_t i = 0; i < ids->value().size(); ++i)
                    bank.lines.push_back({ids->value()[i], lengths->value()[i]});
                check_lines(bank.lines, m_diag, FieldNames{true});
            }
        }
        bank.camera = read_camera(patches);
        check_unknown_attributes(patches, kPatchesPart,
                                 {kAttrFormat, kAttrVersion, kAttrPatchSize, kAttrFps, kAttrClipWidth, kAttrClipHeight,
                                  kAttrFrameCount, kAttrParticleCount, kAttrLineCount, kAttrSourceClip, kAttrDynamics,
                                  kAttrLineIds, kAttrLineLengths, kAttrCameraModel, kAttrCameraUntrusted,
                                  kAttrCameraViewFrame, kAttrCameraMaps, kAttrCameraLargestOffset,
                                  kAttrCameraWorstCorrelation, kAttrUnits, kAttrLayout},
                                 m_diag, m_strictness);
        if (m_motion >= 0)
            check_unknown_attributes(file.header(m_motion), kMotionPart, {kAttrUnits, kAttrLayout}, m_diag, m_strictness);
        if (!patch || !frames || !particles || !line_count || !width || !height || m_diag.has_errors()) return std::nullopt;

        bank.patch_size_px = *patch;
        bank.clip_frame_count = *frames;
        bank.clip_width_px = *width;
        bank.clip_height_px = *height;
        check_scalars(bank, m_diag, FieldNames{true});  // the atlas width limit
        check_camera(bank, m_diag, FieldNames{true});    // its maps against the frame count
        if (m_diag.has_errors()) return std::nullopt;

        const long long atlas_width = static_cast<long long>(*frames) * *patch;
        const long long atlas_height = static_cast<long long>(*particles) * *patch;
        if (atlas_height > std::numeric_limits<int>::max()) {
            m_diag.error(attribute_field(kPatchesPart, kAttrParticleCount), "the atlas would be taller than OpenEXR allows",
                         "the header is damaged; write the bank again");
            return std::nullopt;
        }
        bool layout_ok = check_part_layout(patches, kPatchesPart,
                                           {{"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}},
                                           atlas_width, atlas_height, m_diag, m_strictness);
        layout_ok = check_part_layout(file.header(m_motion), kMotionPart,
                                      {{kArcLengthChannel, Imf::FLOAT}, {kLineChannel, Imf::UINT}}, *frames, *particles,
                                      m_diag, m_strictness) && layout_ok;
        for (int part : {m_patches, m_motion})
            if (file.header(part).hasType() && file.header(part).type() != Imf::SCANLINEIMAGE) {
                m_diag.error("part " + quoted(file.header(part).name()) + " type",
                             "is " + quoted(file.header(part).type()) + ", expected " + quoted(Imf::SCANLINEIMAGE),
                             "write the bank with flowvid");
                layout_ok = false;
            }
        if (!layout_ok) return std::nullopt;

        m_particle_count = *particles;
        const long long motion_bytes = static_cast<long long>(*frames) * *particles * 8;
        if (!within_budget(motion_bytes, attribute_field(kPatchesPart, kAttrParticleCount))) return std::nullopt;
        return bank;
    }

    // The camera of a 1.1 bank: every flowvid.camera_* attribute, or none (a
    // 1.0 bank, or one written without it). Values are checked later, with
    // the frame count.
    std::optional<BankCamera> read_camera(const Imf::Header& patches) {
        const char* names[] = {kAttrCameraModel, kAttrCameraUntrusted, kAttrCameraViewFrame,
                               kAttrCameraMaps, kAttrCameraLargestOffset, kAttrCameraWorstCorrelation};
        std::vector<std::string> missing;
        for (const char* name : names)
            if (patches.find(name) == patches.end()) missing.push_back(name);
        if (missing.size() == std::size(names)) return std::nullopt;
        for (const std::string& name : missing)
            m_diag.error(attribute_field(kPatchesPart, name), "missing while other flowvid.camera_* attributes are present",
                         "write the camera whole (formats/specs/particle_bank.md) or remove every flowvid.camera_* "
                         "attribute (the drift is then estimated from the clip)");
        if (!missing.empty()) return std::nullopt;
        BankCamera camera;
        bool ok = true;
        if (const auto* model = find_attribute<Imf::StringAttribute>(patches, kPatchesPart, kAttrCameraModel, "string", m_diag)) {
            if (model->value() == "still") camera.model = BankCameraModel::still;
            else if (model->value() == "translation") camera.model = BankCameraModel::translation;
            else if (model->value() == "affine") camera.model = BankCameraModel::affine;
            else {
                m_diag.error(attribute_field(kPatchesPart, kAttrCameraModel), "unknown camera model " + quoted(model->value()),
                             "use \"still\", \"translation\" or \"affine\"");
                ok = false;
            }
        } else ok = false;
        if (const auto* untrusted = find_attribute<Imf::IntAttribute>(patches, kPatchesPart, kAttrCameraUntrusted, "int", m_diag)) {
            if (untrusted->value() != 0 && untrusted->value() != 1) {
                m_diag.error(attribute_field(kPatchesPart, kAttrCameraUntrusted),
                             "value " + std::to_string(untrusted->value()) + " is not 0 or 1", "write 1 for an untrusted estimate, else 0");
                ok = false;
            }
            camera.untrusted = untrusted->value() == 1;
        } else ok = false;
        if (const auto* view = find_attribute<Imf::IntAttribute>(patches, kPatchesPart, kAttrCameraViewFrame, "int", m_diag))
            camera.view_frame = view->value();
        else ok = false;
        if (const auto* maps = find_attribute<Imf::FloatVectorAttribute>(patches, kPatchesPart, kAttrCameraMaps, "floatvector", m_diag)) {
            if (maps->value().size() % 6 != 0) {
                m_diag.error(attribute_field(kPatchesPart, kAttrCameraMaps),
                             std::to_string(maps->value().size()) + " values are not whole maps of 6",
                             "write 6 values per source frame: a11 a12 tx a21 a22 ty");
                ok = false;
            } else
                for (std::size_t i = 0; i < maps->value().size(); i += 6) {
                    std::array<float, 6> m;
                    std::copy_n(maps->value().begin() + static_cast<std::ptrdiff_t>(i), 6, m.begin());
                    camera.first_to_frame.push_back(m);
                }
        } else ok = false;
        if (const auto* offset = find_attribute<Imf::FloatAttribute>(patches, kPatchesPart, kAttrCameraLargestOffset, "float", m_diag))
            camera.largest_offset_px = offset->value();
        else ok = false;
        if (const auto* worst = find_attribute<Imf::FloatAttribute>(patches, kPatchesPart, kAttrCameraWorstCorrelation, "float", m_diag))
            camera.worst_correlation = worst->value();
        else ok = false;
        if (!ok) return std::nullopt;
        return camera;
    }

    bool check_format(const Imf::Header& patches) {
        const auto* format = find_attribute<Imf::StringAttribute>(patches, kPatchesPart, kAttrFormat, "string", m_diag);
        if (!format) return false;
        if (format->value() != kParticleBankFormatName) {
            m_diag.error(attribute_field(kPatchesPart, kAttrFormat),
                         "this is a " + quoted(format->value()) + " file, not " + quoted(kParticleBankFormatName),
                         "use the command or reader for " + format->value());
            return false;
        }
        const auto* text = find_attribute<Imf::StringAttribute>(patches, kPatchesPart, kAttrVersion, "string", m_diag);
        if (!text) return false;
        const std::optional<FormatVersion> version = FormatVersion::parse(text->value());
        const std::string field = attribute_field(kPatchesPart, kAttrVersion);
        if (!version) {
            m_diag.error(field, quoted(text->value()) + " is not MAJOR.MINOR",
                         "write " + quoted(kParticleBankFormatVersion.to_string()));
            return false;
        }
        if (version->major != kParticleBankFormatVersion.major) {
            m_diag.error(field,
                         "version " + version->to_string() + " is not supported (this flowvid reads " +
                             std::to_string(kParticleBankFormatVersion.major) + ".x)",
                         version->major > kParticleBankFormatVersion.major ? "upgrade flowvid"
                                                                           : "convert the file with an older flowvid");
            return false;
        }
        if (version->minor > kParticleBankFormatVersion.minor)
            m_diag.warning(field,
                           "version " + version->to_string() + " is newer than " + kParticleBankFormatVersion.to_string() +
                               "; attributes and channels this flowvid does not know are ignored",
                           "upgrade flowvid to use everything in the file");
        return true;
    }

    bool within_budget(long long more_bytes, const std::string& field) {
        m_decoded_bytes += more_bytes;
        const long long by_file = kMaxBankDecodedBytesPerFileByte * static_cast<long long>(m_file_size) + (1LL << 20);
        const long long limit = std::min(kMaxBankDecodedBytes, by_file);
        if (m_decoded_bytes <= limit) return true;
        m_diag.error(field,
                     "the header declares " + std::to_string(m_decoded_bytes) + " bytes of decoded data, more than a " +
                         std::to_string(m_file_size) + "-byte bank can hold (limit " + std::to_string(limit) + ")",
                     "the header is damaged, or the bank is too large: split it");
        return false;
    }

    bool read_motion(Imf::MultiPartInputFile& file, ParticleBank& bank) {
        const int frames = bank.clip_frame_count;
        const int count = m_particle_count;
        Imf::InputPart part(file, m_motion);
        std::vector<float> arc(static_cast<std::size_t>(frames) * count, 0.0f);
        std::vector<unsigned> line(arc.size(), 0u);
        const Imath::Box2i data_window = window(frames, count);
        Imf::FrameBuffer buffer;
        buffer.insert(kArcLengthChannel, Imf::Slice::Make(Imf::FLOAT, arc.data(), data_window));
        buffer.insert(kLineChannel, Imf::Slice::Make(Imf::UINT, line.data(), data_window));
        part.setFrameBuffer(buffer);
        part.readPixels(0, count - 1);

        const std::string line_field = channel_field(kMotionPart, kLineChannel);
        long long texture_bytes = 0;
        bank.particles.resize(count);
        for (int p = 0; p < count; ++p) {
            const unsigned* row = line.data() + static_cast<std::size_t>(p) * frames;
            const std::string where = line_field + " row " + std::to_string(p) + " (particle " + std::to_string(p) + ")";
            int first = -1, last = -1;
            bool row_ok = true;
            for (int f = 0; f < frames && row_ok; ++f) {
                if (row[f] == 0) continue;
                if (first < 0) first = f;
                else if (last != f - 1) {
                    m_diag.error(where, "the life has a gap: dead at frame " + std::to_string(last + 1) +
                                            ", alive again at frame " + std::to_string(f),
                                 "a particle lives for consecutive frames; split the track into two particles");
                    row_ok = false;
                } else if (row[f] != row[first]) {
                    m_diag.error(where, "the particle changes line at frame " + std::to_string(f) + " (" +
                                            std::to_string(row[first]) + " -> " + std::to_string(row[f]) + ")",
                                 "a particle stays on one line");
                    row_ok = false;
                }
                last = f;
            }
            if (!row_ok) continue;
            if (first < 0) {
                m_diag.error(where, "the particle is never alive (all zero)", "drop the row or write its track");
                continue;
            }
            if (row[first] > bank.lines.size()) {
                m_diag.error(where,
                             "line number " + std::to_string(row[first]) + " exceeds the " + std::to_string(bank.lines.size()) +
                                 " lines of " + kAttrLineIds,
                             "write 1 + the index of the particle's line");
                continue;
            }
            TrackedParticle& particle = bank.particles[p];
            particle.line_id = bank.lines[row[first] - 1].id;
            particle.start_frame = first;
            const float* positions = arc.data() + static_cast<std::size_t>(p) * frames;
            particle.arc_length_px.assign(positions + first, positions + last + 1);
            texture_bytes += static_cast<long long>(last - first + 1) * bank.patch_size_px * bank.patch_size_px * 4 *
                             static_cast<long long>(sizeof(float));
        }
        if (m_diag.has_errors()) return false;
        return within_budget(texture_bytes, "part " + quoted(kPatchesPart) + " dataWindow");
    }

    bool read_patches(Imf::MultiPartInputFile& file, ParticleBank& bank, std::string& stage) {
        const int ps = bank.patch_size_px;
        const std::size_t atlas_width = static_cast<std::size_t>(bank.clip_frame_count) * ps;
        Imf::InputPart part(file, m_patches);
        std::vector<half> row(atlas_width * 4);
        Imf::FrameBuffer buffer;
        for (int c = 0; c < 4; ++c)
            buffer.insert(kRgbaChannels[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(row.data() + c), 4 * sizeof(half), 0));
        part.setFrameBuffer(buffer);
        for (int p = 0; p < m_particle_count; ++p) {
            TrackedParticle& particle = bank.particles[p];
            const std::size_t life = particle.arc_length_px.size();
            particle.texture_rgba.assign(life * ps * ps * 4, 0.0f);
            for (int y = 0; y < ps; ++y) {
                const int atlas_y = p * ps + y;
                stage = "part " + quoted(kPatchesPart) + " scanline " + std::to_string(atlas_y) + " (particle " +
                        std::to_string(p) + ")";
                part.readPixels(atlas_y);
                for (std::size_t l = 0; l < life; ++l) {
                    const half* source = row.data() + (particle.start_frame + l) * ps * 4;
                    float* target = particle.texture_rgba.data() + (l * ps + y) * ps * 4;
                    for (std::size_t i = 0; i < static_cast<std::size_t>(ps) * 4; ++i) target[i] = source[i];
                }
            }
        }
        return true;
    }

    std::string m_path;
    std::uintmax_t m_file_size;
    Diagnostics& m_diag;
    Strictness m_strictness;
    int m_patches = -1;
    int m_motion = -1;
    int m_particle_count = 0;
    long long m_decoded_bytes = 0;
};

}  // namespace

void check_particle_bank(const ParticleBank& bank, Diagnostics& diagnostics) {
    check_bank(bank, diagnostics, FieldNames{false}, true);
}

ParticleBank read_particle_bank(const std::string& path, std::vector<Problem>* warnings) {
    const std::uintmax_t size = require_readable_file(path);
    Diagnostics diagnostics(path);
    std::optional<ParticleBank> bank = BankReader(path, size, diagnostics, Strictness::lenient).read();
    diagnostics.throw_if_errors();
    if (warnings) *warnings = diagnostics.warnings();
    return *bank;
}

std::string source_clip_for_bank(const std::string& bank_path, const std::string& clip_path) {
    namespace fs = std::filesystem;
    if (clip_path.empty()) return clip_path;
    std::error_code ec;
    const fs::path clip = fs::absolute(clip_path, ec);
    if (ec) return clip_path;
    const fs::path folder = fs::absolute(bank_path, ec).parent_path();
    if (ec) return clip.string();
    const fs::path relative = clip.lexically_normal().lexically_relative(folder.lexically_normal());
    return relative.empty() ? clip.string() : relative.string();
}

std::string resolve_source_clip(const std::string& bank_path, const ParticleBank& bank) {
    namespace fs = std::filesystem;
    if (bank.source_clip.empty()) return {};
    const fs::path recorded(bank.source_clip);
    if (recorded.is_absolute()) return bank.source_clip;
    std::error_code ec;
    const fs::path beside = (fs::path(bank_path).parent_path() / recorded).lexically_normal();
    const bool present = fs::exists(beside, ec) || first_frame_of_pattern(beside.string());
    return present ? beside.string() : bank.source_clip;
}

void write_particle_bank(const std::string& path, const ParticleBank& bank) {
    Diagnostics diagnostics(path);
    check_particle_bank(bank, diagnostics);
    diagnostics.throw_if_errors();
    write_path_atomically(path, [&](const std::string& temp_path) {
        try {
            write_bank_exr(temp_path, bank);
        } catch (const std::exception& error) {
            throw IoError(path, "", std::string("OpenEXR could not write the bank: ") + error.what(),
                          "check free disk space and permissions");
        }
    });
}

std::vector<Problem> validate_particle_bank_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    try {
        const std::uintmax_t size = require_readable_file(path);
        BankReader(path, size, diagnostics, strictness).read();
    } catch (const IoError& error) {
        diagnostics.error(error.field(), error.message(), error.fix());
    }
    return diagnostics.problems();
}

nlohmann::json summarize_particle_bank(const ParticleBank& bank) {
    nlohmann::json summary = {
        {"format", kParticleBankFormatName},
        {"version", kParticleBankFormatVersion.to_string()},
        {"patch_size_px", bank.patch_size_px},
        {"fps", bank.fps},
        {"clip", {{"width_px", bank.clip_width_px}, {"height_px", bank.clip_height_px},
                  {"frame_count", bank.clip_frame_count}, {"source", bank.source_clip}}},
        {"dynamics", to_string(bank.dynamics)},
        {"line_count", bank.lines.size()},
        {"particle_count", bank.particles.size()},
    };
    if (bank.camera)
        summary["camera"] = {{"model", to_string(bank.camera->model)},
                             {"untrusted", bank.camera->untrusted},
                             {"view_frame", bank.camera->view_frame},
                             {"largest_offset_px", bank.camera->largest_offset_px},
                             {"worst_correlation", bank.camera->worst_correlation}};
    std::map<std::string, std::size_t> per_line;
    long long total_life = 0;
    int min_life = std::numeric_limits<int>::max(), max_life = 0;
    double speed_sum = 0.0, speed_max = 0.0;
    long long speed_samples = 0;
    for (const TrackedParticle& particle : bank.particles) {
        ++per_line[particle.line_id];
        total_life += particle.life_frames();
        min_life = std::min(min_life, particle.life_frames());
        max_life = std::max(max_life, particle.life_frames());
        for (std::size_t i = 1; i < particle.arc_length_px.size(); ++i) {
            const double speed = std::fabs(static_cast<double>(particle.arc_length_px[i]) - particle.arc_length_px[i - 1]);
            speed_sum += speed;
            speed_max = std::max(speed_max, speed);
            ++speed_samples;
        }
    }
    nlohmann::json lines = nlohmann::json::array();
    for (const BankFlowLine& line : bank.lines)
        lines.push_back({{"id", line.id}, {"length_px", line.length_px}, {"particle_count", per_line[line.id]}});
    summary["lines"] = lines;
    if (!bank.particles.empty())
        summary["life_frames"] = {{"min", min_life}, {"max", max_life},
                                  {"mean", static_cast<double>(total_life) / static_cast<double>(bank.particles.size())},
                                  {"total", total_life}};
    if (speed_samples > 0)
        summary["speed_px_per_frame"] = {{"mean", speed_sum / static_cast<double>(speed_samples)}, {"max", speed_max}};
    return summary;
}

}  // namespace flowvid::formats
