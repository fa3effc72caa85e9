#include "exr_preflight.hpp"

#include <algorithm>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <fstream>

namespace flowvid::formats::detail {

namespace {

constexpr unsigned char kMagic[4] = {0x76, 0x2f, 0x31, 0x01};
constexpr std::uint32_t kTiledFlag = 0x200;
constexpr std::uint32_t kLongNamesFlag = 0x400;
constexpr std::uint32_t kDeepFlag = 0x800;
constexpr std::uint32_t kMultiPartFlag = 0x1000;

// Scan lines per compressed chunk, by OpenEXR compression code.
std::int64_t lines_per_chunk(int compression) {
    switch (compression) {
        case 0: case 1: case 2: return 1;      // none, RLE, ZIPS
        case 3: case 5: return 16;             // ZIP, PXR24
        case 4: case 6: case 7: case 8: return 32;  // PIZ, B44, B44A, DWAA
        case 9: return 256;                    // DWAB
        default: return -1;
    }
}

class Cursor {
public:
    explicit Cursor(const std::string& bytes) : m_bytes(bytes) {}
    bool read_u32(std::uint32_t& out) {
        if (m_at + 4 > m_bytes.size()) return false;
        const auto* p = reinterpret_cast<const unsigned char*>(m_bytes.data()) + m_at;
        out = std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[3]) << 24);
        m_at += 4;
        return true;
    }
    bool read_name(std::string& out, std::size_t max_length) {
        const std::size_t end = m_bytes.find('\0', m_at);
        if (end == std::string::npos || end - m_at > max_length) return false;
        out.assign(m_bytes, m_at, end - m_at);
        m_at = end + 1;
        return true;
    }
    bool peek_nul() const { return m_at < m_bytes.size() && m_bytes[m_at] == '\0'; }
    void skip(std::size_t n) { m_at += n; }
    std::size_t remaining() const { return m_at <= m_bytes.size() ? m_bytes.size() - m_at : 0; }
    std::size_t position() const { return m_at; }

private:
    const std::string& m_bytes;
    std::size_t m_at = 0;
};

std::int64_t channel_bytes(const std::string& value) {
    // chlist: repeated (name\0, int32 type, uint8 pLinear, 3 reserved, int32 xs, int32 ys), then \0.
    std::int64_t total = 0;
    std::size_t at = 0;
    while (at < value.size() && value[at] != '\0') {
        const std::size_t end = value.find('\0', at);
        if (end == std::string::npos || end + 17 > value.size()) return -1;
        const auto* p = reinterpret_cast<const unsigned char*>(value.data()) + end + 1;
        const std::uint32_t type = std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8);
        total += type == 1 ? 2 : 4;  // HALF = 1; UINT = 0 and FLOAT = 2 take 4 bytes
        at = end + 17;
    }
    // OpenEXR reads up to the terminating NUL whatever the declared size, so
    // the list must end exactly at the attribute's end or the rest of the
    // header is read out of step.
    if (at + 1 != value.size()) return -1;
    return total;
}

// OpenEXR reads the value of a known fixed-size type by its type, not by the
// declared size: a box2i declared as 0 bytes would put every later read out
// of step (and size an allocation from stray bytes). 0 for variable sizes and
// types flowvid does not know (OpenEXR reads those as opaque bytes of the
// declared size).
std::uint32_t fixed_attribute_size(const std::string& type) {
    static const std::pair<const char*, std::uint32_t> sizes[] = {
        {"int", 4},          {"float", 4},           {"double", 8},   {"compression", 1}, {"lineOrder", 1},
        {"envmap", 1},       {"deepImageState", 1},  {"box2i", 16},   {"box2f", 16},      {"v2i", 8},
        {"v2f", 8},          {"v2d", 16},            {"v3i", 12},     {"v3f", 12},        {"v3d", 24},
        {"m33f", 36},        {"m33d", 72},           {"m44f", 64},    {"m44d", 128},      {"tiledesc", 9},
        {"chromaticities", 32}, {"keycode", 28},     {"timecode", 8}, {"rational", 8},
    };
    for (const auto& [name, size] : sizes)
        if (type == name) return size;
    return 0;
}

constexpr std::uint64_t kSaturated = std::numeric_limits<std::uint64_t>::max() / 2;

std::uint64_t saturating_product(std::initializer_list<std::uint64_t> factors) {
    std::uint64_t product = 1;
    for (const std::uint64_t factor : factors) {
        if (factor != 0 && product > kSaturated / factor) return kSaturated;
        product *= factor;
    }
    return product;
}

// Pixels along one axis that OpenEXR decodes: whole tiles, or whole chunks of scan lines.
std::uint64_t padded_extent(std::int64_t pixels, std::int64_t tile) {
    const auto n = static_cast<std::uint64_t>(pixels);
    if (tile <= 0) return n;
    const auto t = static_cast<std::uint64_t>(tile);
    return (n + t - 1) / t * t;
}

// Names a part's data window the way flowvid's EXR messages do.
std::string window_field(const ExrPeek& peek, const ExrPartPeek& part) {
    if (!peek.multi_part) return "data window";
    return "part \"" + part.name + "\" dataWindow";
}

