#!/usr/bin/env python3
"""rostest: a bag with defects (made at test time from a rendered sequence) must leave the node alive,
skip the bad frames with a reason on /diagnostics and /rosout, and publish nothing wrong.

Frames 0-2 good; 3 right image one column narrower; 4 bayer encoding; 5-6 no left camera_info (never
synchronized); 7-8 dropped (a gap); 9-12 good."""
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
FRAMES = 13
GOOD = [0, 1, 2, 9, 10, 11, 12]


class BadInputTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('bad_input_test')
        cls.period = rospy.get_param('~period_s', 1.0)
        cls.tmp = sup.temp_dir()
        seq = sup.render(os.path.join(cls.tmp, 'flat'), FRAMES, ['--scale', '0.5'])
        bag = sup.make_bag(seq, os.path.join(cls.tmp, 'bad.bag'),
                           ['--bad-size', '3', '--bad-encoding', '4', '--drop-info', '5,6', '--drop', '7,8'])
        cls.logs = []
        cls.log_sub = rospy.Subscriber('/rosout', Log, lambda m: cls.logs.append(m), queue_size=500)
        cls.rec, cls.player = sup.play_bag(NS, bag, cls.period)

    def test_01_no_dem_from_bad_frames(self):
        s0 = self.player.published[0][1]
        stamps = {int(round((s - s0) / 0.1)): round(s, 6) for _, s, _ in self.player.published}
        self.assertEqual(len(self.player.published), FRAMES - 2)  # 7 and 8 are not in the bag
        dem_stamps = [round(m.info.header.stamp.to_sec(), 6) for _, m in self.rec.dems]
        rospy.loginfo('DEMs for frames %s', [int(round((s - s0) / 0.1)) for s in dem_stamps])
        self.assertEqual(dem_stamps, [stamps[k] for k in GOOD], 'DEMs exactly for the good frames')

    def test_02_heights_finite(self):
        for _, m in self.rec.dems:
            h = sup.finite_known(sup.layer(m, 'elevation'))
            self.assertGreater(h.size, 300)
            self.assertLess(float(np.median(np.abs(h))), 0.05, 'flat road stays flat')
        for _, o in self.rec.odoms:
            p = o.pose.pose.position
            self.assertTrue(np.isfinite([p.x, p.y, p.z]).all())

    def test_03_diagnostics_name_the_problems(self):
        statuses = self.rec.diagnostic_statuses()
        bad = [(s.level, s.message) for _, s in statuses if s.level >= 1]
        text = '\n'.join(m for _, m in bad)
        rospy.loginfo('diagnostics WARN/ERROR messages seen:\n%s', '\n'.join(sorted(set(text.split('\n')))))
        self.assertIn('612x185', text)                 # size mismatch (right camera one column narrower)
        self.assertIn('bayer', text)                   # encoding
        self.assertIn('camera_info', text)             # the missing left camera_info
        self.assertIn('gap in the input', text)        # the dropped frames
        self.assertTrue(any(l == 2 and 'bayer' in m for l, m in bad), 'a skipped frame is an ERROR')
        kv = {v.key: v.value for v in statuses[-1][1].values}
        self.assertEqual(int(kv['skipped (invalid input)']), 2)
        self.assertEqual(int(kv['processed frames']), len(GOOD))

    def test_04_logged_errors(self):
        errors = [m.msg for m in self.logs if m.level >= Log.ERROR]
        self.assertTrue(any('bayer' in e and 'frame skipped' in e for e in errors), errors)
        self.assertTrue(any('612x185' in e for e in errors), errors)

    def test_05_node_alive(self):
        rospy.wait_for_service(NS + '/reset', 5.0)
        self.assertTrue(rospy.ServiceProxy(NS + '/reset', Trigger)().success)


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'bad_input', BadInputTest, sys.argv)
