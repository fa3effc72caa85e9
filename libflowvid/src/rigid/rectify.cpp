#include "flowvid/rigid/rectify.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace flowvid::rigid {

Eigen::Vector2d Rectification::apply(const Eigen::Vector2d& pixel) const {
    const Eigen::Vector3d h = homography * Eigen::Vector3d(pixel.x(), pixel.y(), 1.0);
    return h.head<2>() / h.z();
}

Rectification roll_rectification(const formats::CameraModel& camera, const GravityAngles& gravity) {
    Rectification r;
    r.roll_rad = gravity.roll_rad;
    // Rotating camera coordinates by +roll about z takes gravity's image-plane
    // direction (sin roll, cos roll) to (0, 1): straight down.
    r.rotation = Eigen::AngleAxisd(gravity.roll_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    r.homography = camera.K * r.rotation * camera.K.inverse();
    return r;
}

formats::RectificationFile rectification_file(const Rectification& rectification, const GravityAngles& gravity,
                                              const std::string& fit_path) {
    formats::RectificationFile file;
    file.fit = fit_path;
    file.roll_deg = rectification.roll_rad * 180.0 / M_PI;
    file.tilt_deg_not_corrected = gravity.tilt_rad * 180.0 / M_PI;
    file.homography_output_from_input = rectification.homography;
    return file;
}

formats::Image rectify_image(const formats::Image& image, const Rectification& rectification, bool nearest) {
    const int type = CV_32FC(image.channels);
    const cv::Mat source(image.height, image.width, type, const_cast<float*>(image.pixels.data()));
    cv::Mat H(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) H.at<double>(r, c) = rectification.homography(r, c);
    formats::Image out = image;
    cv::Mat target(image.height, image.width, type, out.pixels.data());
    cv::warpPerspective(source, target, H, target.size(), nearest ? cv::INTER_NEAREST : cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar::all(0));
    return out;
}

void write_png(const std::string& path, const formats::Image& image) {
    if (image.channels != 1 && image.channels != 3)
        throw IoError(path, "", "only gray and RGB images can be written as PNG", "convert the image first");
    cv::Mat mat(image.height, image.width, image.channels == 1 ? CV_8UC1 : CV_8UC3);
    for (int y = 0; y < image.height; ++y) {
        std::uint8_t* row = mat.ptr<std::uint8_t>(y);
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < image.channels; ++c) {
                // OpenCV stores colour as BGR.
                const int source = image.channels == 3 ? 2 - c : c;
                const float v = std::clamp(image.at(x, y, source), 0.0f, 1.0f);
                row[x * image.channels + c] = static_cast<std::uint8_t>(std::lround(v * 255.0f));
            }
    }
    std::vector<std::uint8_t> bytes;
    bool ok = false;
    try {
        ok = cv::imencode(".png", mat, bytes);
    } catch (const cv::Exception& error) {
        throw IoError(path, "", std::string("cannot encode the PNG: ") + error.what());
    }
    if (!ok) throw IoError(path, "", "cannot encode the PNG");
    formats::write_file_atomically(path, [&](std::ostream& out) {
        out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    });
}

}  // namespace flowvid::rigid
