#!/usr/bin/env bash
# Runs the segmentation benchmark (cairn vs PCL on the same input, same run) and prints a table
# with time per 100k points and the speed-up of each cairn kernel over its PCL peer.
#   scripts/bench.sh [build-dir]     (default: build; needs a Release build with PCL found)
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-build}
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCAIRN_BUILD_BENCH=ON >/dev/null
cmake --build "$dir" --target bench_segmentation
out=$(mktemp --suffix=.json)
"$dir/bench/bench_segmentation" --benchmark_min_time=1 --benchmark_format=json --benchmark_out="$out" >/dev/null
/usr/bin/python3 - "$out" <<'PY'
import json, sys
runs = {b["name"].split("/")[0][3:]: b for b in json.load(open(sys.argv[1]))["benchmarks"]}
print(f"{'benchmark':<26}{'ms':>10}{'ms/100k pts':>14}{'speed-up vs PCL':>18}")
for name, b in runs.items():
    ms = b["real_time"]  # benchmarks report milliseconds
    per = ms * 1e5 / b["points"]
    peer = runs.get("Pcl_" + name.split("_", 1)[1].replace("SegmentPlaneGround", "Segment")) if name.startswith("Cairn_") else None
    if peer is None and name.startswith("Cairn_Normals"):
        peer = runs.get("Pcl_NormalsOMP")
    ratio = f"{peer['real_time'] / ms:.1f}x" if peer else ""
    print(f"{name:<26}{ms:>10.2f}{per:>14.2f}{ratio:>18}")
PY
rm -f "$out"
