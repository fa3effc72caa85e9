// Camera drift estimated by ECC on the background and removed by resampling
// each frame into the clip's central view (stabilise.hpp).
#include "flowvid/flow/stabilise.hpp"

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

namespace flowvid::flow {
namespace {

// The background: pixels farther than the margin from every input line. A
// margin that leaves less than a tenth of the frame is halved (lines drawn all
// over the frame), down to 20 px.
cv::Mat background_mask(int width, int height, double scale, const std::vector<std::vector<Eigen::Vector2d>>& lines,
                        double margin_px) {
    cv::Mat drawn(height, width, CV_8U, cv::Scalar(255));
    for (const auto& line : lines) {
        std::vector<cv::Point> points;
        for (const Eigen::Vector2d& p : line)
            points.emplace_back(static_cast<int>(std::lround(p.x() * scale)), static_cast<int>(std::lround(p.y() * scale)));
        if (points.size() >= 2) cv::polylines(drawn, points, false, cv::Scalar(0), 1);
    }
    cv::Mat distance;
    cv::distanceTransform(drawn, distance, cv::DIST_L2, 3);
    cv::Mat mask;
    for (double margin = margin_px * scale;; margin *= 0.5) {
        mask = distance > margin;
        if (cv::countNonZero(mask) >= width * height / 10 || margin <= 20.0 * scale) break;
    }
    return mask;
}

cv::Mat gray_for_estimate(const RgbImage& display, double scale) {
    const std::vector<float> y = luma(display);
    cv::Mat gray(display.height, display.width, CV_32F, const_cast<float*>(y.data()));
    cv::Mat out;
    if (scale < 1.0) cv::resize(gray, out, cv::Size(), scale, scale, cv::INTER_AREA);
    else out = gray.clone();
    return out;
}

double largest_corner_offset(const Eigen::Matrix<double, 2, 3>& m, int width, int height) {
    double largest = 0.0;
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(width - 1, 0),
                                         Eigen::Vector2d(0, height - 1), Eigen::Vector2d(width - 1, height - 1)}) {
        const Eigen::Vector2d moved = m.leftCols<2>() * corner + m.col(2);
        largest = std::max(largest, (moved - corner).norm());
    }
    return largest;
}

// One ECC pass over the frames with a motion model, each frame against the
// first, started from the previous frame's answer (drift is gradual). Returns
// the maps at full resolution and the lowest correlation.
std::pair<std::vector<Eigen::Matrix<double, 2, 3>>, double> estimate_with(const std::vector<cv::Mat>& gray, const cv::Mat& mask,
                                                                        int motion_type, double scale,
                                                                        const std::vector<Eigen::Matrix<double, 2, 3>>* start) {
    std::vector<Eigen::Matrix<double, 2, 3>> maps;
    double worst = 1.0;
    cv::Mat warp = cv::Mat::eye(2, 3, CV_32F);
    const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-5);
    for (std::size_t i = 0; i < gray.size(); ++i) {
        if (start) {  // the translation pass's answer, at the reduced size
            const Eigen::Matrix<double, 2, 3>& s = (*start)[i];
            for (int r = 0; r < 2; ++r)
                for (int c = 0; c < 3; ++c) warp.at<float>(r, c) = static_cast<float>(c == 2 ? s(r, c) * scale : s(r, c));
        }
        double correlation = 1.0;
        if (i > 0) {
            try {
                correlation = cv::findTransformECC(gray[0], gray[i], warp, motion_type, stop, mask, 5);
            } catch (const cv::Exception&) {
                correlation = 0.0;  // did not converge: the previous answer stays
            }
        }
        worst = std::min(worst, correlation);
        Eigen::Matrix<double, 2, 3> m;
        for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 3; ++c) m(r, c) = c == 2 ? warp.at<float>(r, c) / scale : warp.at<float>(r, c);
        maps.push_back(m);
    }
    return {maps, worst};
}

Eigen::Vector2d apply(const Eigen::Matrix<double, 2, 3>& m, const Eigen::Vector2d& p) { return m.leftCols<2>() * p + m.col(2); }

Eigen::Matrix<double, 2, 3> inverse(const Eigen::Matrix<double, 2, 3>& m) {
    Eigen::Matrix<double, 2, 3> out;
    const Eigen::Matrix2d a = m.leftCols<2>().inverse();
    out.leftCols<2>() = a;
    out.col(2) = -a * m.col(2);
    return out;
}

