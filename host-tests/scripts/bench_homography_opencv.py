#!/usr/bin/env python3
"""Times OpenCV's homography solvers on the inputs of camgeom's `homography` bench.

The inputs are host-tests/data/fixtures/homography_bench/*.csv (rows x1,y1,x2,y2), written by
host-tests/benches/homography.rs (CAMGEOM_WRITE_FIXTURES=1), so both sides see the same numbers:

  four.csv          cv2.getPerspectiveTransform(src, dst)            (the 4-point solver)
  dlt_{8,64,256}    cv2.findHomography(src, dst, 0)                  (all points, least squares)
  ransac_200        cv2.findHomography(src, dst, cv2.RANSAC, 3.0)    (50 % outliers)

Points are passed as float32 (getPerspectiveTransform requires it; findHomography converts to
float32 anyway) and as float64 (findHomography only). One thread (cv2.setNumThreads(1)); each
function is timed in batches of calls with time.perf_counter_ns, and the median per-call time
over the batches is reported. Python call overhead is included (measured with a no-op and
printed, not subtracted).

With --criterion DIR (criterion's output directory, e.g. $CARGO_TARGET_DIR/criterion) it also
reads camgeom's medians from DIR/homography_<case>_<type>/new/estimates.json and prints the
ratio camgeom / OpenCV.

    python3 host-tests/scripts/bench_homography_opencv.py [--criterion target/criterion]
"""

import argparse
import json
import os
import statistics
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.join(HERE, "..", "data", "fixtures", "homography_bench")


def load(name):
    a = np.loadtxt(os.path.join(FIXTURES, name), delimiter=",", skiprows=1, dtype=np.float64)
    return a[:, :2].copy(), a[:, 2:].copy()


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


def cases():
    s, d = load("four.csv")
    s32, d32 = s.astype(np.float32), d.astype(np.float32)
    yield "four_point", "cv2.getPerspectiveTransform", {
        "f32": lambda: cv2.getPerspectiveTransform(s32, d32),
    }
    for n in (8, 64, 256):
        s, d = load(f"dlt_{n}.csv")
        s32, d32 = s.astype(np.float32), d.astype(np.float32)
        yield f"dlt_{n}", "cv2.findHomography(..., 0)", {
            "f32": lambda s32=s32, d32=d32: cv2.findHomography(s32, d32, 0),
            "f64": lambda s=s, d=d: cv2.findHomography(s, d, 0),
        }
    s, d = load("ransac_200.csv")
    s32, d32 = s.astype(np.float32), d.astype(np.float32)

    def ransac(a, b):
        cv2.setRNGSeed(1)
        return cv2.findHomography(a, b, cv2.RANSAC, 3.0)

    yield "ransac_200", "cv2.findHomography(..., cv2.RANSAC, 3.0)", {
        "f32": lambda: ransac(s32, d32),
        "f64": lambda: ransac(s, d),
    }


def criterion_median(root, case, ty):
    path = os.path.join(root, f"homography_{case}_{ty}", "new", "estimates.json")
    try:
        with open(path) as f:
            return json.load(f)["median"]["point_estimate"]
    except OSError:
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--criterion", help="criterion output directory, for the ratio column")
    ap.add_argument("--seconds", type=float, default=1.0, help="time per measurement")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, threads {cv2.getNumThreads()}")
    noop = median_ns(lambda: None, 0.2)
    print(f"python call overhead (no-op lambda): {noop:.0f} ns")
    s, d = load("ransac_200.csv")
    _, mask = cv2.findHomography(s.astype(np.float32), d.astype(np.float32), cv2.RANSAC, 3.0)
    print(f"ransac_200: OpenCV finds {int(mask.sum())} inliers")
    print()
    header = "| case | type | OpenCV call | OpenCV median | camgeom median | camgeom / OpenCV |"
    print(header)
    print("|---|---|---|---:|---:|---:|")
    for case, call, fns in cases():
        for ty in ("f32", "f64"):
            ours = criterion_median(args.criterion, case, ty) if args.criterion else None
            fn = fns.get(ty) or fns["f32"]
            theirs = median_ns(fn, args.seconds)
            call_ty = call if ty in fns else call + " (float32 points)"
            ratio = f"{ours / theirs:.2f}" if ours else "-"
            ours_s = fmt(ours) if ours else "-"
            print(f"| {case} | {ty} | `{call_ty}` | {fmt(theirs)} | {ours_s} | {ratio} |")


def fmt(ns):
    if ns >= 1e6:
        return f"{ns / 1e6:.2f} ms"
    if ns >= 1e3:
        return f"{ns / 1e3:.2f} µs"
    return f"{ns:.0f} ns"


if __name__ == "__main__":
    main()
