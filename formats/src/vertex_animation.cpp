#include "flowvid/formats/vertex_animation.hpp"

#include "exr_preflight.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfIntAttribute.h>
#include <ImfOutputFile.h>
#include <ImfRationalAttribute.h>
#include <ImfStringAttribute.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>

namespace flowvid::formats {
namespace fs = std::filesystem;

static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "positions are read straight into Vector3f storage");

bool VertexAnimation::operator==(const VertexAnimation& other) const {
    return frame_count == other.frame_count && vertex_count == other.vertex_count && grid_rows == other.grid_rows &&
           grid_cols == other.grid_cols && fps == other.fps && positions_m == other.positions_m;
}

namespace {

constexpr const char* kAttrFormat = "flowvid.format";
constexpr const char* kAttrVersion = "flowvid.version";
constexpr const char* kAttrFps = "flowvid.fps";
constexpr const char* kAttrGridRows = "flowvid.grid_rows";
constexpr const char* kAttrGridCols = "flowvid.grid_cols";
constexpr const char* kPositionChannels[3] = {"R", "G", "B"};

// Above this many bytes of pixels (64 MiB), a compressed file must be at least 1/4096 of
// the raw size (deflate cannot do better than ~1/1032): a tiny corrupt file
// then cannot make the reader allocate gigabytes.
constexpr std::uint64_t kLargeRawBytes = std::uint64_t(64) << 20;
constexpr std::uint64_t kMaxCompressionRatio = 4096;

// Reads an EXR held in memory (fuzz targets, tests); reading past the end
// throws like a truncated file does.
class MemoryIStream : public Imf::IStream {
public:
    MemoryIStream(const std::string& name, const std::string& bytes) : Imf::IStream(name.c_str()), m_bytes(bytes) {}

    bool read(char c[], int n) override {
        if (n < 0 || m_position > m_bytes.size() || static_cast<std::uint64_t>(n) > m_bytes.size() - m_position)
            throw std::runtime_error("unexpected end of file");
        std::memcpy(c, m_bytes.data() + m_position, static_cast<std::size_t>(n));
        m_position += static_cast<std::uint64_t>(n);
        return m_position < m_bytes.size();
    }
    std::uint64_t tellg() override { return m_position; }
    void seekg(std::uint64_t position) override { m_position = position; }
    void clear() override {}

private:
    const std::string& m_bytes;
    std::uint64_t m_position = 0;
};

// Reads from a file through std::ifstream; throws on a short read.
class FileIStream : public Imf::IStream {
public:
    FileIStream(const std::string& path, std::ifstream& in) : Imf::IStream(path.c_str()), m_in(in) {}

