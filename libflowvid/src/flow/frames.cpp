#include "flowvid/flow/frames.hpp"

#include "flowvid/error.hpp"
#include "flowvid/formats/atomic_file.hpp"

#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <optional>
#include <stdexcept>

namespace fs = std::filesystem;

namespace flowvid::flow {

namespace {

// Linear -> sRGB through a table over [0, 1] fine enough that the 8-bit result
// never differs from the exact function by more than rounding (the curve is
// steepest near 0, so the table is indexed by sqrt(linear)).
constexpr int kEncodeTableSize = 8192;
const std::array<float, kEncodeTableSize + 1>& encode_table() {
    static const std::array<float, kEncodeTableSize + 1> table = [] {
        std::array<float, kEncodeTableSize + 1> t{};
        for (int i = 0; i <= kEncodeTableSize; ++i) {
            const double r = static_cast<double>(i) / kEncodeTableSize;
            const double v = r * r;
            t[static_cast<std::size_t>(i)] =
                static_cast<float>(v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055);
        }
        return t;
    }();
    return table;
}

const std::array<float, 65536>& decode_table16() {
    static const std::array<float, 65536> table = [] {
        std::array<float, 65536> t{};
        for (int i = 0; i < 65536; ++i) {
            const double v = i / 65535.0;
            t[static_cast<std::size_t>(i)] =
                static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
        }
        return t;
    }();
    return table;
}

std::uint16_t to_u16(float v) {
    return static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 65535.0f));
}

std::string lower_extension(const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

bool is_video_extension(const std::string& ext) {
    return ext == ".mp4" || ext == ".avi" || ext == ".mov" || ext == ".mkv" || ext == ".webm" || ext == ".m4v";
}

bool has_integer_conversion(const std::string& pattern) {
    return formats::format_frame_pattern(pattern, 1).has_value() &&
           *formats::format_frame_pattern(pattern, 1) != *formats::format_frame_pattern(pattern, 2);
}

}  // namespace

float srgb_to_linear(float encoded) {
    const float v = std::clamp(encoded, 0.0f, 1.0f);
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float linear) {
    const float v = std::clamp(linear, 0.0f, 1.0f);
    const float r = std::sqrt(v) * kEncodeTableSize;
    const int i = std::min(static_cast<int>(r), kEncodeTableSize - 1);
    const float f = r - static_cast<float>(i);
    const auto& t = encode_table();
    return t[static_cast<std::size_t>(i)] + f * (t[static_cast<std::size_t>(i) + 1] - t[static_cast<std::size_t>(i)]);
}

RgbImage to_linear(const RgbImage& display) {
    RgbImage out = display;
    const auto& table = decode_table16();
    for (float& v : out.rgb) v = table[to_u16(v)];
    return out;
}

RgbImage to_display(const RgbImage& linear) {
    RgbImage out = linear;
    for (float& v : out.rgb) v = linear_to_srgb(v);
    return out;
}

std::vector<float> luma(const RgbImage& display) {
    std::vector<float> y(static_cast<std::size_t>(display.width) * display.height);
    for (std::size_t i = 0; i < y.size(); ++i)
        y[i] = 0.2126f * display.rgb[3 * i] + 0.7152f * display.rgb[3 * i + 1] + 0.0722f * display.rgb[3 * i + 2];
    return y;
}

RgbImage display_rgb(const formats::Image& image) {
    RgbImage out(image.width, image.height);
    const std::size_t n = static_cast<std::size_t>(image.width) * image.height;
    const bool linear = image.encoding == formats::Image::Encoding::linear;
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const float v = image.channels >= 3 ? image.pixels[i * static_cast<std::size_t>(image.channels) + c]
                                                : image.pixels[i * static_cast<std::size_t>(image.channels)];
            out.rgb[3 * i + c] = linear ? linear_to_srgb(v) : v;
        }
    return out;
}