// The frame whose camera is nearest all the others: the least sum, over the
// frames and the four corners, of squared distances between where each
// frame sees the same scene point. That sum is n times the squared distance
// to the mean position plus a constant, so the nearest to the mean wins.
int central_frame(const std::vector<Eigen::Matrix<double, 2, 3>>& first_to_frame, int width, int height) {
    const std::array<Eigen::Vector2d, 4> corners = {Eigen::Vector2d(0, 0), Eigen::Vector2d(width - 1, 0),
                                                    Eigen::Vector2d(0, height - 1), Eigen::Vector2d(width - 1, height - 1)};
    std::array<Eigen::Vector2d, 4> mean;
    mean.fill(Eigen::Vector2d::Zero());
    for (const auto& m : first_to_frame)
        for (std::size_t k = 0; k < 4; ++k) mean[k] += apply(m, corners[k]) / static_cast<double>(first_to_frame.size());
    int best = 0;
    double best_sum = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < first_to_frame.size(); ++i) {
        double sum = 0.0;
        for (std::size_t k = 0; k < 4; ++k) sum += (apply(first_to_frame[i], corners[k]) - mean[k]).squaredNorm();
        if (sum < best_sum - 1e-9) {  // the earliest of equals: deterministic
            best_sum = sum;
            best = static_cast<int>(i);
        }
    }
    return best;
}

}  // namespace

Eigen::Matrix<double, 2, 3> CameraMotion::first_to_view() const {
    return still() ? Eigen::Matrix<double, 2, 3>::Identity() : first_to_frame.at(static_cast<std::size_t>(view_frame));
}

Eigen::Matrix<double, 2, 3> CameraMotion::view_to_first() const { return inverse(first_to_view()); }

Eigen::Matrix<double, 2, 3> CameraMotion::view_to_frame(int frame) const {
    if (still()) return Eigen::Matrix<double, 2, 3>::Identity();
    const Eigen::Matrix<double, 2, 3>& to_frame = first_to_frame.at(static_cast<std::size_t>(frame));
    const Eigen::Matrix<double, 2, 3> back = view_to_first();
    Eigen::Matrix<double, 2, 3> out;
    out.leftCols<2>() = to_frame.leftCols<2>() * back.leftCols<2>();
    out.col(2) = to_frame.leftCols<2>() * back.col(2) + to_frame.col(2);
    return out;
}

const char* to_string(CameraMotion::Model model) {
    switch (model) {
        case CameraMotion::Model::still: return "still";
        case CameraMotion::Model::translation: return "translation";
        case CameraMotion::Model::affine: return "affine";
    }
    return "?";
}