    bool read(char c[], int n) override {
        if (n < 0) throw std::runtime_error("negative read size");
        m_in.read(c, n);
        if (m_in.gcount() != n) {
            m_in.clear();
            throw std::runtime_error("unexpected end of file");
        }
        return m_in.peek() != std::char_traits<char>::eof();
    }
    std::uint64_t tellg() override { return static_cast<std::uint64_t>(m_in.tellg()); }
    void seekg(std::uint64_t position) override {
        m_in.clear();
        m_in.seekg(static_cast<std::streamoff>(position));
    }
    void clear() override { m_in.clear(); }

private:
    std::ifstream& m_in;
};

bool has_exr_magic(const char* bytes, std::size_t size) {
    static const unsigned char magic[4] = {0x76, 0x2f, 0x31, 0x01};
    return size >= 4 && std::memcmp(bytes, magic, 4) == 0;
}

std::string pixel_type_name(Imf::PixelType type) {
    switch (type) {
        case Imf::UINT: return "uint";
        case Imf::HALF: return "half";
        case Imf::FLOAT: return "float";
        default: return "unknown";
    }
}

// The header is checked by the shared preflight before OpenEXR sizes its tables
// from it; a vertex-animation texture adds its own limits on top.
std::optional<detail::ExrPartPeek> peek_header(const std::string& bytes, std::uint64_t byte_count, Diagnostics& diag) {
    std::optional<detail::ExrPeek> peek = detail::preflight_exr(bytes, byte_count, diag, kMaxCompressionRatio);
    if (!peek) return std::nullopt;
    if (peek->multi_part) {
        diag.error("header", "a multi-part OpenEXR file (a vertex-animation texture is one RGB image)",
                   "is this a particle texture bank? Otherwise write one part");
        return std::nullopt;
    }
    if (peek->deep) {
        diag.error("header", "a deep OpenEXR file (a vertex-animation texture is a flat RGB image)",
                   "write a flat scan-line image");
        return std::nullopt;
    }
    const detail::ExrPartPeek& part = peek->parts.front();
    if (part.width > kMaxVertexAnimationVertices || part.height > kMaxVertexAnimationFrames ||
        part.width * part.height > kMaxVertexAnimationSamples) {
        diag.error("data window",
                   std::to_string(part.width) + " vertices x " + std::to_string(part.height) +
                       " frames is implausibly large (limits: " + std::to_string(kMaxVertexAnimationVertices) +
                       " vertices, " + std::to_string(kMaxVertexAnimationFrames) + " frames, " +
                       std::to_string(kMaxVertexAnimationSamples) + " samples)",
                   "check that the file is a vertex-animation texture, or split the sequence");
        return std::nullopt;
    }
    return part;
}

std::string attribute_field(const char* name) { return std::string("attribute ") + name; }

// Header checks shared by every reader. Returns false when the pixels must not
// be read (an error was found).
bool check_header(const Imf::Header& header, std::uint64_t byte_count, Diagnostics& diag, Strictness strictness,
                  VertexAnimation& animation) {
    const std::size_t errors_before = diag.problems().size();
    auto had_errors = [&] {
        for (std::size_t i = errors_before; i < diag.problems().size(); ++i)
            if (diag.problems()[i].severity == Problem::Severity::error) return true;
        return false;
    };

    // What the file says it is.
    const auto* format = header.findTypedAttribute<Imf::StringAttribute>(kAttrFormat);
    if (header.find(kAttrFormat) != header.end() && !format)
        diag.error(attribute_field(kAttrFormat), "is not a string attribute",
                   std::string("write the string \"") + kVertexAnimationFormatName + "\"");
    if (format && format->value() != kVertexAnimationFormatName)
        diag.error(attribute_field(kAttrFormat),
                   "this is a \"" + format->value() + "\" file, not \"" + kVertexAnimationFormatName + "\"",
                   "use the reader for " + format->value());
    const auto* version_text = header.findTypedAttribute<Imf::StringAttribute>(kAttrVersion);
    if (header.find(kAttrVersion) != header.end() && !version_text)
        diag.error(attribute_field(kAttrVersion), "is not a string attribute",
                   "write the string \"" + kVertexAnimationFormatVersion.to_string() + "\"");
    if (format && !version_text && header.find(kAttrVersion) == header.end())
        diag.error(attribute_field(kAttrVersion), "missing (the file names its format but not its version)",
                   "add flowvid.version = \"" + kVertexAnimationFormatVersion.to_string() + "\"");
    if (version_text) {
        std::optional<FormatVersion> version = FormatVersion::parse(version_text->value());
        if (!version)
            diag.error(attribute_field(kAttrVersion), "\"" + version_text->value() + "\" is not MAJOR.MINOR",
                       "write \"" + kVertexAnimationFormatVersion.to_string() + "\"");
        else if (version->major != kVertexAnimationFormatVersion.major)
            diag.error(attribute_field(kAttrVersion),
                       "version " + version->to_string() + " is not supported (this flowvid reads " +
                           std::to_string(kVertexAnimationFormatVersion.major) + ".x)",
                       version->major > kVertexAnimationFormatVersion.major ? "upgrade flowvid"
                                                                            : "convert the file with an older flowvid");
        else if (version->minor > kVertexAnimationFormatVersion.minor)
            diag.warning(attribute_field(kAttrVersion),
                         "version " + version->to_string() + " is newer than " +
                             kVertexAnimationFormatVersion.to_string() + "; attributes this flowvid does not know are ignored",
                         "upgrade flowvid to use every attribute");
    }

    // Size: one row per frame, one column per vertex.
    const Imath::Box2i window = header.dataWindow();
    const std::int64_t width = std::int64_t(window.max.x) - std::int64_t(window.min.x) + 1;
    const std::int64_t height = std::int64_t(window.max.y) - std::int64_t(window.min.y) + 1;
    bool size_ok = true;
    if (width < 1 || height < 1) {
        diag.error("data window", "is empty (" + std::to_string(width) + " x " + std::to_string(height) + ")",
                   "write one row per frame and one column per vertex");
        size_ok = false;
    } else if (width > kMaxVertexAnimationVertices || height > kMaxVertexAnimationFrames ||
               width * height > kMaxVertexAnimationSamples) {
        diag.error("data window",
                   std::to_string(width) + " vertices x " + std::to_string(height) +
                       " frames is implausibly large (limits: " + std::to_string(kMaxVertexAnimationVertices) +
                       " vertices, " + std::to_string(kMaxVertexAnimationFrames) + " frames, " +
                       std::to_string(kMaxVertexAnimationSamples) + " samples)",
                   "check that the file is a vertex-animation texture, or split the sequence");
        size_ok = false;
    }
    if (size_ok) {
        animation.vertex_count = static_cast<int>(width);
        animation.frame_count = static_cast<int>(height);
        const std::uint64_t raw_bytes = static_cast<std::uint64_t>(width * height) * 12u;
        if (header.compression() == Imf::NO_COMPRESSION && byte_count < raw_bytes)
            diag.error("pixels",
                       "the file has " + std::to_string(byte_count) + " bytes but its uncompressed pixels need " +
                           std::to_string(raw_bytes) + ": it is truncated",
                       "write the file again");
        else if (raw_bytes > kLargeRawBytes && raw_bytes / kMaxCompressionRatio > byte_count)
            diag.error("pixels",
                       "the header claims " + std::to_string(raw_bytes) + " bytes of pixels in a file of " +
                           std::to_string(byte_count) + " bytes: it is truncated or corrupt",
                       "write the file again");
    }

    // Channels: float R, G, B at full resolution; others are ignored.
    const Imf::ChannelList& channels = header.channels();
    for (const char* name : kPositionChannels) {
        const Imf::Channel* channel = channels.findChannel(name);
        const std::string field = std::string("channel ") + name;
        if (!channel) {
            diag.error(field, "missing (positions need R, G, B = x, y, z in metres)",
                       "write float32 channels R, G and B");
            continue;
        }
        if (channel->type != Imf::FLOAT)
            diag.error(field, "is " + pixel_type_name(channel->type) + ", positions need float32",
                       "write the channel as FLOAT (half loses millimetres at a metre)");
        if (channel->xSampling != 1 || channel->ySampling != 1)
            diag.error(field, "is subsampled (" + std::to_string(channel->xSampling) + " x " +
                                  std::to_string(channel->ySampling) + ")",
                       "write every channel at full resolution");
    }
    for (Imf::ChannelList::ConstIterator it = channels.begin(); it != channels.end(); ++it) {
        const std::string name = it.name();
        if (name == "R" || name == "G" || name == "B") continue;
        const std::string message = "extra channel (not part of a vertex-animation texture)";
        if (strictness == Strictness::strict) diag.error("channel " + name, message, "remove the channel");
        else diag.warning("channel " + name, message + "; ignored", "remove the channel");
    }

    // Optional flowvid attributes.
    if (header.find(kAttrFps) != header.end()) {
        std::optional<double> fps;
        if (const auto* value = header.findTypedAttribute<Imf::DoubleAttribute>(kAttrFps)) fps = value->value();
        else if (const auto* single = header.findTypedAttribute<Imf::FloatAttribute>(kAttrFps)) fps = single->value();
        if (!fps)
            diag.error(attribute_field(kAttrFps), "is not a double attribute", "write frames per second as a double");
        else if (!std::isfinite(*fps) || *fps <= 0.0)
            diag.error(attribute_field(kAttrFps), "must be a finite number > 0 frames per second",
                       "write the frame rate, e.g. 30");
        else animation.fps = *fps;
    } else if (const auto* rate = header.findTypedAttribute<Imf::RationalAttribute>("framesPerSecond")) {
        // The standard attribute, for files written by other tools.
        const double fps = double(rate->value());
        if (std::isfinite(fps) && fps > 0.0) animation.fps = fps;
    }
    const bool has_rows = header.find(kAttrGridRows) != header.end();
    const bool has_cols = header.find(kAttrGridCols) != header.end();
    if (has_rows || has_cols) {
        const auto* rows = header.findTypedAttribute<Imf::IntAttribute>(kAttrGridRows);
        const auto* cols = header.findTypedAttribute<Imf::IntAttribute>(kAttrGridCols);
        if (!has_rows || !has_cols) {
            diag.error(attribute_field(has_rows ? kAttrGridCols : kAttrGridRows),
                       "missing (the grid needs both rows and columns)", "write both grid attributes or neither");
        } else if (!rows || !cols) {
            diag.error(attribute_field(!rows ? kAttrGridRows : kAttrGridCols), "is not an int attribute",
                       "write the grid size as ints");
        } else if (rows->value() < 1 || cols->value() < 1) {
            diag.error(attribute_field(kAttrGridRows),
                       "grid " + std::to_string(rows->value()) + " x " + std::to_string(cols->value()) +
                           " is not positive",
                       "write rows, cols >= 1");
        } else if (size_ok && std::int64_t(rows->value()) * std::int64_t(cols->value()) != width) {
            diag.error(attribute_field(kAttrGridRows),
                       "grid " + std::to_string(rows->value()) + " x " + std::to_string(cols->value()) + " = " +
                           std::to_string(std::int64_t(rows->value()) * cols->value()) + " vertices, but the image has " +
                           std::to_string(width) + " columns",
                       "fix the grid attributes or drop them");
        } else {
            animation.grid_rows = rows->value();
            animation.grid_cols = cols->value();
        }
    }
    for (Imf::Header::ConstIterator it = header.begin(); it != header.end(); ++it) {
        const std::string name = it.name();
        if (name.rfind("flowvid.", 0) != 0) continue;
        if (name == kAttrFormat || name == kAttrVersion || name == kAttrFps || name == kAttrGridRows ||
            name == kAttrGridCols)
            continue;
        const std::string fix = "remove it or correct its spelling (known: flowvid.format, flowvid.version, "
                                "flowvid.fps, flowvid.grid_rows, flowvid.grid_cols)";
        if (strictness == Strictness::strict) diag.error("attribute " + name, "unknown flowvid attribute", fix);
        else diag.warning("attribute " + name, "unknown flowvid attribute (ignored)", fix);
    }
    return !had_errors();
}

void check_finite_positions(const VertexAnimation& animation, Diagnostics& diag, const char* field,
                            MissingPoints missing) {
    std::size_t bad = 0;
    std::size_t first = 0;
    int first_channel = 0;
    std::size_t partial = 0;
    std::size_t first_partial = 0;
    for (std::size_t i = 0; i < animation.positions_m.size(); ++i) {
        const Eigen::Vector3f& p = animation.positions_m[i];
        if (missing == MissingPoints::allow_nan && p.array().isNaN().any()) {
            // An unseen point is NaN in all three channels; one NaN beside
            // numbers is a broken export, not a gap.
            if (!p.array().isNaN().all() && partial++ == 0) first_partial = i;
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            if (std::isfinite(p[c])) continue;
            if (bad == 0) {
                first = i;
                first_channel = c;
            }
            ++bad;
        }
    }
    const std::size_t vertices = static_cast<std::size_t>(std::max(animation.vertex_count, 1));
    if (partial > 0)
        diag.error(field,
                   std::to_string(partial) + " point(s) are NaN in some channels but not all, the first at frame row " +
                       std::to_string(first_partial / vertices) + ", point " + std::to_string(first_partial % vertices),
                   "write an unseen point as NaN in all of R, G and B, a seen one as three finite metres");
    if (bad == 0) return;
    if (missing == MissingPoints::allow_nan)
        diag.error(field,
                   std::to_string(bad) + " infinite value(s), the first at frame row " + std::to_string(first / vertices) +
                       ", point " + std::to_string(first % vertices) + ", channel " + kPositionChannels[first_channel],
                   "positions must be finite metres, or NaN in all three channels where a point was not seen");
    else
        diag.error(field,
                   std::to_string(bad) + " NaN or infinite value(s), the first at frame row " +
                       std::to_string(first / vertices) + ", vertex " + std::to_string(first % vertices) + ", channel " +
                       kPositionChannels[first_channel],
                   "positions must be finite metres: fix the simulation or export that wrote them");
}

std::optional<VertexAnimation> parse_exr(Imf::IStream& stream, std::uint64_t byte_count, Diagnostics& diag,
                                         Strictness strictness, MissingPoints missing) {
    VertexAnimation animation;
    std::unique_ptr<Imf::InputFile> file;
    try {
        file = std::make_unique<Imf::InputFile>(stream);
    } catch (const std::exception& error) {
        diag.error("header", std::string("cannot read the OpenEXR header: ") + error.what(),
                   "the file is truncated or corrupt: write it again");
        return std::nullopt;
    }
    const Imf::Header& header = file->header();
    if (!check_header(header, byte_count, diag, strictness, animation)) return std::nullopt;
    try {
        const Imath::Box2i window = header.dataWindow();
        animation.positions_m.assign(
            static_cast<std::size_t>(animation.frame_count) * static_cast<std::size_t>(animation.vertex_count),
            Eigen::Vector3f::Zero());
        char* base = reinterpret_cast<char*>(animation.positions_m.data());
        Imf::FrameBuffer buffer;
        const std::size_t x_stride = sizeof(Eigen::Vector3f);
        const std::size_t y_stride = x_stride * static_cast<std::size_t>(animation.vertex_count);
        for (int c = 0; c < 3; ++c)
            buffer.insert(kPositionChannels[c], Imf::Slice::Make(Imf::FLOAT, base + c * sizeof(float), window,
                                                                  x_stride, y_stride));
        file->setFrameBuffer(buffer);
        if (!file->isComplete()) {
            diag.error("pixels", "the file is incomplete (some scan lines or tiles are missing)",
                       "the file is truncated: write it again");
            return std::nullopt;
        }
        file->readPixels(window.min.y, window.max.y);
    } catch (const std::exception& error) {
        diag.error("pixels", std::string("cannot decode the OpenEXR pixels: ") + error.what(),
                   "the file is truncated or corrupt: write it again");
        return std::nullopt;
    }
    check_finite_positions(animation, diag, "pixels", missing);
    if (diag.has_errors()) return std::nullopt;
    return animation;
}

std::optional<VertexAnimation> parse_file(const std::string& path, Diagnostics& diag, Strictness strictness,
                                          MissingPoints missing = MissingPoints::refuse) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError(path, "", "no such file", "check the path");
    if (fs::is_directory(path, ec)) throw IoError(path, "", "is a folder, not a file", "name an .exr file");
    const std::uint64_t byte_count = fs::file_size(path, ec);
    std::ifstream in(path, std::ios::binary);
    if (!in || ec) throw IoError(path, "", "cannot open the file", "check permissions");
    // The header (attributes are small; 1 MiB is generous) is checked first.
    std::string head(static_cast<std::size_t>(std::min<std::uint64_t>(byte_count, std::uint64_t(1) << 20)), '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(in.gcount()));
    if (!has_exr_magic(head.data(), head.size())) {
        diag.error("", "not an OpenEXR file (wrong magic number)", "write the positions as an OpenEXR image");
        return std::nullopt;
    }
    if (!peek_header(head, byte_count, diag)) return std::nullopt;
    in.clear();
    in.seekg(0);
    FileIStream stream(path, in);
    return parse_exr(stream, byte_count, diag, strictness, missing);
}

std::optional<VertexAnimation> parse_bytes(const std::string& bytes, Diagnostics& diag, Strictness strictness,
                                           MissingPoints missing = MissingPoints::refuse) {
    if (!has_exr_magic(bytes.data(), bytes.size())) {
        diag.error("", "not an OpenEXR file (wrong magic number)", "write the positions as an OpenEXR image");
        return std::nullopt;
    }
    if (!peek_header(bytes, bytes.size(), diag)) return std::nullopt;
    MemoryIStream stream(diag.file(), bytes);
    return parse_exr(stream, bytes.size(), diag, strictness, missing);
}

}  // namespace