void sample_bilinear(const RgbImage& image, double x, double y, float out[3]) {
    x = std::clamp(x, 0.0, static_cast<double>(image.width - 1));
    y = std::clamp(y, 0.0, static_cast<double>(image.height - 1));
    const int x0 = std::min(static_cast<int>(x), image.width - 2 >= 0 ? image.width - 2 : 0);
    const int y0 = std::min(static_cast<int>(y), image.height - 2 >= 0 ? image.height - 2 : 0);
    const int x1 = std::min(x0 + 1, image.width - 1);
    const int y1 = std::min(y0 + 1, image.height - 1);
    const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
    const float* a = image.pixel(x0, y0);
    const float* b = image.pixel(x1, y0);
    const float* c = image.pixel(x0, y1);
    const float* d = image.pixel(x1, y1);
    for (int k = 0; k < 3; ++k) {
        const float top = a[k] + fx * (b[k] - a[k]);
        const float bottom = c[k] + fx * (d[k] - c[k]);
        out[k] = top + fy * (bottom - top);
    }
}

// ---- CaptureFrames -----------------------------------------------------------------

CaptureFrames::CaptureFrames(const formats::Capture& capture, int max_frames)
    : m_frames(capture), m_count(capture.frames.count), m_fps(capture.fps), m_source(capture.clip_path()) {
    if (max_frames > 0) m_count = std::min(m_count, max_frames);
}

int CaptureFrames::width() const { return m_frames.width(); }
int CaptureFrames::height() const { return m_frames.height(); }

RgbImage CaptureFrames::frame(int index) {
    if (index < 0 || index >= m_count) throw std::out_of_range("frame index " + std::to_string(index) + " outside the clip");
    return display_rgb(m_frames.frame(m_frames.first() + index));
}

// ---- ClipFrames ------------------------------------------------------------------------

ClipFrames::ClipFrames(int width, int height, double fps, std::string source)
    : m_width(width), m_height(height), m_fps(fps), m_source(std::move(source)) {}

ClipFrames ClipFrames::read_all(FrameSequence& frames, int max_frames, const Progress& progress) {
    ClipFrames clip(frames.width(), frames.height(), frames.fps(), frames.source());
    const int count = max_frames > 0 ? std::min(max_frames, frames.count()) : frames.count();
    for (int i = 0; i < count; ++i) {
        clip.append(frames.frame(i));
        if (progress && !progress({"read clip", static_cast<double>(i + 1) / count, {}})) break;
    }
    return clip;
}

void ClipFrames::append(const RgbImage& display) {
    if (display.width != m_width || display.height != m_height)
        throw std::invalid_argument("ClipFrames::append: frame of another size");
    std::vector<std::uint16_t> data(display.rgb.size());
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = to_u16(display.rgb[i]);
    m_frames.push_back(std::move(data));
}

RgbImage ClipFrames::display(int index) const {
    const auto& data = m_frames.at(static_cast<std::size_t>(index));
    RgbImage out(m_width, m_height);
    for (std::size_t i = 0; i < data.size(); ++i) out.rgb[i] = data[i] / 65535.0f;
    return out;
}

RgbImage ClipFrames::linear(int index) const {
    const auto& data = m_frames.at(static_cast<std::size_t>(index));
    const auto& table = decode_table16();
    RgbImage out(m_width, m_height);
    for (std::size_t i = 0; i < data.size(); ++i) out.rgb[i] = table[data[i]];
    return out;
}

std::vector<std::vector<float>> ClipFrames::luma_frames() const {
    std::vector<std::vector<float>> out;
    out.reserve(m_frames.size());
    for (int i = 0; i < count(); ++i) out.push_back(luma(i));
    return out;
}

std::vector<float> ClipFrames::luma(int index) const {
    const auto& data = m_frames.at(static_cast<std::size_t>(index));
    std::vector<float> y(static_cast<std::size_t>(m_width) * m_height);
    for (std::size_t i = 0; i < y.size(); ++i)
        y[i] = (0.2126f * data[3 * i] + 0.7152f * data[3 * i + 1] + 0.0722f * data[3 * i + 2]) / 65535.0f;
    return y;
}

