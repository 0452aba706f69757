#!/usr/bin/env python3
"""Regenerates the planar-pose fixtures in host-tests/data/chessboard/ (OpenCV as the reference).

Nothing here runs during `cargo test`: the outputs are committed. Regenerate from the
repository root with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_pose_fixtures.py

Outputs:
  corners.csv     image,i,j,u,v: the 9x6 inner corners of every chessboard image, found once with
                  cv2.findChessboardCorners and refined with cv2.cornerSubPix (11x11 window,
                  30 iterations / eps 0.001, OpenCV's calibration-sample settings). These are the
                  observations every pose test uses; camgeom has no chessboard detector.
  opencv_pnp.csv  image,method,rx,ry,rz,tx,ty,tz,rms_px: cv2.solvePnP on those corners with the
                  bundled intrinsics and distortion, for SOLVEPNP_IPPE, SOLVEPNP_ITERATIVE and
                  SOLVEPNP_SQPNP; rms_px is the RMS reprojection error through cv2.projectPoints.
"""

import glob
import os

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data", "chessboard")
BOARD = (9, 6)
SQUARE = 0.025


def main():
    fs = cv2.FileStorage(os.path.join(DATA, "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    K = fs.getNode("camera_matrix").mat()
    dist = fs.getNode("distortion_coefficients").mat().reshape(-1)
    fs.release()
    obj = np.array(
        [[SQUARE * i, SQUARE * j, 0.0] for j in range(BOARD[1]) for i in range(BOARD[0])],
        dtype=np.float64,
    )
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001)
    methods = [("ippe", cv2.SOLVEPNP_IPPE), ("iterative", cv2.SOLVEPNP_ITERATIVE), ("sqpnp", cv2.SOLVEPNP_SQPNP)]
    with open(os.path.join(DATA, "corners.csv"), "w") as fc, open(os.path.join(DATA, "opencv_pnp.csv"), "w") as fp:
        fc.write("image,i,j,u,v\n")
        fp.write("image,method,rx,ry,rz,tx,ty,tz,rms_px\n")
        for path in sorted(glob.glob(os.path.join(DATA, "left*.jpg"))):
            name = os.path.splitext(os.path.basename(path))[0]
            gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
            ok, corners = cv2.findChessboardCorners(gray, BOARD)
            assert ok, name
            corners = cv2.cornerSubPix(gray, corners, (11, 11), (-1, -1), criteria).reshape(-1, 2)
            # OpenCV may return the grid starting from either end: orient it so corner 0 is the
            # one nearest the image's top-left, as the board's (0, 0) in the calibration views.
            if np.linalg.norm(corners[0]) > np.linalg.norm(corners[-1]):
                corners = corners[::-1].copy()
            for k, (u, v) in enumerate(corners):
                fc.write(f"{name},{k % BOARD[0]},{k // BOARD[0]},{float(u)!r},{float(v)!r}\n")
            pts = corners.astype(np.float64)
            for mname, flag in methods:
                ok, rvec, tvec = cv2.solvePnP(obj, pts, K, dist, flags=flag)
                assert ok
                proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
                rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - pts) ** 2, axis=1))))
                r, t = rvec.reshape(-1), tvec.reshape(-1)
                fp.write(",".join([name, mname] + [repr(float(x)) for x in (*r, *t)] + [repr(rms)]) + "\n")
    print("OpenCV", cv2.__version__)


if __name__ == "__main__":
    main()
