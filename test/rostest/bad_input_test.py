#!/usr/bin/env python3
"""Rostest of bad sensor input through the nodelets (issue 9): feeds live.launch's points topic
with a synthetic VLP-16-like scan of a box room (ground and four walls), then with malformed and
out-of-order clouds, and checks for each that no odometry comes out of it, that a warning names
the problem, and that good scans after it are still mapped. Also publishes a message of another
type on the points topic (roscpp refuses the connection) and checks the nodelets survive."""
import struct
import time
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import String

PKG = "multisession_mapper"
FRAME = "velodyne"


def room_scan(height_m=1.5, half_x=10.0, half_y=7.0, wall_top=2.5):
    """Points (N, 3), ring (N,) and time (N,) of a VLP-16 in a box room, sensor at the origin."""
    elevations = np.radians(np.arange(-15.0, 16.0, 2.0))
    azimuths = np.radians(np.arange(0.0, 360.0, 0.4))
    el, az = np.meshgrid(elevations, azimuths, indexing="ij")
    ring = np.repeat(np.arange(16), len(azimuths))
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
    t = np.full(len(d), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, bound in ((0, half_x), (1, half_y)):
            for sign in (-1.0, 1.0):
                ti = sign * bound / d[:, axis]
                t = np.where((ti > 0) & (ti < t), ti, t)
        tg = -height_m / d[:, 2]
        t = np.where((tg > 0) & (tg < t), tg, t)
    p = d * t[:, None]
    ok = np.isfinite(t) & (p[:, 2] <= wall_top) & (t < 100.0)
    stamp_frac = np.tile(np.arange(len(azimuths)) / len(azimuths) * 0.1, 16)
    return p[ok], ring[ok], stamp_frac[ok]


def cloud(points, stamp, ring=None, times=None, frame=FRAME):
    """A little-endian PointCloud2 with x y z (float32) [ring (uint16) time (float32)]."""
    msg = PointCloud2()
    msg.header.stamp = rospy.Time.from_sec(stamp)
    msg.header.frame_id = frame
    msg.height = 1
    msg.width = len(points)
    msg.fields = [PointField(n, 4 * i, PointField.FLOAT32, 1) for i, n in enumerate("xyz")]
    fmt = "<fff"
    if ring is not None:
        msg.fields += [PointField("ring", 12, PointField.UINT16, 1),
                       PointField("time", 14, PointField.FLOAT32, 1)]
        fmt = "<fffHf"
    msg.point_step = struct.calcsize(fmt)
    msg.row_step = msg.point_step * msg.width
    msg.is_bigendian = False
    msg.is_dense = False
    rows = []
    for i, p in enumerate(points):
        values = [float(p[0]), float(p[1]), float(p[2])]
        if ring is not None:
            values += [int(ring[i]), float(times[i])]
        rows.append(struct.pack(fmt, *values))
    msg.data = b"".join(rows)
    return msg


class BadInputTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("bad_input_test")
        cls.odom = 0
        cls.logs = []
        rospy.Subscriber("/odom", Odometry, cls.on_odom, queue_size=100)
        rospy.Subscriber("/rosout", Log, lambda m: cls.logs.append(m.msg), queue_size=1000)
        cls.pub = rospy.Publisher("/velodyne_points", PointCloud2, queue_size=10)
        cls.points, cls.ring, cls.times = room_scan()
        cls.stamp = 1000.0
        deadline = time.time() + 60.0
        while cls.pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.2)
        time.sleep(1.0)

    @classmethod
    def on_odom(cls, _):
        cls.odom += 1

    def send(self, msg, wait_s=1.5):
        before = self.odom
        self.pub.publish(msg)
        time.sleep(wait_s)
        return self.odom - before

    def good(self, gap_s=0.1):
        self.stamp += gap_s
        return self.send(cloud(self.points, self.stamp, self.ring, self.times))

    def test_bad_input(self):
        self.assertGreater(len(self.points), 5000)
        mapped = sum(self.good() for _ in range(4))
        self.assertGreaterEqual(mapped, 3, "good scans must be mapped")
        # Each bad cloud is built when sent, with the next stamp, so that only its own defect
        # can make it fail. The warnings are throttled per call site (5 s): the first case of
        # each site is the one whose message is checked below.
        def next_stamp():
            return self.stamp + 0.1

        def no_z():
            msg = cloud(self.points, next_stamp(), self.ring, self.times)
            msg.fields = [f for f in msg.fields if f.name != "z"]
            return msg

        def truncated():
            msg = cloud(self.points, next_stamp(), self.ring, self.times)
            msg.data = msg.data[: len(msg.data) // 2]
            return msg

        n = 2000
        bad = [
            ("repeated stamp", lambda: cloud(self.points, self.stamp, self.ring, self.times)),
            ("older stamp", lambda: cloud(self.points, self.stamp - 5.0, self.ring, self.times)),
            ("empty cloud", lambda: cloud(np.zeros((0, 3)), next_stamp(), [], [])),
            ("all-NaN cloud", lambda: cloud(np.full((n, 3), np.nan), next_stamp(),
                                            np.zeros(n, int), np.zeros(n))),
            ("no z field", no_z),
            ("truncated data", truncated),
            ("other frame_id", lambda: cloud(self.points, next_stamp(), self.ring, self.times,
                                             frame="another_sensor")),
        ]
        for name, make in bad:
            self.assertEqual(self.send(make()), 0, "%s: odometry published" % name)
            self.assertEqual(self.good(), 1, "%s: the next good scan was not mapped" % name)
        # A plain x/y/z layout (no ring, no time) is valid input.
        self.stamp += 0.1
        self.assertEqual(self.send(cloud(self.points, self.stamp)), 1, "x/y/z-only cloud")
        # A gap of several seconds: mapped, the motion model restarts.
        self.assertEqual(self.good(gap_s=5.0), 1, "scan after a 5 s gap")
        # A message of another type on the points topic: roscpp refuses the connection.
        wrong = rospy.Publisher("/velodyne_points", String, queue_size=1)
        time.sleep(1.0)
        wrong.publish(String(data="not a cloud"))
        time.sleep(1.0)
        wrong.unregister()
        self.assertEqual(self.good(), 1, "the nodelets stopped after a wrong-type publisher")
        text = "\n".join(self.logs)
        for problem in ("does not increase", "no x/y/z fields", "is not the sensor frame"):
            self.assertIn(problem, text, "no warning naming '%s'" % problem)


if __name__ == "__main__":
    rostest.rosrun(PKG, "bad_input", BadInputTest)
