#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (AddressSanitizer + UBSan) and runs
# each one for a while over its corpus in fuzz/corpus/<target>. New inputs that
# grow coverage go to build-fuzz/new-corpus/<target>: copy small interesting ones
# into fuzz/corpus/<target> and commit them.
#   bash scripts/fuzz.sh [seconds-per-target] [target...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
shift || true
build_dir=build-fuzz
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DFLOWVID_BUILD_FUZZ=ON -DFLOWVID_BUILD_TESTS=OFF -DFLOWVID_BUILD_BENCH=OFF -DFLOWVID_BUILD_PYTHON=OFF \
  -DFLOWVID_BUILD_CLI=OFF >&2
targets=("$@")
if ((${#targets[@]} == 0)); then
  targets=(fabric_json flowlines_json flowlines_svg capture_json particle_bank vertex_animation motion_gltf)
fi
for target in "${targets[@]}"; do
  cmake --build "$build_dir" --target "fuzz_$target" >&2
  mkdir -p "fuzz/corpus/$target" "$build_dir/new-corpus/$target"
  echo "fuzzing $target for ${seconds}s" >&2
  "$build_dir/fuzz/fuzz_$target" -max_total_time="$seconds" -max_len=65536 -timeout=10 \
    "$build_dir/new-corpus/$target" "fuzz/corpus/$target"
done
