"""What the OpenCV-side bench scripts share: loading the bench inputs, timing a call, reading
criterion's results and formatting times.

The inputs are the CSV files the Rust benches write under host-tests/data/fixtures/ (see
host-tests/src/bench.rs); criterion's results are in <target>/criterion/<id>/new/estimates.json,
where <id> is the bench id with '/' replaced by '_' for plain functions
(`homography/dlt_64/f32` -> `homography_dlt_64_f32`) and kept as directories for benchmark
groups (`klt_known/fixed/homography`).
"""

import json
import os
import statistics
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data")
FIXTURES = os.path.join(DATA, "fixtures")
ROOT = os.path.dirname(os.path.dirname(HERE))


def fixture(bench, name):
    """Path of input `name` of bench directory `bench` (e.g. "homography_bench")."""
    return os.path.join(FIXTURES, bench, name)


def load_table(path):
    """The rows of a CSV file with a header, as a float64 array (one row: still 2-D)."""
    return np.atleast_2d(np.loadtxt(path, delimiter=",", skiprows=1, dtype=np.float64))


def load_pairs(bench, name):
    """(x1, x2) of a file of rows x1,y1,x2,y2, each an (N, 2) float64 array."""
    a = load_table(fixture(bench, name))
    return a[:, :2].copy(), a[:, 2:].copy()


def median_ns(fn, target_s=1.0, batches=31):
    """Median per-call time (ns) of `fn` over `batches` batches sized to take ~target_s in all.

    The batch size is found by doubling until one batch takes 20 ms; Python's call overhead is
    included (a no-op lambda costs ~60 ns here)."""
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


def criterion_median(root, bench_id):
    """criterion's median estimate (ns) of `bench_id`, or None when it has not been run."""
    parts = bench_id.split("/")
    candidates = [os.path.join(root, "_".join(parts)), os.path.join(root, *parts)]
    for c in candidates:
        try:
            with open(os.path.join(c, "new", "estimates.json")) as f:
                return json.load(f)["median"]["point_estimate"]
        except OSError:
            continue
    return None


def seeded(cv2, fn):
    """`fn` with OpenCV's RNG reset first, so every call of a RANSAC draws the same samples."""
    def call():
        cv2.setRNGSeed(1)
        return fn()
    return call


def fmt_ns(ns):
    """A time in ns, to 3 significant digits with its unit; '-' for None."""
    if ns is None:
        return "-"
    for scale, unit in ((1e9, "s"), (1e6, "ms"), (1e3, "µs")):
        if ns >= scale:
            return f"{ns / scale:.3g} {unit}"
    return f"{ns:.3g} ns"


def warp_case(cv2):
    """The features bench's warp (`camgeom_host::bench::warp_case`): the 128x128 checker logo
    (16-pixel cells of 230 and 30), the homography onto its quadrilateral of a 320x240 frame,
    and the frame (grey 100) it goes into."""
    y, x = np.mgrid[0:128, 0:128]
    logo = np.where(((x // 16) + (y // 16)) % 2 == 0, 230, 30).astype(np.uint8)
    src = np.array([[0, 0], [127, 0], [127, 127], [0, 127]], np.float32)
    dst = np.array([[60.3, 40.7], [250.2, 62.9], [231.6, 205.1], [41.8, 180.4]], np.float32)
    return logo, cv2.getPerspectiveTransform(src, dst), np.full((240, 320), 100, np.uint8)
