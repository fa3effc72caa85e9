// The libFuzzer driver of every reader. One binary, flowvid_fuzz, serves all
// targets: it is started as fuzz_<target> (a symbolic link the build makes
// for each target) or with FLOWVID_FUZZ_TARGET=<target> in the environment,
// so that the sanitized readers are linked once, not once per target.
// The custom mutator mixes libFuzzer's byte-level mutations with the
// structure-aware ones of structure_mutator.cpp (deep nesting, odd numbers,
// entity amplification, many attributes, glb/EXR headers, ...).
#include "fuzz_entry_points.hpp"
#include "structure_mutator.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

const flowvid::fuzz::FuzzTarget* g_target = nullptr;

const flowvid::fuzz::FuzzTarget& this_target() {
    if (!g_target) std::abort();
    return *g_target;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    if (std::getenv("FLOWVID_FUZZ_LIST")) {
        for (const flowvid::fuzz::FuzzTarget& target : flowvid::fuzz::fuzz_targets())
            std::printf("%s\t%s\n", target.name.c_str(), target.reader.c_str());
        std::exit(0);
    }
    std::string name;
    if (const char* from_environment = std::getenv("FLOWVID_FUZZ_TARGET")) name = from_environment;
    if (name.empty() && *argc > 0) {
        const std::string program = (*argv)[0];
        const std::string base = program.substr(program.find_last_of('/') + 1);
        if (base.rfind("fuzz_", 0) == 0) name = base.substr(5);
    }
    g_target = flowvid::fuzz::find_fuzz_target(name);
    if (!g_target) {
        std::fprintf(stderr, "flowvid_fuzz: unknown target '%s': run it as fuzz_<target> or set FLOWVID_FUZZ_TARGET to one of:",
                     name.c_str());
        for (const flowvid::fuzz::FuzzTarget& target : flowvid::fuzz::fuzz_targets())
            std::fprintf(stderr, " %s", target.name.c_str());
        std::fprintf(stderr, "\n");
        std::exit(2);
    }
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    flowvid::fuzz::fuzz_one_input(this_target(), data, size);
    return 0;
}

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
    flowvid::fuzz::MutationRandom random(seed);
    // About one mutation in three is structure-aware; the rest are libFuzzer's
    // own (which also splice in values from its dictionary and comparisons).
    if (random.one_in(3)) {
        flowvid::fuzz::Bytes bytes(data, data + size);
        if (!flowvid::fuzz::structure_mutate(bytes, this_target().kind, max_size, random.next()).empty() &&
            bytes.size() <= max_size) {
            std::memcpy(data, bytes.data(), bytes.size());
            return bytes.size();
        }
    }
    return LLVMFuzzerMutate(data, size, max_size);
}
