#pragma once
// Frames of flow-based video (thesis chapter 3): RGB float images, colour
// encodings, clips read from capture folders, video files or image sequences,
// and the background plates synthesis composites onto.
//
// Conventions: pixel (x, y) is the centre of column x, row y (OpenCV, as the
// flow lines); images are row-major from the top row, RGB interleaved.
// Two encodings meet here: *display* values (sRGB-encoded, what 8-bit files and
// videos store; tracking and the quality metrics work on these, as a viewer
// sees them) and *linear* light (particle textures in the bank, rendering and
// blending). Functions say which they take.

#include "flowvid/progress.hpp"
#include "flowvid/formats/capture.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace flowvid::flow {

// An RGB float image, `width x height x 3` values.
struct RgbImage {
    int width = 0;
    int height = 0;
    std::vector<float> rgb;

    RgbImage() = default;
    RgbImage(int w, int h, float value = 0.0f)
        : width(w), height(h), rgb(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3, value) {}
    bool empty() const { return width <= 0 || height <= 0; }
    float* pixel(int x, int y) { return rgb.data() + (static_cast<std::size_t>(y) * width + x) * 3; }
    const float* pixel(int x, int y) const { return rgb.data() + (static_cast<std::size_t>(y) * width + x) * 3; }
};

// The sRGB transfer function (IEC 61966-2-1), for values in [0, 1] (clamped).
float srgb_to_linear(float encoded);
float linear_to_srgb(float linear);
RgbImage to_linear(const RgbImage& display);
RgbImage to_display(const RgbImage& linear);
// Rec. 709 luma of display values: one float per pixel.
std::vector<float> luma(const RgbImage& display);

// A decoded file image (formats::Image) as display RGB: sRGB-encoded files are
// copied, linear (EXR) ones encoded.
RgbImage display_rgb(const formats::Image& image);

// Bilinear sample of channel-interleaved RGB at (x, y), pixel-centre
// coordinates, clamped to the border.
void sample_bilinear(const RgbImage& image, double x, double y, float out[3]);

// ---- clips ---------------------------------------------------------------------

// A clip the tracker and the metrics read frame by frame, in display values.
// Frame indices are 0-based (index 0 = the clip's first frame).
class FrameSequence {
public:
    virtual ~FrameSequence() = default;
    virtual int width() const = 0;
    virtual int height() const = 0;
    virtual int count() const = 0;
    virtual double fps() const = 0;
    // Display RGB of frame `index` (0 <= index < count()). Sequential reading
    // is the fast path.
    virtual RgbImage frame(int index) = 0;
    // Informative: where the frames come from.
    virtual std::string source() const = 0;
};

// Frames of a capture folder (video.flow), a video file or an image sequence,
// decoded on demand through formats::FrameSource.
class CaptureFrames : public FrameSequence {
public:
    explicit CaptureFrames(const formats::Capture& capture, int max_frames = 0);
    int width() const override;
    int height() const override;
    int count() const override { return m_count; }
    double fps() const override { return m_fps; }
    RgbImage frame(int index) override;
    std::string source() const override { return m_source; }

private:
    formats::FrameSource m_frames;
    int m_count = 0;
    double m_fps = 0.0;
    std::string m_source;
};

// All frames in memory at 16 bits per channel (display values): a 640 x 360 x
// 120 clip takes 166 MB. Used for the looped background and the metrics.
class ClipFrames : public FrameSequence {
public:
    ClipFrames() = default;
    ClipFrames(int width, int height, double fps, std::string source);
    // Reads every frame of `frames` (at most max_frames when > 0). `progress`
    // gets the fraction read and may return false to stop early (the clip
    // then holds the frames read so far).
    static ClipFrames read_all(FrameSequence& frames, int max_frames = 0,
                               const Progress& progress = {});
    void append(const RgbImage& display);

    int width() const override { return m_width; }
    int height() const override { return m_height; }
    int count() const override { return static_cast<int>(m_frames.size()); }
    double fps() const override { return m_fps; }
    RgbImage frame(int index) override { return display(index); }
    std::string source() const override { return m_source; }

