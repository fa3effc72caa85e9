#include "flowvid/version.hpp"

namespace flowvid {
std::string version() { return FLOWVID_VERSION_STRING; }
}  // namespace flowvid
