#!/usr/bin/env bash
# ctest RosPipeline.AgainstTheTruth: simulate exp1 (seed 1, 8 s, with the drone) as a bag, then
# rostest (its own master) runs robot.launch + base_station.launch on it and checks every node's
# answers against the run's truth files.
#   run_pipeline_test.sh CAIRN_EXE ROS_PACKAGE_DIR PYTHONPATH_OF_THE_GENERATED_TYPES WORK_DIR [SCENARIO SEED]
# (ctest: exp1 seed 1; other scenarios and seeds measure the same checks on sites nobody tuned on)
set -euo pipefail
cairn=$1
pkg_dir=$2
generated=$3
work=$4
scenario=${5:-exp1}
seed=${6:-1}
rm -rf "$work"
mkdir -p "$work"
"$cairn" simulate --scenario "$scenario" --seed "$seed" --duration 8 --out "$work/run" --bag "$work/run.bag" \
  --log-level warn > "$work/simulate.json"
sweeps=$(/usr/bin/python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["sweeps"])' "$work/simulate.json")
echo "bag: $sweeps sweeps"
export ROS_PACKAGE_PATH="$(dirname "$pkg_dir"):/usr/share"
export PYTHONPATH="$generated${PYTHONPATH:+:$PYTHONPATH}"
export ROS_HOME="$work/ros_home"
export ROS_LOG_DIR="$work/ros_log"
export ROS_IP=127.0.0.1  # rostest starts its own master (a free port), on the loopback interface
# Not --text: with it rostest exits 0 whatever the result. The nodes' output is in the logs.
if ! rostest cairn_ros pipeline.test bag:="$work/run.bag" run:="$work/run" database:="$work/objects.db" \
     sweeps:="$sweeps"; then
  echo "rostest failed; the nodes' logs:" >&2
  find "$ROS_LOG_DIR" -name '*.log' -exec tail -n 40 {} + >&2
  exit 1
fi
