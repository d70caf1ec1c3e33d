#!/usr/bin/env bash
# Installs the Debian 12 packages cairn needs (apt only; no downloads during the build).
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
# kernels: eigen nanoflann tbb; config/CLI/logging: yaml-cpp cli11 spdlog fmt nlohmann-json;
# pictures: zlib; simulator: embree (ray casting), mujoco (grasp physics); mapping: ceres;
# object database: sqlite3; tests and benchmarks: gtest gmock benchmark;
# peers (tests/bench only, never linked by the library): pcl, open3d
PACKAGES=(
  build-essential cmake ninja-build pkg-config python3
  libeigen3-dev libnanoflann-dev libtbb-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev zlib1g-dev
  libembree-dev libmujoco-dev libceres-dev libsqlite3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libpcl-dev libopen3d-dev
)
export DEBIAN_FRONTEND=noninteractive
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "install_deps: installing ${missing[*]}"
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