VertexAnimation read_vertex_animation(const std::string& path, std::vector<Problem>* warnings, MissingPoints missing) {
    Diagnostics diag(path);
    std::optional<VertexAnimation> animation = parse_file(path, diag, Strictness::lenient, missing);
    diag.throw_if_errors();
    if (warnings) *warnings = diag.warnings();
    return std::move(*animation);
}

VertexAnimation read_vertex_animation_from_memory(const std::string& bytes, const std::string& name,
                                                  std::vector<Problem>* warnings) {
    Diagnostics diag(name);
    std::optional<VertexAnimation> animation = parse_bytes(bytes, diag, Strictness::lenient);
    diag.throw_if_errors();
    if (warnings) *warnings = diag.warnings();
    return std::move(*animation);
}

std::vector<Problem> check_vertex_animation(const VertexAnimation& animation, const std::string& file,
                                            MissingPoints missing) {
    Diagnostics diag(file);
    bool sizes_ok = true;
    if (animation.frame_count < 1 || animation.frame_count > kMaxVertexAnimationFrames) {
        diag.error("frame_count", "is " + std::to_string(animation.frame_count) + ", must be in [1, " +
                                      std::to_string(kMaxVertexAnimationFrames) + "]",
                   "store at least one frame");
        sizes_ok = false;
    }
    if (animation.vertex_count < 1 || animation.vertex_count > kMaxVertexAnimationVertices) {
        diag.error("vertex_count", "is " + std::to_string(animation.vertex_count) + ", must be in [1, " +
                                       std::to_string(kMaxVertexAnimationVertices) + "]",
                   "store at least one vertex");
        sizes_ok = false;
    }
    if (sizes_ok) {
        const std::int64_t samples = std::int64_t(animation.frame_count) * animation.vertex_count;
        if (samples > kMaxVertexAnimationSamples)
            diag.error("positions_m", std::to_string(samples) + " samples exceed the limit " +
                                          std::to_string(kMaxVertexAnimationSamples),
                       "split the sequence");
        else if (static_cast<std::int64_t>(animation.positions_m.size()) != samples)
            diag.error("positions_m",
                       "holds " + std::to_string(animation.positions_m.size()) + " positions, expected frame_count x " +
                           "vertex_count = " + std::to_string(samples),
                       "store one position per vertex per frame, frame-major");
        else check_finite_positions(animation, diag, "positions_m", missing);
    }
    if (animation.grid_rows.has_value() != animation.grid_cols.has_value())
        diag.error("grid_rows", "only one of grid_rows and grid_cols is set", "set both or neither");
    else if (animation.grid_rows) {
        if (*animation.grid_rows < 1 || *animation.grid_cols < 1)
            diag.error("grid_rows", "the grid size must be positive", "set rows, cols >= 1");
        else if (std::int64_t(*animation.grid_rows) * *animation.grid_cols != animation.vertex_count)
            diag.error("grid_rows",
                       "grid " + std::to_string(*animation.grid_rows) + " x " + std::to_string(*animation.grid_cols) +
                           " does not have vertex_count = " + std::to_string(animation.vertex_count) + " vertices",
                       "fix the grid or drop it");
    }
    if (!std::isfinite(animation.fps) || animation.fps < 0.0)
        diag.error("fps", "must be a finite number >= 0 (0 = unknown)", "set the frame rate");
    return diag.problems();
}

