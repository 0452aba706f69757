#!/usr/bin/env python3
"""Renders Kalibr AprilGrid calibration sets with exact ground truth, by OpenCV and numpy only.

    python3 host-tests/scripts/aprilgrid_render.py [OUT]   # default host-tests/data/aprilgrid

The board: Kalibr's AprilGrid (`kalibr_create_target_pdf --type apriltag --nx 6 --ny 5
--tsize 0.03 --tspace 0.3`): 6 x 5 tag36h11 tags of side 30 mm (the outer edge of their
2-cell black border, 10 cells across), 9 mm (0.3 x 30 mm) apart, tag `id = 6 y + x` at
`(x (1 + 0.3) 30 mm, y (1 + 0.3) 30 mm)`, and a black square of side 9 mm at each outer
corner of every tag (Kalibr's `symmCorners`), on a white page with a 20 mm margin, on a grey
surround. The tags are drawn by OpenCV (`cv2.aruco.generateImageMarker(DICT_APRILTAG_36h11,
id, px, borderBits=2)`), turned by 180 degrees: OpenCV draws each tag36h11 id turned by 180
degrees from AprilTag's and Kalibr's drawing; checked here, cell for cell, against Kalibr's
own drawing of its codes (`generateAprilTag` of `kalibr_create_target_pdf`, its first 30
t36h11 codes copied below).

Board frame as Kalibr's (`GridCalibrationTargetAprilgrid`): origin at the outer bottom-left
corner of tag 0 on the printed page, x to the right, y up the page, z out of it. Point
`r * 2 COLS + c` (`r < 2 ROWS`, `c < 2 COLS`) is at `((c / 2) (1 + s) S + (c % 2) S, (r / 2)
(1 + s) S + (r % 2) S, 0)`; tag `t`'s corners bottom-left, bottom-right, top-right, top-left
(on the page) are points `b, b + 1, b + 2 COLS + 1, b + 2 COLS` with `b = (t / COLS) 4 COLS +
(t % COLS) 2`.

Two sets of 640x480 views, 6 each, from the cameras of `charuco_render.py`, posed close to the
board so that NO view shows the whole board (every view has grid points outside the frame,
checked):

- `brown/`: fx 520, fy 516, cx 322.5, cy 238.0, k1 -0.30, k2 0.10, p1 0.001, p2 -0.0008,
  k3 -0.015 (cv2.projectPoints's model);
- `fisheye/`: fx 300, fy 299, cx 318.0, cy 242.5, k1..k4 0.05, -0.01, 0.003, -0.0005
  (cv2.fisheye's model).

Each pixel is the mean of 4x4 samples, a sample's ray the exact inverse of the lens model
(charuco_render.py's), the page read bilinearly; then a Gaussian blur of 0.6 px and seeded
noise of sigma 0.4 grey level, 8 bits.

Truth per set, `truth.yaml`: the camera and per view its pose (Rodrigues, metres);
`truth.csv`: view, grid point id, x, y of every point inside the image (pixel (i, j) centred
at (i, j), by cv2.projectPoints / cv2.fisheye.projectPoints). `layout.csv` (beside the sets):
every point's id, x, y in the board frame. Seed 41.
"""
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from charuco_render import CAMS, W, H, SS, project, undistort  # noqa: E402

COLS, ROWS = 6, 5
SIZE = 0.030
SPACING = 0.3
PPM = 8000.0  # texture pixels per metre
MARGIN = 0.020
VIEWS = 6

# kalibr_create_target_pdf, AprilTagCodes.t36h11 (ethz-asl/kalibr, BSD 3-clause): ids 0..29.
KALIBR_T36H11 = [
    0xd5d628584, 0xd97f18b49, 0xdd280910e, 0xe479e9c98, 0xebcbca822, 0xf31dab3ac, 0x056a5d085,
    0x10652e1d4, 0x22b1dfead, 0x265ad0472, 0x34fe91b86, 0x3ff962cd5, 0x43a25329a, 0x474b4385f,
    0x4e9d243e9, 0x5246149ae, 0x5997f5538, 0x683bb6c4c, 0x6be4a7211, 0x7e3158eea, 0x81da494af,
    0x858339a74, 0x8cd51a5fe, 0x9f21cc2d7, 0xa2cabc89c, 0xadc58d9eb, 0xb16e7dfb0, 0xb8c05eb3a,
    0xd25ef139d, 0xd607e1962,
]


