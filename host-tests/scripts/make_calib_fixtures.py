#!/usr/bin/env python3
"""OpenCV reference results for camgeom's chessboard detection and calibration tests.

Nothing here runs during `cargo test`: the outputs are committed. Regenerate from the
repository root with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_calib_fixtures.py            # everything
    python3 host-tests/scripts/make_calib_fixtures.py real       # one part: real, synthetic, undistort, rendered

Outputs (host-tests/data/fixtures/calib/):
  real_corners.csv   image,k,u0,v0,u5,v5,u11,v11: cv2.findChessboardCorners (9x6, default flags)
                     on each bundled left*.jpg, in OpenCV's own order (k = j * 9 + i), raw (u0, v0),
                     after cv2.cornerSubPix 5x5 / COUNT+EPS 30 / 0.1 (OpenCV's test_calibration.py)
                     and after cornerSubPix 11x11 / 30 / 0.001 (OpenCV's calibration sample); plus
                     sb_u, sb_v: cv2.findChessboardCornersSB (default flags) reordered to match.
  real_opencv.json   cv2.calibrateCameraExtended (flags 0) on the 5x5 corners and on the 11x11
                     corners: rms, K, dist (k1 k2 p1 p2 k3), per-view rms, std of the intrinsics.
  synthetic.csv,     calibration with exact ground truth (see synthetic()).
  synthetic_opencv.json
  undistort.json,    new camera matrices, undistortion maps and a remapped frame (see undistort()).
  undistort_map.csv, undistort_remap.png
  rendered/*.png,    boards rendered by OpenCV (see render()), with truth and OpenCV's corners:
  rendered.csv,      case,k,u_true,v_true,u_cv,v_cv,u_sb,v_sb,cv_index (empty when OpenCV found
  rendered_cases.csv nothing); the cases' sizes and what each detector found.
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


# Rendered cases: name, (w, h), board (cols, rows), lens ("none", "brown", "fisheye"),
# rvec, tvec (board units: squares), options. Cameras are chosen per size.
RENDER_CASES = [
    ("fronto", (640, 480), (9, 6), "none", (0.0, 0.0, 0.0), (-4.0, -2.5, 16.0), {}),
    ("rot30", (640, 480), (9, 6), "none", (0.1, -0.15, 0.52), (-3.5, -3.0, 15.0), {}),
    ("rot135", (320, 240), (9, 6), "none", (0.2, 0.1, 2.36), (3.0, 1.0, 18.0), {}),
    ("rot250", (320, 240), (7, 5), "none", (-0.2, 0.3, 4.36), (-1.0, 4.0, 15.0), {}),
    ("perspective", (640, 480), (9, 6), "none", (0.95, 0.2, 0.1), (-4.0, -1.5, 11.0), {}),
    ("perspective2", (320, 240), (9, 6), "none", (-0.2, -1.0, -0.3), (-3.0, -3.0, 13.0), {}),
    ("uneven", (320, 240), (9, 6), "none", (0.3, -0.3, 0.2), (-4.0, -2.5, 16.0), {"light": True}),
    ("border", (320, 240), (9, 6), "none", (0.05, 0.05, 0.03), (-4.7, -2.55, 10.2), {}),
    ("blurry", (320, 240), (9, 6), "none", (0.4, 0.2, -0.3), (-4.0, -2.5, 15.0), {"blur": 1.6, "noise": 3.0}),
    ("small", (320, 240), (9, 6), "none", (0.3, 0.3, 0.4), (-4.0, -2.5, 40.0), {}),
    ("brown", (640, 480), (9, 6), "brown", (0.2, -0.3, 0.1), (-4.0, -2.5, 9.5), {}),
    ("fisheye", (640, 480), (9, 6), "fisheye", (-0.3, 0.4, 0.2), (-4.0, -2.5, 8.5), {}),
    ("partial", (320, 240), (9, 6), "none", (0.1, -0.1, 0.2), (1.0, -2.5, 14.0), {}),
    ("absent", (320, 240), (9, 6), "none", (0.0, 0.0, 0.0), (40.0, 40.0, 10.0), {"texture": True}),
]


def render_camera(size, lens):
    w, h = size
    f = 0.9 * w
    K = np.array([[f, 0, (w - 1) / 2 + 3.0], [0, f * 1.01, (h - 1) / 2 - 2.0], [0, 0, 1.0]])
    if lens == "brown":
        return K, np.array([-0.3, 0.12, 0.001, -0.0008, -0.02])
    if lens == "fisheye":
        K[0, 0], K[1, 1] = 0.45 * w, 0.45 * w * 1.01
        return K, np.array([0.05, -0.02, 0.01, -0.003])
    return K, np.zeros(5)


def render(case, ss=4, sq=64):
    """Renders one case without any camgeom code: each of ss x ss supersamples of every pixel
    is undistorted by OpenCV (cv2.undistortPoints or cv2.fisheye.undistortPoints, 20
    iterations), its ray intersected with the board plane, the high-resolution board (sq px a
    square) sampled there by cv2.remap (INTER_LINEAR), the supersamples averaged
    (cv2.resize INTER_AREA), then optional uneven light, cv2.GaussianBlur and Gaussian noise
    (numpy seed 3). Truth: cv2.projectPoints / cv2.fisheye.projectPoints of the corners."""
    name, (w, h), (cols, rows), lens, rvec, tvec, opt = case
    K, D = render_camera((w, h), lens)
    m = sq
    board = np.full(((rows + 1) * sq + 2 * m, (cols + 1) * sq + 2 * m), 235, np.uint8)
    for j in range(rows + 1):
        for i in range(cols + 1):
            if (i + j) % 2 == 0:
                board[m + j * sq:m + (j + 1) * sq, m + i * sq:m + (i + 1) * sq] = 25
    ys, xs = np.mgrid[0:h * ss, 0:w * ss].astype(np.float64)
    pix = np.stack([(xs + 0.5) / ss - 0.5, (ys + 0.5) / ss - 0.5], axis=-1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)
    if lens == "fisheye":
        nrm = cv2.fisheye.undistortPoints(pix, K, D[:4], criteria=crit)
    else:
        nrm = cv2.undistortPoints(pix, K, D, None, None, None, crit)
    nrm = nrm.reshape(-1, 2)
    R, _ = cv2.Rodrigues(np.array(rvec))
    t = np.array(tvec)
    ray = np.concatenate([nrm, np.ones((len(nrm), 1))], axis=1) @ R  # R^T ray per row
    o = -R.T @ t
    lam = -o[2] / ray[:, 2]
    P = o[None, :] + lam[:, None] * ray
    valid = lam > 0
    bx = np.where(valid, m + (P[:, 0] + 1) * sq - 0.5, -1e4).reshape(h * ss, w * ss).astype(np.float32)
    by = np.where(valid, m + (P[:, 1] + 1) * sq - 0.5, -1e4).reshape(h * ss, w * ss).astype(np.float32)
    bg = 120
    big = cv2.remap(board, bx, by, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
    img = cv2.resize(big.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(3)
    if opt.get("texture"):
        img = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 2.0) * 1.5 - 60
    if opt.get("light"):
        yy, xx = np.mgrid[0:h, 0:w]
        img = img * (0.25 + 0.75 * xx / w) * (1.0 - 0.3 * ((yy - h / 2) / h) ** 2)
    img = cv2.GaussianBlur(img, (0, 0), opt.get("blur", 0.7))
    img = img + rng.normal(0, opt.get("noise", 1.5), img.shape)
    img = np.clip(np.round(img), 0, 255).astype(np.uint8)
    obj = np.array([[i, j, 0.0] for j in range(rows) for i in range(cols)])
    if lens == "fisheye":
        tr, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), np.array(rvec), t, K, D[:4])
    else:
        tr, _ = cv2.projectPoints(obj, np.array(rvec), t, K, D)
    tr = tr.reshape(-1, 2)
    inside = bool(np.all((tr[:, 0] > 0) & (tr[:, 0] < w - 1) & (tr[:, 1] > 0) & (tr[:, 1] < h - 1)))
    return img, tr, inside


def sweep_cases():
    """A rotation sweep: 24 in-plane rotations (15° apart) of a 9x6 board, tilted 20° about a
    varying axis, 320x240, light noise."""
    out = []
    for k in range(24):
        roll = np.deg2rad(15 * k)
        tilt = np.deg2rad(20)
        axis = np.array([np.cos(roll * 0.7), np.sin(roll * 0.7), 0.0]) * tilt
        R = cv2.Rodrigues(axis)[0] @ cv2.Rodrigues(np.array([0, 0, roll]))[0]
        rvec = cv2.Rodrigues(R)[0].reshape(-1)
        centre = np.array([4.0, 2.5, 0.0])
        tvec = np.array([0.0, 0.0, 17.0]) - R @ centre
        out.append((f"sweep{15 * k:03d}", (320, 240), (9, 6), "none", tuple(rvec), tuple(tvec), {"noise": 0.8}))
    return out


def rendered():
    """rendered/<case>.png and rendered.csv (see the module docstring); rendered_cases.csv:
    case,width,height,cols,rows,in_view,half_window,cv_found,sb_found."""
    d = os.path.join(OUT, "rendered")
    os.makedirs(d, exist_ok=True)
    rows_out, cases_out = [], []
    for case in RENDER_CASES + sweep_cases():
        name, (w, h), (cols, rows) = case[0], case[1], case[2]
        img, tr, inside = render(case)
        if name == "absent":
            inside = False
        cv2.imwrite(os.path.join(d, name + ".png"), img)
        half = 5 if w >= 640 else 3
        ok, c = cv2.findChessboardCorners(img, (cols, rows))
        if ok:
            c = cv2.cornerSubPix(img, c, (half, half), (-1, -1), (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001)).reshape(-1, 2)
        oksb, sb = cv2.findChessboardCornersSB(img, (cols, rows))
        sb = sb.reshape(-1, 2) if oksb else None
        cases_out.append((name, w, h, cols, rows, int(inside), half, int(ok), int(oksb)))
        for k in range(cols * rows):
            r = [name, k, tr[k, 0], tr[k, 1]]
            for pts in (c if ok else None, sb):
                if pts is None:
                    r += ["", ""]
                else:
                    # Each detector's corner nearest the truth (their order is checked apart).
                    j = int(np.argmin(np.linalg.norm(pts - tr[k], axis=1)))
                    r += [pts[j, 0], pts[j, 1]]
            r += [int(np.argmin(np.linalg.norm(c - tr[k], axis=1))) if ok else ""]
            rows_out.append(r)
        err = lambda p: np.linalg.norm(p - tr, axis=1) if p is not None else None
        print(name, "in view", inside, "cv", ok, "sb", oksb)
    with open(os.path.join(OUT, "rendered.csv"), "w") as f:
        f.write("case,k,u_true,v_true,u_cv,v_cv,u_sb,v_sb,cv_index\n")
        for r in rows_out:
            f.write(",".join(str(x) if isinstance(x, (str, int)) else repr(float(x)) for x in r) + "\n")
    with open(os.path.join(OUT, "rendered_cases.csv"), "w") as f:
        f.write("case,width,height,cols,rows,in_view,half_window,cv_found,sb_found\n")
        for r in cases_out:
            f.write(",".join(str(x) for x in r) + "\n")


def main():
    os.makedirs(OUT, exist_ok=True)
    parts = sys.argv[1:] or ["real", "synthetic", "undistort", "rendered"]
    for p in parts:
        globals()[p]()
    print("OpenCV", cv2.__version__)


if __name__ == "__main__":
    main()
