#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (AddressSanitizer + UBSan, readers
# instrumented) and, for each target: replays fuzz/regressions/<target> (and,
# in a full run, the generated issue #34 reproducers), then fuzzes it for a
# while over fuzz/corpus/<target>. Writes a summary of every target (executions,
# seconds, coverage, new units, crashes, leaks, timeouts, OOMs, date and commit).
#
#   bash scripts/fuzz.sh [options] [seconds-per-target] [target...]
#     (default: 60 s, every target; FLOWVID_FUZZ_LIST=1 build-fuzz/fuzz/flowvid_fuzz lists them)
#   --ci              the short run of every test suite (ctest fuzz.libfuzzer_short): a seed
#                     fixed per target; the summary goes to BUILD_DIR/RESULTS.md, nothing in
#                     the checkout changes
#   --build-dir DIR   the clang build (default build-fuzz, or $FLOWVID_FUZZ_BUILD_DIR)
#   --jobs N          compile jobs (default 2, or $FLOWVID_JOBS)
#   --keep-going      go on after a crash (libFuzzer -fork=1 -ignore_crashes/timeouts/ooms):
#                     for hunting bugs; a clean run for the record stops at the first
#   --merge           afterwards, minimise fuzz/corpus/<target> together with the new units
#                     (libFuzzer -merge=1): the named seeds stay, found inputs up to
#                     8 KiB ($FLOWVID_FUZZ_CORPUS_MAX_BYTES) are kept when they add coverage
#   --no-regressions  skip the replay of fuzz/regressions
# Limits (safety checks): -rss_limit_mb=1024 -malloc_limit_mb=1024 -timeout=10 -max_len=65536.
# Crashing inputs go to BUILD_DIR/crashes/<target>/; copy each into
# fuzz/regressions/<target>/ under a name that says what it is.
# Exit status: 0 clean, 1 a crash, leak, timeout, OOM or failed regression,
# 77 when clang++ or libFuzzer is missing (said loudly; ctest shows it as skipped).
set -euo pipefail
cd "$(dirname "$0")/.."
source_dir=$PWD

ci=0 keep_going=0 merge=0 regressions=1
build_dir=${FLOWVID_FUZZ_BUILD_DIR:-build-fuzz}
jobs=${FLOWVID_JOBS:-2}
corpus_max_bytes=${FLOWVID_FUZZ_CORPUS_MAX_BYTES:-8192}
positional=()
while (($#)); do
  case $1 in
    --ci) ci=1 ;;
    --build-dir) build_dir=$2; shift ;;
    --jobs) jobs=$2; shift ;;
    --keep-going) keep_going=1 ;;
    --merge) merge=1 ;;
    --no-regressions) regressions=0 ;;
    -h|--help) sed -n '2,25p' "$0"; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) positional+=("$1") ;;
  esac
  shift
