#!/usr/bin/env python3
"""Renders views of an ArUco GridBoard with exact ground truth, by OpenCV and numpy only.

    python3 host-tests/scripts/board_render.py test        # host-tests/data/board/ (committed)
    python3 host-tests/scripts/board_render.py bench DIR   # the views bench_board.py measures

The board: OpenCV's `cv2.aruco.GridBoard((5, 4), 0.04, 0.01, DICT_4X4_50)` (ids 0..19, row by
row), drawn by `board.generateImage` at 20 pixels a cell (a marker 120 px, a gap 30 px) with a
40 px white margin, so board point (X, Y) (metres, OpenCV's board frame: x right, y down the
drawn board, z into it) is board-image pixel 40 - 0.5 + 3000 (X, Y) (pixel centres at
integers). The script checks this on the flat image: OpenCV's ArucoDetector finds every marker
there within 0.1 px of `board.getObjPoints()` mapped so.

A view: the board at a random pose (tilt 0..55 deg about a random in-image axis, in-plane
turn +-30 deg, distance so that it spans 40..90 % of the frame), composited over a background
by apriltag_render.py's `render` (supersampled `cv2.warpPerspective` of the drawn board by
K [r1 r2 t] S, box filter, blur, sensor noise, 8 bits); no lens distortion. A fraction of the
tags is hidden, by one of:
  * `cover`: grey patches painted over the hidden tags' quads (grown by a quarter of the gap,
    so the neighbours stay clear);
  * `frame`: the board moved so that part of it is out of the frame.
A tag is visible when its four corners are 4 px or more inside the frame and no patch touches
it. Bins: 100 %, 50 %, 25 % of the 20 tags visible (20, 10, 5; `frame` views are accepted
within one tag of the bin). Truth: rvec, tvec of X_cam = R X_board + t, and the visible ids.

`test`: 6 views of 320x240 (K = [300 0 159.5; 0 300 119.5]) on a plain, shaded background
(small PNGs): one `full`, `cover` and `frame` at 50 %, `cover` and `frame` at 25 %, and one
`full` at a steep tilt; with board.json / board.yml (the board file `camgeom apriltag --board`
reads), camera.json, truth.json (the views, and OpenCV's own board pose on each: ArucoDetector
with default parameters, `board.matchImagePoints`, `solvePnP` ITERATIVE) and objpoints.json
(`getObjPoints()` of two grids, for the layout test). Seed 41.

`bench DIR`: 640x480 (K = [600 0 319.5; 0 600 239.5]) over bundled photos, `--per-bin`
views (default 20) a bin and way of hiding, into DIR/NNNN.png with DIR/truth.json,
DIR/camera.json and DIR/board.json. Seed 42.
"""
import argparse
import json
import math
import os
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import apriltag_render as ar  # noqa: E402

ROOT = os.path.dirname(HERE)
DATA = os.path.join(ROOT, "data")
DICT = "DICT_4X4_50"
NX, NY, LENGTH, SEP = 5, 4, 0.04, 0.01
CELL = 20  # board-image pixels per marker cell
MARKER_PX = 6 * CELL  # DICT_4X4: 4 cells plus the one-cell border on each side
SEP_PX = int(round(MARKER_PX * SEP / LENGTH))
MARGIN = 40
PX_PER_M = MARKER_PX / LENGTH
BINS = [1.0, 0.5, 0.25]


def board():
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICT))
    return cv2.aruco.GridBoard((NX, NY), LENGTH, SEP, d), d


def board_image(b):
    w = NX * MARKER_PX + (NX - 1) * SEP_PX + 2 * MARGIN
    h = NY * MARKER_PX + (NY - 1) * SEP_PX + 2 * MARGIN
    img = b.generateImage((w, h), marginSize=MARGIN, borderBits=1)
    assert img.shape == (h, w)
    return img


