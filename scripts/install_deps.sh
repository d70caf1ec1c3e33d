#!/usr/bin/env bash
# Installs what cairn needs on Debian 12: apt packages, and the report's web assets from the npm
# registry (web/package-lock.json; inlined into the binary at build time). Nothing is downloaded
# during the build itself.
#   scripts/install_deps.sh           what the main job needs (scripts/setup.sh)
#   scripts/install_deps.sh --tests   that, and what the tests and benchmarks need (scripts/test.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
# kernels: eigen nanoflann tbb; config/CLI/logging: yaml-cpp cli11 spdlog fmt nlohmann-json;
# pictures: zlib; simulator: embree (ray casting), mujoco (grasp physics), qhull (convex parts of
# stones; MuJoCo's own library depends on it); mapping: ceres;
# object database: sqlite3; report: npm (three.js); ROS 1 from Debian (ros/, --bag, the nodes):
# rosbag storage, roscpp, the message headers, and the message definitions + gencpp/genpy that
# generate cairn's own service types.
PACKAGES=(
  build-essential cmake ninja-build pkg-config python3
  libeigen3-dev libnanoflann-dev libtbb-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev zlib1g-dev
  libembree-dev libmujoco-dev libqhull-dev libceres-dev libsqlite3-dev
  librosbag-storage-dev libsensor-msgs-dev libnav-msgs-dev libgeometry-msgs-dev libtf2-msgs-dev libstd-msgs-dev
  pluginlib-dev librcpputils-dev libament-index-cpp-dev libroscpp-dev libstd-srvs-dev libvisualization-msgs-dev
  ros-std-msgs ros-geometry-msgs ros-sensor-msgs python3-gencpp python3-genpy
)
# npm from Debian unless a node.js with npm is installed already (e.g. NodeSource's, which
# conflicts with Debian's npm package).
command -v npm >/dev/null || PACKAGES+=(npm)
# tests and benchmarks: gtest gmock benchmark; the report opened in headless chromium;
# peers (tests/bench only, never linked by the library): pcl, open3d; Debian's `rosbag info` and
# `rosbag check` read the bags cairn writes (python3-rosbag and the messages' Python modules);
# rostest with its own master plays a bag into cairn_mapper (rostest, roslaunch, rosmaster, rospy)
if [ "${1:-}" = "--tests" ]; then
  PACKAGES+=(libgtest-dev libgmock-dev libbenchmark-dev chromium libpcl-dev libopen3d-dev python3-rosbag
             python3-sensor-msgs python3-nav-msgs python3-geometry-msgs python3-tf2-msgs python3-std-msgs
             python3-rostest python3-roslaunch python3-rosmaster python3-rospy python3-std-srvs
             python3-visualization-msgs)
fi
# RViz and a virtual display for its screenshot (ros/scripts/rviz_screenshot.sh; docs/ros.md).
if [ "${1:-}" = "--rviz" ]; then
  PACKAGES+=(rviz xvfb imagemagick python3-visualization-msgs)
fi
export DEBIAN_FRONTEND=noninteractive
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
else
  echo "install_deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
# three.js, pinned by web/package-lock.json (the last release with a self-contained
# build/three.module.min.js).
installed_matches_lock() {
  node -e "const lock = require('./web/package-lock.json').packages['node_modules/three'].version;
           process.exit(lock === require('./web/node_modules/three/package.json').version ? 0 : 1)" 2>/dev/null
}
if ! installed_matches_lock; then
  echo "install_deps: npm ci (web/)"
  (cd web && npm ci --no-audit --no-fund --loglevel=error)
fi
