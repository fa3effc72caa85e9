#pragma once
// `flowvid merge`: joins the shards of a fit that a render farm or a cluster
// ran as independent tasks (`flowvid fit <kind> --shard i/n`). merge.cpp
// reads the shard files and checks that they are one complete split
// (formats::check_fit_shard_set); the kind of fit the shards name finishes
// the winner, registered from its own file like the fit kinds:
//
//   const RegisterMergeKind merge_registration{MergeKind{"cloth", [](const MergeRequest& r, const GlobalOptions& g) {...}}};

#include "command.hpp"

#include "flowvid/formats/fit_shard.hpp"

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace flowvid::cli {

struct MergeRequest {
    std::vector<formats::FitShardFile> shards;  // checked: one fit, shards 1..n once each
    std::size_t winner = 0;                     // position in `shards` of the lowest error
    std::string out;                            // the result to write
    std::string name;                           // result name ("" = from `out`)
    int variability_runs = 0;                   // restarts from the winner (0: none)
    long long variability_evaluations = 40;
    int threads = 0;                            // 0: all cores; the result does not depend on it
    bool json = false;                          // summary as JSON on stdout
};

struct MergeKind {
    std::string kind;  // as in the shard files' "kind"
    std::function<int(const MergeRequest&, const GlobalOptions&)> run;
};

std::vector<MergeKind>& merge_kinds();
struct RegisterMergeKind {
    explicit RegisterMergeKind(MergeKind kind);
};

// Runs the merge of `request` with the kind its shards name (usage error when
// no kind is registered for it).
int run_merge_kind(const MergeRequest& request, const GlobalOptions& global);

}  // namespace flowvid::cli
