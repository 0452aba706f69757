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


SYN_BROWN = {"K": [800.0, 790.0, 330.0, 245.0], "dist": [-0.25, 0.08, 0.001, -0.0005, 0.02]}
SYN_FISHEYE = {"K": [260.0, 258.0, 322.0, 238.0], "dist": [0.06, -0.02, 0.008, -0.002]}
SYN_NOISE = [0.0, 0.1, 0.5, 1.0]
SYN_VIEWS = 12
SQUARE = 0.025


def syn_project(model, obj, rvec, tvec):
    fx, fy, cx, cy = model["K"]
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    if len(model["dist"]) == 5:
        p, _ = cv2.projectPoints(obj, rvec, tvec, K, np.array(model["dist"]))
    else:
        p, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, K, np.array(model["dist"]))
    return p.reshape(-1, 2)


def synthetic():
    """Known boards through known cameras: calibration with exact ground truth.

    synthetic.csv: model,noise,view,k,u,v: cv2.projectPoints (Brown-Conrady) or
    cv2.fisheye.projectPoints (Kannala-Brandt) of the 9x6 board (25 mm) at 12 random poses
    (numpy seed 7, the whole board inside 640x480 with 10 px margin), plus Gaussian noise of
    sigma `noise` px (seed 11 + 1000 noise). synthetic_opencv.json: the truth and, per model and
    noise, cv2.calibrateCamera (flags 0) or cv2.fisheye.calibrate (RECOMPUTE_EXTRINSIC |
    FIX_SKEW, 100 iterations / eps 1e-12) on the same points: rms, K, dist.
    """
    obj = np.array([[SQUARE * i, SQUARE * j, 0.0] for j in range(BOARD[1]) for i in range(BOARD[0])])
    out = {"opencv": cv2.__version__, "brown": {"truth": SYN_BROWN}, "fisheye": {"truth": SYN_FISHEYE}}
    rows = []
    for name, model in (("brown", SYN_BROWN), ("fisheye", SYN_FISHEYE)):
        rng = np.random.default_rng(7)
        poses = []
        while len(poses) < SYN_VIEWS:
            rvec = rng.uniform(-0.6, 0.6, 3)
            rvec[2] = rng.uniform(-0.8, 0.8)
            z = rng.uniform(0.25, 0.5) if name == "brown" else rng.uniform(0.12, 0.3)
            centre = np.array([0.1, 0.0625, 0.0])
            R, _ = cv2.Rodrigues(rvec)
            # Board centre placed anywhere in view.
            off = rng.uniform(-0.5, 0.5, 2) * z * (0.5 if name == "brown" else 1.2)
            tvec = np.array([off[0], off[1], z]) - R @ centre
            p = syn_project(model, obj, rvec, tvec)
            if np.all(p[:, 0] > 10) and np.all(p[:, 0] < 630) and np.all(p[:, 1] > 10) and np.all(p[:, 1] < 470):
                poses.append((rvec, tvec, p))
        for noise in SYN_NOISE:
            nrng = np.random.default_rng(11 + int(1000 * noise))
            pts = []
            for v, (_, _, p) in enumerate(poses):
                q = p + nrng.normal(0.0, noise, p.shape) if noise > 0 else p.copy()
                pts.append(q.astype(np.float64))
                for k in range(len(q)):
                    rows.append((name, noise, v, k, q[k, 0], q[k, 1]))
            objs = [obj.astype(np.float64)] * SYN_VIEWS
            if name == "brown":
                rms, K, dist, _, _ = cv2.calibrateCamera(
                    [o.astype(np.float32) for o in objs], [q.astype(np.float32) for q in pts], (640, 480), None, None
                )
                d = dist.reshape(-1)[:5]
            else:
                flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
                crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
                rms, K, dist, _, _ = cv2.fisheye.calibrate(
                    [o.reshape(1, -1, 3) for o in objs], [q.reshape(1, -1, 2) for q in pts], (640, 480),
                    np.zeros((3, 3)), np.zeros((4, 1)), flags=flags, criteria=crit,
                )
                d = dist.reshape(-1)
            out[name][str(noise)] = {
                "rms": float(rms),
                "K": [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])],
                "dist": [float(x) for x in d],
            }
            print(name, noise, "rms", round(float(rms), 4), "K", np.round(out[name][str(noise)]["K"], 3))
    with open(os.path.join(OUT, "synthetic.csv"), "w") as f:
        f.write("model,noise,view,k,u,v\n")
        for r in rows:
            f.write(f"{r[0]},{r[1]},{r[2]},{r[3]},{float(r[4])!r},{float(r[5])!r}\n")
    with open(os.path.join(OUT, "synthetic_opencv.json"), "w") as f:
        json.dump(out, f, indent=1)