    RgbImage display(int index) const;
    RgbImage linear(int index) const;
    std::vector<float> luma(int index) const;
    std::vector<std::vector<float>> luma_frames() const;  // luma(i) of every frame, in order

private:
    int m_width = 0;
    int m_height = 0;
    double m_fps = 0.0;
    std::string m_source;
    std::vector<std::vector<std::uint16_t>> m_frames;
};

// Frames held as display images (tests, synthetic clips).
class MemoryFrames : public FrameSequence {
public:
    MemoryFrames(std::vector<RgbImage> display_frames, double fps, std::string source = "memory");
    int width() const override;
    int height() const override;
    int count() const override { return static_cast<int>(m_frames.size()); }
    double fps() const override { return m_fps; }
    RgbImage frame(int index) override;
    std::string source() const override { return m_source; }
    const std::vector<RgbImage>& frames() const { return m_frames; }

private:
    std::vector<RgbImage> m_frames;
    double m_fps;
    std::string m_source;
};

// What a clip path names, as a capture: a capture folder (or its
// capture.json) is read and validated; a video file (.mp4, .avi, .mov, .mkv,
// .webm, .m4v) or a printf image pattern ("frames/%06d.png", first number 0
// or 1, counted until a file is missing) becomes a video.flow capture without
// flow lines. `fps` (> 0) overrides the frame rate of files that carry none
// (image sequences default to 25). Throws IoError / ValidationError naming
// the path.
formats::Capture open_clip(const std::string& path, double fps = 0.0);

// ---- backgrounds -----------------------------------------------------------------

// The per-pixel, per-channel median over (at most max_samples evenly spaced)
// frames, in linear light: the static plate of the clip.
RgbImage median_plate(const ClipFrames& clip, int max_samples = 64);
// The same at another quantile (0 = the darkest sample, 0.5 = about the
// median): a low one is the scene with the least light of flames on it.
RgbImage quantile_plate(const ClipFrames& clip, double quantile, int max_samples = 64);

// How regions no flow line covers are filled (issue: "a static median plate
// or the looped clip"). replay: the looped clip in step with the synthesis,
// showing the input frame its particles show (Background::replayed). relit:
// the median plate darkened where that frame is darker (Background::relit).
enum class BackgroundMode { median, loop, replay, relit, none };
const char* to_string(BackgroundMode mode);
// "median", "loop", "replay", "relit", "none"; throws std::invalid_argument otherwise.
BackgroundMode background_mode_from_string(const std::string& text);

// The background of every output frame (linear light).
class Background {
public:
    Background() = default;  // none: black
    static Background plate(RgbImage linear_plate);
    // Output frame t (1-based) shows clip frame (t - 1) mod count.
    static Background looped(std::shared_ptr<const ClipFrames> clip);
    // In step with a synthesis whose diagonal order replays input frames
    // first_frame .. first_frame + period - 1 (Schedule::first_start_frame,
    // period_frames): output frame t shows clip frame first_frame +
    // (t - 1) mod period, the frame its particles show, so texture and
    // background agree where the particles end. Where the order wraps, the
    // particles already on the lines go on showing the frames after the
    // window while new ones start again at first_frame; the background
    // dissolves from the former to the latter over dissolve_frames, where
    // the clip has the former.
    static Background replayed(std::shared_ptr<const ClipFrames> clip, int first_frame, int period_frames,
                               int dissolve_frames);
    // The still plate darkened, frame by frame, where the replayed clip frame
    // (same frames as `replayed`; after the wrap, through fill_replay, the
    // frames the particles still on the lines show) is darker than it: the
    // plate times the ratio of that frame to the plate, both blurred with a
    // Gaussian of sigma light_radius_px, at most 1. Where flames die down the
    // scene they lit darkens with them, so a patch carrying that moment meets
    // a plate lit as it was; the scene's detail stays the plate's, so the
    // clip's own transitions are not replayed.
    static Background relit(std::shared_ptr<const ClipFrames> clip, RgbImage linear_plate, int first_frame,
                            int period_frames, int dissolve_frames, double light_radius_px);
    BackgroundMode mode() const { return m_mode; }
    // Writes the background of output frame `frame` into `out` (resized).
    void fill(int frame, int width, int height, RgbImage& out) const;

