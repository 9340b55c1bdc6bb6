#!/usr/bin/python3
"""How well trajectories agree with the images themselves: a yardstick that needs no GPS.

A real clip's ground truth comes from a GPS/INS (KITTI: OXTS RT3003). Its rotation is good; its
position wanders with the GPS (KITTI raw 0013 reports 0.15-0.30 m accuracy). This script scores
any trajectories of a KITTI-style folder (ground truth, dem_offline's, a peer's) against the images
with two tests that use neither the direct estimator nor the GPS:

1. Reprojection: Shi-Tomasi corners of frame k with an OpenCV SGBM disparity (4-30 m) are tracked
   frame by frame to k+n by pyramidal Lucas-Kanade (forward-backward error < 0.5 px). Their 3-D
   points are moved with the trajectory's relative pose T_{k+n}^-1 T_k and projected; the median
   distance to the tracked corners [px]. A trajectory consistent with the images scores near the
   tracking and stereo noise (~1-2 px at n = 3 on KITTI).
2. Road height, near against far: the road under a 0.5 m cell is measured by SGBM from 14-20 m
   (an earlier frame) and from 5-8 m (a later one), both placed with the trajectory; the median
   difference far - near [cm] per stretch. Stereo's own range bias makes it a constant; a
   trajectory whose vertical motion is wrong between the two frames makes it vary along the clip.
3. Direction of travel: the camera's displacement from frame k to k+s (s = --direction-stride)
   in camera k's frame, from the images alone by OpenCV's five-point essential matrix (RANSAC,
   0.5 px) of Shi-Tomasi corners tracked by Lucas-Kanade; per trajectory the median difference
   of its own displacement's yaw (right +) and elevation (up +) against it [deg]. A camera frame
   rotated against the true one by a constant mounting error (a GPS/INS-to-camera calibration)
   shows here as a constant offset, and bends every trajectory expressed in it: the end error of
   each other trajectory is printed against the first as given and against the first with its
   offset rotated out (its positions in the camera frame the images define).
4. Step length: the SGBM 3-D points of frame k's corners (4-40 m) and their Lucas-Kanade tracks in
   frame k+1 give the step by solvePnPRansac (1 px) and Levenberg-Marquardt; per trajectory the
   median ratio of its own step length to it. The PnP has a bias of its own (a rendered drive's
   exact poses score 0.9939): compare the trajectories with each other, not with 1.

Usage: scripts/trajectory_consistency.py --sequence DIR [--frames-apart N] [--direction-stride S] [--json FILE]
                                         NAME=TRAJECTORY [NAME=TRAJECTORY ...]
  TRAJECTORY: KITTI format (pose of left camera k in camera 0's frame), e.g. DIR/poses.txt or a
  dem_offline OUT/trajectory_kitti.txt. docs/results.md ("The real clips' ground truth") has the
  figures and commands.
"""
import argparse
import json
import os
import sys

import cv2
import numpy as np


def load_poses(path):
    poses = []
    for line in open(path):
        v = [float(x) for x in line.split()]
        if len(v) != 12:
            continue
        t = np.eye(4)
        t[:3, :4] = np.array(v).reshape(3, 4)
        poses.append(t)
    return poses


def load_calib(seq):
    rows = [list(map(float, l.split()[-12:])) for l in open(os.path.join(seq, "calib.txt")) if len(l.split()) >= 12][:2]
    if len(rows) < 2:
        sys.exit("trajectory_consistency: %s/calib.txt needs the two rectified projections" % seq)
    fx, cx, cy = rows[0][0], rows[0][2], rows[0][6]
    return fx, cx, cy, -(rows[1][3] - rows[0][3]) / fx


