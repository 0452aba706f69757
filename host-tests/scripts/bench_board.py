#!/usr/bin/env python3
"""Board pose, camgeom against OpenCV, on OpenCV-rendered GridBoard views with exact truth.

    python3 host-tests/scripts/bench_board.py [--dir DIR] [--per-bin N]

1. Renders the views (`board_render.py bench DIR`, seed 42; kept in --dir and reused): a 5x4
   DICT_4X4_50 GridBoard (0.04 m markers, 0.01 m gaps) at 640x480 (f = 600 px, no distortion)
   over crops of the bundled photos, tilt 0..55 deg, spanning 40..90 % of the frame, with 100 %
   (2 N views), 50 % and 25 % (N covered by patches and N partly out of the frame each) of the
   20 tags visible.
2. camgeom: `camgeom apriltag --frames DIR --board DIR/board.json --intrinsics
   DIR/camera.json` (the release binary; detection with camgeom's defaults, then
   `apriltag::board_pose` in f64).
   OpenCV: `ArucoDetector` (default `DetectorParameters`, which OpenCV's board tutorial uses;
   and again with `CORNER_REFINE_SUBPIX`), `board.matchImagePoints`, `solvePnP` with
   `SOLVEPNP_ITERATIVE` (the tutorial's default) or `SOLVEPNP_IPPE` (planar).
3. Per bin: rotation error (angle of R R_true^T, degrees) and translation error (mm) of each
   pose against the truth (median, 90th percentile, max), views without a pose or with a
   rotation error above 2 deg (failures), tags used against tags visible.
4. Time a view, wall clock, PNG read included: camgeom's whole CLI run divided by the views
   (process start, JSON out included); OpenCV's imread + detect + match + solvePnP, one thread.

Prints Markdown tables.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

import board_render as br  # noqa: E402


def target_dir():
    out = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"],
                         cwd=ROOT, check=True, capture_output=True, text=True).stdout
    return json.loads(out)["target_directory"]


def rot_err(R, rvec):
    Rt, _ = cv2.Rodrigues(np.asarray(rvec, float))
    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(R @ Rt.T)[0])))


def opencv_method(subpix, flags):
    p = cv2.aruco.DetectorParameters()
    if subpix:
        p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    b, _ = br.board()
    det = cv2.aruco.ArucoDetector(b.getDictionary(), p)

    def run(path, K):
        img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        corners, ids, _ = det.detectMarkers(img)
        if ids is None or len(ids) == 0:
            return None
        obj, pix = b.matchImagePoints(corners, ids)
        if obj is None or len(obj) < 4:
            return None
        ok, rvec, tvec = cv2.solvePnP(obj, pix, K, np.zeros(5), flags=flags)
        if not ok:
            return None
        R, _ = cv2.Rodrigues(rvec)
        used = sorted(int(i) for i in ids.ravel() if i < br.NX * br.NY)
        return R, tvec.ravel(), used
    return run


def stats(xs):
    if not xs:
        return "-"
    a = np.array(xs)
    return f"{np.median(a):.4f} / {np.percentile(a, 90):.4f} / {a.max():.4f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=os.path.join(ROOT, "target", "board-bench"))
    ap.add_argument("--per-bin", type=int, default=20)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    if not os.path.isfile(os.path.join(args.dir, "truth.json")):
        subprocess.run([sys.executable, os.path.join(HERE, "board_render.py"), "bench", args.dir,
                        "--per-bin", str(args.per_bin)], check=True)
    subprocess.run(["cargo", "build", "--release", "-p", "camgeom-host", "--bin", "camgeom"],
                   cwd=ROOT, check=True)
    binary = os.path.join(target_dir(), "release", "camgeom")
    with open(os.path.join(args.dir, "truth.json")) as f:
        views = json.load(f)["views"]
    with open(os.path.join(args.dir, "camera.json")) as f:
        c = json.load(f)
    K = np.array([[c["fx"], 0, c["cx"]], [0, c["fy"], c["cy"]], [0, 0, 1.0]])

    results = {}  # method -> image -> (R, t, used) or None
    times = {}
    t0 = time.perf_counter()
    out = subprocess.run([binary, "apriltag", "--frames", args.dir, "--board",
                          os.path.join(args.dir, "board.json"), "--intrinsics",
                          os.path.join(args.dir, "camera.json")],
                         check=True, capture_output=True, text=True).stdout
    times["camgeom"] = (time.perf_counter() - t0) / len(views)
    ours = {}
    for fr in json.loads(out)["frames"]:
        b = fr["board"]
        ours[os.path.basename(fr["image"])] = None if "R" not in b else (
            np.array(b["R"]).reshape(3, 3), np.array(b["t"]), b["tags"])
    results["camgeom"] = ours
    methods = {
        "OpenCV ITERATIVE": (False, cv2.SOLVEPNP_ITERATIVE),
        "OpenCV IPPE": (False, cv2.SOLVEPNP_IPPE),
        "OpenCV subpix + ITERATIVE": (True, cv2.SOLVEPNP_ITERATIVE),
    }
    for name, (subpix, flags) in methods.items():
        run = opencv_method(subpix, flags)
        res = {}
        t0 = time.perf_counter()
        for v in views:
            res[v["image"]] = run(os.path.join(args.dir, v["image"]), K)
        times[name] = (time.perf_counter() - t0) / len(views)
        results[name] = res

    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"OpenCV {cv2.__version__}, one thread; {len(views)} views of 640x480\n")
    print("| visible | views | method | rotation error, deg (median / p90 / max) | "
          "translation error, mm (median / p90 / max) | failures | tags used / visible |")
    print("|---|---|---|---|---|---|---|")
    for frac in br.BINS:
        vs = [v for v in views if v["bin"] == frac]
        for name, res in results.items():
            er, et, fail, used, vis = [], [], 0, 0, 0
            for v in vs:
                vis += len(v["visible"])
                p = res.get(v["image"])
                if p is None:
                    fail += 1
                    continue
                R, t, ids = p
                e = rot_err(R, v["rvec"])
                used += len(ids)
                if e > 2.0:
                    fail += 1
                    continue
                er.append(e)
                et.append(1e3 * float(np.linalg.norm(t - np.array(v["tvec"]))))
            print(f"| {int(frac * 100)} % | {len(vs)} | {name} | {stats(er)} | {stats(et)} | "
                  f"{fail} | {used} / {vis} |")
    print("\n| method | time a view (ms, PNG read included) |")
    print("|---|---|")
    for name, t in times.items():
        print(f"| {name} | {1e3 * t:.2f} |")


if __name__ == "__main__":
    main()