// ---- MemoryFrames ----------------------------------------------------------------------

MemoryFrames::MemoryFrames(std::vector<RgbImage> display_frames, double fps, std::string source)
    : m_frames(std::move(display_frames)), m_fps(fps), m_source(std::move(source)) {}
int MemoryFrames::width() const { return m_frames.empty() ? 0 : m_frames.front().width; }
int MemoryFrames::height() const { return m_frames.empty() ? 0 : m_frames.front().height; }
RgbImage MemoryFrames::frame(int index) { return m_frames.at(static_cast<std::size_t>(index)); }

// ---- open_clip ---------------------------------------------------------------------------

formats::Capture open_clip(const std::string& path, double fps) {
    std::error_code ec;
    if (fs::is_directory(path, ec) || fs::path(path).filename() == "capture.json") {
        formats::Capture capture = formats::read_capture(path);
        if (!capture.is_video())
            throw ValidationError({Problem{Problem::Severity::error, capture.json_path, "/kind",
                                           "the capture is a " + capture.kind + ", not a video.flow clip",
                                           "give a video.flow capture, a video file or an image pattern"}});
        if (fps > 0.0) capture.fps = fps;
        return capture;
    }
    formats::Capture capture;
    capture.kind = "video.flow";
    if (is_video_extension(lower_extension(path))) {
        if (!fs::is_regular_file(path, ec))
            throw IoError(path, "", "no such video file", "check the path of the clip");
        const formats::VideoInfo info = formats::read_video_info(path);
        if (info.frame_count < 1)
            throw IoError(path, "", "the video reports no frames", "re-encode the clip (e.g. H.264 in .mp4)");
        capture.frames.video = fs::absolute(path).string();
        capture.frames.first = 1;
        capture.frames.count = info.frame_count;
        capture.fps = fps > 0.0 ? fps : (info.fps > 0.0 ? info.fps : 25.0);
        capture.folder = fs::path(capture.frames.video).parent_path().string();
        return capture;
    }
    if (has_integer_conversion(path)) {
        const std::string absolute = fs::absolute(path).string();
        const std::optional<int> starts_at = formats::first_frame_of_pattern(absolute);
        if (!starts_at)
            throw IoError(path, "", "no image for frame 0 or 1 of the pattern",
                          "name the frames with one printf integer, e.g. frames/%06d.png, starting at 0 or 1");
        const int first = *starts_at;
        int count = 0;
        while (fs::is_regular_file(*formats::format_frame_pattern(absolute, first + count), ec)) ++count;
        capture.frames.pattern = absolute;
        capture.frames.first = first;
        capture.frames.count = count;
        capture.fps = fps > 0.0 ? fps : 25.0;
        capture.folder = fs::path(absolute).parent_path().string();
        return capture;
    }
    throw IoError(path, "", "not a capture folder, a video file or an image pattern",
                  "give a video.flow capture folder, a video (.mp4, .avi, .mov, .mkv) or a pattern like frames/%06d.png");
}

// ---- backgrounds ---------------------------------------------------------------------------

namespace {

// A still plate: per pixel and channel, `pick` chooses one value from the
// samples of (at most max_samples evenly spaced) linear frames.
template <class Pick>
RgbImage per_pixel_plate(const ClipFrames& clip, int max_samples, Pick pick) {
    const int count = clip.count();
    if (count == 0) return RgbImage(clip.width(), clip.height());
    const int samples = std::max(1, std::min(count, max_samples));
    std::vector<RgbImage> frames;
    for (int i = 0; i < samples; ++i)
        frames.push_back(clip.linear(samples == 1 ? 0 : static_cast<int>(std::lround(static_cast<double>(i) * (count - 1) / (samples - 1)))));
    RgbImage plate(clip.width(), clip.height());
    std::vector<float> values(static_cast<std::size_t>(samples));
    for (std::size_t i = 0; i < plate.rgb.size(); ++i) {
        for (int s = 0; s < samples; ++s) values[static_cast<std::size_t>(s)] = frames[static_cast<std::size_t>(s)].rgb[i];
        plate.rgb[i] = pick(values);
    }
    return plate;
}

}  // namespace

