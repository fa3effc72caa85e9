#pragma once
// Swatch experiments (thesis static drape and waving tests): a rectangular
// swatch hung by pinned corners that follow measured trajectories, starting at
// the static equilibrium under the first pin positions.

#include "flowvid/cloth/equilibrium.hpp"
#include "flowvid/cloth/simulator.hpp"
#include "flowvid/formats/capture.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace flowvid::cloth {

// One pinned point: its normalised uv on the swatch ((0,0) bottom-left as
// hung, (1,1) top-right) and its world position at every frame.
struct PinTrajectory {
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
    std::vector<Eigen::Vector3d> positions_m;
};

// Everything a swatch experiment prescribes. frame_count frames at fps;
// frame 1 (index 0) is the equilibrium under the first pin positions.
struct SwatchExperiment {
    std::string source = "<experiment>";  // file named in error messages (capture.json)
    double width_m = 0.30;   // along u (warp)
    double height_m = 0.30;  // along v (weft)
    double mass_kg = 0.0;    // > 0: overrides the material's areal density
    double fps = 30.0;
    int frame_count = 0;
    std::vector<PinTrajectory> pins;
};

struct SwatchOptions {
    int rows = 24;
    int cols = 24;
    Environment environment;  // gravity, wind, colliders (defaults: still air)
    SimulationSettings simulation;
    EquilibriumOptions equilibrium;
    // Amplitude scale of the initial out-of-plane bow that takes up the slack
    // when pins are closer than the swatch is wide. The bow goes towards the
    // swatch's front, u x v (towards a viewer who sees uv (0,0) bottom-left);
    // -1 bows to the back. Equilibria of hung cloth are not unique: this picks
    // which one the solver finds.
    double initial_bow = 1.0;
    // Optional start for the equilibrium solve (3 * rows * cols), e.g. the
    // equilibrium of the previous parameters in a fit: a few Newton steps
    // instead of a fresh fold search. Empty: hanging_start().
    Eigen::VectorXd initial_positions;
    // Moves every free vertex of the solved equilibrium by a random offset of
    // this RMS size (seeded): measurement noise on the starting shape, for
    // predictability ensembles. 0: the equilibrium itself.
    double initial_jitter_m = 0.0;
    std::uint64_t jitter_seed = 1;
    // per_vertex: independent offsets per vertex and axis (in-plane parts are
    // stretch, which the stiff springs erase within a step). smooth_normal:
    // a random smooth field (the 16 lowest cosine modes over uv) along the
    // surface normal -- the shape error a camera leaves, in the soft
    // direction, where it survives to grow.
    enum class JitterShape { per_vertex, smooth_normal };
    JitterShape jitter_shape = JitterShape::per_vertex;
};

// The swatch options a fit or a command runs with: a rows x cols mesh, the
// integrator (the adaptive explicit ones at a 0.1 mm position tolerance,
// which fits need), the initial bow and the simulation's threads
// (flowvid/threads.hpp).
SwatchOptions run_swatch_options(int rows, int cols, Integrator integrator, double initial_bow, int threads);

// A mesh size written "RxC" (ASCII x or X), rows and cols 2..512 each, as
// commands and fit shards spell meshes; nullopt for anything else.
std::optional<std::pair<int, int>> mesh_size_from_text(const std::string& text);

struct Swatch {
    ClothMesh mesh;
    int rows = 0;
    int cols = 0;
    std::vector<PinnedVertex> pins;  // vertex nearest to each pin's uv
    std::vector<bool> pinned;        // per vertex
};

// The experiment a cloth capture prescribes: swatch size and mass, fps, frame
// count, pins. Throws ValidationError (field "swatch") when the capture is not
// a cloth capture.
SwatchExperiment experiment_from_capture(const formats::Capture& capture);

// Builds the mesh and pins (vertex r*cols + c, row 0 at v = 0). Throws
// flowvid::ValidationError listing every problem, each naming `source` and the
// field as a capture.json pointer (e.g. "/swatch/pins/1/positions").
Swatch build_swatch(const SwatchExperiment& experiment, int rows, int cols);

// The material with the experiment's mass applied (when mass_kg > 0): the
// areal density that, with the material's hem along the swatch's boundary,
// weighs mass_kg (a hem of more than 95 % of it is capped there).
ClothMaterial experiment_material(const SwatchExperiment& experiment, const ClothMaterial& material);

// Whether a rows x cols mesh of the experiment's swatch holds the fabric's
// folds (fold_length_m with the experiment's mass, kLongestEdgePerFoldLength);
// where it does not, the drape is the mesh's own and a finer mesh drapes
// differently (docs/cloth_model.md, "Folds finer than the grid").
struct MeshFoldCheck : FoldCheck {  // edge_m: the mesh's longest edge along u or v
    int rows_needed = 0;  // a square mesh that holds them (rows = cols)
};
MeshFoldCheck check_mesh_folds(const SwatchExperiment& experiment, const ClothMaterial& material, int rows, int cols,
                               double gravity_m_per_s2 = 9.81);

// A hanging start between the pins' first positions: straight down from the
// pins, the slack taken up by an out-of-plane bow (scaled by `bow`).
Eigen::VectorXd hanging_start(const Swatch& swatch, const SwatchExperiment& experiment, double bow = 1.0);

struct SwatchRun {
    Swatch swatch;
    EquilibriumReport equilibrium;
    SimulationResult simulation;  // frames[0] is the equilibrium
};

// Builds the swatch, solves its static equilibrium under the first pin
// positions, then simulates frame_count frames. If the equilibrium does not
// converge the run is reported as blew_up at frame 1 (with the reason).
SwatchRun simulate_swatch(const SwatchExperiment& experiment, const ClothMaterial& material,
                          const SwatchOptions& options, const Progress& progress = {});

// Samples every frame at a rows x cols uv grid (row 0 at v = 0): one
// (rows*cols) x 3 matrix per frame, comparable to truth/positions.exr rows.
std::vector<Eigen::MatrixX3d> sample_frames(const ClothMesh& mesh, const std::vector<Eigen::VectorXd>& frames,
                                            int rows, int cols);

}  // namespace flowvid::cloth
