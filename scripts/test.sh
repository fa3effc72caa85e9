#!/usr/bin/env bash
# Installs missing packages, builds, and runs the whole test suite (ctest).
# Exit code non-zero when any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/bootstrap.sh
build_dir=${FLOWVID_BUILD_DIR:-build}
if [[ ! -d ../shared/captures ]]; then
  echo "flowvid: note: ../shared/captures is absent; tests that read the shared captures are skipped" >&2
fi
# Fuzzing is part of the suite (ctest -L fuzz; fuzz/README.md): fuzz.libfuzzer_short builds the
# libFuzzer targets with clang in $build_dir/fuzz-clang and fuzzes each briefly. Without clang
# or libFuzzer it is skipped: said before and after the tests, where it cannot be missed.
fuzz_probe=$(mktemp -d)
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' >"$fuzz_probe/p.cpp"
fuzz_missing=0
if ! command -v clang++ >/dev/null || ! clang++ -fsanitize=fuzzer "$fuzz_probe/p.cpp" -o "$fuzz_probe/p" 2>/dev/null; then
  fuzz_missing=1
fi
rm -rf "$fuzz_probe"
warn_fuzz() {
  if ((fuzz_missing)); then
    echo "flowvid: WARNING: clang++ with libFuzzer is missing: the libFuzzer step (fuzz.libfuzzer_short) is SKIPPED" >&2
    echo "flowvid:          install it with: apt-get install clang libclang-rt-14-dev" >&2
  fi
}
warn_fuzz
cd "$build_dir"
status=0
ctest --output-on-failure -j "$(nproc)" "$@" || status=$?
warn_fuzz
exit "$status"
