#pragma once
// The preset the converters' tests (U3M, OpenUSD) round-trip: the example
// preset made anisotropic, with every 1.1 parameter away from its neutral
// value and a description needing escapes, so a conversion that drops or
// swaps a value cannot pass.

#include "flowvid/formats/fabric_preset.hpp"
#include "test_support.hpp"

#include <array>

namespace flowvid::testing {

inline formats::FabricPreset converter_test_preset() {
    formats::FabricPreset preset = formats::read_fabric_preset(source_path("formats/examples/cotton.fabric.json"));
    formats::FabricParameters& p = preset.parameters;
    p.stretch_weft_stiffness_N_per_m.value = 610.25;
    p.stretch_weft_stiffness_N_per_m.uncertainty = 33.5;
    p.bend_stiffness_N_m.value = 1.2345678901234567e-5;
    p.stretch_warp_compression_ratio.value = 0.125;
    p.stretch_weft_compression_ratio.value = 0.0625;
    p.drag_linear_normal_kg_per_m2_s = {0.07, 0.01, std::array<double, 2>{0.0, 10.0}};
    p.hem_line_density_kg_per_m.value = 0.003;
    p.diagonal_tension_stiffness_N_per_m.value = 45.0;
    preset.description = "line one \"quoted\"\nline two \\ backslash";
    return preset;
}

}  // namespace flowvid::testing
