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

import cv2
import numpy as np

from cvbench import criterion_median, load_pairs, median_ns, seeded
from cvbench import fmt_ns as fmt

BENCH = "homography_bench"


def cases():
    s, d = load_pairs(BENCH, "four.csv")
    s32, d32 = s.astype(np.float32), d.astype(np.float32)
    yield "four_point", "cv2.getPerspectiveTransform", {
        "f32": lambda: cv2.getPerspectiveTransform(s32, d32),
    }
    for n in (8, 64, 256):
        s, d = load_pairs(BENCH, f"dlt_{n}.csv")
        s32, d32 = s.astype(np.float32), d.astype(np.float32)
        yield f"dlt_{n}", "cv2.findHomography(..., 0)", {
            "f32": lambda s32=s32, d32=d32: cv2.findHomography(s32, d32, 0),
            "f64": lambda s=s, d=d: cv2.findHomography(s, d, 0),
        }
    s, d = load_pairs(BENCH, "ransac_200.csv")
    s32, d32 = s.astype(np.float32), d.astype(np.float32)

    yield "ransac_200", "cv2.findHomography(..., cv2.RANSAC, 3.0)", {
        "f32": seeded(cv2, lambda: cv2.findHomography(s32, d32, cv2.RANSAC, 3.0)),
        "f64": seeded(cv2, lambda: cv2.findHomography(s, d, cv2.RANSAC, 3.0)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--criterion", help="criterion output directory, for the ratio column")
    ap.add_argument("--seconds", type=float, default=1.0, help="time per measurement")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, threads {cv2.getNumThreads()}")
    noop = median_ns(lambda: None, 0.2)
    print(f"python call overhead (no-op lambda): {noop:.0f} ns")
    s, d = load_pairs(BENCH, "ransac_200.csv")
    _, mask = cv2.findHomography(s.astype(np.float32), d.astype(np.float32), cv2.RANSAC, 3.0)
    print(f"ransac_200: OpenCV finds {int(mask.sum())} inliers")
    print()
    header = "| case | type | OpenCV call | OpenCV median | camgeom median | camgeom / OpenCV |"
    print(header)
    print("|---|---|---|---:|---:|---:|")
    for case, call, fns in cases():
        for ty in ("f32", "f64"):
            ours = criterion_median(args.criterion, f"homography/{case}/{ty}") if args.criterion else None
            fn = fns.get(ty) or fns["f32"]
            theirs = median_ns(fn, args.seconds)
            call_ty = call if ty in fns else call + " (float32 points)"
            ratio = f"{ours / theirs:.2f}" if ours else "-"
            ours_s = fmt(ours) if ours else "-"
            print(f"| {case} | {ty} | `{call_ty}` | {fmt(theirs)} | {ours_s} | {ratio} |")


if __name__ == "__main__":
    main()
