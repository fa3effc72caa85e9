#pragma once
// Particle texture bank (*.exr): the textures and motion of particles tracked
// along the input flow lines of a video (thesis chapter 3: every particle that
// enters a flow line is followed frame by frame; its patch of texture and its
// arc-length position along the line are stored, and synthesis later replays
// them). A multi-part OpenEXR file that any EXR viewer opens: part "patches"
// is a half RGBA atlas (one row of patches per particle, one column per source
// frame), part "motion" holds the float32 positions. Format name
// "flowvid.particle_bank", version 1.1 (1.1 adds the camera's drift); see
// formats/specs/particle_bank.md.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kParticleBankFormatName = "flowvid.particle_bank";
inline constexpr FormatVersion kParticleBankFormatVersion{1, 1};

// Limits a reader enforces before allocating, so that a damaged or hostile
// header cannot make it reserve gigabytes. Besides these, the decoded data
// (float textures of the living frames plus positions) may not exceed
// kMaxBankDecodedBytesPerFileByte times the file size nor kMaxBankDecodedBytes:
// no lossless EXR compression packs real data tighter than that.
inline constexpr int kMaxBankPatchSizePx = 1024;
inline constexpr int kMaxBankFrameCount = 100000;
inline constexpr int kMaxBankParticleCount = 1000000;
inline constexpr long long kMaxBankAtlasWidthPx = 1LL << 20;  // clip_frame_count x patch_size_px
inline constexpr long long kMaxBankDecodedBytesPerFileByte = 4096;
inline constexpr long long kMaxBankDecodedBytes = 4LL << 30;

// How the particles of one line move (thesis 3.2). stationary: every particle
// entering a line passes through (nearly) the same positions d1..dn, so
// synthesis may reuse any particle's timing. non_stationary: the speed along
// the line varies with the frame a particle starts on (flames, smoke), so each
// particle's own positions are its speed profile and must be kept with it.
enum class ParticleDynamics { stationary, non_stationary };

const char* to_string(ParticleDynamics dynamics);

// One input flow line as drawn in flowlines.svg (group "input").
struct BankFlowLine {
    std::string id;          // the SVG path id
    float length_px = 0.0f;  // arc length of the whole line, pixels of the source clip
    bool operator==(const BankFlowLine&) const = default;
};

// How the camera drifted while the clip was filmed, as tracking estimated it
// (version 1.1). A bank is tracked in one still view of the clip: the input
// lines, drawn on the first frame, are carried into the view of frame
// `view_frame` and the particles' positions are measured along them. Every
// command that replays the bank needs that same view; stored, it is not
// estimated again (the estimate reads the whole clip).
enum class BankCameraModel { still, translation, affine };

const char* to_string(BankCameraModel model);

struct BankCamera {
    BankCameraModel model = BankCameraModel::still;
    // Still because the background matched the first frame too poorly to
    // tell (flickering firelight): the frames are used as filmed.
    bool untrusted = false;
    // 0-based source frame whose view the bank is in; 0 when still.
    int view_frame = 0;
    // One map per source frame (clip_frame_count of them; none when still):
    // a pixel p of the first frame is the scene point seen at A p + t in
    // frame f, stored row-major {a11, a12, tx, a21, a22, ty}, pixels.
    std::vector<std::array<float, 6>> first_to_frame;
    float largest_offset_px = 0.0f;  // the largest drift of a frame corner from the first frame, px
    float worst_correlation = 1.0f;  // the estimate's lowest correlation of a frame's background with the first's
    bool operator==(const BankCamera&) const = default;
};

// One particle followed along its line for `life_frames()` consecutive frames.
struct TrackedParticle {
    std::string line_id;  // one of ParticleBank::lines[].id
    int start_frame = 0;  // index of its first frame in the source clip, 0 = the clip's first frame
    // #life: position at frame start_frame + i, pixels along the line from its
    // start (sub-pixel, float32 as stored, so a round trip is bit-exact).
    std::vector<float> arc_length_px;
    // #life x patch x patch x 4: linear RGBA with associated (premultiplied)
    // alpha, patch row 0 at the top (image y down), centred on the particle.
    // Stored as half: values round to the nearest half on writing.
    std::vector<float> texture_rgba;

    int life_frames() const { return static_cast<int>(arc_length_px.size()); }
    bool operator==(const TrackedParticle&) const = default;
};

struct ParticleBank {
    int patch_size_px = 24;    // patches are square, patch_size_px on a side
    double fps = 30.0;         // frame rate of the source clip, frames per second
    int clip_width_px = 0;     // size of the source clip's frames
    int clip_height_px = 0;
    int clip_frame_count = 0;  // frames of the source clip covered by the bank (atlas columns)
    std::string source_clip;   // informative: the capture folder or clip the bank was tracked in;
                               // relative to the bank file's folder (source_clip_for_bank)
    ParticleDynamics dynamics = ParticleDynamics::stationary;
    std::vector<BankFlowLine> lines;
    std::vector<TrackedParticle> particles;  // in file order (atlas rows)
    // The view the particles were tracked in (1.1); absent in 1.0 banks, whose
    // readers estimate the drift from the clip again.
    std::optional<BankCamera> camera;

    bool operator==(const ParticleBank&) const = default;
};

// Every problem of an in-memory bank (the writer's check): sizes, ranges,
// finite values, line references. Field names follow the struct members.
void check_particle_bank(const ParticleBank& bank, Diagnostics& diagnostics);

// Reads and validates a file; throws ValidationError (every problem, naming the
// part and attribute or channel) or IoError (missing or unreadable file).
// Warnings (newer minor version, unknown attributes) go to `warnings`.
ParticleBank read_particle_bank(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates, then writes atomically. Throws ValidationError when the bank is
// not valid, leaving any previous file untouched; IoError when writing fails.
void write_particle_bank(const std::string& path, const ParticleBank& bank);

// source_clip as a bank written to `bank_path` records it: relative to the
// bank file's folder, so the bank finds its clip from any working directory
// and when both move together.
std::string source_clip_for_bank(const std::string& bank_path, const std::string& clip_path);
// The clip a bank read from `bank_path` names: an absolute source_clip as
// is; a relative one against the bank's folder when that exists (for a
// frame pattern: when its frame 0 or 1 does), else
// against the working directory (banks written before 2026-11-23 recorded
// it so). Empty when the bank records none.
std::string resolve_source_clip(const std::string& bank_path, const ParticleBank& bank);
// Every problem of a file, for `flowvid validate` and the fuzz targets (never
// throws on bad content). Strict: unknown flowvid.* attributes and extra
// channels are errors rather than warnings.
std::vector<Problem> validate_particle_bank_file(const std::string& path, Strictness strictness);
// A small description for `flowvid info --json`: sizes, lines, life and speed statistics.
nlohmann::json summarize_particle_bank(const ParticleBank& bank);

}  // namespace flowvid::formats
