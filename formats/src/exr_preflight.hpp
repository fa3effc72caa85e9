#pragma once
// Reading an OpenEXR header ourselves before OpenEXR does: the library sizes its
// offset tables and line buffers from header fields, so a corrupt or hostile
// header of a few bytes could make it reserve gigabytes. Every flowvid EXR
// reader calls preflight_exr first and hands the file to OpenEXR only when the
// declared sizes are consistent with the file's size.

#include "flowvid/error.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::formats::detail {

struct ExrPartPeek {
    std::string name;              // "name" attribute (multi-part files), empty otherwise
    std::int64_t width = 0;        // data window size, pixels
    std::int64_t height = 0;
    std::int64_t tile_width = 0;   // 0 for scan-line parts
    std::int64_t tile_height = 0;
    // Scan-line parts: lines OpenEXR decodes at once (by compression; the
    // most any "compression" attribute of the header asks for); 0 for tiles.
    std::int64_t scan_lines_per_chunk = 0;
    std::int64_t bytes_per_pixel = 0;  // sum over channels (full resolution)
    std::int64_t chunk_count = 0;      // offset-table entries OpenEXR will read
};

struct ExrPeek {
    bool multi_part = false;
    bool deep = false;
    std::vector<ExrPartPeek> parts;
};

// `head` holds the file's first bytes (all of the header: 64 KiB is plenty for
// flowvid files; a header longer than `head` is reported as too large), and
// `file_size` the whole file's size. Problems go to `diagnostics` with field "header".
// Checks: magic, version 2, attribute framing, a data window per part, channel
// sizes, and that the offset table and the raw pixels (compressed by at most
// `max_compression_ratio`) can fit in `file_size` bytes.
std::optional<ExrPeek> preflight_exr(const std::string& head, std::uint64_t file_size, Diagnostics& diagnostics,
                                     std::uint64_t max_compression_ratio = 4096);

// Reads up to `bytes` from the start of a file.
std::string read_file_head(const std::string& path, std::size_t bytes);

}  // namespace flowvid::formats::detail
