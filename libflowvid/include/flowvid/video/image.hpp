#pragma once
// A single-channel float image, the working type of the stripe analysis
// (angle maps, rendered stripe images). Row-major from the top row; pixel
// (x, y) is the centre of column x, row y (OpenCV convention, as captures).

#include "flowvid/formats/capture.hpp"

#include <cstddef>
#include <string>
#include <vector>

namespace flowvid::video {

struct ImageF {
    int width = 0;
    int height = 0;
    std::vector<float> pixels;  // width * height

    ImageF() = default;
    ImageF(int w, int h, float value = 0.0f)
        : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), value) {}

    bool empty() const { return width <= 0 || height <= 0; }
    std::size_t index(int x, int y) const {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
    }
    float at(int x, int y) const { return pixels[index(x, y)]; }
    float& at(int x, int y) { return pixels[index(x, y)]; }
    // Resizes (keeping the allocation when large enough) and fills.
    void assign(int w, int h, float value);
};

// sRGB-encoded value in [0, 1] -> linear light (IEC 61966-2-1).
float srgb_to_linear(float encoded);

// The luminance of a decoded frame: the mean of R, G, B (or the single
// channel). With `linearize`, sRGB-encoded images are decoded to linear light
// first, so that footage compares with the linear output of the stripe
// renderer; linear (EXR) images are used as they are.
ImageF gray_from_image(const formats::Image& image, bool linearize = true);

// One-channel formats::Image (linear) of `image`, e.g. for writing a PNG/EXR
// while debugging; values are copied unchanged.
formats::Image image_from_gray(const ImageF& image);

// Writes `image` as an 8-bit gray PNG (or any format OpenCV writes, by the
// extension), mapping [low, high] to [0, 255], atomically. For figures and
// debugging. Throws IoError naming the file.
void write_gray_image(const std::string& path, const ImageF& image, float low = 0.0f, float high = 1.0f);

}  // namespace flowvid::video