def folder(seq, names):
    for n in names:
        if os.path.isdir(os.path.join(seq, n)):
            return os.path.join(seq, n)
    sys.exit("trajectory_consistency: none of %s in %s" % (names, seq))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sequence", required=True)
    ap.add_argument("--frames-apart", type=int, default=3, help="n of the reprojection test")
    ap.add_argument("--direction-stride", type=int, default=4, help="s of the direction test")
    ap.add_argument("--stretch", type=int, default=5, help="frames per row of the tables")
    ap.add_argument("--json", help="write the figures as JSON")
    ap.add_argument("trajectories", nargs="+", metavar="NAME=TRAJECTORY")
    a = ap.parse_args()
    names, trajs = [], []
    for t in a.trajectories:
        if "=" not in t:
            sys.exit("trajectory_consistency: '%s' is not NAME=TRAJECTORY" % t)
        n, p = t.split("=", 1)
        names.append(n)
        trajs.append(load_poses(p))
    fx, cx, cy, baseline = load_calib(a.sequence)
    left_dir = folder(a.sequence, ["image_l", "image_0", "image_00/data"])
    right_dir = folder(a.sequence, ["image_r", "image_1", "image_01/data"])
    files = sorted(os.listdir(left_dir))
    n_frames = min([len(files)] + [len(t) for t in trajs])
    left = [cv2.imread(os.path.join(left_dir, f), cv2.IMREAD_GRAYSCALE) for f in files[:n_frames]]
    right = [cv2.imread(os.path.join(right_dir, f), cv2.IMREAD_GRAYSCALE) for f in files[:n_frames]]
    sgbm = cv2.StereoSGBM_create(0, 128, 5, P1=8 * 25, P2=32 * 25, disp12MaxDiff=1, uniquenessRatio=10,
                                 speckleWindowSize=100, speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    disp = [sgbm.compute(l, r).astype(np.float32) / 16.0 for l, r in zip(left, right)]

    # 1. reprojection of tracked corners over n frames
    n = a.frames_apart
    lk = dict(winSize=(21, 21), maxLevel=3, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))

    def stereo_corners(k, count, max_depth):  # frame k's corners with SGBM depth 4..max_depth m
        corners = cv2.goodFeaturesToTrack(left[k], count, 0.01, 8)
        if corners is None:
            return None, None
        p = corners.reshape(-1, 2)
        d = disp[k][np.round(p[:, 1]).astype(int), np.round(p[:, 0]).astype(int)]
        z = fx * baseline / np.maximum(d, 1e-3)
        ok = (d > 1.0) & (z > 4.0) & (z < max_depth)
        p, z = p[ok], z[ok]
        return p.astype(np.float32).reshape(-1, 1, 2), np.column_stack([(p[:, 0] - cx) * z / fx, (p[:, 1] - cy) * z / fx, z])

    def track(k, steps, points):  # frame by frame to k + steps, forward-backward error < 0.5 px
        cur, alive = points, np.ones(len(points), bool)
        for j in range(k, k + steps):
            nxt, st, _ = cv2.calcOpticalFlowPyrLK(left[j], left[j + 1], cur, None, **lk)
            back, st2, _ = cv2.calcOpticalFlowPyrLK(left[j + 1], left[j], nxt, None, **lk)
            alive &= (st.ravel() == 1) & (st2.ravel() == 1) & (np.linalg.norm((back - cur).reshape(-1, 2), axis=1) < 0.5)
            cur = nxt
        return cur.reshape(-1, 2), alive

    reproj = []  # (start frame, points, median error per trajectory)
    for k in range(n_frames - n):
        pts, xyz = stereo_corners(k, 1500, 30.0)
        if pts is None:
            continue
        cur, alive = track(k, n, pts)
        q, x = cur[alive], xyz[alive]
        if len(q) < 30:
            continue
        errs = []
        for t in trajs:
            rel = np.linalg.inv(t[k + n]) @ t[k]
            y = x @ rel[:3, :3].T + rel[:3, 3]
            u, v = fx * y[:, 0] / y[:, 2] + cx, fx * y[:, 1] / y[:, 2] + cy
            errs.append(float(np.median(np.hypot(u - q[:, 0], v - q[:, 1]))))
        reproj.append((k, len(q), errs))

    # 2. road heights seen from far and from near
    cell = 0.5
    heights = [dict() for _ in trajs]  # per trajectory: cell -> list of (frame, range, height)
    for k in range(n_frames):
        v, u = np.nonzero(disp[k] > 1.0)
        d = disp[k][v, u]
        z = fx * baseline / d
        x, y = (u - cx) * z / fx, (v - cy) * z / fx
        sel = (z > 4) & (z < 22) & (np.abs(x) < 2.5) & (y > 1.0) & (y < 2.3)  # the road ahead, below the camera
        x, y, z = x[sel], y[sel], z[sel]
        if len(x) < 100:
            continue
        plane = np.column_stack([x, z, np.ones_like(x)])
        w = np.ones(len(x), bool)
        for _ in range(4):  # robust plane fit: the road, without kerbs and cars
            coef, *_ = np.linalg.lstsq(plane[w], y[w], rcond=None)
            r = y - plane @ coef
            w = np.abs(r) < max(0.04, 2.5 * np.median(np.abs(r[w])))
        pts = np.vstack([x[w], y[w], z[w], np.ones(w.sum())])
        for i, t in enumerate(trajs):
            pw = t[k] @ pts  # camera 0's frame: y down
            ix, iz = np.floor(pw[0] / cell).astype(int), np.floor(pw[2] / cell).astype(int)
            order = np.lexsort((iz, ix))
            ix, iz, hh, rr = ix[order], iz[order], -pw[1][order], z[w][order]
            keys = ix.astype(np.int64) * 1000003 + iz
            cuts = np.r_[0, np.nonzero(np.diff(keys))[0] + 1, len(keys)]
            for s, e in zip(cuts[:-1], cuts[1:]):
                if e - s >= 5:
                    heights[i].setdefault((ix[s], iz[s]), []).append((k, float(np.median(rr[s:e])), float(np.median(hh[s:e]))))
    near_far = []  # per trajectory: (near frame, far - near [m])
    for h in heights:
        rows = []
        for obs in h.values():
            near = [(f, z) for f, r, z in obs if 5.0 <= r <= 8.0]
            far = [(f, z) for f, r, z in obs if 14.0 <= r <= 20.0]
            if near and far:
                rows.append((np.median([f for f, _ in near]), np.median([z for _, z in far]) - np.median([z for _, z in near])))
        near_far.append(np.array(rows).reshape(-1, 2))

    # 3. direction of travel from the essential matrix
    stride = a.direction_stride
    kmat = np.array([[fx, 0.0, cx], [0.0, fx, cy], [0.0, 0.0, 1.0]])

    def angles(d):  # yaw (right +), elevation (up +) [deg] of a displacement in the camera frame
        return np.degrees(np.arctan2(d[0], d[2])), np.degrees(np.arctan2(-d[1], d[2]))

    direction = []  # (frame, inliers, images' (yaw, elevation), per trajectory (yaw, elevation) - images')
    for k in range(n_frames - stride):
        if np.linalg.norm((np.linalg.inv(trajs[0][k]) @ trajs[0][k + stride])[:3, 3]) < 0.3:
            continue  # standing still: no direction
        corners = cv2.goodFeaturesToTrack(left[k], 2000, 0.01, 8)
        if corners is None:
            continue
        cur, alive = track(k, stride, corners)
        p0, p1 = corners.reshape(-1, 2)[alive], cur[alive]
        if len(p0) < 50:
            continue
        e, mask = cv2.findEssentialMat(p0, p1, kmat, cv2.RANSAC, 0.999, 0.5)
        if e is None or e.shape != (3, 3):
            continue
        inliers, r, t, mask = cv2.recoverPose(e, p0, p1, kmat, mask=mask)
        c = (-r.T @ t).ravel()  # camera k+s's centre in camera k's frame, unit length
        if inliers < 50 or c[2] <= 0.0:
            continue
        img = angles(c)
        offs = []
        for tr in trajs:
            yaw, el = angles((np.linalg.inv(tr[k]) @ tr[k + stride])[:3, 3])
            offs.append((yaw - img[0], el - img[1]))
        direction.append((k, int(inliers), img, offs))
    dir_offset = []  # per trajectory: median (yaw, elevation) offset against the images [deg]
    for i in range(len(names)):
        o = np.array([d[3][i] for d in direction]).reshape(-1, 2)
        dir_offset.append([float(np.median(o[:, 0])), float(np.median(o[:, 1]))] if len(o) else [float("nan")] * 2)
    # the first trajectory's positions in the camera frame the images define: its offset rotated out
    yaw0, el0 = np.radians(-dir_offset[0][0]), np.radians(-dir_offset[0][1])
    rot_yaw = np.array([[np.cos(yaw0), 0.0, np.sin(yaw0)], [0.0, 1.0, 0.0], [-np.sin(yaw0), 0.0, np.cos(yaw0)]])
    rot_el = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(el0), -np.sin(el0)], [0.0, np.sin(el0), np.cos(el0)]])
    first = np.array([t[:3, 3] for t in trajs[0][:n_frames]])
    first_rotated = first @ (rot_el @ rot_yaw).T
    path = float(np.sum(np.linalg.norm(np.diff(first, axis=0), axis=1)))
    end_error = []  # per other trajectory: end error [m] against the first, as given and rotated
    for t in trajs[1:]:
        end = t[n_frames - 1][:3, 3]
        end_error.append((float(np.linalg.norm(end - first[-1])), float(np.linalg.norm(end - first_rotated[-1]))))

    # 4. step length against a stereo PnP of the images
    length_ratio = [[] for _ in trajs]
    for k in range(n_frames - 1):
        pts, xyz = stereo_corners(k, 2000, 40.0)
        if pts is None:
            continue
        cur, alive = track(k, 1, pts)
        if alive.sum() < 50:
            continue
        obj, img = xyz[alive].astype(np.float64), cur[alive].astype(np.float64)
        found, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, kmat, None, iterationsCount=300, reprojectionError=1.0)
        if not found or inl is None or len(inl) < 30:
            continue
        rvec, tvec = cv2.solvePnPRefineLM(obj[inl[:, 0]], img[inl[:, 0]], kmat, None, rvec, tvec)
        step = float(np.linalg.norm(tvec))  # |t| = |camera k+1's centre| in camera k's frame
        if step < 0.3:
            continue
        for i, tr in enumerate(trajs):
            length_ratio[i].append(float(np.linalg.norm((np.linalg.inv(tr[k]) @ tr[k + 1])[:3, 3])) / step)
    step_ratio = [float(np.median(r)) if r else float("nan") for r in length_ratio]

    width = max(12, max(len(s) for s in names))
    print(f"{a.sequence}: {n_frames} frames")
    print(f"\n1. reprojection error of tracked SGBM corners over {n} frames, median [px], by start frame")
    print("frames   points  " + "  ".join(f"{s:>{width}s}" for s in names))
    rk = np.array([r[0] for r in reproj])
    for s in range(0, n_frames, a.stretch):
        m = (rk >= s) & (rk < s + a.stretch)
        if m.any():
            sel = [reproj[i] for i in np.nonzero(m)[0]]
            print(f"{s:3d}-{s + a.stretch - 1:<3d} {int(np.median([r[1] for r in sel])):6d}  " +
                  "  ".join(f"{np.median([r[2][i] for r in sel]):{width}.2f}" for i in range(len(names))))
    overall = [float(np.median([r[2][i] for r in reproj])) for i in range(len(names))] if reproj else []
    print("all              " + "  ".join(f"{v:{width}.2f}" for v in overall))
    print("\n2. road height seen from 14-20 m minus from 5-8 m, median [cm], by the nearer frame")
    print("frames           " + "  ".join(f"{s:>{width}s}" for s in names))
    spread = []
    table = []
    for s in range(0, n_frames, a.stretch):
        row = []
        for nf in near_far:
            m = (nf[:, 0] >= s) & (nf[:, 0] < s + a.stretch)
            row.append(100 * float(np.median(nf[m, 1])) if m.sum() >= 5 else float("nan"))
        if any(np.isfinite(row)):
            table.append((s, row))
            print(f"{s:3d}-{s + a.stretch - 1:<3d}          " + "  ".join(f"{v:{width}.1f}" for v in row))
    for i in range(len(names)):
        col = np.array([r[i] for _, r in table])
        col = col[np.isfinite(col)]
        spread.append(float(col.max() - col.min()) if len(col) else float("nan"))
    print("range (max-min)  " + "  ".join(f"{v:{width}.1f}" for v in spread))
    print(f"\n3. direction of travel over {stride} frames against the images' (essential matrix), "
          f"median of the trajectory's minus the images' [deg]; {len(direction)} frames")
    print("                 " + "  ".join(f"{s:>{width}s}" for s in names))
    print("yaw (right +)    " + "  ".join(f"{o[0]:{width}.3f}" for o in dir_offset))
    print("elevation (up +) " + "  ".join(f"{o[1]:{width}.3f}" for o in dir_offset))
    for name, (given, rotated) in zip(names[1:], end_error):
        print(f"end error of {name} against {names[0]}: {given:.3f} m = {100 * given / path:.2f} % of {path:.1f} m; "
              f"against {names[0]} with its offset rotated out: {rotated:.3f} m = {100 * rotated / path:.2f} %")
    print(f"\n4. step length against the images' (stereo PnP), median ratio; {len(length_ratio[0])} frames")
    print("                 " + "  ".join(f"{s:>{width}s}" for s in names))
    print("length / PnP's   " + "  ".join(f"{v:{width}.4f}" for v in step_ratio))
    if a.json:
        json.dump(dict(sequence=a.sequence, frames=n_frames, frames_apart=n, names=names,
                       reprojection_px=dict(zip(names, overall)),
                       reprojection_by_start=[dict(frame=r[0], points=r[1], px=dict(zip(names, r[2]))) for r in reproj],
                       near_minus_far_cm=[dict(frame=s, cm=dict(zip(names, row))) for s, row in table],
                       near_minus_far_range_cm=dict(zip(names, spread)),
                       direction_stride=stride, direction_frames=len(direction),
                       direction_offset_deg={n: dict(yaw=o[0], elevation=o[1]) for n, o in zip(names, dir_offset)},
                       end_error_m={n: dict(as_given=g, offset_rotated_out=r) for n, (g, r) in zip(names[1:], end_error)},
                       path_m=path, step_length_over_pnp=dict(zip(names, step_ratio))),
                  open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
