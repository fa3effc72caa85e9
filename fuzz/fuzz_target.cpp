// libFuzzer target; FLOWVID_FUZZ_TARGET names the reader (see fuzz_entry_points.cpp).
#include "fuzz_entry_points.hpp"

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const flowvid::fuzz::FuzzTarget* target = flowvid::fuzz::find_fuzz_target(FLOWVID_FUZZ_TARGET);
    if (!target) std::abort();
    flowvid::fuzz::fuzz_one_input(*target, data, size);
    return 0;
}
