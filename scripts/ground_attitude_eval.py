#!/usr/bin/env python3
"""Scores the camera's attitude above the local ground (dem_offline's frames.csv columns
ground_height_m, ground_pitch_deg, ground_roll_deg) against a LiDAR ground reference
(gt/lidar_ground.npz of ../shared/data/kitti_raw_0926_d0013_f000-079, see its gt/README.md).

The reference attitude of frame k is the same fit the estimator makes (GroundAttitudeEstimator):
a least-squares plane through the reference's ground cells within --radius of the camera's nadir,
then the camera's height along the plane normal and its pitch (about the left axis, positive
looking down) and roll (Z-Y-X, positive with the left side up) relative to it, with the camera
pose world_T_camera_lidar[k] (the OXTS pose with the attitude fitted to the scans) or, with
--pose oxts, world_T_camera[k]. Only frames with an estimate (not NaN) are scored.

Usage: ground_attitude_eval.py --ref SEQUENCE_DIR --est DEM_OFFLINE_OUT [--pose lidar|oxts] [--json]
Needs numpy."""
import argparse
import csv
import json
import os
import sys

import numpy as np


def plane_attitude(heights, x, y, world_T_camera, radius):
    p = world_T_camera[:3, 3]
    m = np.isfinite(heights) & ((x - p[0]) ** 2 + (y - p[1]) ** 2 < radius * radius)
    if m.sum() < 100:
        return None
    a = np.c_[x[m], y[m], np.ones(m.sum())]
    abc = np.linalg.lstsq(a, heights[m], rcond=None)[0]
    n = np.array([-abc[0], -abc[1], 1.0])
    n /= np.linalg.norm(n)
    r = world_T_camera[:3, :3]
    forward, left, up = r[:, 2], -r[:, 0], -r[:, 1]
    height = (p[2] - (abc[0] * p[0] + abc[1] * p[1] + abc[2])) * n[2]
    return height, np.degrees(np.arcsin(np.clip(-n.dot(forward), -1, 1))), np.degrees(np.arctan2(n.dot(left), n.dot(up)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--ref', required=True, help='sequence folder with gt/lidar_ground.npz')
    ap.add_argument('--est', required=True, help="dem_offline's output folder (frames.csv)")
    ap.add_argument('--pose', choices=['lidar', 'oxts'], default='lidar')
    ap.add_argument('--radius', type=float, default=8.0, help='as GroundAttitudeOptions::radius_m [m]')
    ap.add_argument('--json', action='store_true')
    a = ap.parse_args()
    ref = np.load(os.path.join(a.ref, 'gt', 'lidar_ground.npz'))
    heights, origin, res = ref['heights'], ref['origin'], float(ref['resolution'])
    poses = ref['world_T_camera_lidar' if a.pose == 'lidar' else 'world_T_camera']
    rows, cols = np.mgrid[0:heights.shape[0], 0:heights.shape[1]]
    x, y = origin[0] + cols * res, origin[1] + rows * res
    with open(os.path.join(a.est, 'frames.csv')) as f:
        frames = list(csv.DictReader(f))
    err = []
    for k, fr in enumerate(frames):
        est = [float(fr.get(c, 'nan')) for c in ('ground_height_m', 'ground_pitch_deg', 'ground_roll_deg')]
        if k >= len(poses) or not all(np.isfinite(est)):
            continue
        t = plane_attitude(heights, x, y, poses[k], a.radius)
        if t is not None:
            err.append([est[i] - t[i] for i in range(3)])
    if not err:
        sys.exit('ground_attitude_eval: no frame with an estimate and a reference')
    e = np.array(err)
    out = {'frames': len(frames), 'scored': len(e), 'pose': a.pose}
    for i, name in enumerate(['height_m', 'pitch_deg', 'roll_deg']):
        out[name] = {'median': float(np.median(e[:, i])), 'median_abs': float(np.median(np.abs(e[:, i]))),
                     'max_abs': float(np.abs(e[:, i]).max())}
    if a.json:
        print(json.dumps(out))
    else:
        print('%d of %d frames scored (pose %s); error = estimate - reference' % (len(e), len(frames), a.pose))
        for name in ['height_m', 'pitch_deg', 'roll_deg']:
            s = out[name]
            print('  %-9s median %+.3f  median |.| %.3f  max |.| %.3f' % (name, s['median'], s['median_abs'], s['max_abs']))


if __name__ == '__main__':
    main()
