#!/usr/bin/env python3
"""rostest: starts and stops launch/dem_nodelet.launch with SIGINT (as roslaunch does on Ctrl-C) by
scripts/ros_shutdown_check.py, idle and while a KITTI frame is being processed, and fails on a heap
error ("double free or corruption"), a crash or a non-zero exit status of any node."""
import os
import subprocess
import sys
import unittest

import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402


class ShutdownTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('shutdown_test')
        cls.tmp = sup.temp_dir()
        cls.bag = sup.make_bag(os.path.join(sup.source_dir(), 'data', 'kitti_seq06_sample'),
                               os.path.join(cls.tmp, 'kitti.bag'))
        cls.script = os.path.join(sup.source_dir(), 'scripts', 'ros_shutdown_check.py')

    def check(self, *args):
        p = subprocess.run([sys.executable, self.script, '--log-dir', os.path.join(self.tmp, 'logs')] + list(args),
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
        rospy.loginfo('%s', p.stdout)
        self.assertEqual(p.returncode, 0, p.stdout)
        self.assertIn('start/stop cycles clean', p.stdout.splitlines()[-1])

    def test_idle(self):
        self.check('--cycles', '1')

    def test_stop_while_processing(self):
        self.check('--bag', self.bag, '--frames-before-stop', '2', '--stop-while-processing', '--cycles', '2')


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'shutdown', ShutdownTest, sys.argv)