RgbImage median_plate(const ClipFrames& clip, int max_samples) {
    return per_pixel_plate(clip, max_samples, [](std::vector<float>& values) {
        const auto mid = values.begin() + static_cast<long>(values.size() / 2);
        std::nth_element(values.begin(), mid, values.end());
        float median = *mid;
        if (values.size() % 2 == 0) median = 0.5f * (median + *std::max_element(values.begin(), mid));
        return median;
    });
}

RgbImage quantile_plate(const ClipFrames& clip, double quantile, int max_samples) {
    const double q = std::clamp(quantile, 0.0, 1.0);
    return per_pixel_plate(clip, max_samples, [q](std::vector<float>& values) {
        const auto rank = values.begin() + static_cast<long>(std::lround(q * static_cast<double>(values.size() - 1)));
        std::nth_element(values.begin(), rank, values.end());
        return *rank;
    });
}

const char* to_string(BackgroundMode mode) {
    switch (mode) {
        case BackgroundMode::median: return "median";
        case BackgroundMode::loop: return "loop";
        case BackgroundMode::replay: return "replay";
        case BackgroundMode::relit: return "relit";
        case BackgroundMode::none: return "none";
    }
    return "?";
}

BackgroundMode background_mode_from_string(const std::string& text) {
    if (text == "median") return BackgroundMode::median;
    if (text == "loop") return BackgroundMode::loop;
    if (text == "replay") return BackgroundMode::replay;
    if (text == "relit") return BackgroundMode::relit;
    if (text == "none") return BackgroundMode::none;
    throw std::invalid_argument("unknown background mode '" + text + "' (median, loop, replay, relit or none)");
}

Background Background::plate(RgbImage linear_plate) {
    Background b;
    b.m_mode = BackgroundMode::median;
    b.m_plate = std::move(linear_plate);
    return b;
}

Background Background::looped(std::shared_ptr<const ClipFrames> clip) {
    Background b;
    b.m_mode = BackgroundMode::loop;
    b.m_clip = std::move(clip);
    return b;
}

Background Background::replayed(std::shared_ptr<const ClipFrames> clip, int first_frame, int period_frames,
                                int dissolve_frames) {
    if (period_frames < 1) throw std::invalid_argument("a replayed background needs a period of at least one frame");
    Background b;
    b.m_mode = BackgroundMode::replay;
    b.m_clip = std::move(clip);
    b.m_first_frame = std::max(0, first_frame);
    b.m_period = period_frames;
    b.m_dissolve = std::max(0, dissolve_frames);
    return b;
}

namespace {

// `image` reduced by `scale` (area average) and blurred with a Gaussian of
// sigma_px (full-size pixels): light varies smoothly, so it is measured small.
RgbImage reduced_light(const RgbImage& image, int scale, double sigma_px) {
    const cv::Mat full(image.height, image.width, CV_32FC3, const_cast<float*>(image.rgb.data()));
    const int w = std::max(1, (image.width + scale - 1) / scale), h = std::max(1, (image.height + scale - 1) / scale);
    cv::Mat small;
    cv::resize(full, small, cv::Size(w, h), 0.0, 0.0, cv::INTER_AREA);
    cv::GaussianBlur(small, small, cv::Size(0, 0), std::max(0.5, sigma_px / scale), 0.0, cv::BORDER_REFLECT);
    RgbImage out(w, h);
    std::copy(small.ptr<float>(), small.ptr<float>() + out.rgb.size(), out.rgb.begin());
    return out;
}

// `small` (light measured by reduced_light) enlarged to width x height, bilinearly.
RgbImage enlarged_light(const RgbImage& small, int width, int height) {
    RgbImage full(width, height);
    cv::Mat out(height, width, CV_32FC3, full.rgb.data());
    cv::resize(cv::Mat(small.height, small.width, CV_32FC3, const_cast<float*>(small.rgb.data())), out, out.size(), 0.0,
               0.0, cv::INTER_LINEAR);
    return full;
}

}  // namespace

