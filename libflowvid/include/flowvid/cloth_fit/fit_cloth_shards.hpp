#pragma once
// A cloth fit split over a render farm or a cluster (docs/farm.md): each task
// runs one shard of the search (ClothFitRequest::shard) and keeps its result
// as a fit shard file (formats/fit_shard.hpp); the merge picks the best shard
// and ends the fit from it exactly as fit_cloth ends, so that n shards and a
// merge give the same preset as `fit cloth --shards n` in one process.
//
// A shard records the options that change the result by their command-line
// names (formats/specs/fit_shard.md: "drag", "metric", "seed", ...), so that a
// merge, on another machine without the command line, rebuilds the request.

#include "flowvid/formats/fit_shard.hpp"
#include "flowvid/progress.hpp"
#include "flowvid/cloth_fit/fit_cloth.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace flowvid::cloth_fit {

// The options of `request` that change a fit's result, named as on the
// command line: the shards of one fit must agree on every one (threads,
// names and the variability restarts, which the merge runs, are not among
// them).
nlohmann::json cloth_fit_result_options(const ClothFitRequest& request);

// The request a shard's options describe (captures, name, threads,
// variability restarts and floors are the merge's to set): the inverse of
// cloth_fit_result_options. Throws ValidationError naming the shard's file
// and field for an option this flowvid does not know.
ClothFitRequest cloth_fit_request_from_shard(const formats::FitShardFile& file);

// A finished shard's partial result (request.shard says which).
formats::FitShard cloth_fit_shard(const ClothFitRequest& request, const ClothFitOutcome& outcome);

struct ClothMergeRequest {
    std::vector<formats::FitShardFile> shards;  // one complete split (formats::check_fit_shard_set)
    std::string name = "fitted fabric";         // the preset's fabric name
    int variability_runs = 0;                   // restarts from the winner (0: none)
    long long variability_evaluations = 40;
    int floor_members = 0;                      // as ClothFitRequest::floor_members
    int threads = 0;                            // the result does not depend on it
    Progress progress;  // as ClothFitRequest::progress
};

struct ClothMergeOutcome {
    ClothFitOutcome fit;         // as finish_cloth_fit ends it; its preset's notes name the winner
    std::size_t winner = 0;      // position in the request's shards
    std::vector<double> shard_errors;  // by shard index 1..n
    long long evaluations = 0;   // every shard's and the merge's
};

// Checks the set, reads the captures again from the paths the shards
// recorded (each must still have the capture.json SHA-256 its shard saw),
// rebuilds the request from the winner's options and ends the fit there.
// Throws ValidationError naming the shard file and field for a set that is
// not one fit, a changed capture or options this flowvid does not know.
ClothMergeOutcome merge_cloth_fit_shards(const ClothMergeRequest& request);

}  // namespace flowvid::cloth_fit