def pattern(w, h):
    """The remap test's source frame, also computed by the Rust test: 8-px checks with a ramp."""
    y, x = np.mgrid[0:h, 0:w]
    return ((((x // 8 + y // 8) % 2) * 150 + (x + 2 * y) % 100)).astype(np.uint8)


def undistort():
    """Frame undistortion references.

    undistort.json: for the bundled camera (left_intrinsics.yml, 640x480)
    cv2.getOptimalNewCameraMatrix at alpha 0, 0.5, 1; for the synthetic fisheye camera
    cv2.fisheye.estimateNewCameraMatrixForUndistortRectify at balance 0, 0.5, 1 (R = I).
    undistort_map.csv: model,x,y,mx,my,qx,qy: cv2.initUndistortRectifyMap (Brown, new K of
    alpha 0) and cv2.fisheye.initUndistortRectifyMap (new K of balance 0.5) every 16 px, as
    CV_32FC1 (mx, my) and as CV_16SC2 + CV_16UC1 folded into Q10.5 (qx = 32 m1.x + m2 % 32,
    qy = 32 m1.y + m2 / 32). undistort_remap.png: cv2.remap of pattern(640, 480) through the
    Brown CV_16SC2 map, INTER_LINEAR, BORDER_CONSTANT 0.
    """
    fs = cv2.FileStorage(os.path.join(DATA, "chessboard", "left_intrinsics.yml"), cv2.FILE_STORAGE_READ)
    K = fs.getNode("camera_matrix").mat()
    dist = fs.getNode("distortion_coefficients").mat().reshape(-1)
    fs.release()
    size = (640, 480)
    out = {"brown": {}, "fisheye": {}}
    for a in (0.0, 0.5, 1.0):
        nk, _ = cv2.getOptimalNewCameraMatrix(K, dist, size, a, size)
        out["brown"][str(a)] = [float(nk[0, 0]), float(nk[1, 1]), float(nk[0, 2]), float(nk[1, 2])]
    fx, fy, cx, cy = SYN_FISHEYE["K"]
    Kf = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    Df = np.array(SYN_FISHEYE["dist"])
    for b in (0.0, 0.5, 1.0):
        nk = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(Kf, Df, size, np.eye(3), balance=b)
        out["fisheye"][str(b)] = [float(nk[0, 0]), float(nk[1, 1]), float(nk[0, 2]), float(nk[1, 2])]
    with open(os.path.join(OUT, "undistort.json"), "w") as f:
        json.dump(out, f, indent=1)
    rows = []
    nkb, _ = cv2.getOptimalNewCameraMatrix(K, dist, size, 0.0, size)
    nkf = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(Kf, Df, size, np.eye(3), balance=0.5)
    maps = {
        "brown": (
            cv2.initUndistortRectifyMap(K, dist, None, nkb, size, cv2.CV_32FC1),
            cv2.initUndistortRectifyMap(K, dist, None, nkb, size, cv2.CV_16SC2),
        ),
        "fisheye": (
            cv2.fisheye.initUndistortRectifyMap(Kf, Df, np.eye(3), nkf, size, cv2.CV_32FC1),
            cv2.fisheye.initUndistortRectifyMap(Kf, Df, np.eye(3), nkf, size, cv2.CV_16SC2),
        ),
    }
    for name, ((fx_, fy_), (m1, m2)) in maps.items():
        for y in range(0, 480, 16):
            for x in range(0, 640, 16):
                qx = 32 * int(m1[y, x, 0]) + int(m2[y, x]) % 32
                qy = 32 * int(m1[y, x, 1]) + int(m2[y, x]) // 32
                rows.append((name, x, y, float(fx_[y, x]), float(fy_[y, x]), qx, qy))
    with open(os.path.join(OUT, "undistort_map.csv"), "w") as f:
        f.write("model,x,y,mx,my,qx,qy\n")
        for r in rows:
            f.write(f"{r[0]},{r[1]},{r[2]},{r[3]!r},{r[4]!r},{r[5]},{r[6]}\n")
    m1, m2 = maps["brown"][1]
    img = cv2.remap(pattern(640, 480), m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    cv2.imwrite(os.path.join(OUT, "undistort_remap.png"), img)
    print("undistort: brown", out["brown"], "fisheye", out["fisheye"])


def main():
    os.makedirs(OUT, exist_ok=True)
    parts = sys.argv[1:] or ["real"]
    for p in parts:
        globals()[p]()
    print("OpenCV", cv2.__version__)


if __name__ == "__main__":
    main()
