#!/usr/bin/env bash
# ctest RosMapper.PlaysABag: simulate a short run as a bag, map it with `cairn map --bag` (the
# reference), then rostest (its own master) plays the bag into cairn_mapper and compares.
#   run_mapper_test.sh CAIRN_EXE ROS_PACKAGE_DIR WORK_DIR [SECONDS]
# SECONDS of simulated scanning (4; the sanitizer build runs the same path on 2).
set -euo pipefail
cairn=$1
pkg_dir=$2
work=$3
seconds=${4:-4}
rm -rf "$work"
mkdir -p "$work"
"$cairn" simulate --scenario exp1 --seed 1 --duration "$seconds" --no-drone --out "$work/run" --bag "$work/run.bag" \
  --log-level warn > "$work/simulate.json"
"$cairn" map --bag "$work/run.bag" --out "$work/map.ply" --log-level warn > "$work/map.json"
read -r sweeps nodes points < <(/usr/bin/python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))
m = json.load(open(sys.argv[2]))
print(s["sweeps"], m["nodes"], m["map_points"])' "$work/simulate.json" "$work/map.json")
echo "bag: $sweeps sweeps; cairn map --bag: $nodes nodes, $points map points"
export ROS_PACKAGE_PATH="$(dirname "$pkg_dir"):/usr/share"
export ROS_HOME="$work/ros_home"
export ROS_LOG_DIR="$work/ros_log"
export ROS_IP=127.0.0.1  # rostest starts its own master (a free port), on the loopback interface
# Not --text: with it rostest exits 0 whatever the result. The nodes' output is in the logs.
if ! rostest cairn_ros mapper.test bag:="$work/run.bag" sweeps:="$sweeps" nodes:="$nodes" map_points:="$points"; then
  echo "rostest failed; the nodes' logs:" >&2
  find "$ROS_LOG_DIR" -name '*.log' -exec tail -n 30 {} + >&2
  exit 1
fi
