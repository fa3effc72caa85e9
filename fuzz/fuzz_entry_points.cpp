#include "fuzz_entry_points.hpp"

#include "flowvid/formats/any_file.hpp"

#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace flowvid::fuzz {
namespace fs = std::filesystem;

const std::vector<FuzzTarget>& fuzz_targets() {
    static const std::vector<FuzzTarget> targets = {
        {"fabric_json", "input.fabric.json"},
        {"flowlines_json", "input.flowlines.json"},
        {"flowlines_svg", "input.svg"},
        {"capture_json", "capture.json"},
        {"particle_bank", "input.bank.exr"},
        {"vertex_animation", "input.exr"},
        {"motion_gltf", "input.glb"},
    };
    return targets;
}

const FuzzTarget* find_fuzz_target(const std::string& name) {
    for (const FuzzTarget& target : fuzz_targets())
        if (target.name == name) return &target;
    return nullptr;
}

std::size_t fuzz_one_input(const FuzzTarget& target, const std::uint8_t* data, std::size_t size) {
    // Readers take paths (as users give them), so the input goes through a file.
    static const fs::path folder = fs::temp_directory_path() / ("flowvid-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(folder);
    const fs::path path = folder / target.file_name;
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    // A capture.json is validated as its folder, the way users name captures.
    const std::string subject = target.name == "capture_json" ? folder.string() : path.string();
    return formats::validate_any_file(subject).size();
}

}  // namespace flowvid::fuzz