// Rows OpenEXR decodes at once: a tile's height, or a scan-line chunk's lines.
std::int64_t decoded_rows_at_once(const ExrPartPeek& part) {
    return part.tile_width > 0 ? part.tile_height : part.scan_lines_per_chunk;
}

}  // namespace

std::string read_file_head(const std::string& path, std::size_t bytes) {
    std::ifstream in(path, std::ios::binary);
    std::string head(bytes, '\0');
    in.read(head.data(), static_cast<std::streamsize>(bytes));
    head.resize(static_cast<std::size_t>(in.gcount()));
    return head;
}

std::optional<ExrPeek> preflight_exr(const std::string& head, std::uint64_t file_size, Diagnostics& diagnostics,
                                     std::uint64_t max_compression_ratio) {
    auto fail = [&](const std::string& message, const std::string& fix) -> std::optional<ExrPeek> {
        diagnostics.error("header", message, fix);
        return std::nullopt;
    };
    const std::string truncated_fix = "the file is truncated or corrupt: write it again from its source";
    if (head.size() < 8 || std::memcmp(head.data(), kMagic, 4) != 0)
        return fail("not an OpenEXR file (the first bytes are not 76 2f 31 01)", "give an OpenEXR file");
    Cursor cursor(head);
    cursor.skip(4);
    std::uint32_t version = 0;
    cursor.read_u32(version);
    if ((version & 0xff) != 2)
        return fail("OpenEXR file version " + std::to_string(version & 0xff) + " (expected 2)", "write it with OpenEXR 2 or later");
    ExrPeek peek;
    peek.multi_part = (version & kMultiPartFlag) != 0;
    peek.deep = (version & kDeepFlag) != 0;
    const std::size_t max_name = (version & kLongNamesFlag) ? 255 : 31;

    for (;;) {
        if (peek.multi_part && !peek.parts.empty() && cursor.peek_nul()) break;  // empty header ends the list
        if (peek.parts.size() >= 64) return fail("more than 64 parts", "flowvid files have at most a few parts");
        ExrPartPeek part;
        bool has_window = false;
        int compression = 0;
        std::int64_t most_lines_per_chunk = 1;  // over every "compression" attribute, should there be several
        bool tiled_part = (version & kTiledFlag) != 0;
        std::int64_t declared_chunks = -1;
        for (;;) {
            std::string name, type;
            if (!cursor.read_name(name, max_name))
                return fail(cursor.remaining() == 0 ? "the header is cut off" : "an attribute name is malformed or too long",
                            truncated_fix);
            if (name.empty()) break;
            std::uint32_t size = 0;
            if (!cursor.read_name(type, max_name) || !cursor.read_u32(size)) return fail("the header is cut off", truncated_fix);
            if (size > cursor.remaining())
                return fail("attribute '" + name + "' declares " + std::to_string(size) + " bytes, more than the header holds",
                            truncated_fix);
            if (const std::uint32_t expected = fixed_attribute_size(type); expected != 0 && size != expected)
                return fail("attribute '" + name + "' of type " + type + " declares " + std::to_string(size) +
                                " bytes; a " + type + " has " + std::to_string(expected),
                            truncated_fix);
            const std::string value = head.substr(cursor.position(), size);
            const auto* v = reinterpret_cast<const unsigned char*>(value.data());
            auto i32 = [&](std::size_t at) {
                return static_cast<std::int32_t>(std::uint32_t(v[at]) | (std::uint32_t(v[at + 1]) << 8) |
                                                 (std::uint32_t(v[at + 2]) << 16) | (std::uint32_t(v[at + 3]) << 24));
            };
            // Variable-size types whose inner lengths OpenEXR trusts.
            bool inner_ok = true;
            const std::int64_t chlist_bytes = type == "chlist" ? channel_bytes(value) : 0;
            if (type == "stringvector") {
                std::size_t at = 0;
                while (inner_ok && at < size) {
                    inner_ok = size - at >= 4 && static_cast<std::uint32_t>(i32(at)) <= size - at - 4;
                    if (inner_ok) at += 4 + static_cast<std::uint32_t>(i32(at));
                }
            } else if (type == "preview") {
                inner_ok = size >= 8 && std::uint64_t(static_cast<std::uint32_t>(i32(0))) *
                                                static_cast<std::uint32_t>(i32(4)) * 4 == size - 8;
            } else if (type == "floatvector") {
                inner_ok = size % 4 == 0;
            } else if (type == "chlist") {
                inner_ok = chlist_bytes >= 0;  // any chlist, not only "channels": OpenEXR reads each to its NUL
            }
            if (!inner_ok)
                return fail("attribute '" + name + "' (" + type + ") is malformed", truncated_fix);
            if (name == "dataWindow" && type == "box2i" && size == 16) {
                part.width = std::int64_t(i32(8)) - i32(0) + 1;
                part.height = std::int64_t(i32(12)) - i32(4) + 1;
                has_window = true;
            } else if (name == "tiles" && type == "tiledesc" && size == 9) {
                part.tile_width = static_cast<std::uint32_t>(i32(0));
                part.tile_height = static_cast<std::uint32_t>(i32(4));
            } else if (name == "compression" && size == 1) {
                compression = v[0];
                most_lines_per_chunk = std::max(most_lines_per_chunk, lines_per_chunk(compression));
            } else if (name == "channels" && type == "chlist") {
                part.bytes_per_pixel = chlist_bytes;  // >= 0: checked above with every chlist
            } else if (name == "name" && type == "string") {
                part.name = value;
            } else if (name == "type" && type == "string") {
                tiled_part = value == "tiledimage" || value == "deeptile";
                peek.deep = peek.deep || value.rfind("deep", 0) == 0;
            } else if (name == "chunkCount" && type == "int" && size == 4) {
                declared_chunks = i32(0);
            }
            cursor.skip(size);
        }
        if (!has_window) return fail("a part without a dataWindow attribute", truncated_fix);
        const std::string which = peek.multi_part ? "part " + std::to_string(peek.parts.size()) + " " : "";
        if (part.width < 1 || part.height < 1 || part.width > (1LL << 31) || part.height > (1LL << 31)) {
            diagnostics.error(window_field(peek, part), std::to_string(part.width) + " x " + std::to_string(part.height) +
                                                            " pixels is empty or implausibly large",
                              truncated_fix);
            return std::nullopt;
        }
        if (!tiled_part) part.tile_width = part.tile_height = 0;  // a stray "tiles" attribute is ignored
        if (tiled_part) {
            if (part.tile_width < 1 || part.tile_height < 1) return fail(which + "tiled without a valid tile size", truncated_fix);
            part.chunk_count = ((part.width + part.tile_width - 1) / part.tile_width) *
                               ((part.height + part.tile_height - 1) / part.tile_height);
        } else {
            const std::int64_t lines = lines_per_chunk(compression);
            if (lines < 0) return fail(which + "unknown compression code " + std::to_string(compression), truncated_fix);
            part.chunk_count = (part.height + lines - 1) / lines;
            part.scan_lines_per_chunk = std::max(lines, most_lines_per_chunk);
        }
        if (declared_chunks >= 0 && declared_chunks != part.chunk_count && !tiled_part)
            return fail(which + "chunkCount " + std::to_string(declared_chunks) + " does not match the data window (" +
                            std::to_string(part.chunk_count) + ")",
                        truncated_fix);
        peek.parts.push_back(part);
        if (!peek.multi_part) break;
    }

    // Each chunk has an 8-byte offset in the file, and compression cannot pack
    // real pixels tighter than max_compression_ratio. OpenEXR decodes a tiled
    // part a whole tile at a time, so tiles larger than the data window count at
    // their full size (a 4 x 2 image in 4 x 40M tiles made it reserve 1.9 GB),
    // and a scan-line part whole chunks of lines (a ZIP image one line high but
    // 7.5M pixels wide made its decompressor reserve 16 lines: 1.4 GB).
    std::uint64_t chunks = 0;
    std::uint64_t raw_bytes = 0;
    std::uint64_t largest_part_bytes = 0;
    const ExrPartPeek* largest = &peek.parts.front();
    for (const ExrPartPeek& part : peek.parts) {
        chunks += static_cast<std::uint64_t>(part.chunk_count);
        const std::uint64_t bytes = saturating_product({padded_extent(part.width, part.tile_width),
                                                        padded_extent(part.height, decoded_rows_at_once(part)),
                                                        static_cast<std::uint64_t>(part.bytes_per_pixel)});
        raw_bytes = std::min(raw_bytes + bytes, kSaturated);
        if (bytes > largest_part_bytes) {
            largest_part_bytes = bytes;
            largest = &part;
        }
    }
    if (chunks * 8 > file_size)
        return fail(std::to_string(chunks) + " chunks cannot fit in a file of " + std::to_string(file_size) + " bytes",
                    truncated_fix);
    if (!peek.deep && raw_bytes > (std::uint64_t(1) << 20) && raw_bytes / max_compression_ratio > file_size) {
        const bool pads = padded_extent(largest->width, largest->tile_width) != std::uint64_t(largest->width) ||
                          padded_extent(largest->height, decoded_rows_at_once(*largest)) != std::uint64_t(largest->height);
        std::string tiles;
        if (pads && largest->tile_width > 0)
            tiles = " (its " + std::to_string(largest->tile_width) + " x " + std::to_string(largest->tile_height) +
                    "-pixel tiles are decoded whole)";
        else if (pads)
            tiles = " (its " + std::to_string(largest->height) + "-line image is decoded " +
                    std::to_string(largest->scan_lines_per_chunk) + " lines at a time)";
        diagnostics.error(window_field(peek, *largest),
                          "the header declares " + std::to_string(raw_bytes) + " bytes of decoded data" + tiles +
                              ", more than a " + std::to_string(file_size) + "-byte file can hold",
                          truncated_fix);
        return std::nullopt;
    }
    return peek;
}

}  // namespace flowvid::formats::detail
