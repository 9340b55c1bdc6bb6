#!/usr/bin/python3
"""A feature-based stereo visual odometry peer built from OpenCV pieces, for comparison with the
direct estimator on the same KITTI frames (docs/results.md).

Per frame: StereoSGBM disparity of the previous pair, Shi-Tomasi corners tracked into the current
left image with pyramidal Lucas-Kanade (forward-backward check < 0.5 px), 3-D points up to 40 m,
solvePnPRansac (1 px) + Levenberg-Marquardt refinement. Writes the trajectory in KITTI format
(pose of left camera k in camera 0's frame) so `sgd_evaluate` can score it like ours.

Usage: scripts/stereo_vo_peer.py SEQUENCE_DIR OUT_DIR [N_FRAMES]
  SEQUENCE_DIR: calib.txt (P0/P1), image_l/ or image_0/, image_r/ or image_1/
  then: sgd_evaluate --sequence SEQUENCE_DIR --result OUT_DIR
"""
import os
import sys

import cv2
import numpy as np


def folder(d, names):
    for n in names:
        if os.path.isdir(os.path.join(d, n)):
            return os.path.join(d, n)
    sys.exit("stereo_vo_peer: none of %s in %s" % (names, d))


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    d, out = sys.argv[1], sys.argv[2]
    lines = [l.split(":", 1)[-1].split() for l in open(os.path.join(d, "calib.txt")) if l.strip()]
    P = [np.array(l, float).reshape(3, 4) for l in lines[:2]]
    K = P[0][:, :3]
    b = -P[1][0, 3] / K[0, 0]
    ldir, rdir = folder(d, ["image_l", "image_0", "image_2"]), folder(d, ["image_r", "image_1", "image_3"])
    names = sorted(os.listdir(ldir))
    n = min(int(sys.argv[3]), len(names)) if len(sys.argv) > 3 else len(names)
    sgbm = cv2.StereoSGBM_create(0, 128, 5, 8 * 25, 32 * 25, 1, 0, 10, 100, 2, cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    T = np.eye(4)
    traj = [T.copy()]
    L0 = cv2.imread(os.path.join(ldir, names[0]), 0)
    R0 = cv2.imread(os.path.join(rdir, names[0]), 0)
    for i in range(1, n):
        L1 = cv2.imread(os.path.join(ldir, names[i]), 0)
        disp = sgbm.compute(L0, R0).astype(np.float32) / 16
        pts = cv2.goodFeaturesToTrack(L0, 3000, 0.01, 7)
        p1, st, _ = cv2.calcOpticalFlowPyrLK(L0, L1, pts, None, winSize=(21, 21), maxLevel=4)
        p0b, st2, _ = cv2.calcOpticalFlowPyrLK(L1, L0, p1, None, winSize=(21, 21), maxLevel=4)
        ok = (st[:, 0] == 1) & (st2[:, 0] == 1) & (np.linalg.norm(p0b - pts, axis=2)[:, 0] < 0.5)
        P3, P2 = [], []
        for (u, v), q, o in zip(pts[:, 0], p1[:, 0], ok):
            if not o:
                continue
            dd = disp[int(round(v)), int(round(u))]
            if dd < 1:
                continue
            Z = K[0, 0] * b / dd
            if Z > 40:
                continue
            P3.append([(u - K[0, 2]) * Z / K[0, 0], (v - K[1, 2]) * Z / K[1, 1], Z])
            P2.append(q)
        P3, P2 = np.array(P3), np.array(P2)
        _, rv, tv, inl = cv2.solvePnPRansac(P3, P2, K, None, reprojectionError=1.0, iterationsCount=300)
        rv, tv = cv2.solvePnPRefineLM(P3[inl[:, 0]], P2[inl[:, 0]], K, None, rv, tv)
        R, _ = cv2.Rodrigues(rv)
        Tk = np.eye(4)
        Tk[:3, :3], Tk[:3, 3] = R, tv[:, 0]  # camera k <- camera k-1
        T = T @ np.linalg.inv(Tk)
        traj.append(T.copy())
        L0, R0 = L1, cv2.imread(os.path.join(rdir, names[i]), 0)
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "trajectory_kitti.txt"), "w") as f:
        for t in traj:
            f.write(" ".join("%.9g" % x for x in t[:3].reshape(-1)) + "\n")
    print("wrote %s/trajectory_kitti.txt (%d frames)" % (out, len(traj)))


if __name__ == "__main__":
    main()
