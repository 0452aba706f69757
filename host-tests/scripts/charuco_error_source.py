#!/usr/bin/env python3
"""Where a ChArUco calibration's intrinsics error comes from: the corners or the solver.

    cargo build --release -p camgeom-host
    python3 host-tests/scripts/charuco_error_source.py --camgeom target/release/camgeom SET_DIR

On one rendered set (charuco_render.py) it prints camgeom's intrinsics error and reported
standard deviations; OpenCV's solver (calibrateCamera, or fisheye.calibrate as in
bench_charuco.py) on camgeom's own corners, and on the true positions of the same corners;
and the mean signed radial error of camgeom's corners (from the true principal point) by
radius, a bias that would move the focal length.
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import bench_charuco as bench  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--camgeom", default="target/release/camgeom")
    ap.add_argument("set")
    a = ap.parse_args()
    K, _, fisheye, t = bench.truth(a.set)
    files = sorted(glob.glob(os.path.join(a.set, "[0-9][0-9].png")))
    tmp = tempfile.mkdtemp()
    corners = os.path.join(tmp, "corners.csv")
    cmd = [a.camgeom, "calibrate", "--images", *files, "--board", bench.SPEC,
           "--out", os.path.join(tmp, "cam.yml"), "--corners-out", corners] + (["--fisheye"] if fisheye else [])
    j = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)
    kerr = lambda M: np.abs(np.array([M[0, 0] - K[0, 0], M[1, 1] - K[1, 1], M[0, 2] - K[0, 2], M[1, 2] - K[1, 2]]))
    s = j["std"]
    print("camgeom: |dfx dfy dcx dcy| %s px, reported std %.3f %.3f %.3f %.3f" % (
        np.round(kerr(np.array(j["K"]).reshape(3, 3)), 4), s["fx"], s["fy"], s["cx"], s["cy"]))
    obj, seen, true, radial = {}, {}, {}, []
    for r in np.loadtxt(corners, delimiter=",", skiprows=1):
        v = int(r[0])
        view = int(os.path.basename(files[v])[:2])
        i = int(round((r[2] / 0.030 - 1) * 10 + (r[1] / 0.030 - 1)))
        tv = t[(t[:, 0] == view) & (t[:, 1] == i)]
        if not len(tv):
            continue
        obj.setdefault(v, []).append([r[1], r[2], 0.0])
        seen.setdefault(v, []).append(r[4:6])
        true.setdefault(v, []).append(tv[0, 2:])
        u = tv[0, 2:] - K[:2, 2]
        if np.linalg.norm(u) >= 1:
            radial.append((np.linalg.norm(u), (r[4:6] - tv[0, 2:]) @ (u / np.linalg.norm(u))))
    size = cv2.imread(files[0], cv2.IMREAD_GRAYSCALE).shape[::-1]

    def opencv(points):
        O = [np.array(obj[v], np.float64) for v in sorted(obj)]
        P = [np.array(points[v], np.float64) for v in sorted(obj)]
        if fisheye:
            _, M, _, _, _ = cv2.fisheye.calibrate(
                [o.reshape(1, -1, 3) for o in O], [p.reshape(1, -1, 2) for p in P], size, np.zeros((3, 3)),
                np.zeros((4, 1)), flags=cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW,
                criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12))
        else:
            _, M, _, _, _ = cv2.calibrateCamera([o.astype(np.float32) for o in O],
                                                [p.astype(np.float32) for p in P], size, None, None)
        return kerr(M)

    print("OpenCV's solver on camgeom's corners: %s px" % np.round(opencv(seen), 4))
    print("OpenCV's solver on the same corners' true positions: %s px" % np.round(opencv(true), 7))
    r = np.array(radial)
    print("camgeom corners, signed radial error: mean %.4f px, std %.4f px" % (r[:, 1].mean(), r[:, 1].std()))
    for lo, hi in [(0, 100), (100, 200), (200, 300), (300, 1000)]:
        m = (r[:, 0] >= lo) & (r[:, 0] < hi)
        if m.any():
            print("  radius %d-%d px: %d corners, mean %.4f px" % (lo, hi, m.sum(), r[m, 1].mean()))


if __name__ == "__main__":
    main()
