#!/usr/bin/env python3
"""rostest: the bundled KITTI sample (data/kitti_seq06_sample, 6 frames) through the nodelet.

A bag is written at test time with kitti_to_bag (with the static base_link -> camera tf) and
replayed frame by frame; checks one DEM per frame with every layer, finite heights, odometry and tf
odom -> base_link, the latency from image stamp to DEM, and the services (get_submap, save_map
against the offline runner's files, reset, load_map of the saved map and of the runner's)."""
import os
import sys
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
import yaml
from std_srvs.srv import Trigger

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sgd_rostest_support as sup  # noqa: E402
from stereo_ground_dem.srv import GetSubmap, LoadMap, SaveMap  # noqa: E402

# Measured: 0.037 m after the 6 frames (final position error 0.074 m); a 2x change either way fails.
POSITION_STD_RANGE_M = (0.018, 0.075)
NS = '/stereo_ground_dem'
LAYERS = ['elevation', 'variance', 'observations', 'slope', 'step', 'roughness', 'traversability',
          'traversability_confidence', 'obstacle', 'obstacle_height', 'residual', 'residual_outlier_rate', 'intensity']


class KittiSampleTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('kitti_sample_test')
        cls.period = rospy.get_param('~period_s', 1.5)
        cls.tmp = sup.temp_dir()
        cls.sequence = os.path.join(sup.source_dir(), 'data', 'kitti_seq06_sample')
        bag = sup.make_bag(cls.sequence, os.path.join(cls.tmp, 'kitti.bag'))
        cls.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(600))
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        cls.rec, cls.player = sup.play_bag(NS, bag, cls.period)

    def test_01_one_dem_per_frame(self):
        frames = len(self.player.published)
        self.assertEqual(frames, 6)
        stamps = [round(s, 6) for _, s, _ in self.player.published]
        dem_stamps = [round(m.info.header.stamp.to_sec(), 6) for _, m in self.rec.dems]
        self.assertEqual(dem_stamps, stamps, 'one DEM per frame, stamped like its images')
        self.assertEqual(len(self.rec.odoms), frames)
        self.assertEqual(len(self.rec.occupancy), frames)

    def test_02_layers_and_heights(self):
        _, last = self.rec.dems[-1]
        self.assertEqual(last.info.header.frame_id, 'odom')
        self.assertEqual(list(last.layers), LAYERS)
        self.assertEqual(list(last.basic_layers), ['elevation'])
        h = sup.finite_known(sup.layer(last, 'elevation'))
        self.assertGreater(h.size, 500, 'known cells in the local DEM')
        # the road is level: the camera is ~1.65 m above it, heights in odom (ground frame) near 0
        self.assertLess(abs(float(np.median(h))), 0.3)
        t = sup.layer(last, 'traversability')
        tk = t[np.isfinite(t)]
        self.assertTrue(((tk >= 0) & (tk <= 1)).all())
        # the ortho-texture's grey per cell: known where the ground is (the road seen up close), in
        # grey levels of the first frame's exposure
        g = sup.layer(last, 'intensity')
        both = np.isfinite(g) & np.isfinite(sup.layer(last, 'elevation'))
        self.assertGreater(np.count_nonzero(both), 0.5 * h.size, 'intensity where the elevation is known')
        self.assertTrue(((g[np.isfinite(g)] >= 0) & (g[np.isfinite(g)] <= 255)).all())
        self.assertGreater(float(np.std(g[both])), 3.0, 'the road has texture')
        # the photometric residual: known where the ground was seen; on the KITTI road a few grey
        # levels (the raw clip: median 6.8 grey), outlier rates within 0..1
        res = sup.layer(last, 'residual')
        rate = sup.layer(last, 'residual_outlier_rate')
        seen = np.isfinite(res)
        self.assertGreater(np.count_nonzero(seen & np.isfinite(sup.layer(last, 'elevation'))), 0.3 * h.size)
        self.assertLess(float(np.median(res[seen])), 15.0)
        self.assertLess(float(np.mean(rate[seen] > 0.5)), 0.3, 'most of the mapped ground is explained')
        occ = np.array(self.rec.occupancy[-1][1].data)
        self.assertTrue(((occ >= -1) & (occ <= 100)).all())
        self.assertGreater(np.count_nonzero(occ == 0) + np.count_nonzero((occ > 0) & (occ < 50)), 100,
                           'free road cells in the occupancy grid')

    def test_03_odometry_and_tf(self):
        _, o = self.rec.odoms[-1]
        self.assertEqual(o.header.frame_id, 'odom')
        self.assertEqual(o.child_frame_id, 'base_link')
        # ground truth: camera0_T_camera5 from poses.txt, base_link rigidly 1.65 m under the camera
        truth = sup.read_poses(os.path.join(self.sequence, 'poses.txt'))
        b_T_c = sup.base_T_camera()
        est0 = sup.pose_to_matrix(self.rec.odoms[0][1].pose.pose)
        err, length = [], 0.0
        for k, (_, od) in enumerate(self.rec.odoms):
            est = np.linalg.inv(est0).dot(sup.pose_to_matrix(od.pose.pose))
            tru = b_T_c.dot(truth[k]).dot(np.linalg.inv(b_T_c))
            err.append(np.linalg.norm(est[:3, 3] - tru[:3, 3]))
        length = sum(np.linalg.norm(truth[k][:3, 3] - truth[k - 1][:3, 3]) for k in range(1, len(self.rec.odoms)))
        rospy.loginfo('KITTI sample: path %.2f m, final position error %.3f m (%.1f %%)', length, err[-1],
                      100 * err[-1] / length)
        self.assertGreater(length, 2.0)
        self.assertLess(err[-1], 0.05 * length, 'odometry within 5 % of the true path')
        self.assertTrue(all(np.isfinite(o.pose.covariance)))
        # The pose covariance accumulates the per-frame motion covariance (the estimator's
        # information, scaled by ~motion_covariance_scale): its position standard deviation after
        # the sample is of the size of the errors (it was 0.5 m per frame from the fallback while
        # the information was lost).
        pos_std = np.sqrt(o.pose.covariance[0] + o.pose.covariance[7] + o.pose.covariance[14])
        rospy.loginfo('KITTI sample: position standard deviation %.3f m after %d frames', pos_std, len(self.rec.odoms))
        self.assertGreater(pos_std, POSITION_STD_RANGE_M[0])
        self.assertLess(pos_std, POSITION_STD_RANGE_M[1])
        # tf: odom -> base_link at the last frame's stamp equals the odometry
        t = self.tf_buffer.lookup_transform('odom', 'base_link', o.header.stamp, rospy.Duration(2.0))
        self.assertAlmostEqual(t.transform.translation.x, o.pose.pose.position.x, places=4)
        self.assertAlmostEqual(t.transform.translation.y, o.pose.pose.position.y, places=4)
        # base_link stays on the road: z near 0 in odom
        self.assertLess(abs(o.pose.pose.position.z), 0.2)

    def test_04_latency(self):
        stamps = {round(s, 6): w for _, s, w in self.player.published}
        lat = [(t - stamps[round(m.info.header.stamp.to_sec(), 6)]) * 1e3 for t, m in self.rec.dems]
        rospy.loginfo('latency images published -> DEM received [ms]: %s; median %.0f, max %.0f',
                      ', '.join('%.0f' % x for x in lat), np.median(lat), max(lat))
        with open(os.path.join(self.tmp, 'latency_ms.txt'), 'w') as f:
            f.write('\n'.join('%.1f' % x for x in lat) + '\n')
        self.assertEqual(len(lat), len(stamps))
        self.assertTrue(all(x > 0 for x in lat))
        self.assertLess(max(lat), self.period * 1e3, 'each frame is processed before the next arrives')
        statuses = self.rec.diagnostic_statuses()
        self.assertTrue(statuses, 'diagnostics published')
        kv = {v.key: v.value for v in statuses[-1][1].values}
        rospy.loginfo('diagnostics: processing mean %s ms, max %s ms', kv.get('processing mean [ms]'),
                      kv.get('processing max [ms]'))
        self.assertEqual(int(kv['processed frames']), 6)
        # the mount from tf (~footprint_frame base_link: level, 1.65 m under the camera)
        self.assertRegex(kv['camera mount, start-up guess'],
                         r'^from tf base_link -> \S+: height 1\.65 m, pitch down -?0\.0 deg, roll -?0\.0 deg$')
        self.assertEqual(int(kv['skipped (invalid input)']), 0)
        # the estimator's guards, as the offline runner's frames.csv has them for the same six frames:
        # no pre-alignment beyond the acceleration bound, frame 5's 2.4 cm shift from the prediction,
        # moving texture carried on frames 3-5 (11, 8, 20 pixels; the node's rig comes from camera_info,
        # which perturbs the counts a little: 26 pixels on frame 5 in the node, measured 2026-12-05)
        self.assertEqual(int(kv['pre-alignment beyond max_acceleration_mps2 (prediction kept)']), 0)
        self.assertAlmostEqual(float(kv['pre-alignment shift from the prediction last [m]']), 0.0242, delta=0.005)
        self.assertEqual(int(kv['frames skipping moving texture carried from the last two']), 3)
        self.assertAlmostEqual(int(kv['moving texture carried last [px at the test level]']), 23, delta=8)

    def test_05_submap(self):
        rospy.wait_for_service(NS + '/get_submap', 5.0)
        get = rospy.ServiceProxy(NS + '/get_submap', GetSubmap)
        _, o = self.rec.odoms[-1]
        p = o.pose.pose.position
        r = get(center_x=p.x + 15.0, center_y=p.y, length_x=20.0, length_y=10.0, layers=['elevation', 'obstacle'])
        self.assertTrue(r.success, r.message)
        self.assertEqual(list(r.map.layers), ['elevation', 'obstacle'])
        self.assertAlmostEqual(r.map.info.length_x, 20.5, places=6)  # 41 cells of 0.5 m
        self.assertAlmostEqual(r.map.info.pose.position.x, p.x + 15.0, delta=0.25)
        self.assertGreater(np.isfinite(sup.layer(r.map, 'elevation')).sum(), 100)
        bad = get(center_x=0.0, center_y=0.0, length_x=10.0, length_y=10.0, layers=['nonsense'])
        self.assertFalse(bad.success)
        self.assertIn('nonsense', bad.message)

    def test_06_save_map_like_offline_runner(self):
        rospy.wait_for_service(NS + '/save_map', 5.0)
        save = rospy.ServiceProxy(NS + '/save_map', SaveMap)
        out = os.path.join(self.tmp, 'saved')
        r = save(directory=out, pictures=True)
        self.assertTrue(r.success, r.message)
        self.assertTrue(os.path.isfile(os.path.join(out, 'state', 'state.yaml')), r.files)
        KittiSampleTest.saved_elevation = self.around_camera()
        offline = os.path.join(self.tmp, 'offline')
        sup.run([sup.executable('dem_offline'), '--sequence', self.sequence, '--out', offline, '--config',
                 os.path.join(sup.source_dir(), 'config', 'kitti.yaml'), '--quiet'])
        for name in ['dem.tif', 'dem.yaml', 'variance.tif', 'traversability.tif', 'dem_height.png',
                     'traversability.png', 'mesh.ply', 'intensity.tif', 'ortho.tif', 'ortho.png', 'residual.tif',
                     'residual_outlier_rate.tif']:
            self.assertTrue(os.path.isfile(os.path.join(out, name)), name)
            self.assertTrue(os.path.isfile(os.path.join(offline, name)), name)
        with open(os.path.join(out, 'dem.yaml')) as f:
            ros_yaml = yaml.safe_load(f)
        with open(os.path.join(offline, 'dem.yaml')) as f:
            off_yaml = yaml.safe_load(f)
        common = set(off_yaml) - {'mode', 'sequence', 'first_mapped_frame', 'first_frame', 'resumed_from'}  # the runner's own
        self.assertTrue(common <= set(ros_yaml), 'dem.yaml keys missing: %s' % (common - set(ros_yaml)))
        self.assertEqual(ros_yaml.get('resolution_m', ros_yaml.get('resolution')),
                         off_yaml.get('resolution_m', off_yaml.get('resolution')))

    def around_camera(self):
        _, o = self.rec.odoms[-1]
        p = o.pose.pose.position
        r = rospy.ServiceProxy(NS + '/get_submap', GetSubmap)(center_x=p.x + 15.0, center_y=p.y, length_x=20.0,
                                                              length_y=10.0, layers=['elevation'])
        self.assertTrue(r.success, r.message)
        return sup.layer(r.map, 'elevation')

    def test_07_reset(self):
        rospy.wait_for_service(NS + '/reset', 5.0)
        r = rospy.ServiceProxy(NS + '/reset', Trigger)()
        self.assertTrue(r.success)
        get = rospy.ServiceProxy(NS + '/get_submap', GetSubmap)
        e = get(center_x=0.0, center_y=0.0, length_x=10.0, length_y=10.0, layers=[])
        self.assertFalse(e.success)
        self.assertIn('empty', e.message)

    def test_08_load_map(self):
        rospy.wait_for_service(NS + '/load_map', 5.0)
        load = rospy.ServiceProxy(NS + '/load_map', LoadMap)
        r = load(directory=os.path.join(self.tmp, 'saved'))
        self.assertTrue(r.success, r.message)
        self.assertIn('loaded', r.message)
        # the map after the reset and the load is the one saved, cell for cell
        back = self.around_camera()
        saved = KittiSampleTest.saved_elevation
        self.assertEqual(back.shape, saved.shape)
        self.assertTrue(np.array_equal(np.isnan(back), np.isnan(saved)))
        self.assertEqual(np.nanmax(np.abs(back - saved)), 0.0)
        # the offline runner's saved state loads too (same parameters: config/kitti.yaml)
        r = load(directory=os.path.join(self.tmp, 'offline'))
        self.assertTrue(r.success, r.message)
        r = load(directory=os.path.join(self.tmp, 'nowhere'))
        self.assertFalse(r.success)
        self.assertIn('is not a directory', r.message)


if __name__ == '__main__':
    rostest.rosrun('stereo_ground_dem', 'kitti_sample', KittiSampleTest, sys.argv)
