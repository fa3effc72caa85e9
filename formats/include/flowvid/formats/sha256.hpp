#pragma once
// SHA-256 (FIPS 180-4) of a byte string, for provenance: a fitted preset
// records the hash of every capture.json it was fitted on, so a result can be
// traced to the exact experiment description it used.

#include <array>
#include <cstdint>
#include <string>

namespace flowvid::formats {

// The 32-byte digest of `bytes`.
std::array<std::uint8_t, 32> sha256(const std::string& bytes);
// The digest as 64 lower-case hex digits (what `sha256sum` prints).
std::string sha256_hex(const std::string& bytes);

}  // namespace flowvid::formats
