#pragma once
// Fuzz entry points: one per reader. Each writes the bytes where a user's file
// would be and runs what `flowvid validate` and `flowvid info` run on it
// (formats::validate_any_file, formats::summarize_any_file), then, when the
// file reads, what the rest of flowvid does with what it read (round trips to
// JSON/SVG, the flow-line helpers, a capture's tracks and truth, a shard set).
// Shared by the libFuzzer targets (fuzz/fuzz_target.cpp, FLOWVID_BUILD_FUZZ=ON
// with clang) and the g++ corpus replay run in every test suite
// (tests/fuzz/fuzz_replay.cpp).
//
// The contract under test: for ANY bytes, the reader returns problems or
// throws flowvid::Error (IoError / ValidationError); any other exception
// escapes fuzz_one_input and is a bug, and so is a crash, a hang or an
// unbounded allocation.

#include "structure_mutator.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace flowvid::fuzz {

struct FuzzTarget {
    std::string name;       // corpus sub-folder and libFuzzer binary suffix, e.g. "fabric_json"
    std::string file_name;  // how the input is named on disk, e.g. "input.fabric.json"
    InputKind kind;         // which structure-aware mutations apply
    std::string reader;     // what it exercises (for RESULTS.md and messages)
};

const std::vector<FuzzTarget>& fuzz_targets();
const FuzzTarget* find_fuzz_target(const std::string& name);

// Runs one input through the target's reader. Returns the number of problems
// the validator found. Exceptions other than flowvid::Error propagate.
std::size_t fuzz_one_input(const FuzzTarget& target, const std::uint8_t* data, std::size_t size);

}  // namespace flowvid::fuzz
