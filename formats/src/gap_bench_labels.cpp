#include "flowvid/formats/gap_bench_labels.hpp"

#include "json_extras.hpp"

#include <cmath>
#include <limits>
#include <set>

namespace flowvid::formats {

namespace {

using detail::expect_object;
using detail::non_empty_string;

constexpr const char* kCaseKinds[] = {"cloth", "rigid"};

// "RxC" with 1 <= R, C <= 10000.
bool is_mesh_size(const std::string& text) {
    const std::size_t x = text.find('x');
    if (x == std::string::npos || x == 0 || x + 1 >= text.size() || x > 5 || text.size() - x - 1 > 5) return false;
    for (std::size_t i = 0; i < text.size(); ++i)
        if (i != x && (text[i] < '0' || text[i] > '9')) return false;
    const int rows = std::stoi(text.substr(0, x)), cols = std::stoi(text.substr(x + 1));
    return rows >= 1 && rows <= 10000 && cols >= 1 && cols <= 10000;
}

// A case id names a folder under cases/ and results/.
bool is_folder_name(const std::string& id) {
    return !id.empty() && id != "." && id != ".." && id.find('/') == std::string::npos &&
           id.find('\\') == std::string::npos && id.find('\0') == std::string::npos;
}

std::optional<std::uint64_t> parse_seed(const JsonView& root) {
    if (!root.has("seed")) {
        root.diagnostics().error("/seed", "missing", "add \"seed\": the draw's seed, an integer >= 0");
        return std::nullopt;
    }
    const nlohmann::json& seed = root.json().at("seed");
    if (seed.is_number_unsigned()) return seed.get<std::uint64_t>();
    if (seed.is_number_integer() && seed.get<std::int64_t>() >= 0) return static_cast<std::uint64_t>(seed.get<std::int64_t>());
    if (seed.is_number_float() && std::isfinite(seed.get<double>()) && seed.get<double>() >= 0.0 &&
        seed.get<double>() <= 9007199254740992.0 && seed.get<double>() == std::floor(seed.get<double>()))
        return static_cast<std::uint64_t>(seed.get<double>());
    root.diagnostics().error("/seed", "expected an integer in [0, 2^64), found " + seed.dump().substr(0, 24),
                             "write the seed the cases were drawn with (--seed)");
    return std::nullopt;
}

std::optional<GapBenchLabel> parse_case(const JsonView& entry, std::set<std::string>& ids) {
    if (!expect_object(entry, "write each case as {\"case\": ..., \"kind\": ..., \"effect\": ..., \"values\": ..., ...}"))
        return std::nullopt;
    Diagnostics& diag = entry.diagnostics();
    entry.check_known_keys({"case", "kind", "effect", "values", "scene", "fabric", "effect_to_noise", "weakened"});
    GapBenchLabel label;
    bool ok = true;
    if (const std::optional<std::string> id = entry.string("case")) {
        label.id = *id;
        if (!is_folder_name(*id)) {
            diag.error(json_pointer_child(entry.pointer(), "case"), "\"" + *id + "\" is not a folder name",
                       "write the case's folder name under cases/, e.g. \"case-001\" (no '/', not empty)");
            ok = false;
        } else if (!ids.insert(*id).second) {
            diag.error(json_pointer_child(entry.pointer(), "case"), "\"" + *id + "\" is listed twice", "list each case once");
            ok = false;
        }
    } else {
        ok = false;
    }
    if (const std::optional<std::string> kind = entry.string("kind")) {
        label.kind = *kind;
        if (*kind != kCaseKinds[0] && *kind != kCaseKinds[1]) {
            diag.error(json_pointer_child(entry.pointer(), "kind"), "\"" + *kind + "\" is not \"cloth\" or \"rigid\"",
                       "write \"cloth\" or \"rigid\"");
            ok = false;
        }
    } else {
        ok = false;
    }
    const std::optional<std::string> effect = non_empty_string(entry, "effect", "write the hidden effect's name, or \"none\"");
    if (effect) label.effect = *effect;
    else ok = false;
    if (const std::optional<JsonView> values = entry.object("values")) {
        for (auto it = values->json().begin(); it != values->json().end(); ++it) {
            const std::optional<double> value = values->child(it.key()).as_number(NumberRange{});
            if (it.key().empty()) {
                diag.error(json_pointer_child(values->pointer(), it.key()), "empty parameter name",
                           "key each value by the effect's parameter, e.g. \"lag_s\"");
                ok = false;
            }
            if (value) label.values[it.key()] = *value;
            else ok = false;
        }
        if (effect && *effect == "none" && !values->json().empty()) {
            diag.error(values->pointer(), "an effect-free case (\"none\") has no effect values", "write \"values\": {}");
            ok = false;
        }
    } else {
        ok = false;
    }
    if (const std::optional<std::string> scene = non_empty_string(entry, "scene", "write the capture folder the case's scene came from"))
        label.scene = *scene;
    else
        ok = false;
    const bool cloth = label.kind == "cloth";
    // Cloth cases record the fabric the footage was made with and how often the effect was halved.
    if (entry.has("fabric") || cloth) {
        if (const std::optional<std::string> fabric = non_empty_string(entry, "fabric", "write the fabric preset the case used"))
            label.fabric = *fabric;
        else
            ok = false;
    }
    if (entry.has("weakened") || cloth) {
        if (const std::optional<std::int64_t> weakened = entry.integer("weakened", 0, 3))
            label.weakened = static_cast<int>(*weakened);
        else
            ok = false;
    }
    if (const std::optional<double> ratio = entry.number("effect_to_noise", NumberRange::non_negative("(floors)")))
        label.effect_to_noise = *ratio;
    else
        ok = false;
    if (!ok) return std::nullopt;
    return label;
}

}  // namespace

std::optional<GapBenchLabels> parse_gap_bench_labels(const nlohmann::json& document, Diagnostics& diagnostics,
                                                     Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!detail::check_integer_format_header(root, kGapBenchLabelsFormatName, kGapBenchLabelsFormatVersion))
        return std::nullopt;
    root.check_known_keys({"format", "version", "seed", "footage_mesh", "footage_integrator", "footage_substeps_per_frame",
                           "frames", "strength", "cases"});
    GapBenchLabels labels;
    const std::optional<std::uint64_t> seed = parse_seed(root);
    if (seed) labels.seed = *seed;
    if (const std::optional<std::string> mesh = root.string("footage_mesh")) {
        labels.footage_mesh = *mesh;
        if (!is_mesh_size(*mesh))
            diagnostics.error("/footage_mesh", "\"" + *mesh + "\" is not ROWSxCOLS", "write the footage's mesh, e.g. \"24x24\"");
    }
    labels.footage_integrator =
        non_empty_string(root, "footage_integrator", "write the integrator the footage was made with, e.g. \"implicit\"")
            .value_or("");
    labels.footage_substeps_per_frame = static_cast<int>(root.integer("footage_substeps_per_frame", 1, 100000).value_or(1));
    labels.frames = static_cast<int>(root.integer("frames", 1, 1000000).value_or(1));
    labels.strength = root.number("strength", NumberRange::positive("(times the default magnitudes)")).value_or(1.0);
    if (const std::optional<JsonView> cases = root.array("cases")) {
        if (cases->size() == 0)
            diagnostics.error("/cases", "no cases", "make the cases again with flowvid bench gap --out DIR");
        std::set<std::string> ids;
        for (std::size_t i = 0; i < cases->size(); ++i)
            if (std::optional<GapBenchLabel> label = parse_case(cases->element(i), ids)) labels.cases.push_back(std::move(*label));
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return labels;
}

nlohmann::json gap_bench_labels_to_json(const GapBenchLabels& labels) {
    nlohmann::json cases = nlohmann::json::array();
    for (const GapBenchLabel& label : labels.cases) {
        nlohmann::json values = nlohmann::json::object();
        for (const auto& [key, value] : label.values) values[key] = value;
        nlohmann::json entry = {{"case", label.id},
                                {"kind", label.kind},
                                {"effect", label.effect},
                                {"values", values},
                                {"scene", label.scene},
                                {"effect_to_noise", label.effect_to_noise}};
        if (label.fabric) entry["fabric"] = *label.fabric;
        if (label.weakened) entry["weakened"] = *label.weakened;
        cases.push_back(entry);
    }
    return {{"format", kGapBenchLabelsFormatName},
            {"version", kGapBenchLabelsFormatVersion},
            {"seed", labels.seed},
            {"footage_mesh", labels.footage_mesh},
            {"footage_integrator", labels.footage_integrator},
            {"footage_substeps_per_frame", labels.footage_substeps_per_frame},
            {"frames", labels.frames},
            {"strength", labels.strength},
            {"cases", cases}};
}

GapBenchLabels read_gap_bench_labels(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<GapBenchLabels>(path, parse_gap_bench_labels, warnings);
}

void write_gap_bench_labels(const std::string& path, const GapBenchLabels& labels) {
    detail::write_validated_json(path, gap_bench_labels_to_json(labels), parse_gap_bench_labels);
}

std::vector<Problem> validate_gap_bench_labels_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_gap_bench_labels);
}

nlohmann::json summarize_gap_bench_labels(const GapBenchLabels& labels) {
    nlohmann::json per_effect = nlohmann::json::object();
    int cloth = 0, rigid = 0, strong = 0;
    for (const GapBenchLabel& label : labels.cases) {
        per_effect[label.effect] = per_effect.value(label.effect, 0) + 1;
        (label.kind == "rigid" ? rigid : cloth) += 1;
        strong += label.effect != "none" && label.effect_to_noise >= 4.0 ? 1 : 0;
    }
    return {{"format", kGapBenchLabelsFormatName},
            {"cases", labels.cases.size()},
            {"cloth_cases", cloth},
            {"rigid_cases", rigid},
            {"per_effect", per_effect},
            {"effects_at_least_4x_noise", strong},
            {"seed", labels.seed},
            {"frames", labels.frames},
            {"strength", labels.strength},
            {"footage", labels.footage_mesh + ", " + labels.footage_integrator + ", " +
                            std::to_string(labels.footage_substeps_per_frame) + " substeps per frame"}};
}

}  // namespace flowvid::formats
