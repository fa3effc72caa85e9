// A shard records the options that change a fit by their command-line names;
// the merge rebuilds the request from them (cloth_fit/fit_cloth_shards.hpp). The
// two directions must agree to the byte with the shards already written.

#include "flowvid/error.hpp"
#include "flowvid/formats/fit_shard.hpp"
#include "flowvid/cloth_fit/fit_cloth_shards.hpp"

#include <gtest/gtest.h>

#include <string>

using namespace flowvid;

namespace {

formats::FitShardFile example_shard() {
    const std::string path = std::string(FLOWVID_SOURCE_DIR) + "/formats/examples/cloth.fit_shard.json";
    return {path, formats::read_fit_shard(path)};
}

}  // namespace

TEST(FitClothShards, TheExampleShardsOptionsRebuildItsRequestAndGiveTheSameBytesBack) {
    const formats::FitShardFile file = example_shard();
    const cloth_fit::ClothFitRequest request = cloth_fit::cloth_fit_request_from_shard(file);
    EXPECT_EQ(request.problem.swatch.rows, 8);
    EXPECT_EQ(request.problem.swatch.simulation.integrator, cloth::Integrator::implicit_euler);
    EXPECT_EQ(request.evaluations, 16);
    EXPECT_EQ(request.seed, 5u);
    // No "search" in a shard: the annealing, which shards used before the search could be chosen.
    EXPECT_EQ(request.search, optim::SearchMethod::annealing);
    EXPECT_EQ(cloth_fit::cloth_fit_result_options(request).dump(), file.shard.options.dump());
}

TEST(FitClothShards, EveryOptionTravelsThroughAShardAndBack) {
    formats::FitShardFile file = example_shard();
    file.shard.options = {{"drag", "linear"},        {"metric", "edge"},          {"seed", 18446744073709551615ULL},
                          {"evaluations", 1234},    {"budget-seconds", 600.0},   {"frames", 20},
                          {"full-weight-frames", 3}, {"half-life-frames", 5.0},  {"resolution", "30x20"},
                          {"integrator", "rk4"},     {"initial-bow", -1.0},       {"fit-to", "tracks"},
                          {"static-weight", 2.5},    {"min-bending", 1e-5},       {"search", "cmaes"},
                          {"second-drape-mesh", "12x10"},       {"shear-cells", 0.5},
                          {"hold", "stretch_warp_compression_ratio,stretch_weft_compression_ratio"}};
    const cloth_fit::ClothFitRequest request = cloth_fit::cloth_fit_request_from_shard(file);
    EXPECT_EQ(request.drag, cloth_fit::DragModel::linear);
    EXPECT_EQ(request.load.target, cloth_fit::FitTarget::tracks);
    EXPECT_EQ(request.held_parameters.size(), 2u);
    EXPECT_EQ(request.problem.swatch.cols, 20);
    EXPECT_EQ(request.problem.second_drape_rows, 12);
    EXPECT_EQ(request.problem.second_drape_cols, 10);
    EXPECT_EQ(request.shear_cell_fraction, 0.5);
    EXPECT_DOUBLE_EQ(request.problem.swatch.simulation.position_tolerance_m, 1e-4);  // an adaptive integrator's
    EXPECT_EQ(cloth_fit::cloth_fit_result_options(request).dump(), file.shard.options.dump());
}

TEST(FitClothShards, AnOptionThisFlowvidDoesNotKnowIsNamedWithTheShardsFileAndField) {
    formats::FitShardFile file = example_shard();
    file.shard.options["integrator"] = "verlet";
    file.shard.options["resolution"] = "8 by 8";
    try {
        cloth_fit::cloth_fit_request_from_shard(file);
        FAIL() << "accepted an unknown integrator";
    } catch (const ValidationError& error) {
        ASSERT_EQ(error.problems().size(), 2u);
        EXPECT_EQ(error.problems()[0].file, file.path);
        EXPECT_EQ(error.problems()[0].field, "/request/options/integrator");
        EXPECT_EQ(error.problems()[1].field, "/request/options/resolution");
    }
}
