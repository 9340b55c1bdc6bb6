#!/usr/bin/env python3
"""rostest: dynamic_reconfigure at run time and the whole-map topics, on the bundled KITTI sample.

- a traversability parameter (critical_step_m) takes effect at once: get_submap on the same map
  before and after the change returns different traversability (every known cell 0 with a 0.1 mm
  critical step);
- an estimator parameter (max_range_m 40 -> 15 m) waits for ~reset (its answer says so) and then
  applies: after the reset the bag is played again and no vertex farther than 15 m + one cell ahead
  of the camera is known;
- ~dem_global and ~traversability_global (latched, global_map_rate_hz high in the .test): the whole
  map, every layer, in odom, the OccupancyGrid cell for cell the HeightGrid, covering the drive."""
import os
import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from dynamic_reconfigure.client import Client
from nav_msgs.msg import OccupancyGrid
from std_srvs.srv import Trigger

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402
from stereo_ground_dem.msg import HeightGrid  # noqa: E402
from stereo_ground_dem.srv import GetSubmap  # noqa: E402

NS = '/stereo_ground_dem'
LAYERS = ['elevation', 'variance', 'observations', 'slope', 'step', 'roughness', 'traversability',
          'traversability_confidence', 'obstacle', 'obstacle_height', 'residual', 'residual_outlier_rate', 'intensity']


class ReconfigureTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('reconfigure_test')
        cls.period = rospy.get_param('~period_s', 1.2)
        cls.tmp = sup.temp_dir()
        cls.bag = sup.make_bag(os.path.join(sup.source_dir(), 'data', 'kitti_seq06_sample'),
                               os.path.join(cls.tmp, 'kitti.bag'))
        cls.lock = threading.Lock()
        cls.globals, cls.global_occ = [], []
        cls.g_sub = rospy.Subscriber(NS + '/dem_global', HeightGrid, lambda m: cls._keep(cls.globals, m),
                                     queue_size=10, buff_size=2 ** 26)
        cls.o_sub = rospy.Subscriber(NS + '/traversability_global', OccupancyGrid,
                                     lambda m: cls._keep(cls.global_occ, m), queue_size=10, buff_size=2 ** 24)
        cls.rec, cls.player = sup.play_bag(NS, cls.bag, cls.period)
        rospy.wait_for_service(NS + '/get_submap', 10.0)
        cls.get = rospy.ServiceProxy(NS + '/get_submap', GetSubmap)
        cls.client = Client(NS, timeout=10.0)

    @classmethod
    def _keep(cls, store, m):
        with cls.lock:
            store.append(m)

    def ahead(self):
        p = self.rec.odoms[-1][1].pose.pose.position
        return self.get(center_x=p.x + 15.0, center_y=p.y, length_x=30.0, length_y=20.0,
                        layers=['elevation', 'traversability'])

    def test_1_traversability_at_once(self):
        before = self.ahead()
        self.assertTrue(before.success, before.message)
        t0 = sup.layer(before.map, 'traversability')
        known = np.isfinite(t0)
        self.assertGreater(known.sum(), 200)
        self.assertGreater(np.count_nonzero(t0[known] > 0.5), 100, 'free road before the change')
        self.client.update_configuration({'critical_step_m': 0.0001})
        after = self.ahead()
        t1 = sup.layer(after.map, 'traversability')
        self.assertTrue(np.array_equal(np.isfinite(t1), known), 'same map, same known cells')
        self.assertEqual(np.count_nonzero(t1[known] > 0.0), 0, 'a 0.1 mm critical step: nothing traversable')
        self.client.update_configuration({'critical_step_m': 0.2})
        again = sup.layer(self.ahead().map, 'traversability')
        self.assertTrue(np.allclose(again[known], t0[known]), 'back to the first values')

    def test_2_estimator_parameter_at_reset(self):
        far_before = self.farthest_known_ahead(self.rec)
        self.assertGreater(far_before, 25.0)
        self.client.update_configuration({'max_range_m': 15.0})
        r = rospy.ServiceProxy(NS + '/reset', Trigger)()
        self.assertTrue(r.success)
        self.assertEqual(r.message, 'map reset; pending parameter changes applied')
        rec, _ = sup.play_bag(NS, self.bag, self.period)  # same stamps again: a new map anyway
        far_after = self.farthest_known_ahead(rec)
        rospy.loginfo('farthest known vertex ahead of the camera: %.1f m before, %.1f m after', far_before,
                      far_after)
        self.assertLess(far_after, 15.0 + 1.0)
        self.client.update_configuration({'max_range_m': 40.0})

    def farthest_known_ahead(self, rec):
        """Largest x - camera x of a known elevation cell in the last local DEM (the road runs along x)."""
        _, dem = rec.dems[-1]
        x, _ = sup.cell_centres(dem)
        e = sup.layer(dem, 'elevation')
        cols = np.isfinite(e).any(axis=1)
        cam_x = rec.odoms[-1][1].pose.pose.position.x
        return float(x[cols].max() - cam_x)

    def test_0_global_map(self):
        end = time.time() + 5.0
        while time.time() < end and not (self.globals and self.global_occ):
            time.sleep(0.1)
        with self.lock:
            g, o = self.globals[-1], self.global_occ[-1]
        self.assertEqual(list(g.layers), LAYERS)
        self.assertEqual(g.info.header.frame_id, 'odom')
        self.assertEqual(o.header.frame_id, 'odom')
        nx = int(round(g.info.length_x / g.info.resolution))
        ny = int(round(g.info.length_y / g.info.resolution))
        self.assertEqual((o.info.width, o.info.height), (nx, ny), 'OccupancyGrid cell for cell the HeightGrid')
        self.assertAlmostEqual(o.info.resolution, g.info.resolution, places=6)
        occ = np.array(o.data)
        self.assertTrue(((occ >= -1) & (occ <= 100)).all())
        e = sup.layer(g, 'elevation')
        local = sup.layer(self.rec.dems[-1][1], 'elevation')
        self.assertGreaterEqual(np.isfinite(e).sum(), np.isfinite(local).sum(), 'the whole map holds the local one')
        x, _ = sup.cell_centres(g)
        known_x = x[np.isfinite(e).any(axis=1)]
        last = self.rec.odoms[-1][1].pose.pose.position.x
        self.assertLess(known_x.min(), 10.0, 'from the start of the drive')
        self.assertGreater(known_x.max(), last + 20.0, 'to beyond the last camera position')


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'reconfigure', ReconfigureTest, sys.argv)