Background Background::relit(std::shared_ptr<const ClipFrames> clip, RgbImage linear_plate, int first_frame,
                             int period_frames, int dissolve_frames, double light_radius_px) {
    if (!(light_radius_px > 0.0)) throw std::invalid_argument("a relit background needs a light radius above 0 px");
    Background b = replayed(std::move(clip), first_frame, period_frames, dissolve_frames);
    b.m_mode = BackgroundMode::relit;
    b.m_plate = std::move(linear_plate);
    // A quarter of the radius per reduced pixel keeps the Gaussian smooth.
    b.m_light_scale = std::max(1, static_cast<int>(light_radius_px / 4.0));
    if (!b.m_clip || b.m_clip->count() == 0 || b.m_plate.width != b.m_clip->width() ||
        b.m_plate.height != b.m_clip->height())
        return b;  // fill() shows black, as for a replay without its clip
    // The light of every frame the background can show, measured once (a
    // period of small images): ratio of blurred frame to blurred plate, at
    // most 1, light only taken away. Brightening the plate where the frame
    // has a flame draws a glow without the flame wherever no particle carries
    // it (fire frame 140 viewed: a haze over the ground beside the flames at
    // a gain of 1.5). The small floor keeps black regions of the plate from
    // amplifying noise.
    constexpr float kDarkFloor = 2e-3f;
    const RgbImage plate_light = reduced_light(b.m_plate, b.m_light_scale, light_radius_px);
    const int n = b.m_clip->count();
    b.m_light_gains.resize(static_cast<std::size_t>(n));
    // The window's frames, and after it those the particles still on the
    // lines at the wrap show (Synthesizer::fill_background follows them).
    for (int r = 0; r < std::max(b.m_period, n - b.m_first_frame); ++r) {
        const int index = r < b.m_period ? (b.m_first_frame + r) % n : b.m_first_frame + r;
        if (index >= n || !b.m_light_gains[static_cast<std::size_t>(index)].empty()) continue;
        RgbImage gain = reduced_light(b.m_clip->linear(index), b.m_light_scale, light_radius_px);
        for (std::size_t i = 0; i < gain.rgb.size(); ++i)
            gain.rgb[i] = std::min(1.0f, (gain.rgb[i] + kDarkFloor) / (plate_light.rgb[i] + kDarkFloor));
        b.m_light_gains[static_cast<std::size_t>(index)] = std::move(gain);
    }
    return b;
}

void Background::fill(int frame, int width, int height, RgbImage& out) const {
    const auto fits = [&](const RgbImage& image) { return image.width == width && image.height == height; };
    if (m_mode == BackgroundMode::median && fits(m_plate)) {
        out = m_plate;
        return;
    }
    const bool have_clip = m_clip && m_clip->count() > 0 && m_clip->width() == width && m_clip->height() == height;
    if (m_mode == BackgroundMode::loop && have_clip) {
        const int n = m_clip->count();
        const int index = (((frame - 1) % n) + n) % n;
        out = m_clip->linear(index);
        return;
    }
    if (m_mode == BackgroundMode::replay && have_clip) {
        const ReplayFrames frames = replay_frames(frame);
        out = m_clip->linear(frames.now);
        if (frames.continuing >= 0 && frames.dissolve_share > 0.0f) {
            const float after = frames.dissolve_share;
            const RgbImage before = m_clip->linear(frames.continuing);
            for (std::size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] = (1.0f - after) * out.rgb[i] + after * before.rgb[i];
        }
        return;
    }
    if (m_mode == BackgroundMode::relit && have_clip && fits(m_plate)) {
        const ReplayFrames frames = replay_frames(frame);
        RgbImage gain = m_light_gains[static_cast<std::size_t>(frames.now)];
        if (frames.continuing >= 0 && frames.dissolve_share > 0.0f) {
            const float after = frames.dissolve_share;
            const RgbImage& before = m_light_gains[static_cast<std::size_t>(frames.continuing)];
            for (std::size_t i = 0; i < gain.rgb.size(); ++i) gain.rgb[i] += after * (before.rgb[i] - gain.rgb[i]);
        }
        out = enlarged_light(gain, width, height);
        for (std::size_t i = 0; i < out.rgb.size(); ++i) out.rgb[i] *= m_plate.rgb[i];
        return;
    }
    out = RgbImage(width, height);
}

