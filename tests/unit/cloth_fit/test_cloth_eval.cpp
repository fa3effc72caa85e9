// The predictability floor's ingredients: how members are drawn around a
// fabric, its time windows, and the pixel footprint that sets the jitter.

#include "flowvid/cloth_fit/cloth_eval.hpp"
#include "flowvid/cloth/material.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace flowvid;
using namespace flowvid::video;
using namespace flowvid::cloth_fit;

TEST(ClothFloor, MembersDrawParametersWithinTheirUncertaintyAndKeepTies) {
    cloth::ClothMaterial fabric;
    fabric.bend_N_m = 4e-9;
    fabric.stretch_warp_N_per_m = fabric.stretch_weft_N_per_m = 200.0;  // a fit's warp/weft tie
    FloorSettings floor;
    floor.members = 4000;
    floor.parameter_sigma = {{"bend_stiffness_N_m", 0.1 * 4e-9},           // 10 %
                             {"stretch_warp_stiffness_N_per_m", 10.0},     // 5 %, tied
                             {"stretch_weft_stiffness_N_per_m", 10.0}};
    const std::vector<FloorMember> members = draw_floor_members(fabric, floor);
    ASSERT_EQ(members.size(), 4000u);

    double bend_sum = 0.0, bend_squares = 0.0, stretch_squares = 0.0, cross = 0.0, worst_tie = 0.0, worst_other = 0.0;
    for (const FloorMember& m : members) {
        const double bend = std::log(m.material.bend_N_m / fabric.bend_N_m);
        const double stretch = std::log(m.material.stretch_warp_N_per_m / fabric.stretch_warp_N_per_m);
        bend_sum += bend;
        bend_squares += bend * bend;
        stretch_squares += stretch * stretch;
        cross += bend * stretch;
        worst_tie = std::max(worst_tie, std::abs(m.material.stretch_weft_N_per_m / m.material.stretch_warp_N_per_m - 1.0));
        worst_other = std::max(worst_other, std::abs(m.material.shear_N_per_m / fabric.shear_N_per_m - 1.0));
    }
    const double n = static_cast<double>(members.size());
    const double bend_sd = std::sqrt(bend_squares / n), stretch_sd = std::sqrt(stretch_squares / n);
    std::printf("[ measured ] log-spread: bend %.4f (asked 0.1), stretch %.4f (asked 0.05), correlation %.3f, "
                "warp/weft apart by %.2g, others moved by %.2g\n",
                bend_sd, stretch_sd, cross / n / (bend_sd * stretch_sd), worst_tie, worst_other);
    // Standard error of a standard deviation from n draws: sd / sqrt(2n) ~ 1.1 %.
    EXPECT_NEAR(bend_sd, 0.1, 0.1 * 0.05);
    EXPECT_NEAR(stretch_sd, 0.05, 0.05 * 0.05);
    EXPECT_NEAR(bend_sum / n, 0.0, 4 * 0.1 / std::sqrt(n));
    EXPECT_LT(std::abs(cross / n / (bend_sd * stretch_sd)), 4 / std::sqrt(n));  // independent
    EXPECT_LE(worst_tie, 2.1e-6);    // the tie moves together; only the 1e-6 jiggle tells them apart
    EXPECT_LE(worst_other, 1.0e-6);  // no uncertainty: the tiny relative perturbation alone

    // Same settings, same members (seeded); another seed, others.
    const std::vector<FloorMember> again = draw_floor_members(fabric, floor);
    EXPECT_EQ(again[17].material.bend_N_m, members[17].material.bend_N_m);
    EXPECT_EQ(again[17].jitter_seed, members[17].jitter_seed);
    floor.seed = 2;
    EXPECT_NE(draw_floor_members(fabric, floor)[17].material.bend_N_m, members[17].material.bend_N_m);
}

TEST(ClothFloor, MembersKeepTheCellShareAndStayValid) {
    // A tracks fit's preset reads all shear on the cells (share 1): a member
    // moved past 1 was refused, and the fit lost its floor with a warning.
    cloth::ClothMaterial fabric;
    fabric.shear_cell_fraction = 1.0;
    FloorSettings floor;
    floor.members = 64;
    floor.relative_perturbation = 1e-3;  // larger than a fit's, so that a moved share would show
    int refused = 0, moved_share = 0, moved_bend = 0;
    for (const FloorMember& m : draw_floor_members(fabric, floor)) {
        refused += cloth::check_material(m.material).empty() ? 0 : 1;
        moved_share += m.material.shear_cell_fraction == 1.0 ? 0 : 1;
        moved_bend += m.material.bend_N_m == fabric.bend_N_m ? 0 : 1;
    }
    EXPECT_EQ(refused, 0);
    EXPECT_EQ(moved_share, 0);
    EXPECT_EQ(moved_bend, 64);  // the fabric's own parameters still move
}

TEST(ClothFloor, PresetUncertaintyIsWhatThePresetCarries) {
    formats::FabricParameters p;
    p.bend_stiffness_N_m = {4e-9, 5e-10, std::array<double, 2>{1e-9, 1e-4}};
    p.drag_normal_kg_per_m3 = {0.17, 0.008, std::nullopt};
    p.shear_stiffness_N_per_m = {7.0, std::nullopt, std::nullopt};
    const std::map<std::string, double> sigma = preset_uncertainty(p);
    ASSERT_EQ(sigma.size(), 2u);
    EXPECT_EQ(sigma.at("bend_stiffness_N_m"), 5e-10);
    EXPECT_EQ(sigma.at("drag_normal_kg_per_m3"), 0.008);
}

TEST(ClothFloor, WindowsAndPixelFootprint) {
    const std::vector<FrameWindow> w = standard_windows(50);
    ASSERT_EQ(w.size(), 4u);
    EXPECT_EQ(window_name(w[0]), "1-10");
    EXPECT_EQ(window_name(w[2]), "26-50");
    EXPECT_EQ(window_name(w[3]), "1-50");  // the whole trial, as the captures' README states Blender's floor
    EXPECT_EQ(standard_windows(10).size(), 1u);

    // A camera 2 m in front of two points, 500 px focal length: 4 mm per pixel.
    formats::CameraModel camera;
    camera.width = 640;
    camera.height = 480;
    camera.K << 500, 0, 320, 0, 500, 240, 0, 0, 1;
    Eigen::VectorXd points(6);
    points << 0.1, 0.0, 1.5, -0.1, 0.2, 2.5;  // camera == world: depths 1.5 and 2.5
    EXPECT_NEAR(pixel_footprint_m(camera, points), 2.0 / 500.0, 1e-15);
}
