#include "flowvid/video/image.hpp"

#include "flowvid/error.hpp"
#include "flowvid/formats/atomic_file.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <ostream>

namespace flowvid::video {

void ImageF::assign(int w, int h, float value) {
    width = w;
    height = h;
    pixels.assign(static_cast<std::size_t>(std::max(w, 0)) * static_cast<std::size_t>(std::max(h, 0)), value);
}

float srgb_to_linear(float encoded) {
    const float c = std::clamp(encoded, 0.0f, 1.0f);
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

namespace {

// 8-bit sources hold at most 256 distinct values per channel: a table is
// exact for them and fast; other values fall back to the formula.
const std::array<float, 256>& srgb_table() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int i = 0; i < 256; ++i) t[static_cast<std::size_t>(i)] = srgb_to_linear(static_cast<float>(i) / 255.0f);
        return t;
    }();
    return table;
}

float decode(float value, bool srgb) {
    if (!srgb) return value;
    const float scaled = value * 255.0f;
    const float rounded = std::round(scaled);
    if (std::abs(scaled - rounded) < 1e-3f && rounded >= 0.0f && rounded <= 255.0f)
        return srgb_table()[static_cast<std::size_t>(rounded)];
    return srgb_to_linear(value);
}

}  // namespace

ImageF gray_from_image(const formats::Image& image, bool linearize) {
    ImageF out(image.width, image.height);
    const bool srgb = linearize && image.encoding == formats::Image::Encoding::srgb;
    const int channels = std::max(image.channels, 1);
    const int used = std::min(channels, 3);
    for (std::size_t i = 0; i < out.pixels.size(); ++i) {
        float sum = 0.0f;
        for (int c = 0; c < used; ++c)
            sum += decode(image.pixels[i * static_cast<std::size_t>(channels) + static_cast<std::size_t>(c)], srgb);
        out.pixels[i] = sum / static_cast<float>(used);
    }
    return out;
}

formats::Image image_from_gray(const ImageF& image) {
    formats::Image out;
    out.width = image.width;
    out.height = image.height;
    out.channels = 1;
    out.encoding = formats::Image::Encoding::linear;
    out.pixels = image.pixels;
    return out;
}

void write_gray_image(const std::string& path, const ImageF& image, float low, float high) {
    cv::Mat bytes(image.height, image.width, CV_8UC1);
    const float scale = high > low ? 255.0f / (high - low) : 0.0f;
    for (int y = 0; y < image.height; ++y) {
        auto* row = bytes.ptr<std::uint8_t>(y);
        for (int x = 0; x < image.width; ++x)
            row[x] = static_cast<std::uint8_t>(std::clamp(std::lround((image.at(x, y) - low) * scale), 0L, 255L));
    }
    std::vector<std::uint8_t> encoded;
    const auto dot = path.find_last_of('.');
    const std::string extension = dot == std::string::npos ? ".png" : path.substr(dot);
    if (!cv::imencode(extension, bytes, encoded))
        throw IoError(path, "", "cannot encode the image as " + extension, "use .png, .pgm or .tif");
    formats::write_file_atomically(path, [&](std::ostream& stream) {
        stream.write(reinterpret_cast<const char*>(encoded.data()), static_cast<std::streamsize>(encoded.size()));
    });
}

}  // namespace flowvid::video