Background::ReplayFrames Background::replay_frames(int frame) const {
    ReplayFrames frames;
    if ((m_mode != BackgroundMode::replay && m_mode != BackgroundMode::relit) || !m_clip || m_clip->count() == 0)
        return frames;
    const int n = m_clip->count();
    const int r = (((frame - 1) % m_period) + m_period) % m_period;
    frames.now = (m_first_frame + r) % n;
    const int continuing = m_first_frame + m_period + r;
    if (continuing < n) {
        frames.continuing = continuing;
        if (r < m_dissolve) frames.dissolve_share = 1.0f - static_cast<float>(r + 1) / static_cast<float>(m_dissolve + 1);
    }
    return frames;
}

void Background::fill_replay(int frame, int width, int height, const std::vector<float>& continuing_share,
                             RgbImage& out) const {
    const ReplayFrames frames = replay_frames(frame);
    const std::size_t pixels = static_cast<std::size_t>(width) * height;
    if (frames.continuing < 0 || m_clip->width() != width || m_clip->height() != height ||
        continuing_share.size() != pixels) {
        fill(frame, width, height, out);
        return;
    }
    if (m_mode == BackgroundMode::relit) {
        // The two frames' light, enlarged, mixed per pixel, on the plate.
        if (!(m_plate.width == width && m_plate.height == height)) {
            fill(frame, width, height, out);
            return;
        }
        out = enlarged_light(m_light_gains[static_cast<std::size_t>(frames.now)], width, height);
        const RgbImage after = enlarged_light(m_light_gains[static_cast<std::size_t>(frames.continuing)], width, height);
        for (std::size_t i = 0; i < pixels; ++i) {
            const float a = continuing_share[i];
            for (std::size_t k = 3 * i; k < 3 * i + 3; ++k)
                out.rgb[k] = m_plate.rgb[k] * (out.rgb[k] + a * (after.rgb[k] - out.rgb[k]));
        }
        return;
    }
    out = m_clip->linear(frames.now);
    const RgbImage after = m_clip->linear(frames.continuing);
    for (std::size_t i = 0; i < pixels; ++i) {
        const float a = continuing_share[i];
        if (a <= 0.0f) continue;
        for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) out.rgb[k] += a * (after.rgb[k] - out.rgb[k]);
    }
}

// ---- writing -------------------------------------------------------------------------------------

