#!/usr/bin/env python3
"""The ground's disparity in stereo mode on real pairs, against a LiDAR ground reference, beside
OpenCV StereoSGBM's own modes.

Usage:
  scripts/stereo_vs_lidar.py [--ref CLIP] [--frames 0,10,20] [--config config/kitti.yaml]
                             [--bin DIR] [--out DIR] [--min-depth 5] [--max-depth 40] [--max-lateral 6]
                             [--json FILE]

For each frame of a clip with a LiDAR ground reference (gt/lidar_ground.npz, as in
../shared/data/kitti_raw_0926_d0013_f000-079; its gt/README.md):
- dem_offline in its one-pair (stereo) mode on the frame's pair: the disparity its ground surface
  implies (dem_disparity_000000.png; none on obstacle pixels);
- OpenCV StereoSGBM with the settings of scripts/compare_sgbm.py (128 disparities, 5x5 blocks,
  P1 8*25, P2 32*25, uniqueness 10, speckle filter 100/2) in three of its modes: 3-way, the default
  (5 directions) and HH (8 directions, full);
- the reference: the centres of the LiDAR ground cells (`heights`), placed with the frame's
  LiDAR-fitted pose (`world_T_camera_lidar`, what `lidar_dem_eval.py --pose lidar` uses), 5-40 m
  deep, within --max-lateral (6 m) of the camera path (the road and its edges; 30 m: all the
  reference), inside the image and right of SGBM's 128 blind columns, and not behind an obstacle cell
  (`obstacle`: any on the segment from the camera to the cell, past 1 m from the camera and
  before 0.3 m from the cell, hides it; a 2.5-D test, obstacles taken as tall as the camera).
  A pixel hit by several cells keeps the nearest. d = fx * baseline / depth.

Prints, for each method and frame and over all frames: coverage (reference pixels where the
method has a disparity), median |d - d_lidar| [px] and D1 (KITTI's bad pixels: |error| > 3 px
and > 5 % of d_lidar) [%]; and, on the reference pixels where both have one, how far SGBM's modes
disagree with each other (D1 of one against the other): SGBM against itself, the yardstick of
issue 10's stereo-mode item.
"""
import argparse
import json
import os
import subprocess
import sys

import cv2
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MODES = (("sgbm_3way", cv2.STEREO_SGBM_MODE_SGBM_3WAY), ("sgbm_5dir", cv2.STEREO_SGBM_MODE_SGBM),
         ("sgbm_hh", cv2.STEREO_SGBM_MODE_HH))


def read_calib(path):
    """fx, cx, fy, cy and the baseline [m] from a KITTI odometry-style calib.txt (P0, P1 lines)."""
    rows = []
    for line in open(path):
        vals = line.split()
        if vals and vals[0].endswith(":"):
            vals = vals[1:]
        if len(vals) == 12:
            rows.append(np.array([float(v) for v in vals]).reshape(3, 4))
    if len(rows) < 2:
        sys.exit("stereo_vs_lidar: %s has no two 3x4 projection matrices" % path)
    p0, p1 = rows[0], rows[1]
    fx = p0[0, 0]
    return fx, p0[0, 2], p0[1, 1], p0[1, 2], (p0[0, 3] - p1[0, 3]) / fx


def sgbm(left, right, mode):
    m = cv2.StereoSGBM_create(0, 128, 5, 8 * 25, 32 * 25, 1, 0, 10, 100, 2, mode)
    d = m.compute(left, right).astype(np.float32) / 16.0
    d[d <= 0] = 0.0
    return d


def ground_cells(ref, max_lateral):
    """Rows and columns of the LiDAR ground cells within max_lateral [m] of the camera path."""
    r, c = np.nonzero(np.isfinite(ref["heights"]))
    near = path_distance(ref, r, c) <= max_lateral
    return r[near], c[near]


def path_distance(ref, r, c):
    """Horizontal distance [m] of cells (r, c) to the camera path (world_T_camera, 0.1 m steps)."""
    from scipy.spatial import cKDTree
    ox, oy, res = float(ref["origin"][0]), float(ref["origin"][1]), float(ref["resolution"])
    xy = ref["world_T_camera"][:, :2, 3]
    pts = [xy[0]]
    for a, b in zip(xy[:-1], xy[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / 0.1)))
        pts.extend(a + (b - a) * (i / n) for i in range(1, n + 1))
    return cKDTree(np.array(pts)).query(np.stack([ox + c * res, oy + r * res], axis=1))[0]


