#!/usr/bin/python3
"""A base station's client of the cairn nodes, as a field engineer would script it: wait until the
bag has been mapped, register the drone cloud (with its SfM model and metric trajectory for the
scale), fill the object database and plan grasps of the largest object. Prints every answer.

  pipeline_client.py --sweeps N --sfm RUN/drone/sparse --metric RUN/drone/vins_trajectory.tum
(the generated service types on PYTHONPATH: build/ros/gen/python)."""
import argparse
import json
import sys
import time

import rospy
from cairn_ros.srv import PlanGrasps, RegisterDrone
from std_msgs.msg import String
from std_srvs.srv import Trigger


def call(name, kind, *args):
    rospy.wait_for_service(name, timeout=60.0)
    return rospy.ServiceProxy(name, kind)(*args)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sweeps", type=int, required=True, help="sweeps in the bag (wait for all)")
    parser.add_argument("--sfm", default="", help="the drone's COLMAP text model (scale recovery)")
    parser.add_argument("--metric", default="", help="the drone's metric TUM trajectory (scale recovery)")
    parser.add_argument("--estimate-scale", action="store_true", help="7-DoF registration (the scale estimated)")
    parser.add_argument("--timeout", type=float, default=300.0, help="[s] waiting for the sweeps")
    a = parser.parse_args(rospy.myargv()[1:])
    rospy.init_node("cairn_pipeline_client", anonymous=True)
    status = {}
    rospy.Subscriber("/cairn_mapper/status", String, lambda m: status.update(json.loads(m.data)))
    deadline = time.time() + a.timeout
    while status.get("sweeps_received", 0) < a.sweeps and time.time() < deadline and not rospy.is_shutdown():
        time.sleep(0.5)
    print("mapper:", call("/cairn_mapper/finish", Trigger).message, flush=True)
    time.sleep(2.0)  # the base station's nodes take the final map
    reg = call("/cairn_registration/register", RegisterDrone, "", a.sfm, a.metric, False, a.estimate_scale)
    print("registration:", "success" if reg.success else "failed: " + reg.message, flush=True)
    time.sleep(2.0)  # the objects node takes the merged map
    seg = call("/cairn_objects/segment", Trigger)
    print("objects:", seg.message if seg.success else "failed: " + seg.message, flush=True)
    plan = call("/cairn_grasp/plan", PlanGrasps, 0)
    print("grasps:", plan.message, flush=True)
    return 0 if reg.success and seg.success and plan.success else 1


if __name__ == "__main__":
    sys.exit(main())
