#include "flowvid/formats/swatch_experiment.hpp"

#include "json_extras.hpp"

namespace flowvid::formats {

namespace {

// frame_count < 1: not known (its own field was refused).
std::optional<SwatchPinTrajectory> parse_pin(const JsonView& pin, int frame_count) {
    if (!detail::expect_object(pin, "write each pin as {\"uv\": [u, v], \"positions_m\": [[x, y, z], ...]}"))
        return std::nullopt;
    pin.check_known_keys({"uv", "positions_m"});
    SwatchPinTrajectory out;
    bool ok = true;
    if (const auto uv = pin.numbers("uv", 2, NumberRange::closed(0.0, 1.0)))
        out.uv = {(*uv)[0], (*uv)[1]};
    else
        ok = false;
    const std::optional<JsonView> positions = pin.array("positions_m");
    if (!positions) return std::nullopt;
    if (frame_count >= 1 && positions->size() != static_cast<std::size_t>(frame_count)) {
        pin.diagnostics().error(positions->pointer(),
                                "has " + std::to_string(positions->size()) + " positions but the experiment has " +
                                    std::to_string(frame_count) + " frames (frame_count)",
                                "give exactly one [x, y, z] position in metres per frame");
        return std::nullopt;
    }
    out.positions_m.reserve(positions->size());
    for (std::size_t f = 0; f < positions->size(); ++f) {
        if (const std::optional<Eigen::Vector3d> p = detail::point_m(positions->element(f))) out.positions_m.push_back(*p);
        else ok = false;
    }
    if (!ok) return std::nullopt;
    return out;
}

}  // namespace

std::optional<SwatchExperimentFile> parse_swatch_experiment(const nlohmann::json& document, Diagnostics& diagnostics,
                                                            Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    // Files of flowvid swatch's first release had no header: the fix names the one to add.
    if (!detail::check_header_first_files_lacked(root, kSwatchExperimentFormatName, kSwatchExperimentFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "name", "width_m", "height_m", "fps", "frame_count", "mass_kg", "pins"});
    SwatchExperimentFile out;
    out.name = root.string("name", false).value_or("");
    out.width_m = root.number("width_m", NumberRange::positive("m")).value_or(0.0);
    out.height_m = root.number("height_m", NumberRange::positive("m")).value_or(0.0);
    out.fps = root.number("fps", NumberRange::positive("frames/s")).value_or(0.0);
    const std::optional<std::int64_t> frame_count = root.integer("frame_count", 1, kSwatchExperimentMaxFrames);
    out.frame_count = static_cast<int>(frame_count.value_or(0));
    out.mass_kg = root.number("mass_kg", NumberRange::positive("kg"), false);
    if (const std::optional<JsonView> pins = root.array("pins")) {
        if (pins->size() == 0)
            diagnostics.error(pins->pointer(), "a swatch experiment needs at least one pinned point",
                              "pin the points the swatch hangs from, e.g. {\"uv\": [0, 1], \"positions_m\": [...]}");
        else if (pins->size() > kSwatchExperimentMaxPins)
            diagnostics.error(pins->pointer(), "has " + std::to_string(pins->size()) + " pins, more than the " +
                                                   std::to_string(kSwatchExperimentMaxPins) + " a reader accepts",
                              "pin fewer points");
        else
            for (std::size_t i = 0; i < pins->size(); ++i) {
                if (std::optional<SwatchPinTrajectory> pin = parse_pin(pins->element(i), out.frame_count))
                    out.pins.push_back(std::move(*pin));
            }
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return out;
}

nlohmann::json swatch_experiment_to_json(const SwatchExperimentFile& e) {
    nlohmann::json pins = nlohmann::json::array();
    for (const SwatchPinTrajectory& pin : e.pins) {
        nlohmann::json positions = nlohmann::json::array();
        for (const Eigen::Vector3d& p : pin.positions_m) positions.push_back({p.x(), p.y(), p.z()});
        pins.push_back({{"uv", {pin.uv.x(), pin.uv.y()}}, {"positions_m", std::move(positions)}});
    }
    nlohmann::json out = {{"format", kSwatchExperimentFormatName},
                          {"version", kSwatchExperimentFormatVersion.to_string()},
                          {"width_m", e.width_m},
                          {"height_m", e.height_m},
                          {"fps", e.fps},
                          {"frame_count", e.frame_count},
                          {"pins", std::move(pins)}};
    if (!e.name.empty()) out["name"] = e.name;
    if (e.mass_kg) out["mass_kg"] = *e.mass_kg;
    return out;
}

SwatchExperimentFile read_swatch_experiment(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<SwatchExperimentFile>(path, parse_swatch_experiment, warnings);
}

void write_swatch_experiment(const std::string& path, const SwatchExperimentFile& experiment) {
    detail::write_validated_json(path, swatch_experiment_to_json(experiment), parse_swatch_experiment);
}

std::vector<Problem> validate_swatch_experiment_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_swatch_experiment);
}

nlohmann::json summarize_swatch_experiment(const SwatchExperimentFile& e) {
    nlohmann::json pins = nlohmann::json::array();
    for (const SwatchPinTrajectory& pin : e.pins)
    {
        std::string uv = "(";
        uv += nlohmann::json(pin.uv.x()).dump();
        uv += ", ";
        uv += nlohmann::json(pin.uv.y()).dump();
        uv += ")";
        pins.push_back(uv);
    }
    nlohmann::json out = {{"format", kSwatchExperimentFormatName},
                          {"name", e.name},
                          {"width_m", e.width_m},
                          {"height_m", e.height_m},
                          {"fps", e.fps},
                          {"frame_count", e.frame_count},
                          {"duration_s", e.frame_count > 1 ? (e.frame_count - 1) / e.fps : 0.0},
                          {"pins", e.pins.size()},
                          {"pins_uv", pins}};
    if (e.mass_kg) out["mass_kg"] = *e.mass_kg;
    return out;
}

}  // namespace flowvid::formats
