#include "flowvid/cloth/material.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace flowvid::cloth {

namespace {

// One table for both directions of the conversion and for the checks.
struct Binding {
    formats::FabricParameter formats::FabricParameters::*preset;
    double ClothMaterial::*material;
};

const Binding kBindings[] = {
    {&formats::FabricParameters::areal_density_kg_per_m2, &ClothMaterial::areal_density_kg_per_m2},
    {&formats::FabricParameters::stretch_warp_stiffness_N_per_m, &ClothMaterial::stretch_warp_N_per_m},
    {&formats::FabricParameters::stretch_weft_stiffness_N_per_m, &ClothMaterial::stretch_weft_N_per_m},
    {&formats::FabricParameters::shear_stiffness_N_per_m, &ClothMaterial::shear_N_per_m},
    {&formats::FabricParameters::bend_stiffness_N_m, &ClothMaterial::bend_N_m},
    {&formats::FabricParameters::stretch_warp_damping_N_s_per_m, &ClothMaterial::stretch_warp_damping_N_s_per_m},
    {&formats::FabricParameters::stretch_weft_damping_N_s_per_m, &ClothMaterial::stretch_weft_damping_N_s_per_m},
    {&formats::FabricParameters::shear_damping_N_s_per_m, &ClothMaterial::shear_damping_N_s_per_m},
    {&formats::FabricParameters::bend_damping_N_m_s, &ClothMaterial::bend_damping_N_m_s},
    {&formats::FabricParameters::drag_normal_kg_per_m3, &ClothMaterial::drag_normal_kg_per_m3},
    {&formats::FabricParameters::drag_degradation_s2_per_m2, &ClothMaterial::drag_degradation_s2_per_m2},
    {&formats::FabricParameters::drag_tangential_kg_per_m2_s, &ClothMaterial::drag_tangential_kg_per_m2_s},
    {&formats::FabricParameters::stretch_warp_compression_ratio, &ClothMaterial::stretch_warp_compression_ratio},
    {&formats::FabricParameters::stretch_weft_compression_ratio, &ClothMaterial::stretch_weft_compression_ratio},
    {&formats::FabricParameters::drag_linear_normal_kg_per_m2_s, &ClothMaterial::drag_linear_normal_kg_per_m2_s},
    {&formats::FabricParameters::hem_line_density_kg_per_m, &ClothMaterial::hem_line_density_kg_per_m},
    {&formats::FabricParameters::diagonal_tension_stiffness_N_per_m, &ClothMaterial::diagonal_tension_N_per_m},
    {&formats::FabricParameters::shear_cell_fraction, &ClothMaterial::shear_cell_fraction},
};

const Binding& binding_of(double ClothMaterial::*member) {
    for (const Binding& b : kBindings)
        if (b.material == member) return b;
    throw std::logic_error("a ClothMaterial member without a preset key");
}

const char* preset_key(formats::FabricParameter formats::FabricParameters::*member) {
    for (const formats::FabricParameterInfo& info : formats::fabric_parameter_table())
        if (info.member == member) return info.key;
    return "?";
}

}  // namespace

ClothMaterial material_from_fabric(const formats::FabricParameters& parameters) {
    ClothMaterial material;
    for (const Binding& b : kBindings) material.*b.material = (parameters.*b.preset).value;
    return material;
}

formats::FabricParameters fabric_from_material(const ClothMaterial& material) {
    formats::FabricParameters parameters;
    for (const Binding& b : kBindings) (parameters.*b.preset).value = material.*b.material;
    return parameters;
}

double fold_length_m(const ClothMaterial& material, double gravity_m_per_s2) {
    const double weight_N_per_m2 = material.areal_density_kg_per_m2 * std::abs(gravity_m_per_s2);
    if (!(material.bend_N_m > 0.0) || !(weight_N_per_m2 > 0.0)) return 0.0;
    return std::cbrt(material.bend_N_m / weight_N_per_m2);
}

FoldCheck check_folds(const ClothMaterial& material, double edge_m, double gravity_m_per_s2) {
    FoldCheck check;
    check.fold_length_m = fold_length_m(material, gravity_m_per_s2);
    check.edge_m = edge_m;
    check.longest_edge_m = kLongestEdgePerFoldLength * check.fold_length_m;
    check.holds_folds = !(check.fold_length_m > 0.0 && edge_m > check.longest_edge_m);
    return check;
}

std::vector<Problem> check_material(const ClothMaterial& material) {
    std::vector<Problem> problems;
    auto add = [&](const Binding& b, const std::string& message, const std::string& fix) {
        Problem p;
        p.file = "<material>";
        p.field = std::string("/parameters/") + preset_key(b.preset) + "/value";
        p.message = message;
        p.fix = fix;
        problems.push_back(std::move(p));
    };
    for (const Binding& b : kBindings) {
        const double value = material.*b.material;
        if (!std::isfinite(value)) add(b, "is not a finite number", "give a finite SI value");
    }
    if (std::isfinite(material.areal_density_kg_per_m2) && !(material.areal_density_kg_per_m2 > 0.0))
        add(kBindings[0], "must be positive (the cloth needs mass)", "give the fabric's areal density in kg/m^2");
    if (std::isfinite(material.shear_cell_fraction) && !(material.shear_cell_fraction >= 0.0 && material.shear_cell_fraction <= 1.0))
        add(binding_of(&ClothMaterial::shear_cell_fraction), "is a share and must lie in [0, 1]",
            "give 0 (shear read across each triangle), 1 (on a grid's cells) or a share between");
    // The optional terms are not preset keys: named by their members.
    const std::pair<const char*, double> optional_terms[] = {
        {"bias_angle_rad", material.bias_angle_rad},
        {"bend_memory_rate_per_s", material.bend_memory_rate_per_s},
    };
    for (const auto& [name, value] : optional_terms)
        if (!std::isfinite(value)) {
            Problem p;
            p.file = "<material>";
            p.field = name;
            p.message = "is not a finite number";
            p.fix = "give a finite SI value (0 switches the term off)";
            problems.push_back(std::move(p));
        }
    return problems;
}

formats::FabricPreset read_preset_for_simulation(const std::string& path, std::vector<Problem>* warnings) {
    formats::FabricPreset preset = formats::read_fabric_preset(path, warnings);
    std::vector<Problem> problems = check_material(material_from_fabric(preset.parameters));
    if (!problems.empty()) {
        for (Problem& problem : problems) problem.file = path;
        throw ValidationError(problems);
    }
    return preset;
}

}  // namespace flowvid::cloth