def to_metres():
    """S: board-image pixel (u, v) to board metres (X, Y, 1)."""
    k = 1.0 / PX_PER_M
    o = MARGIN - 0.5
    return np.array([[k, 0, -k * o], [0, k, -k * o], [0, 0, 1.0]])


def check_layout(b, img):
    """The drawn board is where getObjPoints says: each marker's black border spans exactly the
    pixels between its mapped corners (edges at half pixels), in a window reaching half the gap
    around it. (OpenCV's detector itself puts a sharp image's corners half a pixel inside.)"""
    obj = np.array(b.getObjPoints())
    half = SEP_PX // 2
    for q in obj:
        e = q[:, :2] * PX_PER_M + MARGIN - 0.5  # pixel edges
        x0, y0 = int(round(e[:, 0].min() + 0.5)), int(round(e[:, 1].min() + 0.5))
        x1, y1 = int(round(e[:, 0].max() - 0.5)), int(round(e[:, 1].max() - 0.5))
        win = img[y0 - half:y1 + half + 1, x0 - half:x1 + half + 1]
        ys, xs = np.nonzero(win < 128)
        assert (xs.min() + x0 - half, xs.max() + x0 - half) == (x0, x1), q
        assert (ys.min() + y0 - half, ys.max() + y0 - half) == (y0, y1), q
        assert (win[half:-half, half:-half][[0, -1], :] < 128).all()  # the border rows


def project(K, R, t, X):
    p = (K @ (R @ np.asarray(X, float).T + t[:, None])).T
    return p[:, :2] / p[:, 2:]


def tag_quads(b, K, R, t):
    return [project(K, R, t, q) for q in np.array(b.getObjPoints(), dtype=float)]


def inside(q, W, H, m=4.0):
    return bool((q[:, 0] >= m).all() and (q[:, 0] <= W - 1 - m).all() and
                (q[:, 1] >= m).all() and (q[:, 1] <= H - 1 - m).all())


def grow(q, by):
    c = q.mean(axis=0)
    return c + (q - c) * by


def pose(rng, K, W, H, tilt_max, span):
    R = ar.rotation(rng.uniform(0, tilt_max), rng.uniform(0, 360), rng.uniform(-30, 30))
    # The board centred at the origin: X_cam = R (X - c) + t_c, i.e. t = t_c - R c.
    c = np.array([(NX * LENGTH + (NX - 1) * SEP) / 2, (NY * LENGTH + (NY - 1) * SEP) / 2, 0.0])
    size = NX * LENGTH + (NX - 1) * SEP
    dist = K[0, 0] * size / (span * W)
    return R, c, dist


def view(rng, b, K, W, H, way, frac, tilt_max=55.0):
    """A pose and the patches hiding tags, with the visible ids: None when the draw misses."""
    n = NX * NY
    want = int(round(frac * n))
    span = rng.uniform(0.4, 0.9) if way != "frame" else rng.uniform(0.6, 1.1)
    R, c, dist = pose(rng, K, W, H, tilt_max, span)
    if way == "frame":
        # The board's centre anywhere up to a board's width beyond the frame's centre.
        u = np.array([rng.uniform(-0.3 * W, 1.3 * W), rng.uniform(-0.3 * H, 1.3 * H), 1.0])
    else:
        u = np.array([rng.uniform(0.35 * W, 0.65 * W), rng.uniform(0.35 * H, 0.65 * H), 1.0])
    ray = np.linalg.solve(K, u)
    t = ray / ray[2] * dist - R @ c
    quads = tag_quads(b, K, R, t)
    if any((R @ q3 + t)[2] <= 0.01 for q in np.array(b.getObjPoints()) for q3 in q):
        return None
    shown = [i for i, q in enumerate(quads) if inside(q, W, H)]
    patches = []
    if way == "frame":
        if abs(len(shown) - want) > (0 if frac == 1.0 else 1) or not shown:
            return None
    else:
        if len(shown) != n:
            return None
        hide = sorted(rng.choice(n, n - want, replace=False).tolist()) if want < n else []
        grown = 1 + 0.25 * SEP / LENGTH
        for i in hide:
            patches.append((grow(quads[i], grown), rng.uniform(0.3, 0.7)))
        shown = [i for i in shown if i not in hide]
    return R, t, shown, patches


