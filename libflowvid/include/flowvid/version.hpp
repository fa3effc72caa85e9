#pragma once
#include <string>

namespace flowvid {
// The flowvid release, "MAJOR.MINOR.PATCH"; written into provenance of every file we produce.
std::string version();
}  // namespace flowvid
