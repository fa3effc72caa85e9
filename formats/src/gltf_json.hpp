#pragma once
// The JSON chunk of a glTF binary, read by flowvid before tinygltf is: the
// nesting limit and number checks of parse_json_text apply, and the fields
// glTF defines as indices, offsets and counts are checked to be whole numbers
// in [0, 2^31 - 1]. tinygltf reads them into int and size_t silently, so a
// byteOffset of -384 became 0 and an accessor index of 1e12 a negative one.
// Used by the motion (.glb) and rigid mesh readers.

#include "flowvid/error.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace flowvid::formats::detail {

// `json_text` is the GLB's chunk 0. Problems are recorded with fields such
// as "GLB chunk 0 (JSON), /bufferViews/0/byteOffset"; nullopt when the JSON
// cannot be used.
std::optional<nlohmann::json> read_glb_json_chunk(const std::string& json_text, Diagnostics& diag);

}  // namespace flowvid::formats::detail
