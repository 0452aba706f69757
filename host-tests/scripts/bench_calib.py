#!/usr/bin/env python3
"""Times OpenCV's chessboard detection and calibration on the inputs of camgeom's `calib` bench.

  detect_left01       cv2.findChessboardCorners(left01, (9, 6)) + cv2.cornerSubPix((5, 5),
                      COUNT+EPS 30 / 0.1): the classic detector as OpenCV's acceptance test runs it
  detect_left01 SB    cv2.findChessboardCornersSB(left01, (9, 6))   (default flags)
  calibrate13_brown   cv2.calibrateCamera, flags 0, default criteria, on OpenCV's own 5x5-refined
                      corners of the 13 bundled views (fixtures/calib/real_corners.csv)
  calibrate13_fisheye cv2.fisheye.calibrate, RECOMPUTE_EXTRINSIC | FIX_SKEW, criteria 100 / 1e-12
                      (the calibration notes' settings), on the same corners

left01 is read with cv2.imread(IMREAD_GRAYSCALE). One thread (cv2.setNumThreads(1)); each call
is timed in batches with time.perf_counter_ns and the median per-call time over the batches
is reported (Python call overhead included; it is below a microsecond, negligible here).

With --criterion DIR (criterion's output directory) it reads camgeom's medians of the same
cases (calib/detect_left01/{saddle,cornersubpix5}, calib/calibrate13_{brown,fisheye}/{f64,f32})
and prints the ratio camgeom / OpenCV: run the two in one sitting.

    cargo bench -p camgeom-host --bench calib
    python3 host-tests/scripts/bench_calib.py --criterion target/criterion
"""

import argparse
import os

import cv2
import numpy as np

from cvbench import DATA, FIXTURES, criterion_median, median_ns
from cvbench import fmt_ns as fmt

BOARD = (9, 6)


def opencv_corners():
    views = {}
    with open(os.path.join(FIXTURES, "calib", "real_corners.csv")) as f:
        next(f)
        for line in f:
            r = line.strip().split(",")
            views.setdefault(r[0], []).append((float(r[4]), float(r[5])))
    return [np.array(v, dtype=np.float32).reshape(-1, 1, 2) for v in views.values()]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--criterion", help="criterion output directory, for the ratio column")
    ap.add_argument("--seconds", type=float, default=2.0, help="time per measurement")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, threads {cv2.getNumThreads()}")
    img = cv2.imread(os.path.join(DATA, "chessboard", "left01.jpg"), cv2.IMREAD_GRAYSCALE)
    crit5 = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.1)

    def classic():
        ok, c = cv2.findChessboardCorners(img, BOARD)
        return cv2.cornerSubPix(img, c, (5, 5), (-1, -1), crit5)

    corners = opencv_corners()
    assert len(corners) == 13
    objp = np.zeros((54, 3), np.float32)
    objp[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2)
    obj = [objp] * 13
    obj_fe = [objp.reshape(1, -1, 3).astype(np.float64)] * 13
    img_fe = [c.reshape(1, -1, 2).astype(np.float64) for c in corners]
    # OpenCV 5 names the fisheye flags cv2.CALIB_* (as make_calib_fixtures.py does).
    fe_flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
    fe_crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)

    def brown():
        return cv2.calibrateCamera(obj, corners, (640, 480), None, None, flags=0)

    def fisheye():
        return cv2.fisheye.calibrate(obj_fe, img_fe, (640, 480), np.zeros((3, 3)), np.zeros((4, 1)),
                                     flags=fe_flags, criteria=fe_crit)

    print(f"calibrateCamera rms {brown()[0]:.6f}, fisheye.calibrate rms {fisheye()[0]:.6f}")
    cases = [
        ("detect 640x480 (left01)", "findChessboardCorners + cornerSubPix (5,5)", classic,
         [("saddle (default)", "calib/detect_left01/saddle"),
          ("cornerSubPix (5,5)", "calib/detect_left01/cornersubpix5")]),
        ("detect 640x480 (left01)", "findChessboardCornersSB", lambda: cv2.findChessboardCornersSB(img, BOARD),
         [("saddle (default)", "calib/detect_left01/saddle")]),
        ("calibrate 13 views", "calibrateCamera (flags 0)", brown,
         [("f64", "calib/calibrate13_brown/f64"), ("f32", "calib/calibrate13_brown/f32")]),
        ("fisheye calibrate 13 views", "fisheye.calibrate", fisheye,
         [("f64", "calib/calibrate13_fisheye/f64"), ("f32", "calib/calibrate13_fisheye/f32")]),
    ]
    print()
    print("| case | OpenCV call | OpenCV median | camgeom | camgeom median | camgeom / OpenCV |")
    print("|---|---|---:|---|---:|---:|")
    for case, call, fn, ours in cases:
        theirs = median_ns(fn, args.seconds, batches=15)
        for label, bench_id in ours:
            t = criterion_median(args.criterion, bench_id) if args.criterion else None
            ratio = f"{t / theirs:.2f}" if t else "-"
            print(f"| {case} | `{call}` | {fmt(theirs)} | {label} | {fmt(t)} | {ratio} |")


if __name__ == "__main__":
    main()