    // Replay and relit only. The clip frames output frame `frame` may show: the
    // window's (`now`) and the one after the window that the particles still
    // on the lines from before the wrap show (`continuing`, -1 where the
    // clip has none), with the dissolve's share of the latter (0 once it is
    // over): what fill() shows everywhere.
    struct ReplayFrames {
        int now = -1;
        int continuing = -1;
        float dissolve_share = 0.0f;
    };
    ReplayFrames replay_frames(int frame) const;
    // Replay (relit: the plate lit as) with the continuing frame mixed in per
    // pixel by `continuing_share` (width x height, 0..1) instead of the
    // dissolve: the synthesizer follows the ladder, showing behind each
    // particle the frame it shows (Synthesizer::render).
    void fill_replay(int frame, int width, int height, const std::vector<float>& continuing_share, RgbImage& out) const;

private:
    BackgroundMode m_mode = BackgroundMode::none;
    RgbImage m_plate;
    std::shared_ptr<const ClipFrames> m_clip;
    int m_first_frame = 0;  // replay
    int m_period = 0;
    int m_dissolve = 0;
    int m_light_scale = 1;  // relit: light is measured on frames reduced by this factor
    // relit: per clip frame the background can show, its light relative to
    // the plate's (at most 1), reduced; empty for the others.
    std::vector<RgbImage> m_light_gains;
};

// ---- writing frames ------------------------------------------------------------------

// Writes rendered frames: an image pattern with one printf integer
// ("out/%06d.png"; PNG/JPEG 8-bit sRGB, TIFF 16-bit sRGB, EXR half linear,
// through OpenImageIO), a folder (written as FOLDER/%06d.png), or a video
// file (.mp4/.mov/.mkv H.264, which browsers and editors play, falling back
// to MPEG-4 part 2 where OpenCV's FFmpeg has no H.264 encoder; .avi
// Motion-JPEG; through OpenCV). H.264 needs an even width and height: an odd
// frame is padded by repeating its last column or row. Image
// files are named by output frame number, so ranges rendered apart fit
// together; a video holds the frames in the order written. A caller that
// writes one frame (frame_count 1) may name a plain image file (still.png).
class FrameWriter {
public:
    FrameWriter(const std::string& target, int width, int height, double fps, int frame_count = 0);
    // Throws the IoError the constructor or the first write would, for what
    // the name alone decides (a sequence without a frame number, an image
    // type nothing writes), so commands can say so before long work.
    // `frame_count` as for the constructor (0 = not known yet: several).
    static void check_target(const std::string& target, int frame_count);
    ~FrameWriter();
    FrameWriter(const FrameWriter&) = delete;
    FrameWriter& operator=(const FrameWriter&) = delete;
    bool is_video() const;
    // The video's codec: "h264", "mpeg4" or "mjpeg"; empty for images.
    std::string video_codec() const;
    // The file a frame goes to (the video file for videos).
    std::string path_of(int frame) const;
    // `linear` must have the writer's size. Throws IoError naming the file.
    void write(int frame, const RgbImage& linear);
    // A video is written under a temporary name: close() publishes it under
    // the target name; discard() (and destruction without close()) removes
    // it, leaving any earlier file of that name intact. Image sequences are
    // written frame by frame, each frame atomically.
    void close();
    void discard();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

// Writes one image (format from the extension, as FrameWriter); throws IoError.
void write_image(const std::string& path, const RgbImage& linear);
// Reads an image (any format OpenImageIO or OpenCV reads) as linear RGB.
RgbImage read_image_linear(const std::string& path);

}  // namespace flowvid::flow
