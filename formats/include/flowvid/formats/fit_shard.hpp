#pragma once
// Fit shard (*.json, format "flowvid.fit_shard", version 1.0): the partial
// result of one task of a fit split over a render farm or a cluster
// (`flowvid fit cloth --shard i/n`), which `flowvid merge` joins. It records
// the request every shard of one fit must share (software, captures by their
// capture.json SHA-256, the options that change the result) with its
// fingerprint, which shard it is, and that shard's best point. Nothing in it
// depends on the machine or the time it ran, so a re-run shard gives the same
// bytes. formats/specs/fit_shard.md describes every field.

#include "flowvid/error.hpp"
#include "flowvid/formats/json_fields.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace flowvid::formats {

inline constexpr const char* kFitShardFormatName = "flowvid.fit_shard";
inline constexpr FormatVersion kFitShardFormatVersion{1, 0};

struct FitShardCapture {
    std::string path;                 // capture folder as given to the fit
    std::string capture_json_sha256;  // 64 lower-case hex digits of capture.json's bytes
    bool operator==(const FitShardCapture&) const = default;
};

struct FitShardValue {
    std::string name;  // parameter name as the fit searches it (e.g. bend_stiffness_N_m)
    double value = 0.0;
    bool operator==(const FitShardValue&) const = default;
};

struct FitShard {
    std::string kind;  // what was fitted: "cloth"
    // The request, identical in every shard of one fit.
    std::string software;                   // e.g. "flowvid 0.1.0": another build may search differently
    std::vector<FitShardCapture> captures;  // in the fit's order
    // The options that change the result: a flat object of option name (as
    // on the command line, without "--") -> number, string or boolean.
    nlohmann::json options = nlohmann::json::object();
    // Which shard: 1-based index of count.
    int index = 1;
    int count = 1;
    // Its result: the best point of its search, in search order.
    std::vector<FitShardValue> best;
    double best_error = 0.0;     // the fit's objective there (its own unit)
    long long evaluations = 0;   // objective evaluations this shard made
    std::string status;          // how its search ended, e.g. "converged", "max_evaluations"

    bool operator==(const FitShard&) const = default;
};

// The request part as written in the file ("software", "captures", "options").
nlohmann::json fit_shard_request(const FitShard& shard);
// SHA-256 (hex) of {"kind": ..., "request": ...} without the captures'
// paths, dumped compactly with sorted keys: equal for the shards of one fit,
// different when any capture (by its capture.json SHA-256), option or the
// software differs. Paths may differ between nodes (mounts, working folders).
std::string fit_shard_fingerprint(const FitShard& shard);

// Validates a parsed document (every problem into `diagnostics`) and returns
// the shard when valid. The stored fingerprint must match the request.
std::optional<FitShard> parse_fit_shard(const nlohmann::json& document, Diagnostics& diagnostics,
                                        Strictness strictness = Strictness::lenient);
nlohmann::json fit_shard_to_json(const FitShard& shard);

// Reads and validates; throws ValidationError (every problem) or IoError.
FitShard read_fit_shard(const std::string& path, std::vector<Problem>* warnings = nullptr);
// Validates, then writes atomically (ValidationError, e.g. for a NaN, leaves
// any previous file untouched).
void write_fit_shard(const std::string& path, const FitShard& shard);
// Every problem of a file, for `flowvid validate` (never throws on bad content).
std::vector<Problem> validate_fit_shard_file(const std::string& path, Strictness strictness);
nlohmann::json summarize_fit_shard(const FitShard& shard);

// A shard with the file it came from (for messages).
struct FitShardFile {
    std::string path;
    FitShard shard;
};

// Checks that `shards` are the shards of one fit and together cover 1..count
// exactly once: same kind, count and fingerprint (a differing request is
// reported at each field that differs, e.g.
// /request/captures/0/capture_json_sha256), no index twice, none missing.
// The first shard is the reference the others are compared with.
// Throws ValidationError listing every problem (file and field); returns the
// position in `shards` of the winner: the lowest error, on a tie the lowest
// shard index. std::invalid_argument when `shards` is empty.
std::size_t check_fit_shard_set(const std::vector<FitShardFile>& shards);

}  // namespace flowvid::formats
