#pragma once
// Camera drift (issue #30): a clip filmed from a camera that drifts by a few
// pixels smears the still median plate and makes particles' patches slide
// under them. The clip is brought into one still view, tracked and
// synthesized there; the output is a still camera, since an infinite sequence
// cannot replay a finite drift without a jump. The view is the clip's central
// one (the frame whose camera is nearest the others'), so that the output
// looks like as many of the clip's frames as it can: from the first frame's
// view, the end of a drift is a whole drift away. The flow lines, drawn on
// the first frame, are carried into that view (drawing_in_view). A clip whose
// camera holds still is left exactly as it is.
//
// The drift is estimated on the background only (pixels far from every input
// line: water and flames move on their own) by enhanced correlation
// (OpenCV's ECC), which ignores a global change of gain and offset.

#include "flowvid/progress.hpp"
#include "flowvid/flow/frames.hpp"
#include "flowvid/formats/flowlines.hpp"
#include "flowvid/formats/particle_bank.hpp"

#include <Eigen/Core>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace flowvid::flow {

struct CameraMotionSettings {
    // Pixels within this distance of an input line are left out of the estimate.
    double exclude_around_lines_px = 80.0;
    // A camera whose frames all stay within this distance of the first frame
    // (at every corner) is taken as still and the clip left unchanged: flames
    // and sunlight that change the light move ECC's estimate by about a pixel.
    double still_below_px = 2.0;
    // A frame that matches the first frame's background worse than this
    // (ECC's correlation coefficient) makes the whole estimate untrusted and
    // the clip is left as it is: fire lights its surroundings unevenly, and
    // a shift found under such light is not the camera's.
    double min_correlation = 0.8;
    // Frames wider than this are estimated at a reduced size (speed); the
    // offsets are scaled back.
    int estimate_width_px = 640;
    // The still view the clip is brought into: the central frame's (the
    // least summed squared displacement to every other frame, at the
    // corners), or the first frame's (where the lines are drawn: auto lines
    // are proposed there).
    enum class View { central, first_frame };
    View view = View::central;
};

// Where the camera of each frame looked, relative to the first frame.
struct CameraMotion {
    enum class Model { still, translation, affine };
    Model model = Model::still;
    // Per frame: maps a pixel of the first frame's view to the same scene
    // point in that frame (x' = A x + t), pixels. Identity when still.
    std::vector<Eigen::Matrix<double, 2, 3>> first_to_frame;
    // The frame whose view the stabilised frames (and the output) show; 0 when still.
    int view_frame = 0;
    // Maps a pixel of the view to the same scene point in `frame`.
    Eigen::Matrix<double, 2, 3> view_to_frame(int frame) const;
    // Maps a pixel of the first frame (where lines are drawn) to the view, and back.
    Eigen::Matrix<double, 2, 3> first_to_view() const;
    Eigen::Matrix<double, 2, 3> view_to_first() const;
    double largest_offset_px = 0.0;  // the largest corner displacement over all frames
    double worst_correlation = 1.0;  // ECC's lowest correlation coefficient over the frames
    bool untrusted = false;          // still because the background matched too poorly to tell
    bool still() const { return model == Model::still; }
};
const char* to_string(CameraMotion::Model model);

// Reads every frame once. `input_lines` are the drawn (or densified) input
// lines, pixels; `progress` gets the fraction done and may return false to
// stop (the motion then says still).
CameraMotion estimate_camera_motion(FrameSequence& frames, const std::vector<std::vector<Eigen::Vector2d>>& input_lines,
                                    const CameraMotionSettings& settings = {},
                                    const Progress& progress = {});

// The frames of `source` seen from the view frame's camera: each frame is
// resampled (Lanczos, 8 x 8 taps: bilinear would halve the fine detail of
// water) where the view's pixels lie in it; pixels the frame did not see show
// the view frame's own (fading in over a pixel). Frames of a still camera are
// passed through unchanged. `source` must outlive this.
class StabilisedFrames : public FrameSequence {
public:
    StabilisedFrames(FrameSequence& source, CameraMotion motion);
    int width() const override { return m_source.width(); }
    int height() const override { return m_source.height(); }
    int count() const override { return m_source.count(); }
    double fps() const override { return m_source.fps(); }
    RgbImage frame(int index) override;
    std::string source() const override { return m_source.source(); }
    const CameraMotion& motion() const { return m_motion; }

private:
    FrameSequence& m_source;
    CameraMotion m_motion;
    std::optional<RgbImage> m_view;  // the view frame, read when a frame first needs it
};

// The drawing (drawn on the clip's first frame) in the view the clip is
// stabilised into: every input and output line's points and keys moved with
// the camera. Unchanged for a still camera.
formats::FlowLineSet drawing_in_view(const formats::FlowLineSet& drawing, const CameraMotion& motion);
// The inverse: lines of the view back in the first frame's pixels (files an artist overlays on the clip).
formats::FlowLineSet drawing_as_drawn(const formats::FlowLineSet& view_drawing, const CameraMotion& motion);
// Polylines of the view back where they were drawn (the first frame's pixels).
std::vector<std::vector<Eigen::Vector2d>> polylines_as_drawn(const std::vector<std::vector<Eigen::Vector2d>>& view_lines,
                                                             const CameraMotion& motion);

// The drawing's input lines as polylines: what the drift estimate leaves out.
// track estimates from the drawn lines (not the densified ones), and so do
// synth, edit and quality for a bank that does not store its camera (1.0),
// so that they find the same drift for the same drawing.
std::vector<std::vector<Eigen::Vector2d>> drawn_input_polylines(const formats::FlowLineSet& drawing);

// The whole clip in memory as seen from its view frame's camera: read once,
// the drift estimated around the drawing's input lines, then resampled
// (unchanged when the camera is still). `motion` receives the estimate;
// `as_filmed`, when given and the frames were resampled, the frames as they
// were read (measures that compare with the footage use these: resampling
// softens the finest detail). For a still camera it is left as it was: the
// frames returned are the footage.
ClipFrames read_clip_stabilised(FrameSequence& frames, const formats::FlowLineSet& drawing, CameraMotion& motion,
                                const Progress& progress = {}, ClipFrames* as_filmed = nullptr);

// The same, with the drift already known (a bank that stores the view it
// was tracked in): nothing is estimated.
ClipFrames read_clip_in_view(FrameSequence& frames, const CameraMotion& motion, const Progress& progress = {},
                             ClipFrames* as_filmed = nullptr);

// The camera as a particle bank stores it (its maps in float32, as ECC
// estimates them), and back.
formats::BankCamera to_bank_camera(const CameraMotion& motion);
CameraMotion from_bank_camera(const formats::BankCamera& camera);

// A one-line account for logs: "camera still" or "camera drifts up to 10.4 px
// (translation, ...): tracked and rendered in the view of frame 19, the
// middle of its path, a still camera".
std::string describe(const CameraMotion& motion);

}  // namespace flowvid::flow
