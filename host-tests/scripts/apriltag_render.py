#!/usr/bin/env python3
"""Renders AprilTag test data with exact ground truth, by OpenCV and numpy only.

    python3 host-tests/scripts/apriltag_render.py stills     # host-tests/data/apriltag/stills/
    python3 host-tests/scripts/apriltag_render.py sequence   # host-tests/data/sequences/tag/
    python3 host-tests/scripts/apriltag_render.py study DIR  # the full study set (not committed)

The tag: OpenCV's tag36h11 marker (`cv2.aruco.generateImageMarker`, DICT_APRILTAG_36h11,
borderBits=1) with a white quiet zone of one cell around it (the white border of the printed
tag images), turned by 180 degrees: OpenCV draws AprilTag's tag images upside down (checked in
make_apriltag_families.py), and turned back it is AprilTag's tag image, so that the truth is in
AprilTag's corner order and tag frame. The tag frame is AprilTag's: origin at the centre, x right
and y down the upright tag image, z into the tag; the black border's outer edge is the square
|x|, |y| <= s/2 (s the tag size) and AprilTag's corner i is (s/2) (cx_i, cy_i) with
(cx, cy) = (-1, 1), (1, 1), (1, -1), (-1, -1).

Rendering: the tag image is mapped by cv2.warpPerspective through H = A K [r1 r2 t] S onto a
supersampled canvas (S: tag image pixels to metres; K: the camera; A: the supersampling, pixel
centres kept), composited over a real photo (the bundled images of host-tests/data), box-filtered
down (cv2.resize INTER_AREA by the integer factor), blurred (cv2.GaussianBlur), given sensor noise
(numpy, seeded) and rounded to 8 bits. The truth corners are the exact projections K (R X + t)
(float64) in camgeom's pixel convention (pixel (i, j) centred at (i, j), as OpenCV's).
"""
import argparse
import csv
import json
import math
import os

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "data")
W, H = 320, 240
# A 320x240 camera with a 56 degree horizontal field of view, no distortion.
K = np.array([[300.0, 0.0, 159.5], [0.0, 300.0, 119.5], [0.0, 0.0, 1.0]])
CELL_PX = 64  # tag image pixels per cell
CELLS = 10  # tag36h11: 8 cells across the border plus the one-cell white quiet zone
TAG_PX = CELL_PX * CELLS
CORNERS = np.array([(-1, 1), (1, 1), (1, -1), (-1, -1)], dtype=float)
BACKGROUNDS = [
    "middlebury/basketball1.png",
    "middlebury/rubberwhale1.png",
    "oxford-graf/graf1.png",
    "oxford-graf/graf3.png",
    "features/box_in_scene.png",
    "sequences/tree/0000.png",
    "sequences/tree/0040.png",
    "sequences/box/0000.png",
    "sequences/box/0100.png",
]


def tag_image(tag_id):
    """AprilTag's tag36h11 image of `tag_id`, quiet zone included, as floats 0 (black) .. 1."""
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    m = cv2.aruco.generateImageMarker(d, tag_id, 8 * CELL_PX, borderBits=1)
    m = cv2.copyMakeBorder(m, CELL_PX, CELL_PX, CELL_PX, CELL_PX, cv2.BORDER_CONSTANT, value=255)
    return np.rot90(m, 2).astype(np.float32) / 255.0


def tag_to_metres(size):
    """S: tag image pixel (u, v) (centres at integers) to tag-frame metres (X, Y, 1). The border's
    outer edge is at pixel edges CELL_PX - 0.5 and 9 CELL_PX - 0.5, centre 5 CELL_PX - 0.5."""
    k = size / (8 * CELL_PX)
    c = 5 * CELL_PX - 0.5
    return np.array([[k, 0, -k * c], [0, k, -k * c], [0, 0, 1.0]])


def plane_homography(R, t):
    """Tag-frame metres (X, Y, 1) on Z = 0 to image pixels: K [r1 r2 t]."""
    return K @ np.column_stack([R[:, 0], R[:, 1], t])


def supersample(ss):
    """Low-resolution pixel centres to supersampled ones: u_hi = ss u + (ss - 1) / 2."""
    o = (ss - 1) / 2.0
    return np.array([[ss, 0, o], [0, ss, o], [0, 0, 1.0]])


def corners(R, t, size):
    """The border's outer corners in AprilTag's order, pixels (camgeom's convention)."""
    out = []
    for cx, cy in CORNERS:
        X = np.array([cx * size / 2, cy * size / 2, 0.0])
        p = K @ (R @ X + t)
        out.append(p[:2] / p[2])
    return np.array(out)


