#!/usr/bin/env bash
# Runs the ICP benchmark (cairn vs PCL vs Open3D on the same pairs, same run) and prints, per pair,
# each variant's time, iterations and error against the reference, and cairn's speed-up.
#   scripts/bench_icp.sh [build-dir]     (default: build; needs a Release build with PCL found)
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-build}
# The benchmarks are not part of the test build (scripts/test.sh): configure and build this one.
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCAIRN_BUILD_BENCH=ON >/dev/null
cmake --build "$dir" --target bench_icp
out=$(mktemp --suffix=.json)
"$dir/bench/bench_icp" --benchmark_min_time=1 --benchmark_format=json --benchmark_out="$out" >/dev/null
/usr/bin/python3 - "$out" <<'PY'
import json, sys
runs = {}
for b in json.load(open(sys.argv[1]))["benchmarks"]:
    if b.get("error_occurred"):
        continue
    name, arg = b["name"].split("/")[0][3:], b["name"].split("/")[1]
    runs.setdefault(b.get("label", arg), {})[name] = b
for pair, r in runs.items():
    ours = r.get("Cairn_PointToPlane")
    print(f"\n{pair}")
    print(f"{'variant':<28}{'ms':>10}{'cpu ms':>10}{'iters':>7}{'err mm':>9}{'err mdeg':>10}{'cairn p2pl faster':>19}")
    for name, b in r.items():
        ratio = f"{b['real_time'] / ours['real_time']:.1f}x" if ours and not name.startswith("Cairn") else ""
        it = b.get("icp_iters", float("nan"))
        print(f"{name:<28}{b['real_time']:>10.1f}{b['cpu_time']:>10.1f}{it:>7.0f}{b.get('err_mm', float('nan')):>9.2f}"
              f"{b.get('err_mdeg', float('nan')):>10.1f}{ratio:>19}")
PY
rm -f "$out"
