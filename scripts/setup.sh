#!/usr/bin/env bash
# First README command: install dependencies, build (Release), run the main job on the built-in
# simulated site: experiment 1 end to end. Output: ./cairn_demo/ (report.html, summary.json,
# objects.db, the figures). Installs only what the main job needs (not the tests' peers).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCAIRN_BUILD_TESTS=OFF -DCAIRN_BUILD_BENCH=OFF
cmake --build build --target cairn
./build/apps/cairn/cairn demo --scenario exp1 --out cairn_demo --overwrite
echo "setup: the report is $(pwd)/cairn_demo/report.html"
