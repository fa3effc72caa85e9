#include "flowvid/formats/rectification.hpp"

#include "json_extras.hpp"

#include <Eigen/LU>

#include <cmath>

namespace flowvid::formats {

namespace {

// Angles from atan2 and asin, turned into degrees, may pass +-180 and +-90 by
// a rounding error.
constexpr double kHalfTurnDeg = 180.0 + 1e-9;
constexpr double kQuarterTurnDeg = 90.0 + 1e-9;

std::optional<Eigen::Matrix3d> parse_matrix3(const JsonView& root, const std::string& key) {
    const std::optional<JsonView> rows = root.array(key);
    if (!rows) return std::nullopt;
    if (rows->size() != 3) {
        root.diagnostics().error(rows->pointer(), "expected 3 rows, found " + std::to_string(rows->size()),
                                 "write the 3x3 matrix as three rows of three numbers");
        return std::nullopt;
    }
    Eigen::Matrix3d m;
    bool ok = true;
    for (std::size_t r = 0; r < 3; ++r) {
        const JsonView row = rows->element(r);
        if (!row.json().is_array() || row.size() != 3) {
            root.diagnostics().error(row.pointer(), "expected a row of 3 numbers, found " + row.json().dump().substr(0, 40),
                                     "write the 3x3 matrix as three rows of three numbers");
            ok = false;
            continue;
        }
        for (std::size_t c = 0; c < 3; ++c) {
            const std::optional<double> v = row.element(c).as_number(NumberRange{});
            if (v) m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = *v;
            else ok = false;
        }
    }
    if (!ok) return std::nullopt;
    return m;
}

}  // namespace

std::optional<RectificationFile> parse_rectification(const nlohmann::json& document, Diagnostics& diagnostics,
                                                     Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!check_format_header(root, kRectificationFormatName, kRectificationFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "fit", "roll_deg", "tilt_deg_not_corrected", "homography_output_from_input"});
    RectificationFile out;
    out.fit = detail::non_empty_string(root, "fit", "write the rigid fit file the roll came from").value_or("");
    out.roll_deg = root.number("roll_deg", NumberRange::closed(-kHalfTurnDeg, kHalfTurnDeg, "degrees")).value_or(0.0);
    out.tilt_deg_not_corrected = root.number("tilt_deg_not_corrected", NumberRange::closed(-kQuarterTurnDeg, kQuarterTurnDeg, "degrees")).value_or(0.0);
    if (const std::optional<Eigen::Matrix3d> h = parse_matrix3(root, "homography_output_from_input")) {
        const double scale = h->cwiseAbs().maxCoeff();
        if (!(scale > 0.0) || !(std::abs(h->determinant()) > 1e-12 * scale * scale * scale))
            diagnostics.error("/homography_output_from_input", "the homography is singular (it maps the image onto a line or a point)",
                              "write the invertible homography the frames were warped with");
        else
            out.homography_output_from_input = *h;
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return out;
}

nlohmann::json rectification_to_json(const RectificationFile& r) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index i = 0; i < 3; ++i) {
        nlohmann::json row = nlohmann::json::array();
        for (Eigen::Index j = 0; j < 3; ++j) row.push_back(r.homography_output_from_input(i, j));
        rows.push_back(row);
    }
    return {{"format", kRectificationFormatName},
            {"version", kRectificationFormatVersion.to_string()},
            {"fit", r.fit},
            {"roll_deg", r.roll_deg},
            {"tilt_deg_not_corrected", r.tilt_deg_not_corrected},
            {"homography_output_from_input", rows}};
}

RectificationFile read_rectification(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<RectificationFile>(path, parse_rectification, warnings);
}

void write_rectification(const std::string& path, const RectificationFile& rectification) {
    detail::write_validated_json(path, rectification_to_json(rectification), parse_rectification);
}

std::vector<Problem> validate_rectification_file(const std::string& path, Strictness strictness) {
    return detail::validate_json_file(path, strictness, parse_rectification);
}

nlohmann::json summarize_rectification(const RectificationFile& r) {
    nlohmann::json rows = rectification_to_json(r)["homography_output_from_input"];
    return {{"format", kRectificationFormatName},
            {"fit", r.fit},
            {"roll_deg", r.roll_deg},
            {"tilt_deg_not_corrected", r.tilt_deg_not_corrected},
            {"homography_output_from_input", rows}};
}

}  // namespace flowvid::formats
