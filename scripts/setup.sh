#!/usr/bin/env bash
# First README command: install dependencies, build (Release), run the main job on the built-in
# simulated site. Output: ./cairn_demo/ (segments, map, top_view.png, summary.json).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --target cairn
./build/apps/cairn/cairn demo --out cairn_demo
