// flowvid merge: the last step of a fit split over a farm. Reads the shard
// files, checks they are one complete split, and lets the fit's kind finish
// the winner (fit_cloth.cpp for cloth).

#include "commands/merge.hpp"
#include "output.hpp"

#include "flowvid/formats/atomic_file.hpp"

#include <memory>

namespace flowvid::cli {

std::vector<MergeKind>& merge_kinds() {
    static std::vector<MergeKind> kinds;
    return kinds;
}

RegisterMergeKind::RegisterMergeKind(MergeKind kind) { merge_kinds().push_back(std::move(kind)); }

int run_merge_kind(const MergeRequest& request, const GlobalOptions& global) {
    const std::string& kind = request.shards.at(request.winner).shard.kind;
    for (const MergeKind& k : merge_kinds())
        if (k.kind == kind) return k.run(request, global);
    log_message("error: " + request.shards.front().path + ": /kind: no merge for \"" + kind + "\" shards");
    return kExitUsage;
}

namespace {

struct MergeOptions {
    std::vector<std::string> files;
    MergeRequest request;
};

int run_merge(MergeOptions& options, const GlobalOptions& global) {
    // Every file is read before any is judged, so one run lists every problem.
    std::vector<Problem> problems;
    for (const std::string& path : options.files) {
        try {
            std::vector<Problem> warnings;
            options.request.shards.push_back({path, formats::read_fit_shard(path, &warnings)});
            print_problems(warnings);
        } catch (const ValidationError& error) {
            problems.insert(problems.end(), error.problems().begin(), error.problems().end());
        }
    }
    if (!problems.empty()) throw ValidationError(problems);
    options.request.winner = formats::check_fit_shard_set(options.request.shards);
    formats::create_parent_folder(options.request.out);
    return run_merge_kind(options.request, global);
}

const RegisterCommand registration{Command{
    "merge", "join the shards of a fit run as separate farm or cluster tasks", [](CLI::App& app) -> CommandRunner {
        auto options = std::make_shared<MergeOptions>();
        app.footer(
            "A long fit splits into independent tasks: `flowvid fit cloth ... --shard i/n --out i.json` for\n"
            "i = 1..n, on any machines, in any order. Each writes a partial result (format\n"
            "flowvid.fit_shard: the request's fingerprint, which shard, its best point). merge checks that\n"
            "the files are the shards of one fit (same captures by their capture.json SHA-256, same options,\n"
            "same flowvid) and that they cover 1..n exactly once, takes the lowest error (a tie goes to the\n"
            "lowest shard index), simulates it once more and writes the result exactly as the fit would:\n"
            "the same bytes as `flowvid fit cloth ... --shards n` on one machine (set SOURCE_DATE_EPOCH for\n"
            "both to make the preset's created_utc equal too). The captures are read again from the paths\n"
            "the winning shard recorded. See docs/farm.md for Slurm, OpenCue and Flamenco job files.\n\n"
            "Examples:\n"
            "  flowvid fit cloth --capture /data/silk-static --out shards/1.json --shard 1/3   # ... 2/3, 3/3\n"
            "  flowvid merge --out silk.fabric.json shards/1.json shards/2.json shards/3.json\n"
            "  flowvid merge --out silk.fabric.json --variability-runs 4 shards/*.json\n\n"
            "Exit codes: 0 ok, 2 bad option, 3 the shards are invalid, incomplete, duplicated or of\n"
            "different fits (each problem names its file and field), 4 unreadable or unwritable file,\n"
            "130 interrupted (nothing written).");
        app.add_option("shards", options->files, "the shard files (flowvid.fit_shard), one per --shard i/n")->required();
        app.add_option("--out", options->request.out, "the result to write (cloth: a fabric preset, *.fabric.json)")->required();
        app.add_option("--name", options->request.name, "name in the result (default: from --out)");
        app.add_option("--variability-runs", options->request.variability_runs,
                       "restarts from +-5 % perturbed starts around the winner (the preset's uncertainty); 0 = none")
            ->check(CLI::Range(0, 64))
            ->capture_default_str();
        app.add_option("--variability-evaluations", options->request.variability_evaluations,
                       "evaluations per variability restart")
            ->check(CLI::Range(4LL, 1000000LL))
            ->capture_default_str();
        app.add_option("--threads", options->request.threads, "worker threads (0 = all cores); results do not depend on it")
            ->check(CLI::Range(0, 256))
            ->capture_default_str();
        app.add_flag("--json", options->request.json, "print the summary as JSON");
        return [options](const GlobalOptions& global) { return run_merge(*options, global); };
    }}};

}  // namespace
}  // namespace flowvid::cli
