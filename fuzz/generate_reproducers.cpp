// Writes the generated reproducers of issue #34 (fuzz/reproducers.cpp) as
// files, DIR/<target>/<name>, for scripts/fuzz.sh to replay through the
// sanitized libFuzzer binary:  flowvid_fuzz_generate DIR
#include "reproducers.hpp"

#include <filesystem>
#include <fstream>
#include <iostream>

int main(int argc, char** argv) {
    if (argc != 2) {
        std::cerr << "usage: flowvid_fuzz_generate DIR\n";
        return 2;
    }
    for (const flowvid::fuzz::Reproducer& reproducer : flowvid::fuzz::generated_reproducers()) {
        const std::filesystem::path path = std::filesystem::path(argv[1]) / reproducer.target / reproducer.name;
        std::filesystem::create_directories(path.parent_path());
        std::ofstream out(path, std::ios::binary);
        out.write(reinterpret_cast<const char*>(reproducer.bytes.data()), static_cast<std::streamsize>(reproducer.bytes.size()));
        if (!out) {
            std::cerr << "cannot write " << path << "\n";
            return 1;
        }
    }
    return 0;
}
