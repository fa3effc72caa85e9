#pragma once
// Fuzz entry points: one per reader, all going through the same validator that
// `flowvid validate` uses. Shared by the libFuzzer targets (fuzz/fuzz_*.cpp,
// FLOWVID_BUILD_FUZZ=ON with clang) and the corpus replay run in every test suite.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace flowvid::fuzz {

struct FuzzTarget {
    std::string name;         // corpus sub-folder, e.g. "fabric_json"
    std::string file_name;    // how the input is named on disk, e.g. "input.fabric.json"
};

const std::vector<FuzzTarget>& fuzz_targets();
const FuzzTarget* find_fuzz_target(const std::string& name);

// Writes the bytes to a private temporary file and validates it. Returns the
// number of problems found. Any exception other than flowvid's own, and any
// crash, is a bug the fuzzer reports.
std::size_t fuzz_one_input(const FuzzTarget& target, const std::uint8_t* data, std::size_t size);

}  // namespace flowvid::fuzz
