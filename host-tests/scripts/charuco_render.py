#!/usr/bin/env python3
"""Renders ChArUco calibration sets with exact ground truth, by OpenCV and numpy only.

    python3 host-tests/scripts/charuco_render.py [OUT]   # default host-tests/data/charuco
    python3 host-tests/scripts/charuco_render.py qvga [DIR]   # DIR/brown -> DIR/brown-320x240
    python3 host-tests/scripts/charuco_render.py heldout DIR  # DIR/heldout-{brown,fisheye}

The board: `cv2.aruco.CharucoBoard((11, 8), 0.030, 0.022, DICT_4X4_50)` (OpenCV's default,
non-legacy layout), drawn by `board.generateImage` at 8 px/mm on a white page with a 20 mm
margin, on a grey surround. Board frame as OpenCV's: x along the squares' columns, y down
the rows, origin at the board's outer top-left corner.

Two sets of 640x480 views, 10 each, from a known camera, posed close to the board so that
NO view shows the whole board (every view has board corners outside the frame, checked):

- `brown/`: fx 520, fy 516, cx 322.5, cy 238.0, k1 -0.30, k2 0.10, p1 0.001, p2 -0.0008,
  k3 -0.015 (cv2.projectPoints's model);
- `fisheye/`: fx 300, fy 299, cx 318.0, cy 242.5, k1..k4 0.05, -0.01, 0.003, -0.0005
  (cv2.fisheye's model).

Each pixel is the mean of 4x4 samples; a sample's ray is the exact inverse of the lens model
(Newton to 1e-12 on the normalised coordinates, checked by projecting forward with OpenCV to
below 1e-6 px), intersected with the board plane, and the page read bilinearly. Then a
Gaussian blur of 0.6 px and seeded noise of sigma 0.6 grey level, 8 bits.

Truth per set, `truth.yaml`: the camera, and per view its pose (Rodrigues, metres) and
`truth.csv`: view, ChArUco corner id, x, y of every corner inside the image (pixel (i, j)
centred at (i, j), projected by cv2.projectPoints / cv2.fisheye.projectPoints). Seed 41.

`qvga`: the brown set at 320x240 for the board (the emulated board's calibration job and its
ChArUco bench), `brown-320x240/`: each view reduced by `cv2.resize(INTER_AREA)` (an exact 2x2
mean), so a point at `x` in a 640x480 view is at `(x - 0.5) / 2` in its reduction (pixel
centres at integers); the truth follows: `fx / 2`, `fy / 2`, `(cx - 0.5) / 2`,
`(cy - 0.5) / 2`, the same distortion and poses, every truth corner moved so. Also
`opencv.csv`: `view,id,x,y` of what OpenCV's `CharucoDetector.detectBoard` (default
parameters) finds in each reduced view.
"""
import os
import sys

import cv2
import numpy as np

SQUARES = (11, 8)
SQUARE = 0.030
MARKER = 0.022
PPM = 8000.0  # texture pixels per metre
MARGIN = 0.020
W, H = 640, 480
SS = 4

CAMS = {
    "brown": dict(
        K=np.array([[520.0, 0, 322.5], [0, 516.0, 238.0], [0, 0, 1]]),
        D=np.array([-0.30, 0.10, 0.001, -0.0008, -0.015]),
        fisheye=False,
    ),
    "fisheye": dict(
        K=np.array([[300.0, 0, 318.0], [0, 299.0, 242.5], [0, 0, 1]]),
        D=np.array([0.05, -0.01, 0.003, -0.0005]),
        fisheye=True,
    ),
}


# Held-out cameras (`heldout`): other lenses, other poses (other seeds), the same board and
# renderer, to check that what was measured on the two sets above carries over.
HELDOUT = {
    "heldout-brown": dict(
        K=np.array([[480.0, 0, 314.0], [0, 483.0, 246.5], [0, 0, 1]]),
        D=np.array([-0.22, 0.05, -0.0012, 0.0006, 0.004]),
        fisheye=False,
        seed=4141,
    ),
    "heldout-fisheye": dict(
        K=np.array([[280.0, 0, 325.5], [0, 281.0, 236.0], [0, 0, 1]]),
        D=np.array([0.02, 0.005, -0.004, 0.0008]),
        fisheye=True,
        seed=4142,
    ),
}


def board():
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    b = cv2.aruco.CharucoBoard(SQUARES, SQUARE, MARKER, d)
    return b


def page(b):
    bw, bh = SQUARES[0] * SQUARE, SQUARES[1] * SQUARE
    img = b.generateImage((int(round(bw * PPM)), int(round(bh * PPM))), marginSize=0, borderBits=1)
    m = int(round(MARGIN * PPM))
    out = np.full((img.shape[0] + 2 * m, img.shape[1] + 2 * m), 255, np.uint8)
    out[m:m + img.shape[0], m:m + img.shape[1]] = img
    # texture pixel (i, j) centre = board point ((i + 0.5) / PPM - MARGIN, ...)
    return out.astype(np.float32)