namespace {

void write_image_file(const std::string& path, const RgbImage& linear) {
    const std::string ext = lower_extension(path);
    auto output = OIIO::ImageOutput::create(path);
    if (!output)
        throw IoError(path, "", "no image writer for this file type (" + OIIO::geterror() + ")",
                      "write .png, .exr, .tif or .jpg frames");
    const std::size_t n = linear.rgb.size();
    formats::write_path_atomically(path, [&](const std::string& temp_path) {
        bool ok = false;
        if (ext == ".exr") {
            OIIO::ImageSpec spec(linear.width, linear.height, 3, OIIO::TypeDesc::HALF);
            spec.attribute("compression", "zip");
            ok = output->open(temp_path, spec) && output->write_image(OIIO::TypeDesc::FLOAT, linear.rgb.data());
        } else if (ext == ".tif" || ext == ".tiff") {
            std::vector<std::uint16_t> data(n);
            for (std::size_t i = 0; i < n; ++i) data[i] = to_u16(linear_to_srgb(linear.rgb[i]));
            OIIO::ImageSpec spec(linear.width, linear.height, 3, OIIO::TypeDesc::UINT16);
            ok = output->open(temp_path, spec) && output->write_image(OIIO::TypeDesc::UINT16, data.data());
        } else {
            std::vector<std::uint8_t> data(n);
            for (std::size_t i = 0; i < n; ++i)
                data[i] = static_cast<std::uint8_t>(std::lround(linear_to_srgb(linear.rgb[i]) * 255.0f));
            OIIO::ImageSpec spec(linear.width, linear.height, 3, OIIO::TypeDesc::UINT8);
            ok = output->open(temp_path, spec) && output->write_image(OIIO::TypeDesc::UINT8, data.data());
        }
        const std::string error = output->geterror();
        output->close();
        if (!ok) throw IoError(path, "", "cannot write the image: " + error, "check the folder exists and is writable");
    });
}

}  // namespace

struct FrameWriter::Impl {
    std::string target;
    std::string pattern;  // image sequences
    bool single_image = false;  // one frame to a plain file name: `target` itself
    int width = 0;
    int height = 0;
    double fps = 25.0;
    bool video = false;
    std::optional<formats::PendingFile> video_file;  // published by close(), so no half video ever has the name
    std::string codec;                               // h264, mpeg4, mjpeg
    int encoded_width = 0, encoded_height = 0;       // H.264: the frame's size rounded up to even
    cv::VideoWriter writer;
};

namespace {

// What an output target names, decided from the name alone (no files touched).
struct OutputForm {
    bool video = false;
    bool single_image = false;  // one frame to a plain file name
    bool folder = false;        // a folder: frames go to folder/%06d.png
    std::string pattern;        // image sequences and single images
};

OutputForm output_form(const std::string& target, int frame_count) {
    OutputForm form;
    const std::string ext = lower_extension(target);
    if (is_video_extension(ext)) {
        form.video = true;
    } else if (has_integer_conversion(target)) {
        form.pattern = target;
    } else if (frame_count == 1 && !ext.empty()) {
        form.single_image = true;
        form.pattern = target;
    } else if (ext.empty()) {
        form.folder = true;
        form.pattern = (fs::path(target) / "%06d.png").string();
    } else {
        throw IoError(target, "", "an image output of more than one frame needs a frame number in its name",
                      "write e.g. out/%06d.png, a folder, or a video file (.mp4, .avi); a plain name such as "
                      "still.png takes one frame (--frames A:A)");
    }
    return form;
}

}  // namespace

void FrameWriter::check_target(const std::string& target, int frame_count) {
    const OutputForm form = output_form(target, frame_count);
    if (form.video) return;
    if (!OIIO::ImageOutput::create(form.pattern))
        throw IoError(target, "", "no image writer for the file type " + lower_extension(form.pattern),
                      "write .png, .exr, .tif or .jpg frames, or a video (.mp4, .avi)");
}

