#pragma once
// Structure-aware mutations of flowvid's inputs, shared by the libFuzzer
// targets (LLVMFuzzerCustomMutator in fuzz_target.cpp) and the g++ corpus
// replay (tests/fuzz/fuzz_replay.cpp), so both try the same hostile shapes:
//   JSON: deep nesting, odd numbers (1e999, -0, 1e-400, NaN, Infinity, 1e308,
//         1e12, -384, ...), duplicated keys, many keys, huge arrays, type
//         swaps, path-traversal and format strings, subtree splices;
//   SVG:  many attributes on one element, entity amplification (DOCTYPE with
//         nested entities, recursive and external entities), many elements,
//         deep <g> nesting, odd numbers in path data and transforms, odd
//         attribute values (../../etc/passwd, huge strings);
//   glb:  the JSON chunk is mutated as JSON (byteOffset -384, accessor index
//         1e12, ...) and the container's lengths are fixed up (or not);
//   EXR:  header attributes are found and their sizes, integer values and
//         strings (the bank's JSON) are mutated.
// Deterministic for a given seed: a replay with a fixed seed is the same run.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace flowvid::fuzz {

using Bytes = std::vector<std::uint8_t>;

enum class InputKind { json, svg, glb, exr };

// splitmix64: small, fast and the same on every compiler (std::mt19937's
// distributions are not specified bit for bit).
class MutationRandom {
public:
    explicit MutationRandom(std::uint64_t seed) : m_state(seed) {}
    std::uint64_t next();
    // Uniform in [0, bound) (0 when bound is 0).
    std::size_t below(std::size_t bound) { return bound ? static_cast<std::size_t>(next() % bound) : 0; }
    bool one_in(std::size_t n) { return below(n) == 0; }

private:
    std::uint64_t m_state;
};

// Applies one to three structure-aware operations to `bytes`, keeping the
// result at most `max_size` bytes. Returns the names of the operations applied
// ("" when none could be: e.g. no number to replace and no room to grow), so
// that a caller can fall back to byte-level mutations.
std::string structure_mutate(Bytes& bytes, InputKind kind, std::size_t max_size, std::uint64_t seed);

// The operations, one at a time (for tests of the mutator and for generators).
namespace ops {
// Wraps the value at a random position (or the whole document) in `depth` arrays or objects.
bool json_nest_deep(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_odd_number(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_duplicate_key(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_many_keys(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_huge_array(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_odd_string(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_type_swap(std::string& text, MutationRandom& random, std::size_t max_size);
bool json_splice_subtree(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_many_attributes(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_entity_amplification(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_many_elements(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_nest_deep(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_odd_number(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_odd_attribute(std::string& text, MutationRandom& random, std::size_t max_size);
bool svg_markup_noise(std::string& text, MutationRandom& random, std::size_t max_size);
bool glb_mutate(Bytes& bytes, MutationRandom& random, std::size_t max_size);
bool exr_mutate(Bytes& bytes, MutationRandom& random, std::size_t max_size);
bool binary_odd_integer(Bytes& bytes, MutationRandom& random, std::size_t max_size);
}  // namespace ops

// The odd values the operations insert (also used by the reproducers).
const std::vector<std::string>& odd_json_numbers();
const std::vector<std::string>& odd_strings();

}  // namespace flowvid::fuzz