def kalibr_cells(tag_id):
    """Kalibr's drawing of the 6x6 payload (`generateAprilTag`, rotation=2), row 0 at the top
    of the page; True white."""
    code = KALIBR_T36H11[tag_id]
    m = np.zeros((6, 6))
    for i in range(6):
        for j in range(6):
            if not code & (1 << (6 * i + j)):
                m[i, j] = 1
    return np.rot90(m, 2) == 0


def gap():
    return SPACING * SIZE


def points():
    """Kalibr's createGridPoints: (2 ROWS x 2 COLS, 2)."""
    pts = []
    for r in range(2 * ROWS):
        for c in range(2 * COLS):
            pts.append(((c // 2) * (1 + SPACING) * SIZE + (c % 2) * SIZE,
                        (r // 2) * (1 + SPACING) * SIZE + (r % 2) * SIZE))
    return np.array(pts)


def extent():
    g = gap()
    return COLS * SIZE + (COLS - 1) * g, ROWS * SIZE + (ROWS - 1) * g


def page():
    """The page as an image; texture pixel (i, j) centre is board point
    ((i + 0.5) / PPM - MARGIN - gap, top - (j + 0.5) / PPM) with top = height + gap + MARGIN."""
    g = gap()
    bw, bh = extent()
    pad = MARGIN + g
    tw, th = int(round((bw + 2 * pad) * PPM)), int(round((bh + 2 * pad) * PPM))
    img = np.full((th, tw), 255, np.uint8)
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    px = int(round(SIZE * PPM))
    assert px % 10 == 0
    cell = px // 10

    def to_tex(x, y):  # board (x, y) -> texture column, row of that point (pixel edges)
        return int(round((x + pad) * PPM)), int(round((bh + pad - y) * PPM))

    sq = int(round(g * PPM))
    for ty in range(ROWS):
        for tx in range(COLS):
            t = COLS * ty + tx
            x0, y0 = tx * (1 + SPACING) * SIZE, ty * (1 + SPACING) * SIZE
            tag = np.rot90(cv2.aruco.generateImageMarker(d, t, px, borderBits=2), 2)
            cells = tag.reshape(10, cell, 10, cell).mean(axis=(1, 3)) > 127
            assert not cells[:2].any() and not cells[8:].any()
            assert not cells[:, :2].any() and not cells[:, 8:].any()
            assert (cells[2:8, 2:8] == kalibr_cells(t)).all(), t
            c0, r0 = to_tex(x0, y0 + SIZE)  # top-left on the page
            img[r0:r0 + px, c0:c0 + px] = tag
            # Kalibr's symmCorners: a black square of side gap at each outer corner.
            for cx, cy in ((x0 - g, y0 - g), (x0 + SIZE, y0 - g), (x0 + SIZE, y0 + SIZE),
                           (x0 - g, y0 + SIZE)):
                a, b = to_tex(cx, cy + g)
                img[b:b + sq, a:a + sq] = 0
    return img.astype(np.float32), pad, bh


def render(tex, pad, bh, rvec, tvec, cam, rng):
    K = cam["K"]
    off = (np.arange(SS) + 0.5) / SS - 0.5
    u = (np.arange(W)[None, :, None, None] + off[None, None, None, :])
    v = (np.arange(H)[:, None, None, None] + off[None, None, :, None])
    u = np.broadcast_to(u, (H, W, SS, SS)).ravel()
    v = np.broadcast_to(v, (H, W, SS, SS)).ravel()
    xd = (u - K[0, 2]) / K[0, 0]
    yd = (v - K[1, 2]) / K[1, 1]
    x, y = undistort(xd, yd, cam)
    R, _ = cv2.Rodrigues(rvec)
    t = tvec.ravel()
    ray = np.stack([x, y, np.ones_like(x)])
    rb = R.T @ ray
    tb = R.T @ t
    lam = tb[2] / rb[2]
    X = lam * rb[0] - tb[0]
    Y = lam * rb[1] - tb[1]
    bad = (lam <= 0) | ~np.isfinite(lam)
    sel = np.arange(0, X.size, 997)
    P = np.stack([X[sel], Y[sel], np.zeros(sel.size)], 1)
    ok = ~bad[sel] & (np.abs(X[sel]) < 5) & (np.abs(Y[sel]) < 5)
    fw = project(P[ok], rvec, tvec, cam)
    err = np.hypot(fw[:, 0] - u[sel][ok], fw[:, 1] - v[sel][ok]).max()
    assert err < 1e-6, err
    mx = ((X + pad) * PPM - 0.5).astype(np.float32)
    my = ((bh + pad - Y) * PPM - 0.5).astype(np.float32)
    mx[bad] = -1e6
    s = cv2.remap(tex, mx.reshape(H * SS, W * SS), my.reshape(H * SS, W * SS), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=90.0)
    img = s.reshape(H, W, SS * SS).mean(axis=2)
    img = cv2.GaussianBlur(img, (0, 0), 0.6)
    img = img + rng.normal(0, 0.4, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def poses(rng, cam):
    pts = points()
    obj = np.hstack([pts, np.zeros((len(pts), 1))])
    bw, bh = extent()
    out = []
    dist = (0.19, 0.26) if not cam["fisheye"] else (0.11, 0.16)
    while len(out) < VIEWS:
        tilt = rng.uniform(0.15, 0.7)
        a = rng.uniform(0, 2 * np.pi)
        roll = rng.uniform(-0.4, 0.4)
        # The board faces the camera: its z (out of the page) towards it, R = Rx(pi) R_tilt.
        R0, _ = cv2.Rodrigues(np.array([tilt * np.cos(a), tilt * np.sin(a), roll]))
        R = R0 @ np.diag([1.0, -1.0, -1.0])
        target = np.array([rng.uniform(0.2, 0.8) * bw, rng.uniform(0.2, 0.8) * bh, 0.0])
        t = np.array([0, 0, rng.uniform(*dist)]) - R @ target
        rvec, _ = cv2.Rodrigues(R)
        p = project(obj, rvec, t.reshape(3, 1), cam)
        Xc = (R @ obj.T).T + t
        inside = (p[:, 0] >= 0) & (p[:, 1] >= 0) & (p[:, 0] <= W - 1) & (p[:, 1] <= H - 1) \
            & (Xc[:, 2] > 0)
        if inside.all() or inside.sum() < 24:
            continue
        out.append((rvec, t.reshape(3, 1), p, inside))
    return out


def main():
    outdir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "data", "aprilgrid")
    tex, pad, bh = page()
    os.makedirs(outdir, exist_ok=True)
    with open(os.path.join(outdir, "layout.csv"), "w") as f:
        f.write("id,x,y\n")
        for k, (x, y) in enumerate(points()):
            f.write("%d,%.9g,%.9g\n" % (k, x, y))
    for name, cam in CAMS.items():
        rng = np.random.default_rng(41 + (1 if cam["fisheye"] else 0))
        d = os.path.join(outdir, name)
        os.makedirs(d, exist_ok=True)
        rows = ["view,id,x,y"]
        yaml = ["%YAML:1.0", "---",
                "camera_matrix: [%s]" % ", ".join("%.10g" % x for x in cam["K"].ravel()),
                "distortion: [%s]" % ", ".join("%.10g" % x for x in cam["D"]),
                "model: %s" % ("fisheye" if cam["fisheye"] else "brown"),
                "board: aprilgrid:%dx%d:%g:%g" % (COLS, ROWS, SIZE, SPACING), "views:"]
        for i, (rvec, t, p, inside) in enumerate(poses(rng, cam)):
            img = render(tex, pad, bh, rvec, t, cam, rng)
            cv2.imwrite(os.path.join(d, "%02d.png" % i), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
            for k in np.nonzero(inside)[0]:
                rows.append("%d,%d,%.6f,%.6f" % (i, k, p[k, 0], p[k, 1]))
            yaml.append("  - {rvec: [%s], tvec: [%s]}" % (
                ", ".join("%.12g" % x for x in rvec.ravel()),
                ", ".join("%.12g" % x for x in t.ravel())))
        open(os.path.join(d, "truth.csv"), "w").write("\n".join(rows) + "\n")
        open(os.path.join(d, "truth.yaml"), "w").write("\n".join(yaml) + "\n")


if __name__ == "__main__":
    main()