def distort(x, y, cam):
    D = cam["D"]
    if cam["fisheye"]:
        r = np.hypot(x, y)
        th = np.arctan(r)
        t2 = th * th
        thd = th * (1 + D[0] * t2 + D[1] * t2**2 + D[2] * t2**3 + D[3] * t2**4)
        s = np.where(r > 1e-12, thd / np.maximum(r, 1e-300), 1.0)
        return x * s, y * s
    k1, k2, p1, p2, k3 = D
    r2 = x * x + y * y
    rad = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    return (x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)


def undistort(xd, yd, cam):
    """Newton on (x, y) with a numerical Jacobian, to 1e-12."""
    x, y = xd.copy(), yd.copy()
    if cam["fisheye"]:
        # start from the inverse of the equidistant model
        r = np.hypot(xd, yd)
        s = np.where(r > 1e-12, np.tan(np.minimum(r, 1.4)) / np.maximum(r, 1e-300), 1.0)
        x, y = xd * s, yd * s
    h = 1e-7
    for _ in range(50):
        fx, fy = distort(x, y, cam)
        ex, ey = fx - xd, fy - yd
        if max(np.abs(ex).max(), np.abs(ey).max()) < 1e-13:
            break
        ax, ay = distort(x + h, y, cam)
        bx, by = distort(x, y + h, cam)
        j11, j21 = (ax - fx) / h, (ay - fy) / h
        j12, j22 = (bx - fx) / h, (by - fy) / h
        det = j11 * j22 - j12 * j21
        x = x - (j22 * ex - j12 * ey) / det
        y = y - (-j21 * ex + j11 * ey) / det
    fx, fy = distort(x, y, cam)
    assert max(np.abs(fx - xd).max(), np.abs(fy - yd).max()) < 1e-10
    return x, y


def project(pts, rvec, tvec, cam):
    if cam["fisheye"]:
        p, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), rvec, tvec, cam["K"], cam["D"])
    else:
        p, _ = cv2.projectPoints(pts, rvec, tvec, cam["K"], cam["D"])
    return p.reshape(-1, 2)


