#pragma once
// Flow-based editing (thesis 3.3): the artist draws a sparse set of output
// lines, each naming the input line whose texture it carries; flowvid
// interpolates a dense set between neighbouring output lines, and assigns an
// input line to every interpolated line by dynamic programming over the patch
// overlap error of neighbours (eq. 3.1):
//
//     C(x, y) = min_y' [ C(x-1, y') + E(x-1, y', x, y) ]
//
// where E is the mean squared colour difference (linear RGB) where line x-1
// rendered with input y' and line x rendered with input y overlap (weighted by
// both feather weights), averaged over 30 output frames. Drawn lines keep the
// input their artist gave them; interpolated lines may carry any input line
// with particles. Chains of neighbours are formed as in flow/geometry.hpp.
// Time-varying drawn lines give time-varying interpolated lines.

#include "flowvid/progress.hpp"
#include "flowvid/flow/synthesis.hpp"
#include "flowvid/formats/flowlines.hpp"

#include <Eigen/Core>

#include <functional>
#include <string>
#include <vector>

namespace flowvid::flow {

struct EditSettings {
    double spacing_px = 0.0;    // largest gap between dense neighbours; 0 = half the patch size
    double max_gap_px = 0.0;    // drawn lines further apart (mean gap) are not neighbours; 0 = 6 patch sizes
    double max_angle_deg = 45.0;
    int correspondence_frames = 30;  // output frames the overlap error is averaged over (thesis: 30)
    int first_frame = 1;             // first of those frames
    int samples_along = 12;          // sample points along each neighbour pair (times 5 across)
    ArcMapping mapping = ArcMapping::equal;
    int threads = 0;                 // 0 = hardware concurrency
    // Each interpolated line, and each drawn line carrying an input an earlier
    // drawn line carries, shows its input's particles at its own offset in
    // time (golden-ratio steps through the period): without it, neighbours
    // that carry the same input show the same particles side by side.
    bool offset_interpolated_lines = true;
    // Which input lines an interpolated line may carry. between: those lying
    // between (inclusive) the inputs of the two drawn lines it is interpolated
    // from, across the flow (every input when those two are not neighbours
    // in one chain of inputs). any: every input line (the thesis's Y), which
    // lets eq. 3.1 favour flat, static texture (a line over bare ground).
    enum class InterpolatedInputs { between, any };
    InterpolatedInputs interpolated_inputs = InterpolatedInputs::between;
};

// The solution of eq. 3.1 along one chain.
struct ChainAssignment {
    std::vector<int> choice;  // candidate index per chain position
    double cost = 0.0;        // sum of E over neighbour pairs
};
// Dynamic programme over a chain of X lines and Y candidates:
// pair_costs[x - 1](y', y) = E(x-1, y', x, y) for x = 1..X-1 (Y x Y each);
// allowed[x] lists the candidates line x may take (empty = any). O(X Y^2).
// Throws std::invalid_argument when no assignment is allowed.
ChainAssignment solve_chain(const std::vector<Eigen::MatrixXd>& pair_costs, const std::vector<std::vector<int>>& allowed,
                            int candidate_count);

// E(x-1, y', x, y) for every neighbour pair of `chain` (polylines or keyed
// lines, each at its time_offset_frames) and every pair of candidate streams,
// averaged over the settings' frames. Pairs that never overlap cost 0.
std::vector<Eigen::MatrixXd> overlap_errors(const ParticleStreams& streams, const std::vector<formats::FlowLine>& chain,
                                            const std::vector<int>& candidate_streams, const EditSettings& settings);

struct DenseLine {
    OutputLine output;    // geometry and the input line it carries
    bool drawn = false;   // drawn by the artist (its input is kept) or interpolated
};

struct EditPlan {
    std::vector<DenseLine> lines;
    std::vector<std::vector<int>> chains;  // indices into lines, in order across the flow
    double total_cost = 0.0;               // sum of the chains' DP costs
    std::vector<std::string> warnings;
};

// Interpolates the drawing's output lines into a dense set and assigns inputs.
// Throws std::invalid_argument when the drawing has no output line.
EditPlan plan_edit(const formats::FlowLineSet& drawing, const ParticleStreams& streams, const EditSettings& settings,
                   const Progress& progress = {});

// The plan's lines as Synthesizer outputs.
std::vector<OutputLine> output_lines(const EditPlan& plan);

// The plan as a flow-line set (the drawing's inputs, the dense outputs), to
// save and look at or redraw.
formats::FlowLineSet plan_to_flowlines(const formats::FlowLineSet& drawing, const EditPlan& plan);

}  // namespace flowvid::flow
