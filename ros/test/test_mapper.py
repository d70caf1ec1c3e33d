#!/usr/bin/python3
"""rostest: cairn_mapper fed by `rosbag play` maps the bag as `cairn map --bag` does."""
import json
import time
import unittest

import rospy
import rostest
from nav_msgs.msg import Path
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from std_srvs.srv import Trigger


class MapperPlaysABag(unittest.TestCase):
    def test_every_sweep_mapped_and_the_map_matches_the_cli(self):
        sweeps = int(rospy.get_param("~sweeps"))
        nodes = int(rospy.get_param("~nodes"))
        map_points = int(rospy.get_param("~map_points"))
        status = {}
        rospy.Subscriber("/cairn_mapper/status", String, lambda m: status.update(json.loads(m.data)))
        deadline = time.time() + 150.0
        while time.time() < deadline and not rospy.is_shutdown():
            if status.get("sweeps_received", 0) >= sweeps:
                break
            time.sleep(0.2)
        self.assertEqual(status.get("sweeps_received"), sweeps, status)
        rospy.wait_for_service("/cairn_mapper/finish", timeout=30.0)
        answer = rospy.ServiceProxy("/cairn_mapper/finish", Trigger)()
        self.assertTrue(answer.success, answer.message)
        self.assertEqual(answer.message, "finished: %d sweeps mapped" % sweeps)  # every sweep, none dropped
        cloud = rospy.wait_for_message("/cairn_mapper/map", PointCloud2, timeout=30.0)
        self.assertEqual(cloud.header.frame_id, "map")
        path = rospy.wait_for_message("/cairn_mapper/trajectory", Path, timeout=30.0)
        rospy.loginfo("cairn_mapper: %d map points (cli %d), %d nodes (cli %d)", cloud.width, map_points,
                      len(path.poses), nodes)
        self.assertEqual(status.get("errors"), 0, status)
        self.assertEqual(len(path.poses), nodes)
        self.assertAlmostEqual(cloud.width / float(map_points), 1.0, delta=0.01)


if __name__ == "__main__":
    rospy.init_node("test_mapper")
    rostest.rosrun("cairn_ros", "mapper_plays_a_bag", MapperPlaysABag)
