#!/usr/bin/env python3
"""OpenCV's findEssentialMat + recoverPose on the chessboard pairs of
host-tests/tests/it/twoview_chessboard.rs: the same recorded corners, undistorted with the bundled
calibration (cv2.undistortPoints, P = K), RANSAC with prob 0.999 and a 1 px threshold; the
rotation and translation-direction errors against the calibrated per-view poses.

    python3 host-tests/scripts/chessboard_twoview_opencv.py
"""
import csv
import pathlib

import cv2
import numpy as np

DATA = pathlib.Path(__file__).resolve().parent.parent / "data" / "chessboard"
NAMES = ["01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14"]
PAIRS = [("01", "02"), ("01", "03"), ("02", "03"), ("03", "05"), ("11", "12"), ("05", "12"),
         ("06", "07"), ("07", "08"), ("01", "04"), ("11", "14"), ("04", "09"), ("02", "13")]


def main():
    fs = cv2.FileStorage(str(DATA / "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    k = fs.getNode("camera_matrix").mat()
    dist = fs.getNode("distortion_coefficients").mat()
    ex = fs.getNode("extrinsic_parameters").mat()
    corners = {}
    with open(DATA / "corners.csv") as f:
        for r in csv.DictReader(f):
            corners.setdefault(r["image"], {})[(int(r["i"]), int(r["j"]))] = (
                float(r["u"]), float(r["v"]))
    angle = lambda r: np.degrees(np.linalg.norm(cv2.Rodrigues(r)[0]))
    print("pair | rot err deg | t dir err deg | inliers")
    for a, b in PAIRS:
        ia, ib = NAMES.index(a), NAMES.index(b)
        ra, rb = cv2.Rodrigues(ex[ia, :3])[0], cv2.Rodrigues(ex[ib, :3])[0]
        r_true = rb @ ra.T
        t_true = ex[ib, 3:] - r_true @ ex[ia, 3:]
        ca, cb = corners["left" + a], corners["left" + b]
        keys = sorted(set(ca) & set(cb))
        und = lambda c: cv2.undistortPoints(
            np.array([c[k_] for k_ in keys]).reshape(-1, 1, 2), k, dist, P=k).reshape(-1, 2)
        x1, x2 = und(ca), und(cb)
        e, mask = cv2.findEssentialMat(x1, x2, k, cv2.RANSAC, 0.999, 1.0)
        n, r, t, _ = cv2.recoverPose(e[:3], x1, x2, k, mask=mask.copy())
        cos = float(t.ravel() @ t_true) / np.linalg.norm(t_true)
        print(f"left{a}-left{b} | {angle(r @ r_true.T):.3f} | "
              f"{np.degrees(np.arccos(np.clip(cos, -1, 1))):.3f} | {n}")


if __name__ == "__main__":
    main()