def render(bg, img, Hm, patches, rng, W, H, ss=4, blur=0.5, noise=1.5):
    """apriltag_render.render's compositing with several grey patches painted over the scene
    (supersampled, anti-aliased), then the same box filter, blur and sensor noise."""
    A = ar.supersample(ss)
    big = cv2.resize(bg, (W * ss, H * ss), interpolation=cv2.INTER_LINEAR)
    Hh = A @ Hm
    warped = cv2.warpPerspective(0.08 + 0.84 * img, Hh, (W * ss, H * ss), flags=cv2.INTER_LINEAR)
    mask = cv2.warpPerspective(np.ones_like(img), Hh, (W * ss, H * ss), flags=cv2.INTER_LINEAR)
    big = big * (1 - mask) + warped
    for poly, level in patches:
        m = np.zeros_like(big)
        pts = np.round((np.asarray(poly) * ss + (ss - 1) / 2) * 16).astype(np.int32)
        cv2.fillPoly(m, [pts], 1.0, lineType=cv2.LINE_AA, shift=4)
        big = big * (1 - m) + level * m
    low = cv2.resize(big, (W, H), interpolation=cv2.INTER_AREA) * 255.0
    if blur > 0:
        low = cv2.GaussianBlur(low, (0, 0), blur)
    sigma = np.sqrt(noise ** 2 + 0.02 * np.maximum(low, 0))
    low = low + rng.normal(0, 1, low.shape) * sigma
    return np.clip(np.round(low), 0, 255).astype(np.uint8)


def plain_background(rng, W, H):
    x, y = np.meshgrid(np.linspace(0, 1, W), np.linspace(0, 1, H))
    a, bx, by = rng.uniform(0.3, 0.5), rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15)
    return (a + bx * x + by * y).astype(np.float32)


def opencv_pose(b, img, K, flags=cv2.SOLVEPNP_ITERATIVE):
    """ArucoDetector (defaults) + matchImagePoints + solvePnP: (rvec, tvec, ids) or None."""
    det = cv2.aruco.ArucoDetector(b.getDictionary(), cv2.aruco.DetectorParameters())
    corners, ids, _ = det.detectMarkers(img)
    if ids is None or len(ids) == 0:
        return None
    obj, pix = b.matchImagePoints(corners, ids)
    if obj is None or len(obj) < 4:
        return None
    ok, rvec, tvec = cv2.solvePnP(obj, pix, K, np.zeros(5), flags=flags)
    if not ok:
        return None
    return rvec.ravel(), tvec.ravel(), sorted(int(i) for i in ids.ravel() if i < NX * NY)


def board_file(path):
    with open(path, "w") as f:
        json.dump({"family": DICT, "grid": {"markers_x": NX, "markers_y": NY,
                                            "marker_length": LENGTH, "marker_separation": SEP,
                                            "first_id": 0}}, f, indent=2)
        f.write("\n")


def camera_file(path, K, W, H):
    with open(path, "w") as f:
        json.dump({"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2], "skew": 0.0,
                   "distortion": [0.0] * 5, "width": W, "height": H}, f, indent=2)
        f.write("\n")


