#!/usr/bin/env python3
"""OpenCV timings (one thread) for the same work as host-tests/benches/features.rs.

python3 host-tests/scripts/bench_features.py
"""
import os
import time

import cv2
import numpy as np

import cvbench

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data")


def best_of(f, repeat=7, number=None):
    # Median of `repeat` runs of `number` calls (calibrated to ~0.2 s per run).
    if number is None:
        number, t = 1, 0.0
        while True:
            t0 = time.perf_counter()
            for _ in range(number):
                f()
            t = time.perf_counter() - t0
            if t > 0.2:
                break
            number *= 2
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            f()
        runs.append((time.perf_counter() - t0) / number)
    return float(np.median(runs))


def main():
    cv2.setNumThreads(1)
    g1 = cv2.imread(os.path.join(DATA, "oxford-graf", "graf1.png"), cv2.IMREAD_GRAYSCALE)
    fast = cv2.FastFeatureDetector_create(threshold=20, nonmaxSuppression=True)
    orb = cv2.ORB_create(nfeatures=500)
    rng = np.random.default_rng(7)
    a = rng.integers(0, 256, (500, 32), dtype=np.uint8)
    t = rng.integers(0, 256, (500, 32), dtype=np.uint8)
    bf = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
    logo, h, frame = cvbench.warp_case(cv2)
    cases = {
        "fast_t20_nonmax_graf1_800x640": lambda: fast.detect(g1),
        "orb_500_graf1_800x640": lambda: orb.detectAndCompute(g1, None),
        "match_500x500_crosscheck": lambda: bf.match(a, t),
        "warp_128_into_320x240 (warpPerspective, BORDER_TRANSPARENT)": lambda: cv2.warpPerspective(
            logo, h, (320, 240), dst=frame, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_TRANSPARENT),
    }
    print(f"OpenCV {cv2.__version__}, 1 thread")
    for name, f in cases.items():
        print(f"{name}: {best_of(f) * 1e6:.1f} us")


if __name__ == "__main__":
    main()
