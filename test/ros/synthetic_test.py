#!/usr/bin/env python3
"""rostest: a rendered flat road with obstacles (sgd_render, half KITTI resolution) through the nodelet.

The sequence and its bag are made at test time. Ground truth: the terrain is the plane z = 0 of the
scene frame, which is the estimator's ground frame (odom) up to the estimation error (the first camera
is at the scene origin, heading +x, 1.65 m up); poses.txt gives the true camera motion; scene.yaml the
obstacles (a parked car 4.2 x 1.8 m centred at x = 22, y = -2.6)."""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest
import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402

NS = '/stereo_ground_dem'
FRAMES = 10
# Measured (frames 8 and 9, the valid ones): |height - 1.65| <= 0.3 mm, |pitch|, |roll| <= 0.0044 deg.
ATTITUDE_HEIGHT_TOL_M = 0.001
ATTITUDE_ANGLE_TOL_DEG = 0.01


class SyntheticTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('synthetic_test')
        cls.period = rospy.get_param('~period_s', 1.0)
        cls.tmp = sup.temp_dir()
        cls.sequence = sup.render(os.path.join(cls.tmp, 'flat'), FRAMES, ['--obstacles', '--scale', '0.5'])
        bag = sup.make_bag(cls.sequence, os.path.join(cls.tmp, 'flat.bag'))
        with open(os.path.join(cls.sequence, 'scene.yaml')) as f:
            # OpenCV FileStorage YAML: drop its "%YAML:1.0" directive, which PyYAML rejects
            cls.scene = yaml.safe_load(''.join(l for l in f if not l.startswith('%YAML')))
        cls.rec, cls.player = sup.play_bag(NS, bag, cls.period)

    def test_01_one_dem_per_frame(self):
        self.assertEqual(len(self.player.published), FRAMES)
        self.assertEqual([round(m.info.header.stamp.to_sec(), 6) for _, m in self.rec.dems],
                         [round(s, 6) for _, s, _ in self.player.published])

    def test_02_heights_match_truth(self):
        _, dem = self.rec.dems[-1]
        _, odom = self.rec.odoms[-1]
        cam = odom.pose.pose.position
        h = sup.layer(dem, 'elevation')
        ob = sup.layer(dem, 'obstacle')
        x, y = sup.cell_centres(dem)
        xx, yy = np.meshgrid(x, y, indexing='ij')
        near = np.hypot(xx - cam.x, yy - cam.y) < 20.0
        footprint = np.zeros_like(near)
        for b in self.scene['boxes']:  # the obstacles' footprints (+1 m) are not terrain
            cx = b['center_x_m'] + b['velocity_x_m_per_s'] * 0.1 * (FRAMES - 1)
            footprint |= (np.abs(xx - cx) < b['length_m'] / 2 + 1.0) & \
                         (np.abs(yy - b['center_y_m']) < b['width_m'] / 2 + 1.0)
        sel = near & ~footprint & np.isfinite(h) & ~(ob >= 0.5)
        err = np.abs(h[sel])  # truth: z = 0
        med, p90 = float(np.median(err)), float(np.percentile(err, 90))
        rospy.loginfo('synthetic flat road: %d known cells within 20 m, |height error| median %.4f m, '
                      '90 %% %.4f m', sel.sum(), med, p90)
        self.assertGreater(sel.sum(), 400)
        self.assertLess(med, 0.02)
        self.assertLess(p90, 0.10)

    def test_03_trajectory_matches_truth(self):
        truth = sup.read_poses(os.path.join(self.sequence, 'poses.txt'))
        b_T_c = sup.base_T_camera()
        est0 = sup.pose_to_matrix(self.rec.odoms[0][1].pose.pose)
        errs = []
        for k, (_, od) in enumerate(self.rec.odoms):
            est = np.linalg.inv(est0).dot(sup.pose_to_matrix(od.pose.pose))
            tru = b_T_c.dot(truth[k]).dot(np.linalg.inv(b_T_c))
            errs.append(np.linalg.norm(est[:3, 3] - tru[:3, 3]))
        length = sum(np.linalg.norm(truth[k][:3, 3] - truth[k - 1][:3, 3]) for k in range(1, FRAMES))
        rospy.loginfo('synthetic: path %.2f m, max position error %.4f m (%.2f %% of the path)', length, max(errs),
                      100 * max(errs) / length)
        self.assertEqual(len(self.rec.odoms), FRAMES)
        self.assertLess(max(errs), 0.01 * length, 'odometry within 1 % of the path')

    def test_05_ground_attitude(self):
        # One message per mapped frame, stamped like its images, in the camera frame; an estimate
        # once 60 % of the 8 m disc around the camera is mapped (here from frame 8 of 10).
        att = [m for _, m in self.rec.attitudes]
        self.assertEqual([round(m.header.stamp.to_sec(), 6) for m in att],
                         [round(s, 6) for _, s, _ in self.player.published])
        self.assertEqual({m.header.frame_id for m in att}, {'left_camera_optical'}, 'the images\' frame')
        valid = [m for m in att if m.valid]
        self.assertFalse(att[0].valid, 'frame 0 knows only the ground ahead')
        self.assertTrue(np.isnan(att[0].height))
        for m in valid:
            rospy.loginfo('ground attitude: height %.4f m, pitch %.4f deg, roll %.4f deg, %d vertices', m.height,
                          np.degrees(m.pitch), np.degrees(m.roll), m.vertices)
        # truth: level camera 1.65 m above the plane z = 0
        self.assertGreaterEqual(len(valid), 2)
        for m in valid:
            self.assertLess(abs(m.height - 1.65), ATTITUDE_HEIGHT_TOL_M)
            self.assertLess(abs(np.degrees(m.pitch)), ATTITUDE_ANGLE_TOL_DEG)
            self.assertLess(abs(np.degrees(m.roll)), ATTITUDE_ANGLE_TOL_DEG)
        keys = {v.key for _, st in self.rec.diagnostic_statuses() for v in st.values}
        self.assertIn('camera above the local ground: height [m]', keys)
        self.assertIn('camera mount', keys)
        # the start-up mount from tf: the bag has base_link -> camera but no base_footprint, so pitch
        # and roll come from base_link and the height from ~nominal_height_m
        kv = {v.key: v.value for v in self.rec.diagnostic_statuses()[-1][1].values}
        self.assertRegex(kv['camera mount, start-up guess'],
                         r'^from tf base_link -> \S+ \(pitch, roll\): height 1\.65 m \(~nominal_height_m\), '
                         r'pitch down 0\.0 deg, roll 0\.0 deg$')

    def test_04_obstacle_is_lethal(self):
        _, occ = self.rec.occupancy[-1]
        info = occ.info
        data = np.array(occ.data, dtype=np.int16).reshape(info.height, info.width)  # rows along +y
        xs = info.origin.position.x + (np.arange(info.width) + 0.5) * info.resolution
        ys = info.origin.position.y + (np.arange(info.height) + 0.5) * info.resolution
        xx, yy = np.meshgrid(xs, ys)
        car = self.scene['boxes'][0]
        self.assertEqual(car['velocity_x_m_per_s'], 0.0)
        inside = (np.abs(xx - car['center_x_m']) <= car['length_m'] / 2) & \
                 (np.abs(yy - car['center_y_m']) <= car['width_m'] / 2)
        values = data[inside]
        lethal = np.count_nonzero(values == 100)
        # the driving corridor in front of the vehicle, away from every obstacle: traversable
        road = (xx > 5) & (xx < 15) & (np.abs(yy) < 1.0)
        road_values = data[road]
        known_road = road_values[road_values >= 0]
        rospy.loginfo('parked car footprint: %d cells, %d lethal, %d unknown; road corridor: %d known, '
                      'max cost %d', values.size, lethal, np.count_nonzero(values < 0), known_road.size,
                      known_road.max() if known_road.size else -1)
        self.assertGreater(values.size, 20)
        self.assertGreaterEqual(lethal, 0.3 * values.size, 'the parked car is lethal')
        self.assertGreater(known_road.size, 0.8 * road_values.size)
        self.assertLess(np.percentile(known_road, 95), 50, 'the road ahead is traversable')
        _, dem = self.rec.dems[-1]
        self.assertGreater(np.nansum(sup.layer(dem, 'obstacle') >= 0.5), 10)


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'synthetic', SyntheticTest, sys.argv)
