// A short, deterministic fuzz run for the test suite: every corpus file of every
// reader, plus seeded mutations of it (bit flips, truncations, insertions,
// splices), goes through the validator. Passing means no crash, no hang and no
// exception escaping the validator. Usage: flowvid_fuzz_replay CORPUS_DIR MUTATIONS_PER_TARGET

#include "fuzz_entry_points.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>

namespace fs = std::filesystem;
using namespace flowvid::fuzz;

namespace {

std::vector<std::uint8_t> read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::uint8_t> mutate(const std::vector<std::uint8_t>& input, std::mt19937& random) {
    std::vector<std::uint8_t> bytes = input;
    const int edits = 1 + static_cast<int>(random() % 4);
    for (int e = 0; e < edits; ++e) {
        const std::size_t size = bytes.size();
        switch (random() % 5) {
            case 0:  // flip a bit
                if (size) bytes[random() % size] ^= static_cast<std::uint8_t>(1u << (random() % 8));
                break;
            case 1:  // truncate
                if (size) bytes.resize(random() % size);
                break;
            case 2:  // insert an interesting byte
                bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(size ? random() % size : 0),
                             static_cast<std::uint8_t>("\0\xff{}[]\",:-0e9<>/&"[random() % 17]));
                break;
            case 3:  // overwrite with a large number's bytes (sizes in binary headers)
                if (size >= 4) {
                    const std::size_t at = random() % (size - 3);
                    for (int i = 0; i < 4; ++i) bytes[at + i] = 0xff;
                }
                break;
            default:  // duplicate a slice
                if (size > 2) {
                    const std::size_t from = random() % size;
                    const std::size_t length = std::min<std::size_t>(random() % 64, size - from);
                    std::vector<std::uint8_t> slice(bytes.begin() + static_cast<std::ptrdiff_t>(from),
                                                    bytes.begin() + static_cast<std::ptrdiff_t>(from + length));
                    bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(random() % size), slice.begin(), slice.end());
                }
        }
    }
    return bytes;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::cerr << "usage: flowvid_fuzz_replay CORPUS_DIR MUTATIONS_PER_TARGET\n";
        return 2;
    }
    const fs::path corpus_root = argv[1];
    const int mutations = std::stoi(argv[2]);
    std::mt19937 random(20261121);  // fixed seed: the same run every time
    int targets_run = 0;
    long inputs = 0;
    for (const FuzzTarget& target : fuzz_targets()) {
        const fs::path folder = corpus_root / target.name;
        if (!fs::is_directory(folder)) continue;
        std::vector<std::vector<std::uint8_t>> seeds;
        std::vector<fs::path> files;
        for (const auto& entry : fs::directory_iterator(folder))
            if (entry.is_regular_file()) files.push_back(entry.path());
        std::sort(files.begin(), files.end());
        for (const fs::path& file : files) seeds.push_back(read_bytes(file));
        if (seeds.empty()) continue;
        const auto start = std::chrono::steady_clock::now();
        for (const auto& seed : seeds) {
            fuzz_one_input(target, seed.data(), seed.size());
            ++inputs;
        }
        for (int i = 0; i < mutations; ++i) {
            const std::vector<std::uint8_t> input = mutate(seeds[random() % seeds.size()], random);
            fuzz_one_input(target, input.data(), input.size());
            ++inputs;
        }
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::cerr << target.name << ": " << seeds.size() << " seeds, " << mutations << " mutations, " << seconds
                  << " s\n";
        ++targets_run;
    }
    std::cout << "fuzz replay: " << targets_run << " targets, " << inputs << " inputs, no crash\n";
    return targets_run > 0 ? 0 : 1;
}