CameraMotion estimate_camera_motion(FrameSequence& frames, const std::vector<std::vector<Eigen::Vector2d>>& input_lines,
                                    const CameraMotionSettings& settings, const Progress& progress) {
    CameraMotion still;
    still.first_to_frame.assign(static_cast<std::size_t>(std::max(0, frames.count())), Eigen::Matrix<double, 2, 3>::Identity());
    if (frames.count() < 2) return still;
    const int width = frames.width(), height = frames.height();
    const double scale = width > settings.estimate_width_px ? static_cast<double>(settings.estimate_width_px) / width : 1.0;
    std::vector<cv::Mat> gray;
    gray.reserve(static_cast<std::size_t>(frames.count()));
    for (int i = 0; i < frames.count(); ++i) {
        gray.push_back(gray_for_estimate(frames.frame(i), scale));
        if (progress && !progress({"camera drift", 0.5 * (i + 1) / frames.count(), {}})) return still;
    }
    const cv::Mat mask = background_mask(gray[0].cols, gray[0].rows, scale, input_lines, settings.exclude_around_lines_px);
    if (cv::countNonZero(mask) < mask.rows * mask.cols / 20) return still;  // no background to see the camera by

    // Translation first: robust, and what tells a still camera from a moving one.
    auto [shifts, shift_correlation] = estimate_with(gray, mask, cv::MOTION_TRANSLATION, scale, nullptr);
    if (progress && !progress({"camera drift", 0.75, {}})) return still;
    double largest = 0.0;
    for (const auto& m : shifts) largest = std::max(largest, largest_corner_offset(m, width, height));
    if (largest < settings.still_below_px || shift_correlation < settings.min_correlation) {
        still.largest_offset_px = largest;
        still.worst_correlation = shift_correlation;
        still.untrusted = largest >= settings.still_below_px;
        return still;
    }
    CameraMotion motion;
    motion.model = CameraMotion::Model::translation;
    motion.first_to_frame = shifts;
    motion.worst_correlation = shift_correlation;
    // An affine map follows a slight turn or zoom too. Kept only where it
    // stays near a shift and matches at least as well: on flickering light it
    // can wander off where a shift holds.
    auto [affine, affine_correlation] = estimate_with(gray, mask, cv::MOTION_AFFINE, scale, &shifts);
    bool near_shift = affine_correlation >= shift_correlation - 0.01;
    for (const auto& m : affine) near_shift = near_shift && (m.leftCols<2>() - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff() < 0.03;
    if (near_shift) {
        motion.model = CameraMotion::Model::affine;
        motion.first_to_frame = affine;
        motion.worst_correlation = affine_correlation;
    }
    for (const auto& m : motion.first_to_frame) motion.largest_offset_px = std::max(motion.largest_offset_px, largest_corner_offset(m, width, height));
    if (settings.view == CameraMotionSettings::View::central) motion.view_frame = central_frame(motion.first_to_frame, width, height);
    if (progress) progress({"camera drift", 1.0, {}});
    return motion;
}

StabilisedFrames::StabilisedFrames(FrameSequence& source, CameraMotion motion) : m_source(source), m_motion(std::move(motion)) {
    if (!m_motion.still() && static_cast<int>(m_motion.first_to_frame.size()) != source.count())
        throw std::invalid_argument("StabilisedFrames: one camera map per frame is needed");
}

RgbImage StabilisedFrames::frame(int index) {
    RgbImage seen = m_source.frame(index);
    if (m_motion.still()) return seen;
    const Eigen::Matrix<double, 2, 3> m = m_motion.view_to_frame(index);
    cv::Mat map(2, 3, CV_64F);
    for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 3; ++c) map.at<double>(r, c) = m(r, c);
    const cv::Mat in(seen.height, seen.width, CV_32FC3, seen.rgb.data());
    RgbImage out(seen.width, seen.height);
    cv::Mat warped(out.height, out.width, CV_32FC3, out.rgb.data());
    // WARP_INVERSE_MAP: out(x) = in(A x + t), the view's pixel x as this frame saw it.
    cv::warpAffine(in, warped, map, warped.size(), cv::INTER_LANCZOS4 | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
    for (float& v : out.rgb) v = std::clamp(v, 0.0f, 1.0f);  // Lanczos rings a little past the range
    // What this frame did not see (the camera had moved on) is shown as the
    // view frame saw it, fading in over a pixel: the repeated border column
    // read as a streaked strip along the edge of every replayed frame.
    const cv::Mat ones(seen.height, seen.width, CV_32F, cv::Scalar(1.0f));
    cv::Mat seen_weight;
    cv::warpAffine(ones, seen_weight, map, ones.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                   cv::Scalar(0.0f));
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) {
            const float w = std::clamp(seen_weight.at<float>(y, x), 0.0f, 1.0f);
            if (w >= 1.0f) continue;
            if (!m_view) m_view = m_source.frame(m_motion.view_frame);  // the view's own frame
            float* o = out.pixel(x, y);
            const float* f = m_view->pixel(x, y);
            for (int c = 0; c < 3; ++c) o[c] = w * o[c] + (1.0f - w) * f[c];
        }
    return out;
}

namespace {

formats::FlowLineSet moved_drawing(const formats::FlowLineSet& drawing, const Eigen::Matrix<double, 2, 3>& map) {
    formats::FlowLineSet out = drawing;
    const auto move = [&map](std::vector<Eigen::Vector2d>& points) {
        for (Eigen::Vector2d& p : points) p = apply(map, p);
    };
    for (auto* lines : {&out.inputs, &out.outputs})
        for (formats::FlowLine& line : *lines) {
            move(line.points);
            for (formats::FlowLineKey& key : line.keys) move(key.points);
        }
    return out;
}

}  // namespace

formats::FlowLineSet drawing_in_view(const formats::FlowLineSet& drawing, const CameraMotion& motion) {
    if (motion.still()) return drawing;
    return moved_drawing(drawing, motion.first_to_view());
}

formats::FlowLineSet drawing_as_drawn(const formats::FlowLineSet& view_drawing, const CameraMotion& motion) {
    if (motion.still()) return view_drawing;
    return moved_drawing(view_drawing, motion.view_to_first());
}

std::vector<std::vector<Eigen::Vector2d>> polylines_as_drawn(const std::vector<std::vector<Eigen::Vector2d>>& view_lines,
                                                             const CameraMotion& motion) {
    std::vector<std::vector<Eigen::Vector2d>> out = view_lines;
    if (motion.still()) return out;
    const Eigen::Matrix<double, 2, 3> back = motion.view_to_first();
    for (auto& line : out)
        for (Eigen::Vector2d& p : line) p = apply(back, p);
    return out;
}

std::vector<std::vector<Eigen::Vector2d>> drawn_input_polylines(const formats::FlowLineSet& drawing) {
    std::vector<std::vector<Eigen::Vector2d>> lines;
    for (const formats::FlowLine& line : drawing.inputs) lines.push_back(line.points);
    return lines;
}