def background(rng, name=None):
    """A 320x240 crop of a bundled photo (random region, scale and flip)."""
    name = name or BACKGROUNDS[rng.integers(len(BACKGROUNDS))]
    img = cv2.imread(os.path.join(DATA, name), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255.0
    h, w = img.shape
    scale = rng.uniform(0.6, 1.0)
    cw, ch = int(w * scale), int(w * scale * H / W)
    if ch > h:
        ch, cw = h, int(h * W / H)
    x0, y0 = rng.integers(0, w - cw + 1), rng.integers(0, h - ch + 1)
    crop = img[y0 : y0 + ch, x0 : x0 + cw]
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    return cv2.resize(crop, (W, H), interpolation=cv2.INTER_AREA), name


def render(layers, bg, ss=8, blur=0.0, noise=0.0, gain=1.0, rng=None, occluder=None,
           quantize=True):
    """Composites `layers` = [(tag image, H low-res pixels <- tag pixels, black, white)] over
    `bg` (floats 0..1) at `ss`x supersampling, then box filter, blur, gain, noise, 8 bits.
    `occluder`: a polygon (low-res pixels) painted over the scene with a grey level.
    `quantize=False` returns the floats (0..255) before noise and rounding."""
    A = supersample(ss)
    big = cv2.resize(bg, (W * ss, H * ss), interpolation=cv2.INTER_LINEAR)
    for img, Hm, black, white in layers:
        Hh = A @ Hm
        val = black + (white - black) * img
        warped = cv2.warpPerspective(val, Hh, (W * ss, H * ss), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        mask = cv2.warpPerspective(np.ones_like(img), Hh, (W * ss, H * ss), flags=cv2.INTER_LINEAR,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        big = big * (1 - mask) + warped
    if occluder is not None:
        poly, level = occluder
        m = np.zeros_like(big)
        pts = np.round((np.asarray(poly) * ss + (ss - 1) / 2) * 16).astype(np.int32)
        cv2.fillPoly(m, [pts], 1.0, lineType=cv2.LINE_AA, shift=4)
        big = big * (1 - m) + level * m
    low = cv2.resize(big, (W, H), interpolation=cv2.INTER_AREA)
    if blur > 0:
        low = cv2.GaussianBlur(low, (0, 0), blur)
    low = low * 255.0 * gain
    if not quantize:
        return low
    if noise > 0 and rng is not None:
        # Sensor noise: read noise plus shot noise growing with the signal.
        sigma = np.sqrt(noise ** 2 + 0.02 * np.maximum(low, 0))
        low = low + rng.normal(0, 1, low.shape) * sigma
    return np.clip(np.round(low), 0, 255).astype(np.uint8)


def rotation(tilt_deg, axis_deg, inplane_deg):
    """R = R_axis(tilt) R_z(inplane): the upright, fronto-parallel tag turned in its plane, then
    tilted about the in-image axis at `axis_deg`."""
    rz, _ = cv2.Rodrigues(np.array([0.0, 0.0, math.radians(inplane_deg)]))
    a = math.radians(axis_deg)
    ra, _ = cv2.Rodrigues(np.array([math.cos(a), math.sin(a), 0.0]) * math.radians(tilt_deg))
    return ra @ rz


def place(rng, R, size, distance, margin=3.0):
    """A translation putting the tag (quiet zone included) fully inside the frame, or None."""
    for _ in range(200):
        u = np.array([rng.uniform(0, W), rng.uniform(0, H), 1.0])
        ray = np.linalg.solve(K, u)
        t = ray / ray[2] * distance
        outer = []
        for cx, cy in CORNERS * 1.25:
            p = K @ (R @ np.array([cx * size / 2, cy * size / 2, 0.0]) + t)
            outer.append(p[:2] / p[2])
        outer = np.array(outer)
        if (outer[:, 0] > margin).all() and (outer[:, 0] < W - 1 - margin).all() and \
           (outer[:, 1] > margin).all() and (outer[:, 1] < H - 1 - margin).all():
            return t
    return None


def camera_json(path):
    with open(path, "w") as f:
        json.dump({"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2], "skew": 0.0,
                   "distortion": [0.0] * 5, "width": W, "height": H}, f, indent=2)
        f.write("\n")


def camera_yml(path):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", W)
    fs.write("image_height", H)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.zeros((5, 1)))
    fs.release()


SIZES = [12, 14, 16, 20, 24, 32, 48, 64, 96, 128]
TILTS = [0, 10, 20, 30, 40, 50, 60, 65, 70]
TAG_SIZE = 0.1  # metres
FOCAL = K[0, 0]


def still_params(rng, sweep, value):
    """One still's parameters: `sweep` "size" (tilt 0..30 deg) or "tilt" (at 40 px)."""
    if sweep == "size":
        size_px, tilt = value, rng.uniform(0, 30)
    else:
        size_px, tilt = 40, value
    return {
        "sweep": sweep,
        "size_px": size_px,
        "distance": FOCAL * TAG_SIZE / size_px,
        "tilt": tilt,
        "axis": rng.uniform(0, 360),
        "inplane": rng.uniform(0, 360),
        "id": int(rng.integers(0, 587)),
        "blur": rng.uniform(0.3, 1.0),
        "noise": rng.uniform(1.0, 4.0),
        "black": rng.uniform(0.05, 0.25),
        "white": rng.uniform(0.65, 0.95),
    }


def make_stills(out, per_bin, seed):
    """Stills of both sweeps, `per_bin` per bin: PNGs and truth.csv."""
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(seed)
    rows = []
    k = 0
    for sweep, values in (("size", SIZES), ("tilt", TILTS)):
        for v in values:
            for _ in range(per_bin):
                p = still_params(rng, sweep, v)
                R = rotation(p["tilt"], p["axis"], p["inplane"])
                t = place(rng, R, TAG_SIZE, p["distance"])
                if t is None:
                    raise RuntimeError(f"cannot place {p}")
                bg, bgname = background(rng)
                Hm = plane_homography(R, t) @ tag_to_metres(TAG_SIZE)
                img = render([(tag_image(p["id"]), Hm, p["black"], p["white"])], bg,
                             blur=p["blur"], noise=p["noise"], rng=rng)
                name = f"{k:04d}.png"
                cv2.imwrite(os.path.join(out, name), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
                c = corners(R, t, TAG_SIZE)
                rvec, _ = cv2.Rodrigues(R)
                side = np.mean([np.linalg.norm(c[i] - c[(i + 1) % 4]) for i in range(4)])
                rows.append([name, sweep, p["id"], f"{p['size_px']}", f"{side:.3f}",
                             f"{p['distance']:.5f}", f"{p['tilt']:.3f}", f"{p['blur']:.3f}",
                             f"{p['noise']:.3f}", os.path.basename(bgname)]
                            + [f"{v:.6f}" for v in c.ravel()]
                            + [f"{v:.9f}" for v in rvec.ravel()] + [f"{v:.9f}" for v in t])
                k += 1
    with open(os.path.join(out, "truth.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", "sweep", "id", "size_px", "side_px", "distance_m", "tilt_deg", "blur_px",
                    "noise", "background", "x0", "y0", "x1", "y1", "x2", "y2", "x3", "y3",
                    "rx", "ry", "rz", "tx", "ty", "tz"])
        w.writerows(rows)
    camera_json(os.path.join(out, "camera.json"))
    print(f"{k} stills -> {os.path.relpath(out, ROOT)}")


def smooth(t, keys):
    """Piecewise cubic (Catmull-Rom) interpolation of (time, value) keys at time t."""
    ts = [k[0] for k in keys]
    vs = [np.asarray(k[1], dtype=float) for k in keys]
    if t <= ts[0]:
        return vs[0]
    if t >= ts[-1]:
        return vs[-1]
    i = max(j for j in range(len(ts) - 1) if ts[j] <= t)
    u = (t - ts[i]) / (ts[i + 1] - ts[i])
    p0, p1, p2, p3 = vs[max(i - 1, 0)], vs[i], vs[i + 1], vs[min(i + 2, len(vs) - 1)]
    return 0.5 * ((2 * p1) + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u * u
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * u * u * u)


# The sequence: (frame, [rx ry rz in degrees (tilt about x, y, in-plane), x, y, z in metres]).
SEQ_KEYS = [
    (0, [5, -5, 0, -0.02, 0.00, 0.35]),
    (18, [25, 10, 15, 0.03, -0.02, 0.30]),
    (36, [-20, 35, 40, 0.06, 0.03, 0.40]),
    (53, [10, -45, 70, -0.04, 0.02, 0.55]),
    (71, [40, 5, 100, 0.00, -0.03, 0.45]),
    (89, [-30, -20, 130, 0.02, 0.01, 0.32]),
    (102, [15, 25, 150, 0.12, 0.00, 0.38]),
    (114, [10, 30, 160, 0.30, 0.02, 0.40]),  # out to the right, past the border
    (124, [-10, 10, 175, 0.28, -0.02, 0.42]),
    (138, [-25, -15, 200, 0.02, 0.02, 0.36]),
    (151, [10, -30, 230, -0.05, -0.03, 0.28]),
    (159, [0, 0, 250, 0.00, 0.00, 0.33]),
]
SEQ_FRAMES = 160
SEQ_TAG_SIZE = 0.08
SEQ_ID = 42


def seq_pose(f):
    v = smooth(f, SEQ_KEYS)
    rx, _ = cv2.Rodrigues(np.array([math.radians(v[0]), 0, 0]))
    ry, _ = cv2.Rodrigues(np.array([0, math.radians(v[1]), 0]))
    rz, _ = cv2.Rodrigues(np.array([0, 0, math.radians(v[2])]))
    return rx @ ry @ rz, np.array(v[3:6])


def make_sequence(out, seed):
    """The tag sequence: frames, truth.csv, camera.yml and camera.json."""
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(seed)
    bg, _ = background(rng, "oxford-graf/graf1.png")
    tag = tag_image(SEQ_ID)
    S = tag_to_metres(SEQ_TAG_SIZE)
    rows = []
    for f in range(SEQ_FRAMES):
        # Motion blur: the exposure spans half a frame interval, 6 sub-frames averaged; the truth
        # is the pose at mid-exposure.
        subs = [f - 0.25 + 0.5 * (i + 0.5) / 6 for i in range(6)]
        # Exposure: a drop to 45 % over frames 62..75, back by 88.
        gain = 1.0 - 0.55 * np.clip(min((f - 62) / 13, (88 - f) / 13), 0, 1) if 62 <= f <= 88 else 1.0
        # Occluder: a dark bar sweeping over the tag in frames 89..101.
        occ = None
        occluded = 0.0
        if 89 <= f <= 101:
            R, t = seq_pose(f)
            c = corners(R, t, SEQ_TAG_SIZE)
            cx = c[:, 0].min() + (c[:, 0].max() - c[:, 0].min()) * (f - 89) / 12.0
            poly = [(cx - 6, -5), (cx + 6, -5), (cx + 14, H + 5), (cx + 2, H + 5)]
            occ = (poly, 0.12)
            occluded = 1.0
        acc = np.zeros((H, W), np.float64)
        for s in subs:
            R, t = seq_pose(s)
            Hm = plane_homography(R, t) @ S
            acc += render([(tag, Hm, 0.08, 0.85)], bg, ss=4, occluder=occ, quantize=False)
        low = acc / len(subs) / 255.0
        low = cv2.GaussianBlur(low, (0, 0), 0.6)
        low = low * 255.0 * gain
        sigma = np.sqrt(2.0 ** 2 + 0.02 * np.maximum(low, 0))
        low = np.clip(np.round(low + rng.normal(0, 1, low.shape) * sigma), 0, 255).astype(np.uint8)
        cv2.imwrite(os.path.join(out, f"{f:04d}.png"), low, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        R, t = seq_pose(f)
        c = corners(R, t, SEQ_TAG_SIZE)
        inside = bool(((c[:, 0] >= 0) & (c[:, 0] <= W - 1) & (c[:, 1] >= 0) & (c[:, 1] <= H - 1)).all())
        rvec, _ = cv2.Rodrigues(R)
        rows.append([f, SEQ_ID, int(inside), f"{occluded:.0f}", f"{gain:.4f}"]
                    + [f"{v:.9f}" for v in R.ravel()] + [f"{v:.9f}" for v in t]
                    + [f"{v:.9f}" for v in rvec.ravel()] + [f"{v:.6f}" for v in c.ravel()])
    with open(os.path.join(out, "truth.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "id", "in_view", "occluded", "gain",
                    "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33", "tx", "ty", "tz",
                    "rx", "ry", "rz", "x0", "y0", "x1", "y1", "x2", "y2", "x3", "y3"])
        w.writerows(rows)
    camera_yml(os.path.join(out, "camera.yml"))
    camera_json(os.path.join(out, "camera.json"))
    print(f"{SEQ_FRAMES} frames -> {os.path.relpath(out, ROOT)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["stills", "sequence", "study"])
    ap.add_argument("out", nargs="?")
    ap.add_argument("--per-bin", type=int, default=None)
    args = ap.parse_args()
    if args.what == "stills":
        make_stills(args.out or os.path.join(DATA, "apriltag", "stills"), args.per_bin or 3, seed=11)
    elif args.what == "study":
        make_stills(args.out or os.path.join(ROOT, "..", "target", "apriltag-study"),
                    args.per_bin or 40, seed=12)
    else:
        make_sequence(args.out or os.path.join(DATA, "sequences", "tag"), seed=13)


if __name__ == "__main__":
    main()
