#!/usr/bin/env python3
"""AprilGrid calibration: camgeom against OpenCV on the rendered sets (aprilgrid_render.py).

    cargo build --release -p camgeom-host
    python3 host-tests/scripts/bench_aprilgrid.py [--camgeom target/release/camgeom] [SET_DIR ...]

For each set (default host-tests/data/aprilgrid/brown and .../fisheye): `camgeom calibrate
--board aprilgrid:6x5:0.03:0.3` (with --fisheye for the fisheye set), and OpenCV's
`ArucoDetector` with `DICT_APRILTAG_36h11`, `markerBorderBits = 2` and
`cornerRefinementMethod` SUBPIX (or APRILTAG, `--refine apriltag`), one thread, on every image:
its markers of the grid's ids (an id found twice dropped) give their 4 corners at Kalibr's
grid points (OpenCV draws each tag36h11 id turned by 180 degrees: its corners top-left,
top-right, bottom-right, bottom-left are the upright tag's bottom-right, bottom-left, top-left,
top-right, so AprilTag's corner j, bottom-left first, is OpenCV's corner j xor 1); then `cv2.calibrateCamera` (Brown-Conrady, 5
coefficients) or `cv2.fisheye.calibrate` (RECOMPUTE_EXTRINSIC | FIX_SKEW) on the views with at
least 8 corners. Prints a Markdown table: views used, corners used, corner error against the
exact truth (median/max, px), RMS, and the intrinsics' error against the truth (|dfx|, |dfy|,
|dcx|, |dcy| px, and the largest distortion coefficient error).
"""
import argparse
import glob
import json
import os
import subprocess

import cv2
import numpy as np

COLS, ROWS, SIZE, SPACING = 6, 5, 0.03, 0.3
SPEC = "aprilgrid:%dx%d:%g:%g" % (COLS, ROWS, SIZE, SPACING)
MIN_CORNERS = 8


def truth(d):
    lines = open(os.path.join(d, "truth.yaml")).read().splitlines()
    get = lambda key: [float(x) for x in next(l for l in lines if l.startswith(key)).split("[")[1].rstrip("]").split(",")]
    K = np.array(get("camera_matrix")).reshape(3, 3)
    D = np.array(get("distortion"))
    model = next(l for l in lines if l.startswith("model")).split(":")[1].strip()
    t = np.loadtxt(os.path.join(d, "truth.csv"), delimiter=",", skiprows=1)
    return K, D, model == "fisheye", t


