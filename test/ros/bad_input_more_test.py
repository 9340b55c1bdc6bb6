#!/usr/bin/env python3
"""rostest: more ROS input defects (docs/bad_input.md, "## ROS"), in one bag made at test time from a
rendered flat road (half resolution). The node must stay alive, name each problem (diagnostics,
/rosout), skip or reject exactly the bad frames, restart the map where the input says so, and publish
nothing wrong.

 0-2 good | 3 16UC1 big-endian (skipped) | 4 mono16 big-endian (valid: byte-swapped, mapped)
 5 NaN in camera_info (skipped) | 6 right fx 1 % off (skipped) | 7 black, 8 saturated (rejected by the core)
 9 duplicate stamp (skipped) | 10 stamp 30 ms older than the last accepted one (skipped)
 11 right camera 30 ms late (never synchronized) | 12-14 good | 15-17 new calibration (map restarts)
 18-20 stamps 5 s later (map restarts)"""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest
from rosgraph_msgs.msg import Log
from std_srvs.srv import Trigger

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402

NS = '/stereo_ground_dem'
FRAMES = 21
PROCESSED = [0, 1, 2, 4, 12, 13, 14, 15, 16, 17, 18, 19, 20]
SKIPPED = 7  # 3, 5, 6, 9, 10 invalid; 7, 8 rejected by the estimator


class BadInputMoreTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('bad_input_more_test')
        cls.period = rospy.get_param('~period_s', 0.6)
        cls.tmp = sup.temp_dir()
        seq = sup.render(os.path.join(cls.tmp, 'flat'), FRAMES, ['--scale', '0.5'])
        bag = sup.make_bag(seq, os.path.join(cls.tmp, 'bad.bag'), [
            '--generic-16u', '3', '--mono16-be', '4', '--nan-info', '5', '--inconsistent-info', '6',
            '--black', '7', '--saturated', '8', '--duplicate-stamp', '9', '--stamp-offset', '10:-0.23',
            '--unsync', '11', '--change-info-from', '15', '--time-shift', '18:5.0'])
        cls.logs = []
        cls.log_sub = rospy.Subscriber('/rosout', Log, lambda m: cls.logs.append(m), queue_size=1000)
        cls.rec, cls.player = sup.play_bag(NS, bag, cls.period)
        cls.statuses = cls.rec.diagnostic_statuses()
        cls.messages = set(s.message for _, s in cls.statuses if s.level >= 1)
        rospy.loginfo('diagnostics WARN/ERROR messages:\n%s', '\n'.join(sorted(cls.messages)))

    def test_01_dems_exactly_for_the_processed_frames(self):
        stamp_of = {k: round(s, 6) for k, s, _ in self.player.published}
        dem_stamps = [round(m.info.header.stamp.to_sec(), 6) for _, m in self.rec.dems]
        self.assertEqual(dem_stamps, [stamp_of[k] for k in PROCESSED])

    def test_02_nothing_bad_fused(self):
        for _, m in self.rec.dems:
            h = sup.finite_known(sup.layer(m, 'elevation'))
            self.assertGreater(h.size, 300)
            self.assertLess(float(np.median(np.abs(h))), 0.05, 'flat road stays flat')
        for _, o in self.rec.odoms:
            p = o.pose.pose.position
            self.assertTrue(np.isfinite([p.x, p.y, p.z]).all())

    def test_03_each_problem_named(self):
        expected = [
            "left image: encoding '16UC1' is a generic (depth-image) encoding, not a grey image: publish mono8 or "
            "mono16 (or remap the camera's image_rect, not a depth image) (frame skipped)",
            'camera_info: left camera_info P[2] is nan: the calibration is broken (NaN or infinite projection '
            'matrix) (frame skipped)',
            'duplicate time stamp: the frame has the same stamp as the previous one (frame skipped)',
            'time stamp goes backwards by 0.030 s (frames out of order) (frame skipped)',
            'map reset: the camera calibration changed (camera_info P or size): starting a new map',
        ]
        for e in expected:
            self.assertIn(e, self.messages)
        starts = ['camera_info: inconsistent stereo calibration: left and right fx differ (',
                  'images rejected by the estimator: left image is black (mean 0 grey levels)',
                  'images rejected by the estimator: left image is saturated (100% of pixels)',
                  'map reset: time jumped forward by 5.',
                  'gap in the input: ']
        for s in starts:
            self.assertTrue(any(m.startswith(s) for m in self.messages), s)

    def test_04_counts(self):
        kv = {v.key: v.value for v in self.statuses[-1][1].values}
        self.assertEqual(int(kv['processed frames']), len(PROCESSED))
        self.assertEqual(int(kv['skipped (invalid input)']), SKIPPED)
        self.assertEqual(int(kv['rejected by the estimator']), 2)
        self.assertEqual(int(kv['map restarts']), 2)
        self.assertEqual(int(kv['initialized']), 3)  # frame 0 and after each restart
        self.assertEqual(int(kv['dropped (busy: replaced by a newer frame)']), 0)
        self.assertEqual(int(kv['synchronized frames']), FRAMES - 1)  # 11 never synchronizes

    def test_05_logged_once_each(self):
        errors = [m.msg for m in self.logs if m.level >= Log.ERROR]
        self.assertEqual(sum('P[2] is nan' in e for e in errors), 1, errors)
        self.assertEqual(sum("'16UC1'" in e for e in errors), 1, errors)

    def test_06_node_alive(self):
        rospy.wait_for_service(NS + '/reset', 5.0)
        self.assertTrue(rospy.ServiceProxy(NS + '/reset', Trigger)().success)


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'bad_input_more', BadInputMoreTest, sys.argv)
