// EXR headers that declare more than the file holds are refused before
// OpenEXR allocates anything (a fuzzer found a 3.7 KB bank that made OpenEXR
// reserve 1.7 GB for one attribute).

#include "flowvid/formats/particle_bank.hpp"
#include "flowvid/formats/vertex_animation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>

using namespace flowvid;
using namespace flowvid::formats;
using flowvid::testing::read_text;
using flowvid::testing::scratch_dir;
using flowvid::testing::source_path;
using flowvid::testing::test_data;
using flowvid::testing::write_text;

namespace {

long peak_rss_kb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss;
}

std::string joined(const std::vector<Problem>& problems) {
    std::string text;
    for (const Problem& p : problems) text += p.to_string() + "\n";
    return text;
}

// Overwrites 4 little-endian bytes at `at`.
void poke_u32(std::string& bytes, std::size_t at, std::uint32_t value) {
    for (int i = 0; i < 4; ++i) bytes[at + i] = static_cast<char>((value >> (8 * i)) & 0xff);
}

}  // namespace

TEST(ExrPreflight, HugeAttributeSizeIsRefusedWithoutAllocating) {
    const std::string path = test_data("formats/exr/huge_attribute_size.bank.exr");
    const long before = peak_rss_kb();
    const std::vector<Problem> problems = validate_particle_bank_file(path, Strictness::strict);
    const std::string text = joined(problems);
    EXPECT_NE(text.find(path + ": header: attribute 'flowvid.dynamics' declares"), std::string::npos) << text;
    EXPECT_LT(peak_rss_kb() - before, 64 * 1024) << "the reader allocated more than 64 MB for a 4 KB file";
}

TEST(ExrPreflight, DataWindowLargerThanTheFileIsRefused) {
    // A valid vertex-animation file whose dataWindow is stretched to 16M lines:
    // its offset table alone would need 128 MB.
    std::string bytes = read_text(source_path("formats/examples/example.vertex_animation.exr"));
    const std::size_t window = bytes.find("dataWindow");
    ASSERT_NE(window, std::string::npos);
    const std::size_t value = window + std::string("dataWindow").size() + 1 + std::string("box2i").size() + 1 + 4;
    poke_u32(bytes, value + 12, (1u << 24) - 2);  // max_y
    const std::string path = scratch_dir("exr_preflight") + "/stretched.exr";
    write_text(path, bytes);
    const std::string text = joined(validate_vertex_animation_file(path, Strictness::strict));
    EXPECT_NE(text.find(path + ": header:"), std::string::npos) << text;
    EXPECT_NE(text.find("cannot fit in a file"), std::string::npos) << text;
}

TEST(ExrPreflight, TilesLargerThanTheImageCountAtTheirDecodedSize) {
    // 465 bytes: a 4 x 2 float RGB image in tiles 4 x 40M pixels. OpenEXR
    // decodes whole tiles, so it reserved 1.9 GB (found by the CI fuzz run).
    const std::string path = test_data("formats/exr/huge_tiles.vertex_animation.exr");
    const long before = peak_rss_kb();
    const std::string text = joined(validate_vertex_animation_file(path, Strictness::strict));
    EXPECT_NE(text.find(path + ": data window: the header declares " + std::to_string(4ull * 40'000'000 * 12) +
                        " bytes of decoded data (its 4 x 40000000-pixel tiles are decoded whole)"),
              std::string::npos)
        << text;
    EXPECT_LT(peak_rss_kb() - before, 64 * 1024) << "the reader allocated more than 64 MB for a 465-byte file";

    // The same file with its 4 x 4 tiles (as written) reads: tiles are not refused as such.
    const VertexAnimation tiled = read_vertex_animation(test_data("formats/exr/tiled.vertex_animation.exr"));
    EXPECT_EQ(tiled.vertex_count, 4);
    EXPECT_EQ(tiled.frame_count, 2);
    EXPECT_FLOAT_EQ(tiled.positions_m.back().z(), 0.5f);
}

TEST(ExrPreflight, ScanLineChunksCountAtTheirDecodedSize) {
    // 337 bytes: a float RGB image one line high and 100 000 pixels wide,
    // ZIP-compressed. OpenEXR decodes ZIP 16 lines at a time, so the line
    // counts as 16: 19.2 MB, more than 4096 x 337 bytes. Counted as one line
    // (1.2 MB) it passed; the fuzzer's 7.5M-pixel line made it reserve 1.4 GB.
    const std::string path = test_data("formats/exr/wide_zip_line.vertex_animation.exr");
    const long before = peak_rss_kb();
    const std::string text = joined(validate_vertex_animation_file(path, Strictness::strict));
    EXPECT_NE(text.find(path + ": data window: the header declares " + std::to_string(16ull * 100'000 * 12) +
                        " bytes of decoded data (its 1-line image is decoded 16 lines at a time), more than a 337-byte file"),
              std::string::npos)
        << text;
    EXPECT_LT(peak_rss_kb() - before, 64 * 1024) << "the reader allocated more than 64 MB for a 337-byte file";
}

TEST(ExrPreflight, ValidFilesPass) {
    EXPECT_TRUE(validate_particle_bank_file(source_path("formats/examples/example.bank.exr"), Strictness::strict).empty());
    EXPECT_TRUE(validate_vertex_animation_file(source_path("formats/examples/example.vertex_animation.exr"), Strictness::strict)
                    .empty());
}
