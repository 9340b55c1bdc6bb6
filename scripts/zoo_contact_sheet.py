#!/usr/bin/env python3
"""Contact sheet of the scene zoo (docs/zoo.md): the left image of frame 0 and of a middle frame of
every scene, downsized and labelled, two scenes per row.

    for s in flat bump offroad crest sag banked_curve bounce tight_curve ramp rolling shadows traffic; do
      sgd_render --scene $s --frames 40 --out /tmp/zoo/$s --quiet; done
    scripts/zoo_contact_sheet.py --root /tmp/zoo --out docs/images/zoo_contact_sheet.jpg
"""
import argparse
import os
import sys

import cv2
import numpy as np

SCENES = ["flat", "bump", "offroad", "crest", "sag", "banked_curve", "bounce", "tight_curve",
          "ramp", "rolling", "shadows", "traffic"]


def tile(path, scale, label):
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        sys.exit(f"zoo_contact_sheet: cannot read {path}")
    img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    cv2.rectangle(img, (0, 0), (len(label) * 10 + 10, 22), (0, 0, 0), -1)
    cv2.putText(img, label, (5, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", required=True, help="folder holding one sgd_render folder per scene")
    ap.add_argument("--out", required=True, help="output picture (.jpg)")
    ap.add_argument("--middle", type=int, default=20, help="the middle frame (default 20)")
    ap.add_argument("--scale", type=float, default=0.35, help="downsizing factor (default 0.35)")
    ap.add_argument("--per-row", type=int, default=2, help="scenes per row (default 2)")
    a = ap.parse_args()
    gap = 6
    tiles = []
    for s in SCENES:
        pair = [tile(os.path.join(a.root, s, "image_0", f"{k:06d}.png"), a.scale, f"{s}  frame {k}")
                for k in (0, a.middle)]
        h = pair[0].shape[0]
        tiles.append(np.hstack([pair[0], np.full((h, gap, 3), 255, np.uint8), pair[1]]))
    h, w = tiles[0].shape[:2]
    rows = []
    for i in range(0, len(tiles), a.per_row):
        row = tiles[i:i + a.per_row]
        row += [np.full((h, w, 3), 255, np.uint8)] * (a.per_row - len(row))
        parts = []
        for t in row:
            parts += [t, np.full((h, 3 * gap, 3), 255, np.uint8)]
        rows += [np.hstack(parts[:-1]), np.full((gap, parts[0].shape[1] * a.per_row + 3 * gap * (a.per_row - 1), 3), 255, np.uint8)]
    sheet = np.vstack(rows[:-1])
    cv2.imwrite(a.out, sheet, [cv2.IMWRITE_JPEG_QUALITY, 80])
    print(f"zoo_contact_sheet: wrote {a.out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
