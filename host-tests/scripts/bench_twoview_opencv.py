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

import cv2
import numpy as np

from cvbench import criterion_median, fixture, load_pairs, median_ns, seeded
from cvbench import fmt_ns as fmt

BENCH = "twoview_bench"


def truth():
    v = np.loadtxt(fixture(BENCH, "truth.csv"), delimiter=",", skiprows=1)
    fx, fy, cx, cy = v[:4]
    k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    return k, v[4:13].reshape(3, 3), v[13:16].reshape(3, 1), v[16:25].reshape(3, 3)


def cases():
    k, r, t, e = truth()
    out = []
    a, b = load_pairs(BENCH, "eight_64.csv")
    out.append(("eight_point_64", "findFundamentalMat(FM_8POINT)",
                lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_8POINT)))
    a, b = load_pairs(BENCH, "seven.csv")
    out.append(("seven_point", "findFundamentalMat(FM_7POINT)",
                lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_7POINT)))
    a, b = load_pairs(BENCH, "five.csv")
    out.append(("five_point", "findEssentialMat(RANSAC) on 5 rows",
                seeded(cv2, lambda a=a, b=b: cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0))))
    a, b = load_pairs(BENCH, "ransac_200.csv")
    out.append(("f_ransac_200", "findFundamentalMat(FM_RANSAC, 1.0, 0.999)",
                seeded(cv2, lambda a=a, b=b: cv2.findFundamentalMat(a, b, cv2.FM_RANSAC, 1.0, 0.999))))
    out.append(("e_ransac_200", "findEssentialMat(RANSAC, 0.999, 1.0)",
                seeded(cv2, lambda a=a, b=b: cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0))))
    a, b = load_pairs(BENCH, "pose_100.csv")
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
    a, b = load_pairs(BENCH, "ransac_200.csv")
    cv2.setRNGSeed(1)
    _, m = cv2.findFundamentalMat(a, b, cv2.FM_RANSAC, 1.0, 0.999)
    cv2.setRNGSeed(1)
    _, me = cv2.findEssentialMat(a, b, k, cv2.RANSAC, 0.999, 1.0)
    print(f"ransac_200: OpenCV F {int(m.sum())} inliers, E {int(me.sum())} inliers")


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
        ours = {ty: criterion_median(args.criterion, f"twoview/{case}/{ty}") if args.criterion else None
                for ty in ("f32", "f64")}
        cols = [fmt(ours[ty]) if ours[ty] else "-" for ty in ("f32", "f64")]
        ratios = [f"{ours[ty] / theirs:.2f}" if ours[ty] else "-" for ty in ("f32", "f64")]
        print(f"| {case} | `{call}` | {fmt(theirs)} | {cols[0]} | {cols[1]} | "
              f"{ratios[0]} | {ratios[1]} |")


if __name__ == "__main__":
    main()
