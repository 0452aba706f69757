#!/usr/bin/env python3
"""Times OpenCV's two-view functions on the inputs of camgeom's `twoview` bench.

The inputs are host-tests/data/fixtures/twoview_bench/ (rows x1,y1,x2,y2 in pixels of the
camera in truth.csv), written by host-tests/benches/twoview.rs (CAMGEOM_WRITE_FIXTURES=1), so
both sides see the same numbers:

  eight_64        cv2.findFundamentalMat(x1, x2, cv2.FM_8POINT)
  seven           cv2.findFundamentalMat(x1, x2, cv2.FM_7POINT)            (7 rows)
  five            cv2.findEssentialMat(x1, x2, K, cv2.RANSAC, 0.999, 1.0)  (5 rows: one 5-point
                  solve plus OpenCV's RANSAC bookkeeping; OpenCV has no bare 5-point call)
  ransac_200      cv2.findFundamentalMat(x1, x2, cv2.FM_RANSAC, 1.0, 0.999)
                  cv2.findEssentialMat(x1, x2, K, cv2.RANSAC, 0.999, 1.0)  (50 % outliers)
  pose_100        cv2.recoverPose(E, x1, x2, K)     (E of the true pose, from truth.csv)
                  cv2.triangulatePoints([I|0], [R|t], x̂1, x̂2)   (normalised coordinates)

Points are float64 (OpenCV converts to what it needs) and, for the f32 rows, float32. One
thread (cv2.setNumThreads(1)); each call is timed in batches with time.perf_counter_ns and the
median per-call time over the batches reported. Python call overhead is included.

With --criterion DIR (criterion's output directory, e.g. target/criterion) it also reads
camgeom's medians from DIR/twoview_<case>_<type>/new/estimates.json and prints the ratio
camgeom / OpenCV.

    python3 host-tests/scripts/bench_twoview_opencv.py [--criterion target/criterion]
"""

import argparse
import json
import os
import statistics
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.join(HERE, "..", "data", "fixtures", "twoview_bench")


def load(name):
    a = np.loadtxt(os.path.join(FIXTURES, name), delimiter=",", skiprows=1, dtype=np.float64)
    return a[:, :2].copy(), a[:, 2:].copy()


def truth():
    v = np.loadtxt(os.path.join(FIXTURES, "truth.csv"), delimiter=",", skiprows=1)
    fx, fy, cx, cy = v[:4]
    k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    return k, v[4:13].reshape(3, 3), v[13:16].reshape(3, 1), v[16:25].reshape(3, 3)


def median_ns(fn, target_s=1.0, batches=31):
    """Median per-call time (ns) over `batches` batches sized to take ~target_s in total."""
    fn()
    n = 1
    while True:
        t = time.perf_counter_ns()
        for _ in range(n):
            fn()
        dt = time.perf_counter_ns() - t
        if dt > 2e7 or n > 1 << 20:
            break
        n *= 2
    per_batch = max(1, int(n * (target_s * 1e9 / batches) / max(dt, 1)))
    samples = []
    for _ in range(batches):
        t = time.perf_counter_ns()
        for _ in range(per_batch):
            fn()
        samples.append((time.perf_counter_ns() - t) / per_batch)
    return statistics.median(samples)


def seeded(fn):
    def call():
        cv2.setRNGSeed(1)
        return fn()
    return call


def cases():
    k, r, t, e = truth()
    out = []
    a, b = load("eight_64.csv")
    out.append(("eight_point_64", "findFundamentalMat(FM_8POINT)",
                lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_8POINT)))
    a, b = load("seven.csv")
    out.append(("seven_point", "findFundamentalMat(FM_7POINT)",
                lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_7POINT)))
    a, b = load("five.csv")
    out.append(("five_point", "findEssentialMat(RANSAC) on 5 rows",
                seeded(lambda a=a, b=b: cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0))))
    a, b = load("ransac_200.csv")
    out.append(("f_ransac_200", "findFundamentalMat(FM_RANSAC, 1.0, 0.999)",
                seeded(lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_RANSAC, 1.0, 0.999))))
    out.append(("e_ransac_200", "findEssentialMat(RANSAC, 0.999, 1.0)",
                seeded(lambda a=a, b=b: cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0))))
    a, b = load("pose_100.csv")
    out.append(("recover_pose_100", "recoverPose(E, x1, x2, K)",
                lambda a=a, b=b: cv2.recoverPose(e, a, b, k)))
    kinv = np.linalg.inv(k)
    na = (kinv @ np.vstack([a.T, np.ones(len(a))]))[:2].copy()
    nb = (kinv @ np.vstack([b.T, np.ones(len(b))]))[:2].copy()
    p1 = np.hstack([np.eye(3), np.zeros((3, 1))])
    p2 = np.hstack([r, t])
    out.append(("triangulate_dlt_100", "triangulatePoints (normalised)",
                lambda: cv2.triangulatePoints(p1, p2, na, nb)))
    return out


def report_inliers():
    k, _, _, _ = truth()
    a, b = load("ransac_200.csv")
    cv2.setRNGSeed(1)
    _, m = cv2.findFundamentalMat(a, b, cv2.FM_RANSAC, 1.0, 0.999)
    cv2.setRNGSeed(1)
    _, me = cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0)
    print(f"ransac_200: OpenCV F {int(m.sum())} inliers, E {int(me.sum())} inliers")


def criterion_median(root, case, ty):
    path = os.path.join(root, f"twoview_{case}_{ty}", "new", "estimates.json")
    try:
        with open(path) as f:
            return json.load(f)["median"]["point_estimate"]
    except OSError:
        return None


def fmt(ns):
    if ns >= 1e6:
        return f"{ns / 1e6:.2f} ms"
    if ns >= 1e3:
        return f"{ns / 1e3:.2f} µs"
    return f"{ns:.0f} ns"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--criterion", help="criterion output directory, for the ratio column")
    ap.add_argument("--seconds", type=float, default=1.0, help="time per measurement")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, threads {cv2.getNumThreads()}")
    print(f"python call overhead (no-op lambda): {median_ns(lambda: None, 0.2):.0f} ns")
    report_inliers()
    print()
    print("| case | OpenCV call | OpenCV median | camgeom f32 | camgeom f64 | f32 / OpenCV | f64 / OpenCV |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for case, call, fn in cases():
        theirs = median_ns(fn, args.seconds)
        ours = {ty: criterion_median(args.criterion, case, ty) if args.criterion else None
                for ty in ("f32", "f64")}
        cols = [fmt(ours[ty]) if ours[ty] else "-" for ty in ("f32", "f64")]
        ratios = [f"{ours[ty] / theirs:.2f}" if ours[ty] else "-" for ty in ("f32", "f64")]
        print(f"| {case} | `{call}` | {fmt(theirs)} | {cols[0]} | {cols[1]} | "
              f"{ratios[0]} | {ratios[1]} |")


if __name__ == "__main__":
    main()
