#include "flowvid/cloth_fit/fit_cloth_shards.hpp"

#include "flowvid/cloth/simulator.hpp"
#include "flowvid/cloth/swatch.hpp"
#include "flowvid/formats/json_fields.hpp"
#include "flowvid/threads.hpp"
#include "flowvid/version.hpp"

#include <algorithm>
#include <initializer_list>
#include <limits>

namespace flowvid::cloth_fit {

namespace {

const char* metric_name(video::SilhouetteTerm term) { return term == video::SilhouetteTerm::edge_distance ? "edge" : "xor"; }

}  // namespace

ClothFitRequest cloth_fit_request_from_shard(const formats::FitShardFile& file) {
    Diagnostics diagnostics(file.path);
    const formats::JsonView view(file.shard.options, "/request/options", diagnostics);
    const auto one_of = [&](const char* key, std::initializer_list<const char*> allowed, std::string fallback) {
        const std::optional<std::string> value = view.string(key);
        if (!value) return fallback;
        for (const char* a : allowed)
            if (*value == a) return *value;
        diagnostics.error(std::string("/request/options/") + key, "\"" + *value + "\" is not a choice of this flowvid",
                          "run the shard with this flowvid's options");
        return fallback;
    };
    ClothFitRequest request;
    request.drag = one_of("drag", {"nonlinear", "linear"}, "nonlinear") == "linear" ? DragModel::linear : DragModel::nonlinear;
    const video::SilhouetteTerm term =
        one_of("metric", {"xor", "edge"}, "xor") == "edge" ? video::SilhouetteTerm::edge_distance : video::SilhouetteTerm::pixel_xor;
    request.problem.metric.silhouette_term = term;
    request.load.silhouette_term = term;
    // Shards older than tracks fits have no "fit-to" (footage), older than the search choice no "search" (annealing).
    request.load.target = *fit_target_from_name(view.has("fit-to") ? one_of("fit-to", {"footage", "scan", "tracks"}, "footage")
                                                                    : "footage");
    request.search = *optim::search_method_from_name(view.has("search") ? one_of("search", {"annealing", "cmaes"}, "annealing")
                                                                         : "annealing");
    const std::string integrator = one_of("integrator", {"rk4", "dopri54", "bs32", "implicit", "bdf2"}, "implicit");
    if (view.has("seed") && view.json().at("seed").is_number_unsigned()) request.seed = view.json().at("seed").get<std::uint64_t>();
    else request.seed = static_cast<std::uint64_t>(view.integer("seed", 0, std::numeric_limits<std::int64_t>::max()).value_or(1));
    request.evaluations = view.integer("evaluations", 10, 1000000).value_or(request.evaluations);
    request.budget_seconds = view.number("budget-seconds", formats::NumberRange::non_negative("s")).value_or(0.0);
    request.load.waving_frames = static_cast<int>(view.integer("frames", 2, 100000).value_or(50));
    request.load.full_weight_frames = static_cast<int>(view.integer("full-weight-frames", 1, 100000).value_or(10));
    request.load.half_life_frames = view.number("half-life-frames", formats::NumberRange::non_negative("frames")).value_or(0.0);
    request.load.static_weight =  // written only when not 1 (older shards have none)
        view.has("static-weight") ? view.number("static-weight", formats::NumberRange::non_negative("")).value_or(1.0) : 1.0;
    if (view.has("min-bending"))  // written only when set
        request.min_bending_N_m = view.number("min-bending", formats::NumberRange::non_negative("N m")).value_or(0.0);
    // Written only when parameters were held out of the fit: their keys, comma-separated (options are flat).
    if (const std::optional<std::string> held = view.has("hold") ? view.string("hold") : std::nullopt) {
        std::size_t from = 0;
        while (from <= held->size()) {
            const std::size_t comma = std::min(held->find(',', from), held->size());
            const std::string key = held->substr(from, comma - from);
            if (key.empty()) diagnostics.error("/request/options/hold", "an empty parameter name", "run the shard again");
            else request.held_parameters.push_back(key);
            from = comma + 1;
        }
    }
    // Written only when not 0; shards older than the cells' shear have none.
    request.shear_cell_fraction =
        view.has("shear-cells") ? view.number("shear-cells", formats::NumberRange::closed(0.0, 1.0)).value_or(0.0) : 0.0;
    if (view.has("second-drape-mesh")) {  // written only when set
        const std::string text = view.string("second-drape-mesh").value_or("");
        if (const auto mesh = cloth::mesh_size_from_text(text)) {
            request.problem.second_drape_rows = mesh->first;
            request.problem.second_drape_cols = mesh->second;
        } else {
            diagnostics.error("/request/options/second-drape-mesh", "\"" + text + "\" is not ROWSxCOLS", "run the shard again");
        }
    }
    const std::string resolution = view.string("resolution").value_or("24x24");
    const double initial_bow = view.number("initial-bow", formats::NumberRange::closed(-2.0, 2.0)).value_or(1.0);
    view.check_known_keys({"drag", "metric", "fit-to", "seed", "evaluations", "budget-seconds", "frames", "full-weight-frames",
                           "half-life-frames", "static-weight", "min-bending", "second-drape-mesh", "hold", "search",
                           "resolution", "integrator", "initial-bow", "shear-cells"});
    const auto mesh = cloth::mesh_size_from_text(resolution);
    if (!mesh)
        diagnostics.error("/request/options/resolution", "\"" + resolution + "\" is not ROWSxCOLS", "run the shard again");
    diagnostics.throw_if_errors();
    request.problem.swatch =
        cloth::run_swatch_options(mesh->first, mesh->second, cloth::integrators_by_short_name().at(integrator), initial_bow, 0);
    return request;
}

nlohmann::json cloth_fit_result_options(const ClothFitRequest& request) {
    const cloth::SwatchOptions& swatch = request.problem.swatch;
    nlohmann::json options = {{"drag", drag_model_name(request.drag)},
                              {"metric", metric_name(request.problem.metric.silhouette_term)},
                              {"seed", request.seed},
                              {"evaluations", request.evaluations},
                              {"budget-seconds", request.budget_seconds},
                              {"frames", request.load.waving_frames},
                              {"full-weight-frames", request.load.full_weight_frames},
                              {"half-life-frames", request.load.half_life_frames},
                              {"resolution", std::to_string(swatch.rows) + "x" + std::to_string(swatch.cols)},
                              {"integrator", cloth::integrator_short_name(swatch.simulation.integrator)},
                              {"initial-bow", swatch.initial_bow}};
    // Only tracks fits say what they fitted to, so footage shards keep the bytes older ones had.
    if (request.load.target != FitTarget::footage) options["fit-to"] = fit_target_name(request.load.target);
    if (request.load.static_weight != 1.0) options["static-weight"] = request.load.static_weight;
    if (request.min_bending_N_m > 0.0) options["min-bending"] = request.min_bending_N_m;
    if (const double share = resolved_shear_cell_fraction(request); share != 0.0) options["shear-cells"] = share;
    if (request.problem.has_second_drape_mesh())
        options["second-drape-mesh"] =
            std::to_string(request.problem.second_drape_rows) + "x" + std::to_string(request.problem.second_drape_cols);
    if (!request.held_parameters.empty()) {
        std::string held;
        for (const std::string& key : request.held_parameters) held += (held.empty() ? "" : ",") + key;
        options["hold"] = held;
    }
    // Written only when not the thesis's annealing, which shards written
    // before the search could be chosen used (and have no "search").
    if (request.search != optim::SearchMethod::annealing) options["search"] = optim::search_method_name(request.search);
    return options;
}

formats::FitShard cloth_fit_shard(const ClothFitRequest& request, const ClothFitOutcome& outcome) {
    formats::FitShard shard;
    shard.kind = "cloth";
    shard.software = "flowvid " + flowvid::version();
    for (const formats::Capture& c : request.captures) shard.captures.push_back({c.folder, c.capture_json_sha256});
    shard.options = cloth_fit_result_options(request);
    shard.index = request.shard.value_or(ClothFitShard{}).index;
    shard.count = request.shard.value_or(ClothFitShard{}).count;
    const Eigen::VectorXd& best = outcome.search.annealing.best_values;
    for (std::size_t i = 0; i < outcome.parameters.size() && static_cast<Eigen::Index>(i) < best.size(); ++i)
        shard.best.push_back({outcome.parameters[i].key, best(static_cast<Eigen::Index>(i))});
    shard.best_error = outcome.search.annealing.best_value;
    shard.evaluations = outcome.evaluations;
    shard.status = optim::status_name(outcome.search.annealing.status);
    return shard;
}

ClothMergeOutcome merge_cloth_fit_shards(const ClothMergeRequest& merge) {
    ClothMergeOutcome out;
    out.winner = formats::check_fit_shard_set(merge.shards);
    const formats::FitShardFile& winner = merge.shards.at(out.winner);
    ClothFitRequest request = cloth_fit_request_from_shard(winner);
    request.name = merge.name;
    request.variability_runs = merge.variability_runs;
    request.variability_evaluations = merge.variability_evaluations;
    request.floor_members = merge.floor_members;
    request.threads = resolve_thread_count(merge.threads);
    request.problem.swatch.simulation.threads = request.threads;
    request.progress = merge.progress;
    // The captures again, from the paths the shards recorded: they must be
    // the very experiments the shards fitted.
    std::vector<Problem> changed;
    for (std::size_t i = 0; i < winner.shard.captures.size(); ++i) {
        const formats::FitShardCapture& recorded = winner.shard.captures[i];
        request.captures.push_back(formats::read_capture_of_kind(recorded.path, {"cloth.static", "cloth.waving"}, "flowvid merge"));
        const formats::Capture& now = request.captures.back();
        if (now.capture_json_sha256 != recorded.capture_json_sha256)
            changed.push_back({Problem::Severity::error, winner.path, "/request/captures/" + std::to_string(i) + "/capture_json_sha256",
                               now.json_path + " has changed since the shard ran (its SHA-256 is now " +
                                   now.capture_json_sha256 + ")",
                               "restore that capture.json, or run the shards again on the capture as it is"});
    }
    if (!changed.empty()) throw ValidationError(changed);

    std::vector<std::string> names;
    Eigen::VectorXd values(static_cast<Eigen::Index>(winner.shard.best.size()));
    for (std::size_t i = 0; i < winner.shard.best.size(); ++i) {
        names.push_back(winner.shard.best[i].name);
        values(static_cast<Eigen::Index>(i)) = winner.shard.best[i].value;
    }
    try {
        out.fit = finish_cloth_fit(request, names, values, winner.shard.best_error);
    } catch (const std::invalid_argument& error) {
        throw ValidationError({Problem{Problem::Severity::error, winner.path, "/result/parameters", error.what(),
                                       "run the shard again with this flowvid"}});
    }
    out.evaluations = out.fit.evaluations;
    std::vector<const formats::FitShardFile*> by_index(merge.shards.size());
    for (const formats::FitShardFile& file : merge.shards) by_index.at(static_cast<std::size_t>(file.shard.index - 1)) = &file;
    for (const formats::FitShardFile* file : by_index) {
        out.evaluations += file->shard.evaluations;
        out.shard_errors.push_back(file->shard.best_error);
    }
    if (out.fit.preset)
        out.fit.preset->provenance.notes = "main search split into " + std::to_string(winner.shard.count) +
                                           " shards (flowvid merge); shard " + std::to_string(winner.shard.index) + "/" +
                                           std::to_string(winner.shard.count) + " had the lowest error";
    return out;
}

}  // namespace flowvid::cloth_fit