def render(tex, rvec, tvec, cam, rng):
    K = cam["K"]
    off = (np.arange(SS) + 0.5) / SS - 0.5
    u = (np.arange(W)[None, :, None, None] + off[None, None, None, :])
    v = (np.arange(H)[:, None, None, None] + off[None, None, :, None])
    u = np.broadcast_to(u, (H, W, SS, SS)).ravel()
    v = np.broadcast_to(v, (H, W, SS, SS)).ravel()
    xd = (u - K[0, 2] - K[0, 1] * 0) / K[0, 0]
    yd = (v - K[1, 2]) / K[1, 1]
    x, y = undistort(xd, yd, cam)
    R, _ = cv2.Rodrigues(rvec)
    t = tvec.ravel()
    # ray (x, y, 1) in camera: X_board = R^T (lambda ray - t), z_board = 0
    ray = np.stack([x, y, np.ones_like(x)])
    rb = R.T @ ray
    tb = R.T @ t
    lam = tb[2] / rb[2]
    X = lam * rb[0] - tb[0]
    Y = lam * rb[1] - tb[1]
    bad = (lam <= 0) | ~np.isfinite(lam)
    # forward check on a subset
    sel = np.arange(0, X.size, 997)
    P = np.stack([X[sel], Y[sel], np.zeros(sel.size)], 1)
    ok = ~bad[sel] & (np.abs(X[sel]) < 5) & (np.abs(Y[sel]) < 5)
    fw = project(P[ok], rvec, tvec, cam)
    err = np.hypot(fw[:, 0] - u[sel][ok], fw[:, 1] - v[sel][ok]).max()
    assert err < 1e-6, err
    mx = ((X + MARGIN) * PPM - 0.5).astype(np.float32)
    my = ((Y + MARGIN) * PPM - 0.5).astype(np.float32)
    mx[bad] = -1e6
    s = cv2.remap(tex, mx.reshape(H * SS, W * SS), my.reshape(H * SS, W * SS), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=90.0)
    img = s.reshape(H, W, SS * SS).mean(axis=2)
    img = cv2.GaussianBlur(img, (0, 0), 0.6)
    img = img + rng.normal(0, 0.6, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def poses(rng, cam, b):
    corners = b.getChessboardCorners().astype(np.float64)
    bw, bh = SQUARES[0] * SQUARE, SQUARES[1] * SQUARE
    out = []
    dist = (0.20, 0.27) if not cam["fisheye"] else (0.12, 0.17)
    while len(out) < 10:
        tilt = rng.uniform(0.15, 0.7)
        a = rng.uniform(0, 2 * np.pi)
        roll = rng.uniform(-0.4, 0.4)
        R, _ = cv2.Rodrigues(np.array([tilt * np.cos(a), tilt * np.sin(a), roll]))
        target = np.array([rng.uniform(0.2, 0.8) * bw, rng.uniform(0.2, 0.8) * bh, 0.0])
        t = np.array([0, 0, rng.uniform(*dist)]) - R @ target
        rvec, _ = cv2.Rodrigues(R)
        p = project(corners, rvec, t.reshape(3, 1), cam)
        Xc = (R @ corners.T).T + t
        inside = (p[:, 0] >= 0) & (p[:, 1] >= 0) & (p[:, 0] <= W - 1) & (p[:, 1] <= H - 1) & (Xc[:, 2] > 0)
        # every view misses part of the board; enough of it in view
        if inside.all() or inside.sum() < 20:
            continue
        out.append((rvec, t.reshape(3, 1), p, inside))
    return out


def qvga(root):
    src, dst = os.path.join(root, "brown"), os.path.join(root, "brown-320x240")
    os.makedirs(dst, exist_ok=True)
    det = cv2.aruco.CharucoDetector(board())
    found = ["view,id,x,y"]
    for i in range(10):
        img = cv2.imread(os.path.join(src, "%02d.png" % i), cv2.IMREAD_GRAYSCALE)
        assert img.shape == (H, W)
        small = cv2.resize(img, (W // 2, H // 2), interpolation=cv2.INTER_AREA)
        cv2.imwrite(os.path.join(dst, "%02d.png" % i), small, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        cc, ci, _, _ = det.detectBoard(small)
        if ci is not None:
            for k, p in sorted(zip(ci.ravel(), cc.reshape(-1, 2)), key=lambda r: r[0]):
                found.append("%d,%d,%.6f,%.6f" % (i, k, p[0], p[1]))
    rows = open(os.path.join(src, "truth.csv")).read().splitlines()
    out = [rows[0]]
    for r in rows[1:]:
        v, k, x, y = r.split(",")
        out.append("%s,%s,%.6f,%.6f" % (v, k, (float(x) - 0.5) / 2, (float(y) - 0.5) / 2))
    open(os.path.join(dst, "truth.csv"), "w").write("\n".join(out) + "\n")
    open(os.path.join(dst, "opencv.csv"), "w").write("\n".join(found) + "\n")
    yaml = open(os.path.join(src, "truth.yaml")).read().splitlines()
    K = CAMS["brown"]["K"]
    k2 = [K[0, 0] / 2, 0, (K[0, 2] - 0.5) / 2, 0, K[1, 1] / 2, (K[1, 2] - 0.5) / 2, 0, 0, 1]
    yaml = ["camera_matrix: [%s]" % ", ".join("%.10g" % x for x in k2) if l.startswith("camera_matrix") else l
            for l in yaml]
    open(os.path.join(dst, "truth.yaml"), "w").write("\n".join(yaml) + "\n")


def write_set(cam, rng, d, tex, b):
    """Renders one set of views of board `b` (page `tex`) through `cam` into directory `d`: the
    PNGs, truth.csv (every corner inside the view) and truth.yaml (camera and view poses)."""
    os.makedirs(d, exist_ok=True)
    rows = ["view,id,x,y"]
    yaml = ["%YAML:1.0", "---", "camera_matrix: [%s]" % ", ".join("%.10g" % x for x in cam["K"].ravel()),
            "distortion: [%s]" % ", ".join("%.10g" % x for x in cam["D"]),
            "model: %s" % ("fisheye" if cam["fisheye"] else "brown"), "views:"]
    for i, (rvec, t, p, inside) in enumerate(poses(rng, cam, b)):
        img = render(tex, rvec, t, cam, rng)
        cv2.imwrite(os.path.join(d, "%02d.png" % i), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        for k in np.nonzero(inside)[0]:
            rows.append("%d,%d,%.6f,%.6f" % (i, k, p[k, 0], p[k, 1]))
        yaml.append("  - {rvec: [%s], tvec: [%s]}" % (
            ", ".join("%.12g" % x for x in rvec.ravel()), ", ".join("%.12g" % x for x in t.ravel())))
    open(os.path.join(d, "truth.csv"), "w").write("\n".join(rows) + "\n")
    open(os.path.join(d, "truth.yaml"), "w").write("\n".join(yaml) + "\n")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "qvga":
        return qvga(sys.argv[2] if len(sys.argv) > 2 else os.path.join(
            os.path.dirname(__file__), "..", "data", "charuco"))
    cams = CAMS
    if len(sys.argv) > 1 and sys.argv[1] == "heldout":
        if len(sys.argv) < 3:
            sys.exit("usage: charuco_render.py heldout DIR")
        cams = HELDOUT
        sys.argv = sys.argv[1:]
    outdir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "data", "charuco")
    b = board()
    tex = page(b)
    for name, cam in cams.items():
        rng = np.random.default_rng(cam.get("seed", 41 + (1 if cam["fisheye"] else 0)))
        write_set(cam, rng, os.path.join(outdir, name), tex, b)


if __name__ == "__main__":
    main()
