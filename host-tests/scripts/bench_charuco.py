#!/usr/bin/env python3
"""ChArUco calibration: camgeom against OpenCV on the rendered sets (charuco_render.py).

    cargo build --release -p camgeom-host
    python3 host-tests/scripts/bench_charuco.py [--camgeom target/release/camgeom] [SET_DIR ...]

For each set (default host-tests/data/charuco/brown and .../fisheye): `camgeom calibrate
--board charuco:11x8:0.030:0.022:DICT_4X4_50` (with --fisheye for the fisheye set), and
OpenCV's `CharucoDetector.detectBoard` (default parameters) on every image, then
`cv2.calibrateCamera` (Brown-Conrady, 5 coefficients) or `cv2.fisheye.calibrate`
(RECOMPUTE_EXTRINSIC | FIX_SKEW) on its ChArUco corners of the views with at least 6. Prints a
Markdown table: views used, corners used, corner error against the exact truth (median/max,
px), RMS, and the intrinsics' error against the truth (|dfx|, |dfy|, |dcx|, |dcy| px, and the
largest distortion coefficient error).
"""
import argparse
import glob
import json
import os
import subprocess
import sys

import cv2
import numpy as np

SPEC = "charuco:11x8:0.030:0.022:DICT_4X4_50"


def truth(d):
    lines = open(os.path.join(d, "truth.yaml")).read().splitlines()
    get = lambda key: [float(x) for x in next(l for l in lines if l.startswith(key)).split("[")[1].rstrip("]").split(",")]
    K = np.array(get("camera_matrix")).reshape(3, 3)
    D = np.array(get("distortion"))
    model = next(l for l in lines if l.startswith("model")).split(":")[1].strip()
    t = np.loadtxt(os.path.join(d, "truth.csv"), delimiter=",", skiprows=1)
    return K, D, model == "fisheye", t


def corner_errors(t, view, ids, pts):
    e = []
    tv = t[t[:, 0] == view]
    for i, p in zip(ids, pts):
        r = tv[tv[:, 1] == i]
        if len(r):
            e.append(np.hypot(*(p - r[0, 2:])))
    return e


def opencv(d, files, fisheye, t):
    dic = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    board = cv2.aruco.CharucoBoard((11, 8), 0.030, 0.022, dic)
    det = cv2.aruco.CharucoDetector(board)
    obj, img, errs = [], [], []
    size = None
    for f in files:
        im = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = im.shape[::-1]
        cc, ci, _, _ = det.detectBoard(im)
        if ci is None or len(ci) < 6:
            continue
        o, p = board.matchImagePoints(cc, ci)
        obj.append(o.astype(np.float32))
        img.append(p.astype(np.float32))
        errs += corner_errors(t, int(os.path.basename(f)[:2]), ci.ravel(), cc.reshape(-1, 2))
    if fisheye:
        flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
        rms, K, D, _, _ = cv2.fisheye.calibrate(
            [o.reshape(1, -1, 3).astype(np.float64) for o in obj], [p.reshape(1, -1, 2).astype(np.float64) for p in img], size, np.zeros((3, 3)), np.zeros((4, 1)),
            flags=flags, criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    else:
        rms, K, D, _, _ = cv2.calibrateCamera(obj, img, size, None, None)
    return dict(rms=rms, K=K, D=np.array(D).ravel(), views=len(obj), corners=sum(len(o) for o in obj), errs=errs)


def camgeom(exe, d, files, fisheye, t, tmp):
    corners = os.path.join(tmp, "corners.csv")
    cmd = [exe, "calibrate", "--images", *files, "--board", SPEC, "--out", os.path.join(tmp, "cam.yml"),
           "--corners-out", corners] + (["--fisheye"] if fisheye else [])
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    j = json.loads(out)
    c = np.loadtxt(corners, delimiter=",", skiprows=1)
    errs = []
    pts = t[:, 1]
    for row in c:
        view = int(os.path.basename(files[int(row[0])])[:2])
        i = int(round((row[2] / 0.030 - 1) * 10 + (row[1] / 0.030 - 1)))
        errs += corner_errors(t, view, [i], [row[4:6]])
    return dict(rms=j["rms_px"], K=np.array(j["K"]).reshape(3, 3), D=np.array(j["distortion"]),
                views=j["views_used"], corners=len(c), errs=errs)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--camgeom", default="target/release/camgeom")
    ap.add_argument("sets", nargs="*")
    a = ap.parse_args()
    here = os.path.join(os.path.dirname(__file__), "..", "data", "charuco")
    sets = a.sets or [os.path.join(here, "brown"), os.path.join(here, "fisheye")]
    tmp = "charuco_bench_out"
    os.makedirs(tmp, exist_ok=True)
    print("| set | who | views used | corners | corner error median / max px | RMS px | "
          "\\|dfx\\| \\|dfy\\| \\|dcx\\| \\|dcy\\| px | max \\|d dist\\| |")
    print("|---|---|---|---|---|---|---|---|")
    for d in sets:
        K, D, fisheye, t = truth(d)
        files = sorted(glob.glob(os.path.join(d, "*.png")))
        for who, r in (("camgeom", camgeom(a.camgeom, d, files, fisheye, t, tmp)),
                       ("OpenCV", opencv(d, files, fisheye, t))):
            dk = np.abs(r["K"] - K)
            dd = np.abs(r["D"][:len(D)] - D).max()
            e = np.array(r["errs"])
            print("| %s (%d images) | %s | %d | %d | %.3f / %.3f | %.3f | %.3f %.3f %.3f %.3f | %.4f |" % (
                os.path.basename(os.path.normpath(d)), len(files), who, r["views"], r["corners"],
                np.median(e), e.max(), r["rms"], dk[0, 0], dk[1, 1], dk[0, 2], dk[1, 2], dd))


if __name__ == "__main__":
    main()