def make(out, plan, W, H, K, rng, background, with_opencv):
    os.makedirs(out, exist_ok=True)
    b, _ = board()
    img = board_image(b)
    check_layout(b, img)
    img = img.astype(np.float32) / 255.0
    Hs = to_metres()
    views = []
    for k, (way, frac, tilt_max) in enumerate(plan):
        for _ in range(5000):
            v = view(rng, b, K, W, H, way, frac, tilt_max)
            if v is not None:
                break
        else:
            raise RuntimeError(f"cannot place a {way} view at {frac}")
        R, t, shown, patches = v
        Hm = K @ np.column_stack([R[:, 0], R[:, 1], t]) @ Hs
        frame = render(background(rng), img, Hm, patches, rng, W, H)
        name = f"{k:04d}.png"
        cv2.imwrite(os.path.join(out, name), frame, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        rvec, _ = cv2.Rodrigues(R)
        entry = {"image": name, "way": way, "bin": frac, "visible": shown,
                 "rvec": rvec.ravel().tolist(), "tvec": t.tolist()}
        if with_opencv:
            p = opencv_pose(b, frame, K)
            entry["opencv"] = None if p is None else {
                "rvec": p[0].tolist(), "tvec": p[1].tolist(), "ids": p[2]}
        views.append(entry)
    with open(os.path.join(out, "truth.json"), "w") as f:
        json.dump({"board": {"dictionary": DICT, "size": [NX, NY], "marker_length": LENGTH,
                             "marker_separation": SEP}, "opencv": cv2.__version__,
                   "views": views}, f, indent=1)
        f.write("\n")
    board_file(os.path.join(out, "board.json"))
    camera_file(os.path.join(out, "camera.json"), K, W, H)
    return views


def objpoints(path):
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    grids = []
    for (nx, ny, length, sep, first) in [(5, 4, 0.04, 0.01, 0), (3, 2, 0.035, 0.0071, 7)]:
        ids = np.arange(first, first + nx * ny, dtype=np.int32)
        g = cv2.aruco.GridBoard((nx, ny), length, sep, d, ids)
        grids.append({"markers_x": nx, "markers_y": ny, "marker_length": length,
                      "marker_separation": sep, "first_id": first,
                      "ids": g.getIds().ravel().tolist(),
                      # float32 as OpenCV holds them, written exactly.
                      "objpoints": [[[float(v) for v in c] for c in q]
                                    for q in np.array(g.getObjPoints())]})
    with open(path, "w") as f:
        json.dump({"opencv": cv2.__version__, "grids": grids}, f, indent=1)
        f.write("\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["test", "bench"])
    ap.add_argument("out", nargs="?")
    ap.add_argument("--per-bin", type=int, default=20)
    args = ap.parse_args()
    if args.what == "test":
        out = args.out or os.path.join(DATA, "board")
        W, H = 320, 240
        K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
        plan = [("full", 1.0, 40.0), ("cover", 0.5, 55.0), ("frame", 0.5, 55.0),
                ("cover", 0.25, 55.0), ("frame", 0.25, 55.0), ("full", 1.0, 65.0)]
        rng = np.random.default_rng(41)
        views = make(out, plan, W, H, K, rng, lambda r: plain_background(r, W, H), True)
        objpoints(os.path.join(out, "objpoints.json"))
        with open(os.path.join(out, "board.yml"), "w") as f:
            f.write(f"%YAML:1.0\n---\nfamily: {DICT}\ngrid:\n   markers_x: {NX}\n"
                    f"   markers_y: {NY}\n   marker_length: {LENGTH}\n"
                    f"   marker_separation: {SEP}\n   first_id: 0\n")
    else:
        out = args.out
        W, H = 640, 480
        K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
        plan = [(way, frac, 55.0) for frac in BINS
                for way in (["full"] if frac == 1.0 else ["cover", "frame"])
                for _ in range(args.per_bin * (2 if frac == 1.0 else 1))]
        rng = np.random.default_rng(42)
        ar.W, ar.H = W, H

        def photo(r):
            ar.W, ar.H = W, H
            return ar.background(r)[0]
        views = make(out, plan, W, H, K, rng, photo, False)
    print(f"{len(views)} views -> {out}")


if __name__ == "__main__":
    main()
