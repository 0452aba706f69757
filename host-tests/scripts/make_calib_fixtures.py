#!/usr/bin/env python3
"""OpenCV reference results for camgeom's chessboard detection and calibration tests.

Nothing here runs during `cargo test`: the outputs are committed. Regenerate from the
repository root with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_calib_fixtures.py            # everything
    python3 host-tests/scripts/make_calib_fixtures.py real       # one part: real, rendered, synthetic

Outputs (host-tests/data/fixtures/calib/):
  real_corners.csv   image,k,u0,v0,u5,v5,u11,v11: cv2.findChessboardCorners (9x6, default flags)
                     on each bundled left*.jpg, in OpenCV's own order (k = j * 9 + i), raw (u0, v0),
                     after cv2.cornerSubPix 5x5 / COUNT+EPS 30 / 0.1 (OpenCV's test_calibration.py)
                     and after cornerSubPix 11x11 / 30 / 0.001 (OpenCV's calibration sample); plus
                     sb_u, sb_v: cv2.findChessboardCornersSB (default flags) reordered to match.
  real_opencv.json   cv2.calibrateCameraExtended (flags 0) on the 5x5 corners and on the 11x11
                     corners: rms, K, dist (k1 k2 p1 p2 k3), per-view rms, std of the intrinsics.
  rendered/*.png,    boards rendered by OpenCV (see render()), with truth and OpenCV's corners:
  rendered.csv       case,k,u_true,v_true,u_cv,v_cv,u_sb,v_sb (empty when OpenCV found nothing).
  synthetic.csv,     calibration with exact ground truth (see synthetic()).
  synthetic_opencv.json
"""

import glob
import json
import os
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data")
OUT = os.path.join(DATA, "fixtures", "calib")
BOARD = (9, 6)


def calibrate(obj, pts, size, flags=0):
    rms, K, dist, rvecs, tvecs, std_in, std_ex, per_view = cv2.calibrateCameraExtended(
        obj, pts, size, None, None, flags=flags
    )
    return {
        "rms": float(rms),
        "K": [float(x) for x in K.reshape(-1)],
        "dist": [float(x) for x in dist.reshape(-1)[:5]],
        "per_view_rms": [float(x) for x in per_view.reshape(-1)],
        "std_intrinsics": [float(x) for x in std_in.reshape(-1)[:9]],
        "rvecs": [[float(x) for x in r.reshape(-1)] for r in rvecs],
        "tvecs": [[float(x) for x in t.reshape(-1)] for t in tvecs],
    }


def real():
    obj1 = np.zeros((BOARD[0] * BOARD[1], 3), np.float32)
    obj1[:, :2] = np.indices(BOARD).T.reshape(-1, 2)
    rows, pts5, pts11 = [], [], []
    names = []
    for path in sorted(glob.glob(os.path.join(DATA, "chessboard", "left*.jpg"))):
        name = os.path.splitext(os.path.basename(path))[0]
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        ok, c0 = cv2.findChessboardCorners(gray, BOARD)
        assert ok, name
        c5 = cv2.cornerSubPix(gray, c0.copy(), (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.1))
        c11 = cv2.cornerSubPix(gray, c0.copy(), (11, 11), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001))
        oksb, sb = cv2.findChessboardCornersSB(gray, BOARD)
        sb = sb.reshape(-1, 2) if oksb else None
        if sb is not None:
            # Match SB's order to the classic detector's by nearest corner.
            d = np.linalg.norm(sb[None, :, :] - c11.reshape(-1, 1, 2), axis=2)
            sb = sb[np.argmin(d, axis=1)]
        names.append(name)
        pts5.append(c5.reshape(-1, 2))
        pts11.append(c11.reshape(-1, 2))
        for k in range(BOARD[0] * BOARD[1]):
            r = [name, k, *c0.reshape(-1, 2)[k], *c5.reshape(-1, 2)[k], *c11.reshape(-1, 2)[k]]
            r += list(sb[k]) if sb is not None else ["", ""]
            rows.append(r)
    with open(os.path.join(OUT, "real_corners.csv"), "w") as f:
        f.write("image,k,u0,v0,u5,v5,u11,v11,sb_u,sb_v\n")
        for r in rows:
            f.write(",".join(str(x) if isinstance(x, (str, int)) else repr(float(x)) for x in r) + "\n")
    size = (640, 480)
    res = {
        "opencv": cv2.__version__,
        "images": names,
        "subpix5": calibrate([obj1] * len(names), pts5, size),
        "subpix11": calibrate([obj1] * len(names), pts11, size),
    }
    with open(os.path.join(OUT, "real_opencv.json"), "w") as f:
        json.dump(res, f, indent=1)
    print("real: subpix5 rms", res["subpix5"]["rms"], "subpix11 rms", res["subpix11"]["rms"])


def main():
    os.makedirs(OUT, exist_ok=True)
    parts = sys.argv[1:] or ["real"]
    for p in parts:
        globals()[p]()
    print("OpenCV", cv2.__version__)


if __name__ == "__main__":
    main()
