#!/usr/bin/env python3
"""rostest: scripts/ros_realtime_check.py on the bundled KITTI sample at the camera's rate (10 Hz):
every frame reaches the node, each is mapped, dropped (the node was busy) or skipped, the summary line
and the figures are there, the first frame is mapped and the odometry of the mapped frames stays
within 5 % of the true path."""
import json
import os
import subprocess
import sys
import unittest

import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402


class RealtimeTest(unittest.TestCase):
    def test_sample_at_10_hz(self):
        rospy.init_node('realtime_test')
        tmp = sup.temp_dir()
        seq = os.path.join(sup.source_dir(), 'data', 'kitti_seq06_sample')
        bag = sup.make_bag(seq, os.path.join(tmp, 'kitti.bag'))
        out = os.path.join(tmp, 'figures.json')
        p = subprocess.run([sys.executable, os.path.join(sup.source_dir(), 'scripts', 'ros_realtime_check.py'),
                            '--bag', bag, '--sequence', seq, '--json', out, '--log-dir', os.path.join(tmp, 'logs')],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        rospy.loginfo('%s', p.stdout)
        self.assertEqual(p.returncode, 0, p.stdout)
        self.assertTrue(p.stdout.strip().splitlines()[-1].startswith('realtime check: kitti.bag (6 frames'), p.stdout)
        with open(out) as f:
            r = json.load(f)
        self.assertEqual(r['received'], 6)
        self.assertEqual(r['skipped'], 0)
        self.assertEqual(r['mapped'] + r['failed'] + r['dropped'], 6, r)
        self.assertGreaterEqual(r['mapped'], 2, r)  # the first frame, then at least the latest one
        self.assertEqual(r['dems'], r['mapped'] + r['failed'])
        self.assertGreater(r['latency_median_ms'], 0.0)
        self.assertLess(r['drift_percent'], 5.0, r)


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'realtime', RealtimeTest, sys.argv)
