#!/usr/bin/python3
"""rostest: the bag played into cairn_mapper; cairn_registration, cairn_objects and cairn_grasp
called as a base station would; every answer checked against the simulator's truth files."""
import json
import math
import os
import time
import unittest

import rospy
import rostest
from cairn_ros.srv import ObjectEvent, PlanGrasps, RegisterDrone
from geometry_msgs.msg import PoseArray
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

# The registration protocol's bounds (cmd_protocol: beyond them a success is a wrong alignment).
MAX_ROTATION_DEG = 2.0
MAX_TRANSLATION_M = 0.10
# A database object's centroid (visible surface) is this close to its stone's true centroid.
MAX_CENTROID_DISTANCE_M = 0.5
# The best grasp's gripper origin lies this close to the object's centroid (gripper reach).
MAX_GRASP_DISTANCE_M = 2.0


def matrix(flat):
    return [list(flat[4 * r:4 * r + 4]) for r in range(4)]


def apply(m, p):
    return [sum(m[r][c] * p[c] for c in range(3)) + m[r][3] for r in range(3)]


def inverse_similarity(m):
    s = math.sqrt(sum(m[r][0] ** 2 for r in range(3)))
    rt = [[m[c][r] / (s * s) for c in range(3)] for r in range(3)]  # (sR)^-1 = R^T / s
    t = [-sum(rt[r][c] * m[c][3] for c in range(3)) for r in range(3)]
    return [rt[r] + [t[r]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def rotation_deg(a, b):
    sa = math.sqrt(sum(a[r][0] ** 2 for r in range(3)))
    sb = math.sqrt(sum(b[r][0] ** 2 for r in range(3)))
    trace = sum(a[r][c] * b[r][c] for r in range(3) for c in range(3)) / (sa * sb)  # tr(Ra Rb^T)
    return math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0))))


