#include "flowvid/formats/fit_shard.hpp"

#include "flowvid/formats/atomic_file.hpp"
#include "flowvid/formats/sha256.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>
#include <set>
#include <stdexcept>

namespace flowvid::formats {

namespace {

constexpr const char* kKinds[] = {"cloth"};
// Shards of one fit; more is a mistake (a typo like 8000 for 8).
constexpr int kMaxShards = 10000;

bool is_sha256_hex(const std::string& text) {
    return text.size() == 64 &&
           std::all_of(text.begin(), text.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

// A short rendering of a JSON value for messages.
std::string shown(const nlohmann::json* value) {
    if (!value) return "absent";
    std::string text = value->dump();
    if (text.size() > 80) text = text.substr(0, 77) + "...";
    return text;
}

void parse_captures(const JsonView& request, FitShard& shard) {
    std::optional<JsonView> captures = request.array("captures");
    if (!captures) return;
    if (captures->size() == 0)
        captures->diagnostics().error(captures->pointer(), "no captures", "a shard records the captures it was fitted on");
    for (std::size_t i = 0; i < captures->size(); ++i) {
        const JsonView entry = captures->element(i);
        if (!entry.json().is_object()) {
            entry.diagnostics().error(entry.pointer(), "expected an object",
                                      "write {\"path\": ..., \"capture_json_sha256\": ...}");
            continue;
        }
        entry.check_known_keys({"path", "capture_json_sha256"});
        FitShardCapture capture;
        capture.path = entry.string("path").value_or("");
        if (entry.has("path") && capture.path.empty())
            entry.diagnostics().error(json_pointer_child(entry.pointer(), "path"), "empty", "write the capture folder");
        if (std::optional<std::string> sha = entry.string("capture_json_sha256")) {
            if (!is_sha256_hex(*sha))
                entry.diagnostics().error(json_pointer_child(entry.pointer(), "capture_json_sha256"),
                                          "not 64 lower-case hex digits", "write the SHA-256 of capture.json (sha256sum)");
            capture.capture_json_sha256 = *sha;
        }
        shard.captures.push_back(capture);
    }
}

void parse_options(const JsonView& request, FitShard& shard) {
    std::optional<JsonView> options = request.object("options");
    if (!options) return;
    for (auto it = options->json().begin(); it != options->json().end(); ++it) {
        const nlohmann::json& value = it.value();
        if (value.is_number() || value.is_string() || value.is_boolean()) continue;
        options->diagnostics().error(json_pointer_child(options->pointer(), it.key()),
                                     std::string("expected a number, string or boolean, found ") + value.type_name(),
                                     "options are flat: write the option's value as on the command line");
    }
    shard.options = options->json();
}

void parse_result(const JsonView& root, FitShard& shard) {
    std::optional<JsonView> result = root.object("result");
    if (!result) return;
    result->check_known_keys({"parameters", "error", "evaluations", "status"});
    if (std::optional<JsonView> parameters = result->array("parameters")) {
        if (parameters->size() == 0)
            parameters->diagnostics().error(parameters->pointer(), "no parameters", "list the shard's best point");
        std::set<std::string> seen;
        for (std::size_t i = 0; i < parameters->size(); ++i) {
            const JsonView entry = parameters->element(i);
            if (!entry.json().is_object()) {
                entry.diagnostics().error(entry.pointer(), "expected an object", "write {\"name\": ..., \"value\": ...}");
                continue;
            }
            entry.check_known_keys({"name", "value"});
            FitShardValue value;
            value.name = entry.string("name").value_or("");
            if (entry.has("name") && value.name.empty())
                entry.diagnostics().error(json_pointer_child(entry.pointer(), "name"), "empty", "write the parameter's name");
            else if (!value.name.empty() && !seen.insert(value.name).second)
                entry.diagnostics().error(json_pointer_child(entry.pointer(), "name"), "\"" + value.name + "\" is listed twice",
                                          "list each parameter once");
            value.value = entry.number("value", NumberRange{}).value_or(0.0);
            shard.best.push_back(value);
        }
    }
    shard.best_error = result->number("error", NumberRange{}).value_or(0.0);
    shard.evaluations = result->integer("evaluations", 0, std::numeric_limits<std::int64_t>::max()).value_or(0);
    shard.status = result->string("status").value_or("");
}

}  // namespace

nlohmann::json fit_shard_request(const FitShard& shard) {
    nlohmann::json captures = nlohmann::json::array();
    for (const FitShardCapture& c : shard.captures)
        captures.push_back({{"path", c.path}, {"capture_json_sha256", c.capture_json_sha256}});
    return {{"software", shard.software}, {"captures", captures}, {"options", shard.options}};
}

namespace {
// What makes shards one fit: the request without the capture paths (a node
// may mount the captures elsewhere, or be given them relative to another
// folder; their SHA-256 says which experiments they are).
nlohmann::json fit_shard_identity(const FitShard& shard) {
    nlohmann::json request = fit_shard_request(shard);
    for (nlohmann::json& capture : request["captures"]) capture.erase("path");
    return {{"kind", shard.kind}, {"request", request}};
}
}  // namespace

std::string fit_shard_fingerprint(const FitShard& shard) { return sha256_hex(fit_shard_identity(shard).dump()); }

std::optional<FitShard> parse_fit_shard(const nlohmann::json& document, Diagnostics& diagnostics, Strictness strictness) {
    const JsonView root(document, "", diagnostics, strictness);
    if (!check_format_header(root, kFitShardFormatName, kFitShardFormatVersion)) return std::nullopt;
    root.check_known_keys({"format", "version", "kind", "request", "fingerprint_sha256", "shard", "result"});
    FitShard shard;
    if (std::optional<std::string> kind = root.string("kind")) {
        shard.kind = *kind;
        if (std::find(std::begin(kKinds), std::end(kKinds), *kind) == std::end(kKinds))
            diagnostics.error("/kind", "\"" + *kind + "\" shards cannot be merged by this flowvid",
                              "only cloth fits are split into shards (write \"cloth\")");
    }
    if (std::optional<JsonView> request = root.object("request")) {
        request->check_known_keys({"software", "captures", "options"});
        shard.software = request->string("software").value_or("");
        parse_captures(*request, shard);
        parse_options(*request, shard);
    }
    if (std::optional<JsonView> position = root.object("shard")) {
        position->check_known_keys({"index", "count"});
        const std::optional<std::int64_t> count = position->integer("count", 1, kMaxShards);
        const std::optional<std::int64_t> index = position->integer("index", 1, kMaxShards);
        if (count) shard.count = static_cast<int>(*count);
        if (index) shard.index = static_cast<int>(*index);
        if (index && count && *index > *count)
            diagnostics.error("/shard/index", "shard " + std::to_string(*index) + " of " + std::to_string(*count) + " does not exist",
                              "use an index in 1.." + std::to_string(*count));
    }
    parse_result(root, shard);
    // The fingerprint is checked last: it is only meaningful for a request that parsed.
    if (std::optional<std::string> fingerprint = root.string("fingerprint_sha256")) {
        if (!diagnostics.has_errors() && *fingerprint != fit_shard_fingerprint(shard))
            diagnostics.error("/fingerprint_sha256", "does not match the request (the file was edited after the shard ran)",
                              "run the shard again rather than editing its file");
    }
    if (diagnostics.has_errors()) return std::nullopt;
    return shard;
}

nlohmann::json fit_shard_to_json(const FitShard& shard) {
    nlohmann::json parameters = nlohmann::json::array();
    for (const FitShardValue& v : shard.best) parameters.push_back({{"name", v.name}, {"value", v.value}});
    // nlohmann objects sort their keys: written in a fixed order on every machine.
    return {{"format", kFitShardFormatName},
            {"version", kFitShardFormatVersion.to_string()},
            {"kind", shard.kind},
            {"request", fit_shard_request(shard)},
            {"fingerprint_sha256", fit_shard_fingerprint(shard)},
            {"shard", {{"index", shard.index}, {"count", shard.count}}},
            {"result",
             {{"parameters", parameters},
              {"error", shard.best_error},
              {"evaluations", shard.evaluations},
              {"status", shard.status}}}};
}

FitShard read_fit_shard(const std::string& path, std::vector<Problem>* warnings) {
    return read_json_format_file<FitShard>(path, parse_fit_shard, warnings);
}

void write_fit_shard(const std::string& path, const FitShard& shard) {
    Diagnostics diagnostics(path);
    // JSON has no NaN or infinity: name the value before it would become null.
    for (std::size_t i = 0; i < shard.best.size(); ++i)
        if (!std::isfinite(shard.best[i].value))
            diagnostics.error("/result/parameters/" + std::to_string(i) + "/value", "not a finite number",
                              "the search produced no usable value for " + shard.best[i].name);
    if (!std::isfinite(shard.best_error))
        diagnostics.error("/result/error", "not a finite number", "the shard found no point the fit could evaluate");
    diagnostics.throw_if_errors();
    const nlohmann::json document = fit_shard_to_json(shard);
    parse_fit_shard(document, diagnostics, Strictness::strict);  // what is written reads back
    diagnostics.throw_if_errors();
    const std::string text = dump_json(document);
    write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

std::vector<Problem> validate_fit_shard_file(const std::string& path, Strictness strictness) {
    Diagnostics diagnostics(path);
    if (std::optional<std::string> text = read_text_reporting(path, diagnostics))
        if (std::optional<nlohmann::json> document = parse_json_text(*text, diagnostics))
            parse_fit_shard(*document, diagnostics, strictness);
    return diagnostics.problems();
}

nlohmann::json summarize_fit_shard(const FitShard& shard) {
    nlohmann::json best = nlohmann::json::object();
    for (const FitShardValue& v : shard.best) best[v.name] = v.value;
    return {{"format", kFitShardFormatName},
            {"kind", shard.kind},
            {"shard", std::to_string(shard.index) + "/" + std::to_string(shard.count)},
            {"fingerprint_sha256", fit_shard_fingerprint(shard)},
            {"captures", shard.captures.size()},
            {"best_error", shard.best_error},
            {"best", best},
            {"evaluations", shard.evaluations},
            {"status", shard.status}};
}

std::size_t check_fit_shard_set(const std::vector<FitShardFile>& shards) {
    if (shards.empty()) throw std::invalid_argument("check_fit_shard_set: no shards");
    std::vector<Problem> problems;
    const auto problem = [&](const std::string& file, const std::string& field, std::string message, std::string fix) {
        problems.push_back(Problem{Problem::Severity::error, file, field, std::move(message), std::move(fix)});
    };
    const FitShardFile& reference = shards.front();
    const nlohmann::json reference_identity = fit_shard_identity(reference.shard);
    const std::string reference_fingerprint = fit_shard_fingerprint(reference.shard);
    std::map<int, const FitShardFile*> by_index;
    for (const FitShardFile& file : shards) {
        const FitShard& s = file.shard;
        bool same_fit = true;
        if (s.kind != reference.shard.kind) {
            problem(file.path, "/kind", "a " + s.kind + " shard among " + reference.shard.kind + " shards (" + reference.path + ")",
                    "merge the shards of one fit only");
            same_fit = false;
        } else if (fit_shard_fingerprint(s) != reference_fingerprint) {
            // Name every field that differs, e.g. a capture.json hash or an option
            // (the identity has the file's layout, so its pointers are the file's fields).
            const nlohmann::json identity = fit_shard_identity(s);
            for (const nlohmann::json& op : nlohmann::json::diff(reference_identity, identity)) {
                const nlohmann::json::json_pointer at(op["path"].get<std::string>());
                const nlohmann::json* here = identity.contains(at) ? &identity.at(at) : nullptr;
                const nlohmann::json* there = reference_identity.contains(at) ? &reference_identity.at(at) : nullptr;
                problem(file.path, op["path"].get<std::string>(),
                        "this shard's request differs from " + reference.path + "'s: " + shown(here) + " here, " +
                            shown(there) + " there",
                        "merge shards of one fit: same captures, options and flowvid, only --shard differs");
            }
            same_fit = false;
        }
        if (s.count != reference.shard.count) {
            problem(file.path, "/shard/count",
                    "split " + std::to_string(s.count) + " ways, but " + reference.path + " is split " +
                        std::to_string(reference.shard.count) + " ways",
                    "merge the shards of one split (the same n in every --shard i/n)");
            same_fit = false;
        }
        if (!same_fit) continue;
        const auto [at, inserted] = by_index.emplace(s.index, &file);
        if (!inserted)
            problem(file.path, "/shard/index",
                    "shard " + std::to_string(s.index) + "/" + std::to_string(s.count) + " again (also " + at->second->path + ")",
                    "give each shard's file once");
    }
    std::string missing;
    for (int i = 1; i <= reference.shard.count; ++i)
        if (!by_index.count(i)) missing += (missing.empty() ? "" : ", ") + std::to_string(i);
    if (!missing.empty())
        problem(reference.path, "/shard/count",
                "the fit is split " + std::to_string(reference.shard.count) + " ways but shard(s) " + missing + " are missing",
                "add the file of each missing --shard i/" + std::to_string(reference.shard.count) + " (run it again if it failed)");
    if (!problems.empty()) throw ValidationError(std::move(problems));

    // The winner: lowest error, then lowest shard index (by_index is ordered).
    const FitShardFile* best = nullptr;
    for (const auto& [index, file] : by_index)
        if (!best || file->shard.best_error < best->shard.best_error) best = file;
    return static_cast<std::size_t>(best - shards.data());
}

}  // namespace flowvid::formats
