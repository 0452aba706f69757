#!/usr/bin/env python3
"""OpenCV's side of benches/klt.rs: calcOpticalFlowPyrLK, single thread, same pair, points,
window (21x21), maxLevel 3 and criteria (30 / 0.01), pyramids built beforehand with
cv2.buildOpticalFlowPyramid timed separately and subtracted (calcOpticalFlowPyrLK then
computes the derivatives per level, as camgeom's per-level mode does). Also pyrDown x3 and goodFeaturesToTrack (400).

Run: python3 host-tests/scripts/bench_klt_opencv.py
"""

import os
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data")


def best(f, reps=20, inner=1):
    """Best-of `reps` wall time of `inner` calls, per call (s)."""
    t = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(inner):
            f()
        t.append((time.perf_counter() - t0) / inner)
    return min(t), float(np.median(t))


def main():
    cv2.setNumThreads(1)
    a = cv2.imread(os.path.join(DATA, "middlebury", "basketball1.png"), cv2.IMREAD_GRAYSCALE)
    b = cv2.imread(os.path.join(DATA, "middlebury", "basketball2.png"), cv2.IMREAD_GRAYSCALE)
    pts = np.loadtxt(os.path.join(DATA, "fixtures", "klt", "basketball_bench_pts.csv"),
                     delimiter=",", skiprows=1, dtype=np.float32).reshape(-1, 1, 2)
    win = (21, 21)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)
    print(f"OpenCV {cv2.__version__}, threads {cv2.getNumThreads()}")
    # The Python binding does not take prebuilt pyramids (a list of arrays is not an
    # InputArray there), so each call builds both; that cost is measured and subtracted.
    pyr, _ = best(lambda: (cv2.buildOpticalFlowPyramid(a, win, 3, withDerivatives=False),
                           cv2.buildOpticalFlowPyramid(b, win, 3, withDerivatives=False)))
    print(f"buildOpticalFlowPyramid x2 (both frames): best {pyr * 1e3:.3f} ms")
    for n in (100, 1000):
        p = pts[:n].copy()
        f = lambda: cv2.calcOpticalFlowPyrLK(a, b, p, None, winSize=win, maxLevel=3, criteria=crit)
        lo, med = best(f)
        print(f"calcOpticalFlowPyrLK {n:5d} points: best {lo * 1e3:8.3f} ms (median {med * 1e3:8.3f}); "
              f"minus pyramids {(lo - pyr) * 1e3:8.3f} ms = {(lo - pyr) / n * 1e6:6.2f} us/feature")
    lo, med = best(lambda: [cv2.pyrDown(cv2.pyrDown(cv2.pyrDown(a)))], inner=5)
    print(f"pyrDown x3 640x480: best {lo * 1e6:.1f} us, median {med * 1e6:.1f} us")
    lo, med = best(lambda: cv2.goodFeaturesToTrack(a, 400, 0.01, 10, blockSize=3))
    print(f"goodFeaturesToTrack 640x480 400: best {lo * 1e3:.3f} ms, median {med * 1e3:.3f} ms")


if __name__ == "__main__":
    main()
