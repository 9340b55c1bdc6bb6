#!/usr/bin/python3
"""The LiDAR height error of a dem_offline output along the drive, and with the along-track datum
removed.

../shared/tools/lidar_dem_eval.py scores every DEM vertex against the LiDAR ground reference of a
KITTI raw clip. The reference takes its height datum from the GPS/INS trajectory (its gt/README.md:
close-range returns placed with the OXTS poses), so a wander of the GPS altitude shows as a height
error that changes along the drive (docs/results.md, "The real clips' ground truth"). This prints
the signed error per stretch of frames (vertices by their nearest camera), then the error with a
running median over +-2 frames removed: what is left is the map's shape where the vehicle drives
(cross slope, kerbs, obstacles' edges), not its datum.

Usage: scripts/lidar_along_track.py --ref CLIP_DIR --est OUT [--pose gt|lidar] [--stretch N] [--json FILE]
"""
import argparse
import json
import os
import sys

import numpy as np
from scipy.spatial import cKDTree

SHARED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), os.pardir, "shared")
sys.path.insert(0, os.path.join(SHARED, "tools"))
import lidar_dem_eval  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", required=True)
    ap.add_argument("--est", required=True)
    ap.add_argument("--pose", default="lidar", choices=["gt", "lidar"])
    ap.add_argument("--stretch", type=int, default=5)
    ap.add_argument("--json")
    a = ap.parse_args()
    res, _ = lidar_dem_eval.evaluate(a.ref, a.est, pose=a.pose)
    xy, err, cams = res["_world"]["xy"], res["_world"]["err"], res["_world"]["cams"]
    nearest = cKDTree(cams).query(xy.T)[1]
    rows = []
    print("frames    vertices  median error [cm]  median |error| [cm]")
    for s in range(0, len(cams), a.stretch):
        m = (nearest >= s) & (nearest < s + a.stretch)
        if m.sum() < 10:
            continue
        rows.append(dict(frames=[s, s + a.stretch - 1], n=int(m.sum()), median_cm=100 * float(np.median(err[m])),
                         median_abs_cm=100 * float(np.median(np.abs(err[m])))))
        print(f"{s:3d}-{s + a.stretch - 1:<3d}  {m.sum():8d}  {rows[-1]['median_cm']:17.1f}  {rows[-1]['median_abs_cm']:19.1f}")
    detrended = []
    for k in range(len(cams)):
        here, around = nearest == k, np.abs(nearest - k) <= 2
        if here.any() and around.sum() >= 10:
            detrended.append(err[here] - np.median(err[around]))
    d = np.abs(np.concatenate(detrended)) if detrended else np.array([np.nan])
    out = dict(all_median_abs_cm=100 * float(np.median(np.abs(err))), detrended_median_abs_cm=100 * float(np.median(d)),
               detrended_p95_cm=100 * float(np.percentile(d, 95)), vertices=int(len(err)), by_stretch=rows)
    print(f"all: median |error| {out['all_median_abs_cm']:.1f} cm; with the along-track datum removed (running median "
          f"over +-2 frames): median {out['detrended_median_abs_cm']:.1f} cm, 95th {out['detrended_p95_cm']:.1f} cm "
          f"({out['vertices']} vertices)")
    if a.json:
        json.dump(out, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