done
seconds=60
if ((${#positional[@]})) && [[ ${positional[0]} =~ ^[0-9]+$ ]]; then
  seconds=${positional[0]}
  positional=("${positional[@]:1}")
fi
mkdir -p "$build_dir"
build_dir=$(cd "$build_dir" && pwd)

skip() {
  echo "" >&2
  echo "************************************************************************" >&2
  echo "flowvid: SKIPPED libFuzzer fuzzing: $1" >&2
  echo "  install clang and libFuzzer (Debian 12: apt-get install clang libclang-rt-14-dev)" >&2
  echo "************************************************************************" >&2
  exit 77
}
command -v clang++ >/dev/null || skip "clang++ is not installed"
probe=$(mktemp -d)
scratch=""
trap 'rm -rf "$probe" ${scratch:+"$scratch"}' EXIT
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' > "$probe/probe.cpp"
clang++ -fsanitize=fuzzer,address,undefined "$probe/probe.cpp" -o "$probe/probe" 2>"$probe/log" ||
  skip "clang++ cannot link -fsanitize=fuzzer,address,undefined ($(head -c 300 "$probe/log"))"
python=/usr/bin/python3
[[ -x $python ]] || python=python3

# ---- Build: only the formats library (instrumented) and the fuzz driver ----
build_start=$(date +%s)
cmake -S "$source_dir" -B "$build_dir" -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Fuzz \
  -DCMAKE_CXX_FLAGS_FUZZ="-O1 -gline-tables-only" -DFLOWVID_BUILD_FUZZ=ON -DFLOWVID_BUILD_TESTS=OFF \
  -DFLOWVID_BUILD_BENCH=OFF -DFLOWVID_BUILD_PYTHON=OFF -DFLOWVID_BUILD_CLI=OFF >"$build_dir/configure.log" 2>&1 ||
  { cat "$build_dir/configure.log" >&2; exit 1; }
cmake --build "$build_dir" --target fuzz_all -j "$jobs" >"$build_dir/build.log" 2>&1 ||
  { tail -50 "$build_dir/build.log" >&2; exit 1; }
build_seconds=$(($(date +%s) - build_start))
echo "fuzz.sh: clang build took ${build_seconds}s" >&2

fuzzer="$build_dir/fuzz/flowvid_fuzz"
mapfile -t all_targets < <(FLOWVID_FUZZ_LIST=1 "$fuzzer" 2>/dev/null | grep -P '^\w+\t' | cut -f1)
((${#all_targets[@]})) || { echo "fuzz.sh: $fuzzer lists no targets" >&2; exit 1; }
for target in "${all_targets[@]}"; do ln -sf flowvid_fuzz "$build_dir/fuzz/fuzz_$target"; done
targets=("${positional[@]}")
((${#targets[@]})) || targets=("${all_targets[@]}")
for target in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $target "* ]] || { echo "fuzz.sh: unknown target $target (${all_targets[*]})" >&2; exit 2; }
done

generated="$build_dir/generated"
if ((regressions && !ci)); then
  rm -rf "$generated"
  "$build_dir/fuzz/flowvid_fuzz_generate" "$generated"
fi

run_dir="$build_dir/runs"
rm -rf "$run_dir"
mkdir -p "$run_dir"
FLOWVID_FUZZ_LIST=1 "$fuzzer" 2>/dev/null | grep -P '^\w+\t' >"$run_dir/targets.tsv" || true
# The targets write each input to a file (readers take paths): in memory when /dev/shm is there.
if [[ -z ${TMPDIR:-} && -d /dev/shm && -w /dev/shm ]]; then
  scratch=$(mktemp -d /dev/shm/flowvid-fuzz-run.XXXXXX)
  export TMPDIR=$scratch
fi
# Smaller ASan quarantine: the RSS limit is for the readers, not for ASan's bookkeeping.
export ASAN_OPTIONS=${ASAN_OPTIONS:-quarantine_size_mb=64:malloc_context_size=20}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
limits=(-rss_limit_mb=1024 -malloc_limit_mb=1024)
has_artifacts() {
  local kind
  for kind in crash leak timeout oom; do compgen -G "$1/$kind-*" >/dev/null && return 0; done
  return 1
}
status=0
for target in "${targets[@]}"; do
  binary="$build_dir/fuzz/fuzz_$target"
  out="$run_dir/$target"
  crashes="$build_dir/crashes/$target"
  new_corpus="$build_dir/new-corpus/$target"
  ((ci)) && rm -rf "$new_corpus"  # each CI run starts from the kept corpus: a fixed amount of work
  mkdir -p "$out" "$crashes" "$new_corpus" "fuzz/corpus/$target"
  rm -f "$crashes"/*

  # 1. Regressions: each input once, in its own process.
  : >"$out/regressions.txt"
  if ((regressions)); then
    for file in fuzz/regressions/"$target"/* "$generated/$target"/*; do
      [[ -f $file ]] || continue
      set +e
      # The generated reproducers are megabytes: ASan makes them 15 times slower and
      # doubles their memory (the g++ fuzz.regressions test holds them to 30 s, 1 GiB).
      replay_limits=(-rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=30)
      [[ $file == "$generated"/* ]] && replay_limits=(-rss_limit_mb=4096 -malloc_limit_mb=1024 -timeout=180)
      timeout 600 "$binary" "${replay_limits[@]}" -artifact_prefix="$crashes/regression-" "$file" \
        >"$out/regression.log" 2>&1
      rc=$?
      set -e
      if ((rc == 0)); then
        echo "pass ${file#"$source_dir"/}" >>"$out/regressions.txt"
      else
        reason=$(grep -m1 -oE 'ERROR: [A-Za-z]+Sanitizer: [a-z-]+|ERROR: libFuzzer: [a-z0-9 -]+(\(malloc\([0-9]+\)\))?|runtime error: .{0,80}|terminate called .{0,100}' \
                   "$out/regression.log" || true)
        echo "FAIL ${file#"$source_dir"/}: ${reason:-exit status $rc}" >>"$out/regressions.txt"
        cp "$out/regression.log" "$out/regression-$(basename "$file").log"
        status=1
      fi
    done
    grep '^FAIL' "$out/regressions.txt" | sed 's/^/  /' >&2 || true
  fi

  # 2. Fuzzing.
  echo "fuzz.sh: fuzzing $target for ${seconds}s" >&2
  options=("${limits[@]}" -timeout=10 -max_len=65536 -max_total_time="$seconds" -print_final_stats=1
           -artifact_prefix="$crashes/")
  ((keep_going)) && options+=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1)
  # CI fuzzes with a seed fixed per target, so a commit's test result does not depend
  # on the draw (a random seed once failed CI on a bug older than the change under
  # test); the exploratory runs draw a fresh seed each time.
  ((ci)) && options+=(-seed=$(($(cksum <<<"$target" | cut -d' ' -f1) % 1000000 + 1)))
  start=$(date +%s)
  set +e
  timeout $((seconds + 300)) "$binary" "${options[@]}" "$new_corpus" "fuzz/corpus/$target" >"$out/fuzz.log" 2>&1
  rc=$?
  set -e
  echo "$(($(date +%s) - start))" >"$out/wall_seconds"
  echo "$rc" >"$out/exit_status"
  if ((rc != 0)) || has_artifacts "$crashes"; then
    status=1
    echo "fuzz.sh: $target FOUND A PROBLEM (exit $rc); log $out/fuzz.log, inputs in $crashes" >&2
    grep -m3 -E 'ERROR: |runtime error|terminate called|SUMMARY' "$out/fuzz.log" | sed 's/^/  /' >&2 || true
  fi

  # Each saved input replayed alone, for the summary's account of what went wrong.
  count=0
  for artifact in "$crashes"/crash-* "$crashes"/leak-* "$crashes"/timeout-* "$crashes"/oom-*; do
    [[ -f $artifact ]] || continue
    ((++count <= 20)) || break
    timeout 120 "$binary" "${limits[@]}" -timeout=10 "$artifact" >"$artifact.log" 2>&1 || true
  done

  # 3. Corpus minimisation (full runs only, on request).
  if ((merge && !ci)); then
    # The named seeds (real files, issue cases) stay; libFuzzer's finds (named by their
    # SHA-1) are kept when they add coverage and are small (the mutator makes big ones).
    merged=$(mktemp -d)
    candidates=$(mktemp -d)
    find "fuzz/corpus/$target" -maxdepth 1 -type f -regextype posix-extended ! -regex '.*/[0-9a-f]{40}' -exec cp -t "$merged" {} +
    find "fuzz/corpus/$target" "$new_corpus" -maxdepth 1 -type f -regextype posix-extended -regex '.*/[0-9a-f]{40}' \
      -size -$((corpus_max_bytes + 1))c -exec cp -t "$candidates" {} +
    # -use_counters=0: an input is kept for a new edge, not for a new hit count of one.
    "$binary" -merge=1 -use_counters=0 "${limits[@]}" -timeout=10 "$merged" "$candidates" >"$out/merge.log" 2>&1
    rm -rf "fuzz/corpus/$target"
    mkdir -p "fuzz/corpus/$target"
    cp "$merged"/* "fuzz/corpus/$target/"
    rm -rf "$merged" "$candidates"
    echo "fuzz.sh: fuzz/corpus/$target minimised to $(ls "fuzz/corpus/$target" | wc -l) inputs" \
      "($(du -sk "fuzz/corpus/$target" | cut -f1) KiB)" >&2
  fi
done

results=fuzz/RESULTS.md
data=fuzz/results.json
if ((ci)); then
  results="$build_dir/RESULTS.md"
  data="$build_dir/results.json"
fi
"$python" fuzz/fuzz_results.py --runs "$run_dir" --crashes "$build_dir/crashes" --data "$data" --markdown "$results" \
  --seconds "$seconds" --build-seconds "$build_seconds" --mode "$( ((ci)) && echo ci || echo full)" \
  --keep-going "$keep_going" --targets "${all_targets[@]}" >&2
echo "fuzz.sh: summary in $results" >&2
exit "$status"