void write_vertex_animation(const std::string& path, const VertexAnimation& animation, MissingPoints missing) {
    Diagnostics diag(path);
    diag.merge(check_vertex_animation(animation, path, missing));
    diag.throw_if_errors();

    Imf::Header header(animation.vertex_count, animation.frame_count);
    header.compression() = Imf::ZIP_COMPRESSION;  // lossless for float: the round trip is bit-exact
    for (const char* name : kPositionChannels) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    header.insert(kAttrFormat, Imf::StringAttribute(kVertexAnimationFormatName));
    header.insert(kAttrVersion, Imf::StringAttribute(kVertexAnimationFormatVersion.to_string()));
    if (animation.fps > 0.0) header.insert(kAttrFps, Imf::DoubleAttribute(animation.fps));
    if (animation.grid_rows) {
        header.insert(kAttrGridRows, Imf::IntAttribute(*animation.grid_rows));
        header.insert(kAttrGridCols, Imf::IntAttribute(*animation.grid_cols));
    }

    write_path_atomically(path, [&](const std::string& temp_path) {
        try {
            Imf::OutputFile file(temp_path.c_str(), header);
            // OpenEXR's slices take a non-const pointer but only read through it.
            char* base = const_cast<char*>(reinterpret_cast<const char*>(animation.positions_m.data()));
            const std::size_t x_stride = sizeof(Eigen::Vector3f);
            const std::size_t y_stride = x_stride * static_cast<std::size_t>(animation.vertex_count);
            Imf::FrameBuffer buffer;
            for (int c = 0; c < 3; ++c)
                buffer.insert(kPositionChannels[c],
                              Imf::Slice(Imf::FLOAT, base + c * sizeof(float), x_stride, y_stride));
            file.setFrameBuffer(buffer);
            file.writePixels(animation.frame_count);
        } catch (const std::exception& error) {
            throw IoError(path, "", std::string("writing the OpenEXR file failed: ") + error.what(),
                          "check free disk space and permissions");
        }
    });
}

