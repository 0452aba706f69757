#!/usr/bin/env python3
"""Regenerates the OpenCV reference fixtures in host-tests/data/chessboard/.

Nothing here runs during `cargo test`: the outputs are committed, and the Rust tests compare
camgeom against them. Regenerate (from the repository root) with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_fixtures.py

and commit the changed files together with the OpenCV version the script prints.

Inputs: left_intrinsics.yml (OpenCV's calibration of the left01..left14 chessboard images), read
with cv2.FileStorage so the fixtures do not depend on camgeom's own parser.

Outputs:
  board_corners.csv        the 9x6 inner corners of the board in its own frame, metres:
                           X = 0.025 i, Y = 0.025 j, Z = 0 (i = 0..8 along the row, j = 0..5;
                           j outer, i inner, OpenCV's calibration-sample order)
  opencv_projections.csv   view,i,j,u,v: cv2.projectPoints of every corner with the camera matrix,
                           the 5 distortion coefficients and view `view`'s pose, where view k is
                           row k (0-based) of `extrinsic_parameters` (rvec then tvec)
  opencv_undistort.csv     u,v,u_ideal,v_ideal: cv2.undistortPointsIter(..., P=K) (OpenCV 4;
                           undistortPoints with criteria in OpenCV 5) with 100 iterations / eps 1e-12 on a 40-px grid over the whole 640x480 image,
                           borders (u = 639, v = 479) included
  left_intrinsics.xml      the same calibration written by cv2.FileStorage as XML (the XML
                           loader's real-world input)
"""

import os
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data", "chessboard")
BOARD_W, BOARD_H, SQUARE = 9, 6, 0.025
WIDTH, HEIGHT = 640, 480


def fmt(v):
    # repr() is the shortest text that reads back to the same double.
    return repr(float(v))


def main():
    fs = cv2.FileStorage(os.path.join(DATA, "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    K = fs.getNode("camera_matrix").mat()
    dist = fs.getNode("distortion_coefficients").mat().reshape(-1)
    ext = fs.getNode("extrinsic_parameters").mat()
    width = int(fs.getNode("image_width").real())
    height = int(fs.getNode("image_height").real())
    fs.release()
    assert K.shape == (3, 3) and dist.shape == (5,) and ext.shape[1] == 6
    assert (width, height) == (WIDTH, HEIGHT)

    # The board corners, j (rows) outer, i (columns) inner.
    ij = [(i, j) for j in range(BOARD_H) for i in range(BOARD_W)]
    obj = np.array([[SQUARE * i, SQUARE * j, 0.0] for i, j in ij], dtype=np.float64)
    with open(os.path.join(DATA, "board_corners.csv"), "w") as f:
        f.write("X,Y,Z\n")
        for p in obj:
            f.write(",".join(fmt(v) for v in p) + "\n")

    with open(os.path.join(DATA, "opencv_projections.csv"), "w") as f:
        f.write("view,i,j,u,v\n")
        for view, row in enumerate(ext):
            rvec, tvec = row[:3].reshape(3, 1), row[3:].reshape(3, 1)
            img, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
            for (i, j), uv in zip(ij, img.reshape(-1, 2)):
                f.write(f"{view},{i},{j},{fmt(uv[0])},{fmt(uv[1])}\n")

    # Undistortion reference on a coarse grid covering the whole image.
    us = list(range(0, WIDTH, 40)) + [WIDTH - 1]
    vs = list(range(0, HEIGHT, 40)) + [HEIGHT - 1]
    grid = np.array([[u, v] for v in vs for u in us], dtype=np.float64).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4.x
        ideal = cv2.undistortPointsIter(grid, K, dist, None, K, crit)
    else:  # OpenCV 5 folded the criteria into undistortPoints
        ideal = cv2.undistortPoints(grid, K, dist, R=None, P=K, criteria=crit)
    ideal = ideal.reshape(-1, 2)
    # Check the reference itself: distorting the ideal pixels must give the grid back.
    n = np.linalg.solve(K, np.vstack([ideal.T, np.ones(len(ideal))])).T
    back, _ = cv2.projectPoints(n, np.zeros(3), np.zeros(3), K, dist)
    residual = np.abs(back.reshape(-1, 2) - grid.reshape(-1, 2)).max()
    print(f"undistortPointsIter round-trip residual: {residual:.3g} px")
    assert residual < 1e-6, "OpenCV's iteration did not converge: the fixture would be wrong"
    with open(os.path.join(DATA, "opencv_undistort.csv"), "w") as f:
        f.write("u,v,u_ideal,v_ideal\n")
        for p, q in zip(grid.reshape(-1, 2), ideal):
            f.write(f"{int(p[0])},{int(p[1])},{fmt(q[0])},{fmt(q[1])}\n")

    out = cv2.FileStorage(
        os.path.join(DATA, "left_intrinsics.xml"),
        cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_XML,
    )
    out.write("image_width", width)
    out.write("image_height", height)
    out.write("camera_matrix", K)
    out.write("distortion_coefficients", dist.reshape(5, 1))
    out.release()

    # Which image is which view: detect the corners and match them to the projections (the
    # per-view reprojection errors in the YAML are ~0.2 px, so the match is unambiguous).
    for view, row in enumerate(ext):
        img_pts, _ = cv2.projectPoints(obj, row[:3], row[3:], K, dist)
        img_pts = img_pts.reshape(-1, 2)
        best = None
        for name in sorted(os.listdir(DATA)):
            if not (name.startswith("left") and name.endswith(".jpg")):
                continue
            gray = cv2.imread(os.path.join(DATA, name), cv2.IMREAD_GRAYSCALE)
            ok, corners = cv2.findChessboardCorners(gray, (BOARD_W, BOARD_H))
            if not ok:
                continue
            corners = cv2.cornerSubPix(
                gray, corners, (11, 11), (-1, -1),
                (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-3),
            ).reshape(-1, 2)
            err = min(
                np.sqrt(((corners - img_pts) ** 2).sum(1)).mean(),
                np.sqrt(((corners[::-1] - img_pts) ** 2).sum(1)).mean(),
            )
            if best is None or err < best[0]:
                best = (err, name)
        print(f"view {view:2d}: {best[1]} (mean corner distance {best[0]:.3f} px)")

    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}: fixtures written to {DATA}")


if __name__ == "__main__":
    sys.exit(main())