def distance(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


class PipelineAgainstTheTruth(unittest.TestCase):
    def setUp(self):
        self.run = rospy.get_param("~run")
        self.sweeps = int(rospy.get_param("~sweeps"))
        with open(os.path.join(self.run, "truth", "site.json")) as f:
            self.stones = [s["centroid"] for s in json.load(f)["stones"]]
        with open(os.path.join(self.run, "truth", "drone.json")) as f:
            self.T_map_drone = json.load(f)["T_map_drone"]
        self.status = {}
        rospy.Subscriber("/cairn_mapper/status", String, lambda m: self.status.update(json.loads(m.data)))

    def wait_for(self, condition, timeout, what):
        deadline = time.time() + timeout
        while time.time() < deadline and not rospy.is_shutdown():
            if condition():
                return
            time.sleep(0.2)
        self.fail("timed out waiting for " + what + ": " + json.dumps(self.status))

    def call(self, name, kind, *args):
        rospy.wait_for_service(name, timeout=30.0)
        return rospy.ServiceProxy(name, kind)(*args)

    def test_map_register_segment_plan_grasp_release(self):
        # The bag mapped, every sweep.
        self.wait_for(lambda: self.status.get("sweeps_received", 0) >= self.sweeps, 150.0, "every sweep")
        finished = self.call("/cairn_mapper/finish", Trigger)
        self.assertTrue(finished.success, finished.message)
        self.assertEqual(finished.message, "finished: %d sweeps mapped" % self.sweeps)
        full_map = rospy.wait_for_message("/cairn_mapper/map", PointCloud2, timeout=30.0)
        time.sleep(2.0)  # the base station's subscribers take the final map

        # Registration of the drone cloud (SfM frame, from the bag's topic) with scale recovery.
        drone = os.path.join(self.run, "drone")
        reg = self.call("/cairn_registration/register", RegisterDrone, "", os.path.join(drone, "sparse"),
                        os.path.join(drone, "vins_trajectory.tum"), False, False)
        self.assertTrue(reg.success, reg.message)
        estimate = matrix(reg.T_map_drone)
        at = [sum(c[i] for c in self.stones) / len(self.stones) for i in range(3)]  # the stones' centre
        x = apply(inverse_similarity(self.T_map_drone), at)
        rot, trans = rotation_deg(estimate, self.T_map_drone), distance(apply(estimate, x), at)
        rospy.loginfo("registration: %.3f deg, %.3f m from the truth", rot, trans)
        self.assertLess(rot, MAX_ROTATION_DEG)
        self.assertLess(trans, MAX_TRANSLATION_M)
        self.assertTrue(json.loads(reg.json)["success"])
        aligned = rospy.wait_for_message("/cairn_registration/aligned", PointCloud2, timeout=30.0)
        self.assertGreater(aligned.width, 1000)

        merged = rospy.wait_for_message("/cairn_registration/merged", PointCloud2, timeout=30.0)
        self.assertGreaterEqual(merged.width, full_map.width // 2)
        time.sleep(1.0)  # the objects node takes the merged map

        # Objects: one per stone, each near its stone (segmented on the map merged with the drone's).
        seg = self.call("/cairn_objects/segment", Trigger)
        self.assertTrue(seg.success, seg.message)
        self.assertEqual(json.loads(seg.message)["segmented"], "merged")
        objects = json.loads(rospy.wait_for_message("/cairn_objects/objects", String, timeout=30.0).data)["objects"]
        rospy.loginfo("objects: %s", json.dumps(objects))
        self.assertEqual(len(objects), len(self.stones))
        for k, stone in enumerate(self.stones):
            nearest = min(distance(o["centroid"], stone) for o in objects)
            self.assertLess(nearest, MAX_CENTROID_DISTANCE_M, "stone %d" % k)
        markers = rospy.wait_for_message("/cairn_objects/markers", MarkerArray, timeout=30.0)
        self.assertEqual(len([m for m in markers.markers if m.ns == "objects"]), len(objects))

        # Grasps of the largest object, with the gripper's markers.
        time.sleep(1.0)  # the grasp node takes the registered drone cloud
        plan = self.call("/cairn_grasp/plan", PlanGrasps, 0)
        self.assertTrue(plan.success, plan.message)
        largest = max(objects, key=lambda o: o["num_points"])
        self.assertEqual(plan.object_id, largest["id"])
        self.assertGreater(len(plan.grasps.poses), 0)
        best = plan.grasps.poses[0]
        origin = [best.position.x, best.position.y, best.position.z]
        self.assertLess(distance(origin, largest["centroid"]), MAX_GRASP_DISTANCE_M)
        self.assertEqual(len(json.loads(plan.json)["grasps"]), len(plan.grasps.poses))
        gripper = rospy.wait_for_message("/cairn_grasp/markers", MarkerArray, timeout=30.0)
        self.assertGreaterEqual(len([m for m in gripper.markers if m.ns == "gripper"]), 3)  # palm, two jaws
        self.assertEqual(len(rospy.wait_for_message("/cairn_grasp/grasps", PoseArray, timeout=30.0).poses),
                         len(plan.grasps.poses))

        # Grasp event: stored, and the object's points leave the mapper's map.
        grasp = self.call("/cairn_objects/grasp", ObjectEvent, plan.object_id, best, 100.0)
        self.assertTrue(grasp.success, grasp.message)
        self.assertEqual(json.loads(grasp.json)["status"], "grasped")
        self.wait_for(lambda: self.status.get("edits", 0) == 1, 30.0, "the map edit")
        edited = rospy.wait_for_message("/cairn_mapper/map", PointCloud2, timeout=30.0)
        rospy.loginfo("map: %d points, %d after the grasp", full_map.width, edited.width)
        self.assertLess(edited.width, full_map.width)

        # Release 0.5 m further along x, same orientation: Eq. 3 moves the centroid by exactly that.
        best.position.x += 0.5
        release = self.call("/cairn_objects/release", ObjectEvent, plan.object_id, best, 110.0)
        self.assertTrue(release.success, release.message)
        moved = json.loads(release.json)
        self.assertEqual(moved["status"], "placed")
        expected = [largest["centroid"][0] + 0.5] + largest["centroid"][1:]
        self.assertLess(distance(moved["centroid"], expected), 1e-3)
        self.assertEqual(self.status.get("errors"), 0, self.status)

        # Bad input is an answer, not a crash.
        unknown = self.call("/cairn_grasp/plan", PlanGrasps, 9999)
        self.assertFalse(unknown.success)
        self.assertIn("no object 9999", unknown.message)


if __name__ == "__main__":
    rospy.init_node("test_pipeline")
    rostest.rosrun("cairn_ros", "pipeline_against_the_truth", PipelineAgainstTheTruth)