namespace {

Progress progress_part(const Progress& progress, double from, double to) {
    return Progress([&progress, from, to](const ProgressReport& r) {
        return !progress || progress({"read clip", from + (to - from) * r.fraction, r.message});
    });
}

ClipFrames resample_into_view(ClipFrames seen, const CameraMotion& motion, const Progress& progress, ClipFrames* as_filmed) {
    if (motion.still()) return seen;
    StabilisedFrames stabilised(seen, motion);
    ClipFrames out = ClipFrames::read_all(stabilised, 0, progress);
    if (as_filmed) *as_filmed = std::move(seen);
    return out;
}

}  // namespace

ClipFrames read_clip_stabilised(FrameSequence& frames, const formats::FlowLineSet& drawing, CameraMotion& motion,
                                const Progress& progress, ClipFrames* as_filmed) {
    ClipFrames seen = ClipFrames::read_all(frames, 0, progress_part(progress, 0.0, 0.5));
    motion = estimate_camera_motion(seen, drawn_input_polylines(drawing), {}, progress_part(progress, 0.5, 0.8));
    return resample_into_view(std::move(seen), motion, progress_part(progress, 0.8, 1.0), as_filmed);
}

ClipFrames read_clip_in_view(FrameSequence& frames, const CameraMotion& motion, const Progress& progress,
                             ClipFrames* as_filmed) {
    if (!motion.still() && static_cast<int>(motion.first_to_frame.size()) != frames.count())
        throw std::invalid_argument("read_clip_in_view: one camera map per frame is needed");
    ClipFrames seen = ClipFrames::read_all(frames, 0, progress_part(progress, 0.0, 0.7));
    return resample_into_view(std::move(seen), motion, progress_part(progress, 0.7, 1.0), as_filmed);
}

formats::BankCamera to_bank_camera(const CameraMotion& motion) {
    formats::BankCamera camera;
    switch (motion.model) {
        case CameraMotion::Model::still: camera.model = formats::BankCameraModel::still; break;
        case CameraMotion::Model::translation: camera.model = formats::BankCameraModel::translation; break;
        case CameraMotion::Model::affine: camera.model = formats::BankCameraModel::affine; break;
    }
    camera.untrusted = motion.untrusted;
    camera.view_frame = motion.still() ? 0 : motion.view_frame;
    if (!motion.still())
        for (const Eigen::Matrix<double, 2, 3>& m : motion.first_to_frame)
            camera.first_to_frame.push_back({static_cast<float>(m(0, 0)), static_cast<float>(m(0, 1)), static_cast<float>(m(0, 2)),
                                             static_cast<float>(m(1, 0)), static_cast<float>(m(1, 1)), static_cast<float>(m(1, 2))});
    camera.largest_offset_px = static_cast<float>(motion.largest_offset_px);
    camera.worst_correlation = static_cast<float>(motion.worst_correlation);
    return camera;
}

CameraMotion from_bank_camera(const formats::BankCamera& camera) {
    CameraMotion motion;
    switch (camera.model) {
        case formats::BankCameraModel::still: motion.model = CameraMotion::Model::still; break;
        case formats::BankCameraModel::translation: motion.model = CameraMotion::Model::translation; break;
        case formats::BankCameraModel::affine: motion.model = CameraMotion::Model::affine; break;
    }
    motion.untrusted = camera.untrusted;
    motion.view_frame = camera.view_frame;
    for (const std::array<float, 6>& m : camera.first_to_frame) {
        Eigen::Matrix<double, 2, 3> map;
        map << m[0], m[1], m[2], m[3], m[4], m[5];
        motion.first_to_frame.push_back(map);
    }
    motion.largest_offset_px = camera.largest_offset_px;
    motion.worst_correlation = camera.worst_correlation;
    return motion;
}

std::string describe(const CameraMotion& motion) {
    char text[200];
    if (motion.untrusted)
        std::snprintf(text, sizeof text,
                      "camera drift unclear (the background's lowest correlation with the first frame is %.2f, light "
                      "changes too much): frames used as they are",
                      motion.worst_correlation);
    else if (motion.still())
        std::snprintf(text, sizeof text, "camera still (largest drift %.1f px): frames used as they are", motion.largest_offset_px);
    else
        std::snprintf(text, sizeof text,
                      "camera drifts up to %.1f px (%s, lowest correlation %.2f): tracked and rendered in the view of "
                      "frame %d%s, a still camera",
                      motion.largest_offset_px, to_string(motion.model), motion.worst_correlation, motion.view_frame + 1,
                      motion.view_frame == 0 ? "" : ", the middle of its path");
    return text;
}

}  // namespace flowvid::flow
