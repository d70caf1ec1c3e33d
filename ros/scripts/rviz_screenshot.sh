#!/usr/bin/env bash
# RViz showing the pipeline's answers, rendered under Xvfb and saved as a PNG (docs/ros.md):
# simulate exp1 as a bag, launch pipeline_bag.launch with RViz, drive the services with
# pipeline_client.py, take a screenshot of the virtual display.
#   ros/scripts/rviz_screenshot.sh [OUT.png]     (after the build; packages: install_deps.sh --rviz)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
out=$(realpath -m "${1:-$root/docs/images/rviz.png}")
build="$root/build"
work=$(mktemp -d)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT
"$build/apps/cairn/cairn" simulate --scenario exp1 --seed 1 --duration 8 --out "$work/run" --bag "$work/run.bag" \
  --log-level warn > "$work/simulate.json"
sweeps=$(/usr/bin/python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["sweeps"])' "$work/simulate.json")
export ROS_PACKAGE_PATH="$build/ros/pkg:/usr/share" PYTHONPATH="$build/ros/gen/python"
export ROS_HOME="$work/ros_home" ROS_LOG_DIR="$work/ros_log" ROS_IP=127.0.0.1
export ROS_MASTER_URI=http://127.0.0.1:11711 DISPLAY=:71 LIBGL_ALWAYS_SOFTWARE=1
Xvfb :71 -screen 0 1400x900x24 > "$work/xvfb.log" 2>&1 & pids+=($!)
roscore -p 11711 > "$work/roscore.log" 2>&1 & pids+=($!)
sleep 3
roslaunch cairn_ros pipeline_bag.launch bag:="$work/run.bag" database:="$work/objects.db" rviz:=true \
  > "$work/launch.log" 2>&1 & pids+=($!)
/usr/bin/python3 "$root/ros/scripts/pipeline_client.py" --sweeps "$sweeps" --sfm "$work/run/drone/sparse" \
  --metric "$work/run/drone/vins_trajectory.tum"
sleep 8  # RViz draws the latched answers
mkdir -p "$(dirname "$out")"
import -display :71 -window root "$out"
echo "rviz_screenshot: $out"