def grid_point(k):
    r, c = divmod(k, 2 * COLS)
    return ((c // 2) * (1 + SPACING) * SIZE + (c % 2) * SIZE,
            (r // 2) * (1 + SPACING) * SIZE + (r % 2) * SIZE)


def tag_points(t):
    b = (t // COLS) * 4 * COLS + (t % COLS) * 2
    return [b, b + 1, b + 2 * COLS + 1, b + 2 * COLS]  # AprilTag's corner order


def corner_errors(t, view, ids, pts):
    e = []
    tv = t[t[:, 0] == view]
    for i, p in zip(ids, pts):
        r = tv[tv[:, 1] == i]
        if len(r):
            e.append(np.hypot(*(p - r[0, 2:])))
    return e


def calibrate(obj, img, size, fisheye):
    if fisheye:
        flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
        rms, K, D, _, _ = cv2.fisheye.calibrate(
            [o.reshape(1, -1, 3).astype(np.float64) for o in obj],
            [p.reshape(1, -1, 2).astype(np.float64) for p in img], size, np.zeros((3, 3)),
            np.zeros((4, 1)), flags=flags,
            criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12))
    else:
        rms, K, D, _, _ = cv2.calibrateCamera(obj, img, size, None, None)
    return rms, K, np.array(D).ravel()


def opencv(files, fisheye, t, refine):
    cv2.setNumThreads(1)
    dic = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    prm = cv2.aruco.DetectorParameters()
    prm.markerBorderBits = 2
    prm.cornerRefinementMethod = (cv2.aruco.CORNER_REFINE_APRILTAG if refine == "apriltag"
                                  else cv2.aruco.CORNER_REFINE_SUBPIX)
    det = cv2.aruco.ArucoDetector(dic, prm)
    obj, img, errs = [], [], []
    size = None
    for f in files:
        im = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = im.shape[::-1]
        corners, ids, _ = det.detectMarkers(im)
        if ids is None:
            continue
        ids = ids.ravel()
        o, p, k = [], [], []
        for c, i in zip(corners, ids):
            if i >= COLS * ROWS or (ids == i).sum() > 1:
                continue
            c = c.reshape(4, 2)
            for j, point in enumerate(tag_points(int(i))):
                # AprilTag's corner j is OpenCV's corner j xor 1 (the module docs).
                q = c[j ^ 1]
                o.append((*grid_point(point), 0.0))
                p.append(q)
                k.append(point)
        if len(o) < MIN_CORNERS:
            continue
        obj.append(np.array(o, np.float32))
        img.append(np.array(p, np.float32))
        errs += corner_errors(t, int(os.path.basename(f)[:2]), k, p)
    rms, K, D = calibrate(obj, img, size, fisheye)
    return dict(rms=rms, K=K, D=D, views=len(obj), corners=sum(len(o) for o in obj), errs=errs)


def camgeom(exe, files, fisheye, t, tmp):
    corners = os.path.join(tmp, "corners.csv")
    cmd = [exe, "calibrate", "--images", *files, "--board", SPEC, "--out",
           os.path.join(tmp, "cam.yml"), "--corners-out", corners] + (["--fisheye"] if fisheye else [])
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    j = json.loads(out)
    c = np.loadtxt(corners, delimiter=",", skiprows=1)
    lut = {tuple(np.round(grid_point(k), 6)): k for k in range(4 * COLS * ROWS)}
    errs = []
    for row in c:
        view = int(os.path.basename(files[int(row[0])])[:2])
        k = lut[(round(row[1], 6), round(row[2], 6))]
        errs += corner_errors(t, view, [k], [row[4:6]])
    return dict(rms=j["rms_px"], K=np.array(j["K"]).reshape(3, 3), D=np.array(j["distortion"]),
                views=j["views_used"], corners=len(c), errs=errs)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--camgeom", default="target/release/camgeom")
    ap.add_argument("--refine", choices=["subpix", "apriltag"], default="subpix")
    ap.add_argument("sets", nargs="*")
    a = ap.parse_args()
    here = os.path.join(os.path.dirname(__file__), "..", "data", "aprilgrid")
    sets = a.sets or [os.path.join(here, "brown"), os.path.join(here, "fisheye")]
    tmp = "aprilgrid_bench_out"
    os.makedirs(tmp, exist_ok=True)
    print("| set | who | views used | corners | corner error median / max px | RMS px | "
          "\\|dfx\\| \\|dfy\\| \\|dcx\\| \\|dcy\\| px | max \\|d dist\\| |")
    print("|---|---|---|---|---|---|---|---|")
    for d in sets:
        K, D, fisheye, t = truth(d)
        files = sorted(glob.glob(os.path.join(d, "*.png")))
        for who, r in (("camgeom", camgeom(a.camgeom, files, fisheye, t, tmp)),
                       ("OpenCV (%s)" % a.refine.upper(), opencv(files, fisheye, t, a.refine))):
            dk = np.abs(r["K"] - K)
            dd = np.abs(r["D"][:len(D)] - D).max()
            e = np.array(r["errs"])
            print("| %s (%d images) | %s | %d | %d | %.3f / %.3f | %.3f | %.3f %.3f %.3f %.3f | %.4f |" % (
                os.path.basename(os.path.normpath(d)), len(files), who, r["views"], r["corners"],
                np.median(e), e.max(), r["rms"], dk[0, 0], dk[1, 1], dk[0, 2], dk[1, 2], dd))


if __name__ == "__main__":
    main()
