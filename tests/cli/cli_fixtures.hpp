#pragma once
// Small inputs that several CLI tests build the way a user would have them.

#include <string>

namespace flowvid::testing {

// A video.flow capture folder at `dir`: 40 frames of 64 x 64, a texture
// sliding down a vertical band, with its flowlines.svg. Returns `dir`.
std::string tiny_flow_capture(const std::string& dir);

}  // namespace flowvid::testing