def reference_disparity(ref, cells, k, shape, calib, min_depth, max_depth):
    """The LiDAR ground's disparity image of frame k from the ground cells (r, c) (0 where there is none)."""
    fx, cx, fy, cy, baseline = calib
    h, w = shape
    heights, obstacle = ref["heights"], ref["obstacle"].astype(bool)
    ox, oy, res = float(ref["origin"][0]), float(ref["origin"][1]), float(ref["resolution"])
    world_T_cam = ref["world_T_camera_lidar"][k]
    cam_T_world = np.linalg.inv(world_T_cam)
    r, c = cells
    pw = np.stack([ox + c * res, oy + r * res, heights[r, c].astype(np.float64), np.ones(len(r))])
    pc = cam_T_world @ pw
    z = pc[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = fx * pc[0] / z + cx
        v = fy * pc[1] / z + cy
    keep = (z >= min_depth) & (z <= max_depth) & (u >= 128) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
    r, c, z, u, v = r[keep], c[keep], z[keep], u[keep], v[keep]
    # 2.5-D occlusion: obstacle cells on the segment camera -> cell (horizontal, world grid)
    cam = world_T_cam[:3, 3]
    px, py = ox + c * res, oy + r * res
    dist = np.hypot(px - cam[0], py - cam[1])
    hidden = np.zeros(len(r), bool)
    steps = np.arange(0.0, 1.0, 0.1 / max_depth)  # 0.1 m apart at the longest segment
    for s0 in range(0, len(r), 4000):
        sl = slice(s0, s0 + 4000)
        t = steps[None, :]
        along = t * dist[sl, None]
        sx = cam[0] + t * (px[sl, None] - cam[0])
        sy = cam[1] + t * (py[sl, None] - cam[1])
        ci = np.rint((sx - ox) / res).astype(np.int64)
        ri = np.rint((sy - oy) / res).astype(np.int64)
        inside = (ri >= 0) & (ri < obstacle.shape[0]) & (ci >= 0) & (ci < obstacle.shape[1])
        hit = np.zeros(ri.shape, bool)
        hit[inside] = obstacle[ri[inside], ci[inside]]
        hit &= (along > 1.0) & (along < dist[sl, None] - 0.3)
        hidden[sl] = hit.any(axis=1)
    z, u, v = z[~hidden], np.rint(u[~hidden]).astype(np.int64), np.rint(v[~hidden]).astype(np.int64)
    # the nearest cell per pixel
    pix = v * w + u
    order = np.lexsort((z, pix))
    first = np.ones(len(order), bool)
    first[1:] = pix[order][1:] != pix[order][:-1]
    sel = order[first]
    d = np.zeros(shape, np.float32)
    d.flat[pix[sel]] = fx * baseline / z[sel]
    return d, int(hidden.sum())


def scores(d, d_ref, mask):
    have = mask & (d > 0)
    if have.sum() == 0:
        return {"pixels": int(mask.sum()), "coverage_pct": 0.0, "median_px": float("nan"), "d1_pct": float("nan")}
    err = np.abs(d[have] - d_ref[have])
    bad = (err > 3.0) & (err > 0.05 * d_ref[have])
    return {"pixels": int(mask.sum()), "coverage_pct": 100.0 * have.sum() / mask.sum(),
            "median_px": float(np.median(err)), "d1_pct": 100.0 * bad.mean(), "err": err, "bad": bad}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default=os.path.join(REPO, "..", "shared", "data", "kitti_raw_0926_d0013_f000-079"))
    ap.add_argument("--frames", default="0,10,20,30,40,50,60,70")
    ap.add_argument("--config", default=os.path.join(REPO, "config", "kitti.yaml"))
    ap.add_argument("--bin", default=os.path.join(REPO, ".catkin_ws", "devel", "lib", "stereo_ground_dem"))
    ap.add_argument("--out", default="/tmp/sgd_stereo_vs_lidar")
    ap.add_argument("--min-depth", type=float, default=5.0)
    ap.add_argument("--max-depth", type=float, default=40.0)
    ap.add_argument("--max-lateral", type=float, default=6.0,
                    help="only ground cells within this distance [m] of the camera path (the road; 30: all)")
    ap.add_argument("--json")
    a = ap.parse_args()
    ref = np.load(os.path.join(a.ref, "gt", "lidar_ground.npz"))
    calib_path = os.path.join(a.ref, "calib.txt")
    calib = read_calib(calib_path)
    frames = [int(f) for f in a.frames.split(",") if f]
    cells = ground_cells(ref, a.max_lateral)
    methods = ["ours"] + [m for m, _ in MODES]
    pooled = {m: {"err": [], "bad": [], "have": 0, "pixels": 0} for m in methods}
    pooled_pairs = {}
    rows = []
    print("%-6s %-10s %7s %8s %9s %7s" % ("frame", "method", "pixels", "cov %", "med px", "D1 %"))
    for k in frames:
        lp = os.path.join(a.ref, "image_l", "%06d.png" % k)
        rp = os.path.join(a.ref, "image_r", "%06d.png" % k)
        left, right = cv2.imread(lp, cv2.IMREAD_GRAYSCALE), cv2.imread(rp, cv2.IMREAD_GRAYSCALE)
        if left is None or right is None:
            sys.exit("stereo_vs_lidar: cannot read frame %d's pair" % k)
        out = os.path.join(a.out, "%06d" % k)
        run = subprocess.run([os.path.join(a.bin, "dem_offline"), "--left", lp, "--right", rp, "--calib", calib_path,
                              "--config", a.config, "--out", out], capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit("stereo_vs_lidar: dem_offline failed on frame %d: %s" % (k, run.stderr.strip()))
        ours = cv2.imread(os.path.join(out, "dem_disparity_000000.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 256.0
        d_ref, hidden = reference_disparity(ref, cells, k, left.shape, calib, a.min_depth, a.max_depth)
        mask = d_ref > 0
        disp = {"ours": ours}
        for name, mode in MODES:
            disp[name] = sgbm(left, right, mode)
        for m in methods:
            s = scores(disp[m], d_ref, mask)
            print("%-6d %-10s %7d %8.1f %9.3f %7.2f" % (k, m, s["pixels"], s["coverage_pct"], s["median_px"], s["d1_pct"]))
            rows.append({"frame": k, "method": m, **{x: s[x] for x in ("pixels", "coverage_pct", "median_px", "d1_pct")}})
            if "err" in s:
                pooled[m]["err"].append(s["err"])
                pooled[m]["bad"].append(s["bad"])
                pooled[m]["have"] += len(s["err"])
            pooled[m]["pixels"] += s["pixels"]
        # SGBM against itself, and ours against SGBM 3-way, on the reference pixels where both have one
        for x, y in (("sgbm_3way", "sgbm_5dir"), ("sgbm_3way", "sgbm_hh"), ("sgbm_5dir", "sgbm_hh"), ("ours", "sgbm_3way")):
            both = mask & (disp[x] > 0) & (disp[y] > 0)
            e = np.abs(disp[x][both] - disp[y][both])
            bad = (e > 3.0) & (e > 0.05 * np.maximum(disp[x][both], disp[y][both]))
            p = pooled_pairs.setdefault(x + "~" + y, {"err": [], "bad": []})
            p["err"].append(e)
            p["bad"].append(bad)
        print("%-6d reference pixels %d (%d cells hidden behind obstacles)" % (k, int(mask.sum()), hidden))
    print("\nall frames %s, %g-%g m deep, within %g m of the path:" %
          (",".join(str(f) for f in frames), a.min_depth, a.max_depth, a.max_lateral))
    summary = {}
    for m in methods:
        err = np.concatenate(pooled[m]["err"]) if pooled[m]["err"] else np.zeros(0)
        bad = np.concatenate(pooled[m]["bad"]) if pooled[m]["bad"] else np.zeros(0, bool)
        cov = 100.0 * pooled[m]["have"] / max(1, pooled[m]["pixels"])
        med = float(np.median(err)) if len(err) else float("nan")
        d1 = 100.0 * bad.mean() if len(bad) else float("nan")
        summary[m] = {"coverage_pct": cov, "median_px": med, "d1_pct": d1}
        print("  %-10s against the LiDAR: coverage %5.1f %%, median %.3f px, D1 %5.2f %%" % (m, cov, med, d1))
    for pair, p in pooled_pairs.items():
        e, bad = np.concatenate(p["err"]), np.concatenate(p["bad"])
        summary[pair] = {"pixels": int(len(e)), "median_px": float(np.median(e)) if len(e) else float("nan"),
                         "d1_pct": 100.0 * bad.mean() if len(bad) else float("nan")}
        print("  %-20s against each other: %7d pixels, median %.3f px, D1 %5.2f %%" %
              (pair, len(e), summary[pair]["median_px"], summary[pair]["d1_pct"]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"frames": rows, "all": summary}, f, indent=1)


if __name__ == "__main__":
    main()
