#!/usr/bin/python3
"""Make a copy of a sequence in which tracking is lost for a few frames: frames FIRST .. FIRST+COUNT-1
are replaced by their own pair turned upside down (rotated 180 deg, left and right swapped so that
the disparities keep their sign). A consistent stereo pair of a world the map does not hold: the
estimator must refuse to fuse those frames and find its way back afterwards (re-localization,
docs/results.md "Lost for three frames"). Everything else (calibration, stamps, poses) is linked.

Usage: scripts/make_lost_stretch.py --sequence SEQ --out OUT [--first 12] [--count 3]
Works with the zoo's layout (image_0 / image_1) and the KITTI clips' (image_l / image_r).
"""
import argparse
import os
import sys

import cv2

PAIRS = {"image_0": "image_1", "image_1": "image_0", "image_l": "image_r", "image_r": "image_l"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequence", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--first", type=int, default=12, help="first replaced frame (0-based)")
    ap.add_argument("--count", type=int, default=3, help="replaced frames")
    a = ap.parse_args()
    seq = os.path.abspath(a.sequence)
    dirs = [d for d in PAIRS if os.path.isdir(os.path.join(seq, d))]
    if len(dirs) != 2:
        sys.exit("make_lost_stretch: %s has no image_0/image_1 or image_l/image_r" % seq)
    os.makedirs(a.out, exist_ok=True)
    for name in os.listdir(seq):
        src = os.path.join(seq, name)
        dst = os.path.join(a.out, name)
        if name not in dirs:
            if not os.path.lexists(dst):
                os.symlink(src, dst)
            continue
        os.makedirs(dst, exist_ok=True)
        files = sorted(os.listdir(src))
        if a.first + a.count > len(files):
            sys.exit("make_lost_stretch: %s has %d frames" % (src, len(files)))
        for i, f in enumerate(files):
            d = os.path.join(dst, f)
            if os.path.lexists(d):
                os.remove(d)
            if a.first <= i < a.first + a.count:
                other = cv2.imread(os.path.join(seq, PAIRS[name], f), cv2.IMREAD_UNCHANGED)
                if other is None:
                    sys.exit("make_lost_stretch: cannot read %s" % os.path.join(seq, PAIRS[name], f))
                cv2.imwrite(d, cv2.rotate(other, cv2.ROTATE_180))
            else:
                os.symlink(os.path.join(src, f), d)
    print("%s: frames %d-%d upside down" % (a.out, a.first, a.first + a.count - 1))


if __name__ == "__main__":
    main()
