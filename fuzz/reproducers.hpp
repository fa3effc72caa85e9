#pragma once
// The reproducers of issue #34 that are too big to keep as files (hundreds
// of kilobytes to megabytes), generated at full size. The small ones are
// files in fuzz/regressions/<target>/. Both are replayed by the fuzz.regressions
// test (tests/fuzz/fuzz_replay.cpp) and by scripts/fuzz.sh; write them out with
//   flowvid_fuzz_replay write-generated DIR
// to feed one to `flowvid validate` or a libFuzzer binary.

#include "structure_mutator.hpp"

#include <string>
#include <vector>

namespace flowvid::fuzz {

struct Reproducer {
    std::string target;  // fuzz target (fuzz_entry_points.cpp)
    std::string name;    // file name when written out
    std::string what;    // the case, as the issue states it
    Bytes bytes;
};

std::vector<Reproducer> generated_reproducers();

}  // namespace flowvid::fuzz
