// Loading a capture's images: frames (numbered files or one video), masks and
// background. OpenCV decodes PNG/JPEG and video, OpenImageIO reads EXR and
// image headers; neither leaks into the public header.

#include "flowvid/formats/capture.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cctype>
#include <filesystem>
#include <list>
#include <stdexcept>

namespace flowvid::formats {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

void require_regular_file(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError(path, "", "no such file", "check the capture folder");
    if (!fs::is_regular_file(path, ec)) throw IoError(path, "", "not a regular file", "name an image or video file");
}

// Converts a float image (values already scaled to [0, 1] or linear) to the
// requested channel count. `bgr` says whether colour channels are in OpenCV's
// order.
Image to_image(const cv::Mat& floats, int channels, bool bgr, Image::Encoding encoding, const std::string& path) {
    const int stored = floats.channels();
    cv::Mat out;
    if (channels == 3) {
        switch (stored) {
            case 1: cv::cvtColor(floats, out, cv::COLOR_GRAY2RGB); break;
            case 2: {  // gray + alpha
                std::vector<cv::Mat> planes;
                cv::split(floats, planes);
                cv::cvtColor(planes[0], out, cv::COLOR_GRAY2RGB);
                break;
            }
            case 3:
                if (bgr) cv::cvtColor(floats, out, cv::COLOR_BGR2RGB);
                else out = floats;
                break;
            default: {
                std::vector<cv::Mat> planes;
                cv::split(floats, planes);
                std::vector<cv::Mat> rgb = bgr ? std::vector<cv::Mat>{planes[2], planes[1], planes[0]}
                                               : std::vector<cv::Mat>{planes[0], planes[1], planes[2]};
                cv::merge(rgb, out);
                break;
            }
        }
    } else if (channels == 1) {
        std::vector<cv::Mat> planes;
        cv::split(floats, planes);
        if (stored <= 2) out = planes[0];
        else out = (planes[0] + planes[1] + planes[2]) / 3.0;
    } else {
        throw std::invalid_argument("load_image: channels must be 1 or 3");
    }
    if (out.empty()) throw IoError(path, "", "cannot convert the image's channels", "write an RGB or gray image");
    if (!out.isContinuous()) out = out.clone();
    Image image;
    image.width = out.cols;
    image.height = out.rows;
    image.channels = channels;
    image.encoding = encoding;
    const auto* begin = reinterpret_cast<const float*>(out.data);
    image.pixels.assign(begin, begin + static_cast<std::size_t>(out.total()) * static_cast<std::size_t>(channels));
    return image;
}

Image mat_to_image(const cv::Mat& mat, int channels, const std::string& path) {
    double scale = 1.0;
    Image::Encoding encoding = Image::Encoding::srgb;
    switch (mat.depth()) {
        case CV_8U: scale = 1.0 / 255.0; break;
        case CV_16U: scale = 1.0 / 65535.0; break;
        case CV_32F: encoding = Image::Encoding::linear; break;
        default:
            throw IoError(path, "", "unsupported pixel depth (OpenCV depth " + std::to_string(mat.depth()) + ")",
                          "write 8- or 16-bit PNG/JPEG, or float EXR");
    }
    cv::Mat floats;
    mat.convertTo(floats, CV_MAKETYPE(CV_32F, mat.channels()), scale);
    return to_image(floats, channels, true, encoding, path);
}

std::uint32_t png_crc32(const unsigned char* data, std::size_t size) {
    static const std::array<std::uint32_t, 256> table = [] {
        std::array<std::uint32_t, 256> t{};
        for (std::uint32_t n = 0; n < 256; ++n) {
            std::uint32_t c = n;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            t[n] = c;
        }
        return t;
    }();
    std::uint32_t c = 0xFFFFFFFFu;
    for (std::size_t i = 0; i < size; ++i) c = table[(c ^ data[i]) & 0xFF] ^ (c >> 8);
    return c ^ 0xFFFFFFFFu;
}

// The PNG chunk structure (lengths, CRCs, IHDR first, IEND last), checked
// before libpng sees the bytes: libpng prints its own "libpng error: ..."
// line to stderr on a damaged file, and a truncated or corrupted frame
// deserves a message naming the file and saying what is wrong.
void check_png_container(const std::string& bytes, const std::string& path) {
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
    const std::string fix = "the file is damaged or was cut short: copy or render it again";
    if (bytes.size() < 8 || !std::equal(signature, signature + 8, data))
        throw IoError(path, "", "not a PNG file (no PNG signature)", "write a PNG, JPEG or EXR image");
    std::size_t at = 8;
    bool first = true;
    while (true) {
        if (bytes.size() - at < 12)
            throw IoError(path, "", "the PNG ends at byte " + std::to_string(bytes.size()) + " before its IEND chunk", fix);
        const std::uint32_t length = std::uint32_t(data[at]) << 24 | std::uint32_t(data[at + 1]) << 16 |
                                     std::uint32_t(data[at + 2]) << 8 | std::uint32_t(data[at + 3]);
        const std::string type = bytes.substr(at + 4, 4);
        if (length > bytes.size() - at - 12)
            throw IoError(path, "", "the PNG chunk " + type + " at byte " + std::to_string(at) + " runs past the end of the file",
                          fix);
        if (first && type != "IHDR") throw IoError(path, "", "the PNG does not start with an IHDR chunk", fix);
        first = false;
        const std::size_t crc_at = at + 8 + length;
        const std::uint32_t stored = std::uint32_t(data[crc_at]) << 24 | std::uint32_t(data[crc_at + 1]) << 16 |
                                     std::uint32_t(data[crc_at + 2]) << 8 | std::uint32_t(data[crc_at + 3]);
        if (png_crc32(data + at + 4, length + 4) != stored)
            throw IoError(path, "", "the PNG chunk " + type + " at byte " + std::to_string(at) + " fails its CRC check", fix);
        at = crc_at + 4;
        if (type == "IEND") return;
    }
}

Image load_exr(const std::string& path, int channels) {
    auto input = OIIO::ImageInput::open(path);
    if (!input) throw IoError(path, "", "cannot open the EXR image: " + OIIO::geterror(), "check the file");
    const OIIO::ImageSpec spec = input->spec();
    if (spec.width < 1 || spec.height < 1 || spec.nchannels < 1 || spec.width > 100000 || spec.height > 100000 ||
        spec.nchannels > 64)
        throw IoError(path, "", "implausible image size", "check the file");
    cv::Mat floats(spec.height, spec.width, CV_MAKETYPE(CV_32F, spec.nchannels));
    if (!input->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, floats.data))
        throw IoError(path, "", "cannot decode the EXR image: " + input->geterror(), "write the file again");
    return to_image(floats, channels, false, Image::Encoding::linear, path);
}

}  // namespace

