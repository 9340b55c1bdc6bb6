#!/usr/bin/python3
"""Run dem_offline on the development zoo and both real KITTI clips and print one table.

Every rendered scene of docs/zoo.md (rendered into --scenes on first use with sgd_render, and again
when another build of the renderer made the cached one: render_stamp.txt) and the
two clips in ../shared/data: end-point drift, end rotation error, height errors of the vertices
seen within 20 m (median / 95th, synthetic truth) or against the LiDAR reference (raw clip, all
scored vertices, --pose lidar), coverage, failed frames and the median time per frame.

Usage: scripts/evaluate_zoo.py [--only a,b] [--config FILE] [--frames N] [--seed S] [--scenes DIR]
                               [--out DIR] [--json FILE] [--bin DIR]
"""
import argparse
import hashlib
import json
import shutil
import os
import subprocess
import sys

import yaml

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(REPO), "shared")
SCENES = ["flat", "bump", "offroad", "crest", "sag", "banked_curve", "bounce", "tight_curve", "ramp", "rolling",
          "shadows", "traffic"]
# The LiDAR scorer needs numpy/scipy: Debian's python3 has them (install_deps.sh), a pyenv or
# virtualenv python3 that runs this script may not.
PYTHON = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable
CLIPS = {"kitti_raw_0013": os.path.join(SHARED, "data", "kitti_raw_0926_d0013_f000-079"),
         "kitti_odom_06": os.path.join(SHARED, "data", "kitti_odom_seq06_f000-050")}


def renderer_stamp(bin_dir, frames, seed):
    """What made a rendered scene: the renderer's binary and its library (hashed), frames and seed.

    A scene cached in --scenes by another build of the renderer is rendered again: an older render
    kept in /tmp would otherwise be scored as if it were today's scene."""
    h = hashlib.sha1()
    lib = os.path.join(os.path.dirname(bin_dir), "libstereo_ground_dem_sim.so")
    for path in (os.path.join(bin_dir, "sgd_render"), lib):
        if os.path.exists(path):
            with open(path, "rb") as f:
                h.update(f.read())
    return f"{h.hexdigest()} frames {frames} seed {seed}\n"


def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def summary(out):
    s = {}
    path = os.path.join(out, "summary.txt")
    if os.path.exists(path):
        for line in open(path):
            if ":" in line:
                k, v = line.split(":", 1)
                s[k.strip()] = v.strip()
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", default="", help="comma-separated scene / clip names")
    ap.add_argument("--config", default=os.path.join(REPO, "config", "kitti.yaml"))
    ap.add_argument("--frames", type=int, default=40, help="frames rendered per scene")
    ap.add_argument("--seed", type=int, default=1,
                    help="texture / terrain seed of the rendered scenes (1: the zoo the tests use; others: "
                         "the same scenes with other terrain and texture, a check on data not tuned on)")
    ap.add_argument("--scenes", help="rendered scenes (made on first use; default /tmp/sgd_zoo, "
                    "/tmp/sgd_zoo_seedS for another seed)")
    ap.add_argument("--out", default="/tmp/sgd_zoo_out")
    ap.add_argument("--json", help="write the rows as JSON")
    ap.add_argument("--bin", default=os.path.join(REPO, ".catkin_ws", "devel", "lib", "stereo_ground_dem"))
    a = ap.parse_args()
    if not a.scenes:
        a.scenes = "/tmp/sgd_zoo" if a.seed == 1 else f"/tmp/sgd_zoo_seed{a.seed}"
    only = [s for s in a.only.split(",") if s]
    cases = [(n, os.path.join(a.scenes, n)) for n in SCENES] + list(CLIPS.items())
    rows = []
    stamp = renderer_stamp(a.bin, a.frames, a.seed)
    print(f"{'case':16s} {'failed':>6s} {'ms':>6s} {'drift %':>8s} {'rot deg':>8s} {'h med cm':>9s} {'h p95 cm':>9s} {'cov %':>6s}")
    for name, seq in cases:
        if only and name not in only:
            continue
        stamp_path = os.path.join(seq, "render_stamp.txt")
        stale = name in SCENES and (not os.path.exists(os.path.join(seq, "times.txt")) or not os.path.exists(stamp_path)
                                    or open(stamp_path).read() != stamp)
        if stale:
            if os.path.exists(os.path.join(seq, "times.txt")):
                shutil.rmtree(seq)  # a render of another build, frame count or seed (leaves no stray frames)
            r = run([os.path.join(a.bin, "sgd_render"), "--scene", name, "--frames", str(a.frames), "--seed", str(a.seed),
                     "--out", seq, "--quiet"])
            if r.returncode != 0:
                print(f"{name}: sgd_render failed: {r.stderr.strip()}")
                continue
            with open(stamp_path, "w") as f:
                f.write(stamp)
        out = os.path.join(a.out, name)
        os.makedirs(out, exist_ok=True)
        r = run([os.path.join(a.bin, "dem_offline"), "--sequence", seq, "--out", out, "--config", a.config, "--quiet"])
        s = summary(out)
        row = dict(case=name, failed=s.get("failed", "?"), median_ms=float(s.get("median_ms", "nan")),
                   drift_pct=float("nan"), rotation_deg=float("nan"), height_median_cm=float("nan"),
                   height_p95_cm=float("nan"), coverage_pct=float("nan"))
        if r.returncode != 0:
            row["error"] = r.stderr.strip()[-300:]
        run([os.path.join(a.bin, "sgd_evaluate"), "--sequence", seq, "--result", out])
        ev_path = os.path.join(out, "evaluation.yaml")
        if os.path.exists(ev_path):
            e = yaml.safe_load(open(ev_path)) or {}
            row["drift_pct"] = e.get("end_drift_pct", float("nan"))
            row["rotation_deg"] = e.get("end_rotation_error_deg", float("nan"))
            w = ((e.get("dem") or {}).get("within_20m") or [{}])[0]
            if w:
                row.update(height_median_cm=100 * w["median_m"], height_p95_cm=100 * w["p95_m"],
                           coverage_pct=100 * w["coverage"])
        lidar = os.path.join(seq, "gt", "lidar_ground.npz")
        if os.path.exists(lidar):
            l = run([PYTHON, os.path.join(SHARED, "tools", "lidar_dem_eval.py"), "--ref", seq, "--est", out,
                     "--pose", "lidar", "--json"])
            try:
                j = json.loads(l.stdout.strip().splitlines()[-1])
                row.update(height_median_cm=100 * j["dem"]["all"]["median_abs"], height_p95_cm=100 * j["dem"]["all"]["p95"],
                           coverage_pct=j["dem"]["coverage_pct"], lidar=True)
            except (ValueError, IndexError, KeyError):
                row["error"] = "lidar_dem_eval: " + l.stderr.strip()[-200:]
        rows.append(row)
        print(f"{name:16s} {row['failed']:>6s} {row['median_ms']:6.1f} {row['drift_pct']:8.2f} {row['rotation_deg']:8.3f} "
              f"{row['height_median_cm']:9.2f} {row['height_p95_cm']:9.2f} {row['coverage_pct']:6.1f}"
              + ("  (LiDAR)" if row.get("lidar") else "") + (f"  ERROR {row['error']}" if row.get("error") else ""),
              flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