FrameWriter::FrameWriter(const std::string& target, int width, int height, double fps, int frame_count)
    : m_impl(std::make_unique<Impl>()) {
    m_impl->target = target;
    m_impl->width = width;
    m_impl->height = height;
    m_impl->fps = fps > 0.0 ? fps : 25.0;
    const OutputForm form = output_form(target, frame_count);
    std::error_code ec;
    if (form.video) {
        m_impl->video = true;
        const fs::path parent = fs::path(target).parent_path();
        if (!parent.empty() && !fs::is_directory(parent, ec))
            throw IoError(target, "", "the folder " + parent.string() + " does not exist", "create it first");
        m_impl->video_file.emplace(target);
        const auto open_with = [&](const char* codec, int fourcc, int encoded_width, int encoded_height) {
            m_impl->codec = codec;
            m_impl->encoded_width = encoded_width;
            m_impl->encoded_height = encoded_height;
            return m_impl->writer.open(m_impl->video_file->temp_path(), cv::CAP_FFMPEG, fourcc, m_impl->fps,
                                       cv::Size(encoded_width, encoded_height), true);
        };
        if (lower_extension(target) == ".avi") {
            open_with("mjpeg", cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), width, height);
        } else if (!open_with("h264", cv::VideoWriter::fourcc('a', 'v', 'c', '1'), width + width % 2, height + height % 2)) {
            // An OpenCV whose FFmpeg lacks an H.264 encoder: MPEG-4 part 2,
            // which players (not browsers) show.
            open_with("mpeg4", cv::VideoWriter::fourcc('m', 'p', '4', 'v'), width, height);
        }
        if (!m_impl->writer.isOpened())
            throw IoError(target, "", "cannot open the video for writing", "use .mp4 or .avi, or write an image sequence");
        return;
    }
    if (form.folder) {
        fs::create_directories(target, ec);
        if (ec) throw IoError(target, "", "cannot create the folder: " + ec.message(), "check permissions");
    }
    m_impl->single_image = form.single_image;
    m_impl->pattern = form.pattern;
    const fs::path parent = fs::path(m_impl->pattern).parent_path();
    if (!parent.empty() && !fs::is_directory(parent, ec))
        throw IoError(target, "", "the folder " + parent.string() + " does not exist", "create it first");
}

FrameWriter::~FrameWriter() { discard(); }

bool FrameWriter::is_video() const { return m_impl->video; }

std::string FrameWriter::video_codec() const { return m_impl->video ? m_impl->codec : std::string(); }

std::string FrameWriter::path_of(int frame) const {
    if (m_impl->video || m_impl->single_image) return m_impl->target;
    return *formats::format_frame_pattern(m_impl->pattern, frame);
}

void FrameWriter::write(int frame, const RgbImage& linear) {
    if (linear.width != m_impl->width || linear.height != m_impl->height)
        throw std::invalid_argument("FrameWriter::write: frame of another size");
    if (!m_impl->video) {
        write_image_file(path_of(frame), linear);
        return;
    }
    cv::Mat mat(m_impl->encoded_height, m_impl->encoded_width, CV_8UC3);
    for (int y = 0; y < m_impl->encoded_height; ++y) {
        auto* row = mat.ptr<std::uint8_t>(y);
        const float* in = linear.pixel(0, std::min(y, m_impl->height - 1));  // padding repeats the last row
        for (int x = 0; x < m_impl->encoded_width; ++x) {
            const int source = std::min(x, m_impl->width - 1);  // and the last column
            for (int c = 0; c < 3; ++c)  // OpenCV wants BGR
                row[3 * x + c] = static_cast<std::uint8_t>(std::lround(linear_to_srgb(in[3 * source + (2 - c)]) * 255.0f));
        }
    }
    m_impl->writer.write(mat);
}

void FrameWriter::close() {
    if (!m_impl || !m_impl->video) return;
    if (m_impl->writer.isOpened()) m_impl->writer.release();
    if (m_impl->video_file) m_impl->video_file->commit();
}

void FrameWriter::discard() {
    if (!m_impl || !m_impl->video) return;
    if (m_impl->writer.isOpened()) m_impl->writer.release();
    if (m_impl->video_file) m_impl->video_file->discard();
}

void write_image(const std::string& path, const RgbImage& linear) { write_image_file(path, linear); }

RgbImage read_image_linear(const std::string& path) {
    const formats::Image image = formats::load_image(path, 3);
    if (image.encoding == formats::Image::Encoding::linear) {
        RgbImage out(image.width, image.height);
        out.rgb = image.pixels;
        return out;
    }
    return to_linear(display_rgb(image));
}

}  // namespace flowvid::flow
