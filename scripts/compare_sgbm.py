#!/usr/bin/python3
"""The DEM-implied disparity of a stereo pair against OpenCV's StereoSGBM on the same pixels.

Usage:
  scripts/compare_sgbm.py --left L.png --right R.png --disparity OUT/dem_disparity_000000.png
                          [--polygon road_polygon.txt] [--picture sgbm.png]

--disparity is the KITTI-format (uint16, d * 256, 0 = none) picture written by dem_offline.
--polygon restricts the comparison to pixels inside an outline (one "u v" per line, # comments),
e.g. data/kitti_seq06_sample/road_polygon_000000.txt. Prints one line of figures:
pixels compared, SGBM coverage of the DEM's pixels, median |d_dem - d_sgbm| [px], share over 3 px.
SGBM settings: 128 disparities, 5x5 blocks, P1 = 8*25, P2 = 32*25, uniqueness 10, speckle
filter 100/2, 3-way mode (a common KITTI setting).
"""
import argparse
import sys

import cv2
import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--left", required=True)
    ap.add_argument("--right", required=True)
    ap.add_argument("--disparity", required=True)
    ap.add_argument("--polygon")
    ap.add_argument("--picture")
    a = ap.parse_args()
    left = cv2.imread(a.left, cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(a.right, cv2.IMREAD_GRAYSCALE)
    dem = cv2.imread(a.disparity, cv2.IMREAD_UNCHANGED)
    for name, im in (("left", left), ("right", right), ("disparity", dem)):
        if im is None:
            sys.exit("compare_sgbm: cannot read the %s image" % name)
    if dem.dtype != np.uint16 or dem.shape != left.shape or right.shape != left.shape:
        sys.exit("compare_sgbm: the images and the uint16 disparity must have the same size")
    d_dem = dem.astype(np.float32) / 256.0
    sgbm = cv2.StereoSGBM_create(0, 128, 5, 8 * 25, 32 * 25, 1, 0, 10, 100, 2, cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    d_sgbm = sgbm.compute(left, right).astype(np.float32) / 16.0
    region = np.ones(left.shape, bool)
    if a.polygon:
        pts = np.loadtxt(a.polygon, comments="#").astype(np.int32)
        mask = np.zeros(left.shape, np.uint8)
        cv2.fillPoly(mask, [pts.reshape(-1, 1, 2)], 255)
        region = mask > 0
    have_dem = region & (d_dem > 0)
    both = have_dem & (d_sgbm > 0)
    if both.sum() == 0:
        sys.exit("compare_sgbm: no pixel has both disparities")
    diff = np.abs(d_dem[both] - d_sgbm[both])
    print("pixels %d  sgbm_coverage %.1f%%  median_abs_diff_px %.3f  over_3px %.2f%%  (dem pixels in region %d)" %
          (both.sum(), 100.0 * both.sum() / have_dem.sum(), np.median(diff), 100.0 * (diff > 3).mean(), have_dem.sum()))
    if a.picture:
        # left: the image with |difference| coloured where both exist (green small .. red >= 3 px)
        vis = cv2.cvtColor(left, cv2.COLOR_GRAY2BGR)
        err = np.zeros(left.shape, np.float32)
        err[both] = np.minimum(np.abs(d_dem[both] - d_sgbm[both]) / 3.0, 1.0)
        colour = np.stack([np.zeros_like(err), 255 * (1 - err), 255 * err], axis=-1).astype(np.uint8)
        vis[both] = (0.4 * vis[both] + 0.6 * colour[both]).astype(np.uint8)
        if a.polygon:
            cv2.polylines(vis, [pts.reshape(-1, 1, 2)], True, (255, 255, 0), 1)
        cv2.putText(vis, "|d_DEM - d_SGBM|: green 0 .. red >= 3 px", (10, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                    (255, 255, 255), 2)
        cv2.imwrite(a.picture, vis)


if __name__ == "__main__":
    main()
