#pragma once
// Roll correction (thesis fig. 2.8): warp footage so that gravity points
// straight down the image. The warp is the image of a camera rotated about
// its optical axis by the gravity roll angle, u' = K Rz(roll) K^-1 u, so it
// is a rotation about the principal point when fx = fy (a homography
// otherwise). Only roll is corrected; the tilt (pitch) stays, as in the
// thesis. Lens distortion is not removed: the warp treats the image as a
// pinhole image (exact when the capture's dist is zero).

#include "flowvid/formats/capture.hpp"
#include "flowvid/formats/rectification.hpp"
#include "flowvid/rigid/dynamics.hpp"

#include <Eigen/Core>

#include <string>

namespace flowvid::rigid {

struct Rectification {
    double roll_rad = 0.0;
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();     // rectified_camera_from_camera (about z)
    Eigen::Matrix3d homography = Eigen::Matrix3d::Identity();   // input pixel -> output pixel (homogeneous)

    Eigen::Vector2d apply(const Eigen::Vector2d& pixel) const;
};

Rectification roll_rectification(const formats::CameraModel& camera, const GravityAngles& gravity);

// What rectify.json records of a rectification made from the fit at
// `fit_path` (format flowvid.rectification, formats/specs/rectification.md):
// the roll removed, the tilt left (both from `gravity`, in degrees) and the
// homography. Write it with formats::write_rectification.
formats::RectificationFile rectification_file(const Rectification& rectification, const GravityAngles& gravity,
                                              const std::string& fit_path);

// The warped image, same size and channels; pixels coming from outside the
// input are 0. Bilinear, or nearest for masks.
formats::Image rectify_image(const formats::Image& image, const Rectification& rectification, bool nearest = false);

// Writes an 8-bit PNG (values in [0, 1] as stored, rounded) atomically.
// Throws IoError naming the file when it cannot be written.
void write_png(const std::string& path, const formats::Image& image);

}  // namespace flowvid::rigid