std::vector<Problem> validate_vertex_animation_file(const std::string& path, Strictness strictness,
                                                    MissingPoints missing) {
    Diagnostics diag(path);
    try {
        parse_file(path, diag, strictness, missing);
    } catch (const Error& error) {
        diag.error(error.field(), error.message(), error.fix());
    }
    return diag.problems();
}

std::vector<Problem> validate_vertex_animation_bytes(const std::string& bytes, const std::string& name,
                                                     Strictness strictness) {
    Diagnostics diag(name);
    parse_bytes(bytes, diag, strictness);
    return diag.problems();
}

nlohmann::json summarize_vertex_animation(const VertexAnimation& animation) {
    nlohmann::json summary = {{"format", kVertexAnimationFormatName},
                              {"frames", animation.frame_count},
                              {"vertices", animation.vertex_count}};
    if (animation.fps > 0.0) {
        summary["fps"] = animation.fps;
        summary["duration_s"] = animation.frame_count / animation.fps;
    }
    if (animation.grid_rows) summary["grid"] = {{"rows", *animation.grid_rows}, {"cols", *animation.grid_cols}};
    if (!animation.positions_m.empty() && animation.vertex_count > 0) {
        // Gaps (NaN points of measured tracks) are left out of every figure.
        const float inf = std::numeric_limits<float>::infinity();
        Eigen::Vector3f lo = Eigen::Vector3f::Constant(inf), hi = Eigen::Vector3f::Constant(-inf);
        std::size_t seen = 0;
        for (const Eigen::Vector3f& p : animation.positions_m) {
            if (!p.allFinite()) continue;
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
            ++seen;
        }
        if (seen > 0) {
            summary["bbox_min_m"] = {lo.x(), lo.y(), lo.z()};
            summary["bbox_max_m"] = {hi.x(), hi.y(), hi.z()};
        }
        if (seen < animation.positions_m.size())
            summary["seen_share"] = static_cast<double>(seen) / static_cast<double>(animation.positions_m.size());
        float largest = 0.0f;
        const std::size_t vertices = static_cast<std::size_t>(animation.vertex_count);
        for (std::size_t i = vertices; i < animation.positions_m.size(); ++i) {
            const Eigen::Vector3f move = animation.positions_m[i] - animation.positions_m[i % vertices];
            if (move.allFinite()) largest = std::max(largest, move.norm());
        }
        summary["max_displacement_from_first_frame_m"] = largest;
    }
    return summary;
}

}  // namespace flowvid::formats
