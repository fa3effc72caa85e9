#!/usr/bin/env bash
# The main job on bundled data: installs missing packages, builds, then shows
# what flowvid does today, writing everything to ./out/demo.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/bootstrap.sh
build_dir=${FLOWVID_BUILD_DIR:-build}
exec "$build_dir/cli/flowvid" demo --out out/demo "$@"
