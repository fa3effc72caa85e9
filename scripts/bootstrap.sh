#!/usr/bin/env bash
# Installs what is missing (Debian 12 packages), then configures and builds
# flowvid in ./build. Safe to run again: it only installs and rebuilds what changed.
#   FLOWVID_BUILD_DIR  build folder (default: build)
#   FLOWVID_JOBS       parallel compile jobs (default: number of cores)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev nlohmann-json3-dev libopenexr-dev libopenimageio-dev openimageio-tools
  libopencv-dev libtinygltf-dev libcli11-dev libtbb-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-dev pybind11-dev python3-numpy
  blender ffmpeg chromium xvfb
  clang libclang-rt-14-dev
)
missing=()
for package in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if ((${#missing[@]})); then
  echo "flowvid: installing ${#missing[@]} missing Debian packages: ${missing[*]}" >&2
  if [[ $(id -u) -ne 0 ]]; then sudo=sudo; else sudo=; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

# Optional: the Slurm farm test (slurm.farm_array_job) starts a private
# one-node cluster with these. Where apt cannot install them, that test is
# skipped and the build goes on.
optional=(slurm-wlm munge)
missing_optional=()
for package in "${optional[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing_optional+=("$package")
done
if ((${#missing_optional[@]})); then
  echo "flowvid: installing optional Debian packages: ${missing_optional[*]}" >&2
  if [[ $(id -u) -ne 0 ]]; then sudo=sudo; else sudo=; fi
  if ! { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
           "${missing_optional[@]}"; } >&2; then
    echo "flowvid: note: could not install ${missing_optional[*]}: the Slurm test (slurm.farm_array_job) will be skipped" >&2
  fi
fi

build_dir=${FLOWVID_BUILD_DIR:-build}
jobs=${FLOWVID_JOBS:-$(nproc)}
# Blender's Python is Debian's /usr/bin/python3: the module is built for it.
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE=/usr/bin/python3 >&2
cmake --build "$build_dir" -j "$jobs" >&2