ImageInfo read_image_info(const std::string& path) {
    require_regular_file(path);
    // A PNG cut short still has a readable header; its chunks tell.
    if (lower_extension(path) == ".png") check_png_container(read_text_file(path), path);
    auto input = OIIO::ImageInput::open(path);
    if (!input) throw IoError(path, "", "not a readable image: " + OIIO::geterror(), "write a PNG, JPEG or EXR image");
    const OIIO::ImageSpec& spec = input->spec();
    return {spec.width, spec.height, spec.nchannels};
}

Image load_image(const std::string& path, int channels) {
    require_regular_file(path);
    if (lower_extension(path) == ".exr") return load_exr(path, channels);
    cv::Mat mat;
    try {
        // Decoded from bytes read once, after the PNG structure is checked.
        const std::string bytes = read_text_file(path);
        if (lower_extension(path) == ".png") check_png_container(bytes, path);
        const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
        mat = cv::imdecode(encoded, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& error) {
        throw IoError(path, "", std::string("cannot decode the image: ") + error.what(), "write the file again");
    }
    if (mat.empty()) throw IoError(path, "", "cannot decode the image", "write a PNG or JPEG image");
    return mat_to_image(mat, channels, path);
}

VideoInfo read_video_info(const std::string& path) {
    require_regular_file(path);
    cv::VideoCapture video;
    try {
        video.open(path, cv::CAP_FFMPEG);
    } catch (const cv::Exception& error) {
        throw IoError(path, "", std::string("cannot open the video: ") + error.what(), "re-encode the clip");
    }
    if (!video.isOpened()) throw IoError(path, "", "cannot open the video", "re-encode the clip (e.g. H.264 in .mp4)");
    VideoInfo info;
    info.width = static_cast<int>(video.get(cv::CAP_PROP_FRAME_WIDTH));
    info.height = static_cast<int>(video.get(cv::CAP_PROP_FRAME_HEIGHT));
    const double frames = video.get(cv::CAP_PROP_FRAME_COUNT);
    info.frame_count = frames > 0.0 && frames < 1e9 ? static_cast<int>(frames + 0.5) : 0;
    info.fps = video.get(cv::CAP_PROP_FPS);
    if (info.width < 1 || info.height < 1) throw IoError(path, "", "the video reports no frame size", "re-encode the clip");
    return info;
}

// ---- FrameSource ------------------------------------------------------------

struct FrameSource::Impl {
    Capture capture;
    int width = 0;
    int height = 0;
    std::string expected_from;

    // Video decoding state: the next read returns file frame index next_index (0-based).
    cv::VideoCapture video;
    bool video_open = false;
    int next_index = 0;
    static constexpr std::size_t kCacheFrames = 8;
    std::list<std::pair<int, Image>> cache;  // most recent first

    void check_size(const Image& image, int number, const std::string& path, const std::string& field) const {
        if (image.width == width && image.height == height) return;
        throw ValidationError({Problem{Problem::Severity::error, capture.json_path, field,
                                       "frame " + std::to_string(number) + " (" + path + ") is " +
                                           std::to_string(image.width) + " x " + std::to_string(image.height) +
                                           " pixels but " + expected_from + " says " + std::to_string(width) + " x " +
                                           std::to_string(height),
                                       "make every image the calibrated size"}});
    }

    void open_video() {
        const std::string path = capture.resolve(capture.frames.video);
        video.release();
        video_open = false;
        require_regular_file(path);
        if (!video.open(path, cv::CAP_FFMPEG))
            throw IoError(path, "/frames/video", "cannot open the video", "re-encode the clip (e.g. H.264 in .mp4)");
        video_open = true;
        next_index = 0;
    }

    Image video_frame(int number) {
        const int index = number - 1;  // first = 1 is the file's first frame
        for (auto it = cache.begin(); it != cache.end(); ++it) {
            if (it->first != index) continue;
            cache.splice(cache.begin(), cache, it);
            return cache.front().second;
        }
        const std::string path = capture.resolve(capture.frames.video);
        // Sequential decoding is exact whatever the key-frame spacing; going
        // back starts again from the top.
        if (!video_open || index < next_index) open_video();
        cv::Mat mat;
        try {
            while (next_index < index) {
                if (!video.grab())
                    throw IoError(path, "/frames/count",
                                  "the video ends after " + std::to_string(next_index) + " frames; frame " +
                                      std::to_string(number) + " was asked for",
                                  "lower frames.count to fit the clip");
                ++next_index;
            }
            if (!video.read(mat) || mat.empty())
                throw IoError(path, "/frames/count",
                              "cannot decode frame " + std::to_string(number) + " (the video may end earlier)",
                              "lower frames.count to fit the clip");
        } catch (const cv::Exception& error) {
            video_open = false;
            throw IoError(path, "/frames/video", std::string("decoding failed: ") + error.what(), "re-encode the clip");
        }
        ++next_index;
        Image image = mat_to_image(mat, 3, path);
        check_size(image, number, path, "/frames/video");
        cache.emplace_front(index, image);
        if (cache.size() > kCacheFrames) cache.pop_back();
        return image;
    }
};

FrameSource::FrameSource(const Capture& capture) : m_impl(std::make_unique<Impl>()) {
    m_impl->capture = capture;
    if (capture.camera) {
        m_impl->width = capture.camera->width;
        m_impl->height = capture.camera->height;
        m_impl->expected_from = "/camera";
    } else if (capture.frames.is_video()) {
        const VideoInfo info = read_video_info(capture.resolve(capture.frames.video));
        m_impl->width = info.width;
        m_impl->height = info.height;
        m_impl->expected_from = "the clip";
    } else {
        const ImageInfo info = read_image_info(capture.frame_path(capture.frames.first));
        m_impl->width = info.width;
        m_impl->height = info.height;
        m_impl->expected_from = "the first frame";
    }
}

FrameSource::~FrameSource() = default;
FrameSource::FrameSource(FrameSource&&) noexcept = default;
FrameSource& FrameSource::operator=(FrameSource&&) noexcept = default;

int FrameSource::first() const { return m_impl->capture.frames.first; }
int FrameSource::count() const { return m_impl->capture.frames.count; }
int FrameSource::last() const { return m_impl->capture.frames.last(); }
int FrameSource::width() const { return m_impl->width; }
int FrameSource::height() const { return m_impl->height; }

Image FrameSource::frame(int number) {
    if (number < first() || number > last())
        throw std::out_of_range("frame " + std::to_string(number) + " is outside the capture's frames " +
                                std::to_string(first()) + ".." + std::to_string(last()));
    if (m_impl->capture.frames.is_video()) return m_impl->video_frame(number);
    const std::string path = m_impl->capture.frame_path(number);
    Image image = load_image(path, 3);
    m_impl->check_size(image, number, path, "/frames/pattern");
    return image;
}

bool FrameSource::has_masks() const { return !m_impl->capture.masks.empty(); }

Image FrameSource::mask(int number) {
    if (!has_masks()) throw std::logic_error("the capture has no masks");
    if (number < first() || number > last())
        throw std::out_of_range("mask " + std::to_string(number) + " is outside the capture's frames " +
                                std::to_string(first()) + ".." + std::to_string(last()));
    const std::string path = m_impl->capture.mask_path(number);
    Image image = load_image(path, 1);
    m_impl->check_size(image, number, path, "/masks");
    return image;
}

bool FrameSource::has_background() const { return !m_impl->capture.background.empty(); }

Image FrameSource::background() {
    if (!has_background()) throw std::logic_error("the capture has no background image");
    const std::string path = m_impl->capture.resolve(m_impl->capture.background);
    Image image = load_image(path, 3);
    if (image.width != m_impl->width || image.height != m_impl->height)
        throw ValidationError({Problem{Problem::Severity::error, m_impl->capture.json_path, "/background",
                                       "background (" + path + ") is " + std::to_string(image.width) + " x " +
                                           std::to_string(image.height) + " pixels but " + m_impl->expected_from +
                                           " says " + std::to_string(m_impl->width) + " x " +
                                           std::to_string(m_impl->height),
                                       "render or crop the background at the calibrated size"}});
    return image;
}

}  // namespace flowvid::formats
