#!/usr/bin/env bash
# First README command: install dependencies, build (Release), run the main job on the built-in
# simulated site: experiment 1 end to end. Output: ./cairn_demo/ (summary.json, objects.db).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --target cairn
./build/apps/cairn/cairn demo --scenario exp1 --out cairn_demo --overwrite
