#!/usr/bin/env python3
"""Renders ArUco test data with exact ground truth, by OpenCV and numpy only.

    python3 host-tests/scripts/aruco_render.py test         # host-tests/data/aruco/ (committed)
    python3 host-tests/scripts/aruco_render.py bench DIR    # the sweep bench_aruco.py measures

The marker: OpenCV's drawing (`cv2.aruco.generateImageMarker`, borderBits=1) with a white quiet
zone of one cell around it. Its frame: origin at the centre, x right and y down the upright
marker image as OpenCV draws it, z into the marker; the black border's outer edge is the square
|x|, |y| <= s/2, and OpenCV's corner i (top-left, top-right, bottom-right, bottom-left, the
order `ArucoDetector.detectMarkers` returns) is (s/2) (cx_i, cy_i) with (cx, cy) = (-1, -1),
(1, -1), (1, 1), (-1, 1).

Rendering is apriltag_render.py's (same camera, backgrounds, supersampled cv2.warpPerspective,
box filter, blur, seeded sensor noise, 8 bits); the truth corners are the exact projections
K (R X + t) in OpenCV's pixel convention (pixel (i, j) centred at (i, j)).

`test`: 6 frames of 320x240, one a dictionary (DICT_4X4_50, DICT_5X5_100, DICT_6X6_250,
DICT_7X7_1000, DICT_ARUCO_ORIGINAL, DICT_ARUCO_MIP_36h12), each holding 6 markers in a 3x2 grid
(side 10 to 48 px, tilt up to 70 deg, one region each), and quiet.png: four DICT_4X4_50
markers on a dark surround with a white quiet zone of 1, 0.5, 0.25 and no cell (sweep
`quiet_<cells>`): truth.csv, and opencv.csv with what
OpenCV's ArucoDetector (default parameters, one thread) finds in each frame (ids and corners
in its order), which the host tests compare camgeom's with. Seed 41.

`bench DIR`: one marker a frame, for each of DICT_4X4_50, DICT_5X5_100, DICT_6X6_250 and
DICT_7X7_1000: a size sweep (side 10..96 px, i.e. distance 3.0..0.31 m for a 0.1 m marker,
tilt 0..30 deg) and a tilt sweep (0..70 deg at 40 px), `--per-bin` stills a bin (default 8),
into DIR/<dictionary>/NNNN.png with DIR/<dictionary>/truth.csv. Seed 42.
"""
import argparse
import csv
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
CELL_PX = 32  # marker image pixels per cell
CORNERS = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1)], dtype=float)  # OpenCV's order
MARKER_SIZE = 0.1  # metres
TEST_DICTS = ["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_7X7_1000",
              "DICT_ARUCO_ORIGINAL", "DICT_ARUCO_MIP_36h12"]
BENCH_DICTS = ["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_7X7_1000"]
SIZES = [10, 12, 14, 16, 20, 24, 32, 48, 64, 96]
TILTS = [0, 10, 20, 30, 40, 50, 60, 65, 70]


def dictionary(name):
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def marker_image(d, marker_id):
    """OpenCV's marker `marker_id` with a one-cell white quiet zone, floats 0 (black) .. 1."""
    n = d.markerSize
    m = cv2.aruco.generateImageMarker(d, marker_id, (n + 2) * CELL_PX, borderBits=1)
    m = cv2.copyMakeBorder(m, CELL_PX, CELL_PX, CELL_PX, CELL_PX, cv2.BORDER_CONSTANT, value=255)
    return m.astype(np.float32) / 255.0


def to_metres(n, size):
    """S: marker image pixel (u, v) (centres at integers) to marker-frame metres (X, Y, 1). The
    border's outer edge is at pixel edges CELL_PX - 0.5 and (n + 3) CELL_PX - 0.5."""
    k = size / ((n + 2) * CELL_PX)
    c = (n + 4) / 2 * CELL_PX - 0.5
    return np.array([[k, 0, -k * c], [0, k, -k * c], [0, 0, 1.0]])


def corners(R, t, size):
    out = []
    for cx, cy in CORNERS:
        p = ar.K @ (R @ np.array([cx * size / 2, cy * size / 2, 0.0]) + t)
        out.append(p[:2] / p[2])
    return np.array(out)


def outline(R, t, size, scale):
    """The corners of the square `scale` times the marker's (the quiet zone's outer edge)."""
    return corners(R, t, size * scale)


def params(rng, sweep, value, ncodes):
    if sweep == "size":
        size_px, tilt = value, rng.uniform(0, 30)
    else:
        size_px, tilt = 40, value
    return {
        "sweep": sweep, "size_px": size_px, "distance": ar.FOCAL * MARKER_SIZE / size_px,
        "tilt": tilt, "axis": rng.uniform(0, 360), "inplane": rng.uniform(0, 360),
        "id": int(rng.integers(0, ncodes)), "blur": rng.uniform(0.3, 1.0),
        "noise": rng.uniform(1.0, 4.0), "black": rng.uniform(0.05, 0.25),
        "white": rng.uniform(0.65, 0.95),
    }


def write_truth(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", "dictionary", "sweep", "id", "size_px", "side_px", "distance_m",
                    "tilt_deg", "x0", "y0", "x1", "y1", "x2", "y2", "x3", "y3"])
        w.writerows(rows)


def row(name, dname, p, c):
    side = np.mean([np.linalg.norm(c[i] - c[(i + 1) % 4]) for i in range(4)])
    return ([name, dname, p["sweep"], p["id"], p["size_px"], f"{side:.3f}",
             f"{p['distance']:.5f}", f"{p['tilt']:.3f}"] + [f"{v:.6f}" for v in c.ravel()])


def make_bench(out, per_bin, seed):
    rng = np.random.default_rng(seed)
    for dname in BENCH_DICTS:
        d = dictionary(dname)
        n = d.markerSize
        sub = os.path.join(out, dname)
        os.makedirs(sub, exist_ok=True)
        rows, k = [], 0
        for sweep, values in (("size", SIZES), ("tilt", TILTS)):
            for v in values:
                for _ in range(per_bin):
                    p = params(rng, sweep, v, d.bytesList.shape[0])
                    R = ar.rotation(p["tilt"], p["axis"], p["inplane"])
                    t = ar.place(rng, R, MARKER_SIZE * (n + 4) / (n + 2) / 1.25, p["distance"])
                    if t is None:
                        raise RuntimeError(f"cannot place {p}")
                    bg, _ = ar.background(rng)
                    Hm = ar.plane_homography(R, t) @ to_metres(n, MARKER_SIZE)
                    img = ar.render([(marker_image(d, p["id"]), Hm, p["black"], p["white"])], bg,
                                    blur=p["blur"], noise=p["noise"], rng=rng)
                    name = f"{k:04d}.png"
                    cv2.imwrite(os.path.join(sub, name), img)
                    rows.append(row(name, dname, p, corners(R, t, MARKER_SIZE)))
                    k += 1
        write_truth(os.path.join(sub, "truth.csv"), rows)
        print(f"{dname}: {k} stills -> {sub}")


# The test frames' six markers: (side px, tilt deg), one a 3x2 grid region.
TEST_MARKERS = [(10, 5), (14, 20), (20, 45), (32, 70), (48, 30), (28, 60)]


def make_test(out, seed):
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(seed)
    rows, found = [], []
    for f, dname in enumerate(TEST_DICTS):
        d = dictionary(dname)
        n = d.markerSize
        ids = rng.choice(d.bytesList.shape[0], len(TEST_MARKERS), replace=False)
        if dname == "DICT_ARUCO_ORIGINAL":
            ids[0] = 1023  # its own half turn: the corner order is the marker's to choose
        layers, truth = [], []
        order = rng.permutation(len(TEST_MARKERS))
        for slot, (mi, (size_px, tilt)) in enumerate(zip(ids, [TEST_MARKERS[i] for i in order])):
            gx, gy = slot % 3, slot // 3
            cx, cy = (gx + 0.5) * ar.W / 3, (gy + 0.5) * ar.H / 2
            dist = ar.FOCAL * MARKER_SIZE / size_px
            for _ in range(200):
                R = ar.rotation(tilt, rng.uniform(0, 360), rng.uniform(0, 360))
                u = np.array([cx + rng.uniform(-6, 6), cy + rng.uniform(-6, 6), 1.0])
                ray = np.linalg.solve(ar.K, u)
                t = ray / ray[2] * dist
                o = outline(R, t, MARKER_SIZE, (n + 4) / (n + 2))
                x0, x1 = gx * ar.W / 3 + 2, (gx + 1) * ar.W / 3 - 2
                y0, y1 = gy * ar.H / 2 + 2, (gy + 1) * ar.H / 2 - 2
                if (o[:, 0] > x0).all() and (o[:, 0] < x1).all() and \
                   (o[:, 1] > y0).all() and (o[:, 1] < y1).all():
                    break
            else:
                raise RuntimeError(f"cannot place {dname} {size_px}px {tilt}deg")
            black, white = rng.uniform(0.05, 0.25), rng.uniform(0.65, 0.95)
            Hm = ar.plane_homography(R, t) @ to_metres(n, MARKER_SIZE)
            layers.append((marker_image(d, int(mi)), Hm, black, white))
            p = {"sweep": "grid", "size_px": size_px, "distance": dist, "tilt": tilt,
                 "id": int(mi)}
            truth.append((p, corners(R, t, MARKER_SIZE)))
        bg, _ = ar.background(rng)
        img = ar.render(layers, bg, blur=rng.uniform(0.3, 0.8), noise=rng.uniform(1.0, 3.0),
                        rng=rng)
        name = f"{f:04d}.png"
        cv2.imwrite(os.path.join(out, name), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        rows += [row(name, dname, p, c) for p, c in truth]
        for mid, c in opencv_detect(img, dname):
            found.append([name, dname, mid] + [f"{v:.4f}" for v in c.ravel()])
    rows += make_quiet(out, rng, found)
    write_truth(os.path.join(out, "truth.csv"), rows)
    with open(os.path.join(out, "opencv.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["image", "dictionary", "id", "x0", "y0", "x1", "y1", "x2", "y2", "x3", "y3"])
        w.writerows(found)
    print(f"{len(TEST_DICTS)} frames, {len(rows)} markers, OpenCV {cv2.__version__} found "
          f"{len(found)} -> {os.path.relpath(out, ROOT)}")


# The quiet-zone frame: DICT_4X4_50 markers on a dark surround with a white quiet zone of
# 1, 0.5, 0.25 and 0 cells.
QUIET = [1.0, 0.5, 0.25, 0.0]


def make_quiet(out, rng, found):
    """quiet.png: four 56 px DICT_4X4_50 markers, tilted 15 deg, on a dark (0.12) surround,
    each with a quiet zone of QUIET[i] cells (the white square drawn, then the marker)."""
    dname = "DICT_4X4_50"
    d = dictionary(dname)
    n = d.markerSize
    layers, rows = [], []
    for i, q in enumerate(QUIET):
        size_px, tilt = 56, 15.0
        dist = ar.FOCAL * MARKER_SIZE / size_px
        R = ar.rotation(tilt, rng.uniform(0, 360), rng.uniform(-20, 20))
        u = np.array([(i + 0.5) * ar.W / 4, ar.H / 2, 1.0])
        t = np.linalg.solve(ar.K, u)
        t = t / t[2] * dist
        img = marker_image(d, 7 + i)
        # The quiet zone outside q cells is painted dark (the surround).
        keep = int(round(CELL_PX * (1 - q)))
        if keep > 0:
            img[:keep, :] = 0.0
            img[-keep:, :] = 0.0
            img[:, :keep] = 0.0
            img[:, -keep:] = 0.0
        Hm = ar.plane_homography(R, t) @ to_metres(n, MARKER_SIZE)
        layers.append((img, Hm, 0.12, 0.85))
        p = {"sweep": f"quiet_{q}", "size_px": size_px, "distance": dist, "tilt": tilt,
             "id": 7 + i}
        rows.append(row("quiet.png", dname, p, corners(R, t, MARKER_SIZE)))
    bg = np.full((ar.H, ar.W), 0.12, np.float32)
    img = ar.render(layers, bg, blur=0.5, noise=2.0, rng=rng)
    cv2.imwrite(os.path.join(out, "quiet.png"), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    for mid, c in opencv_detect(img, dname):
        found.append(["quiet.png", dname, mid] + [f"{v:.4f}" for v in c.ravel()])
    return rows


def opencv_detect(img, dname, subpix=False):
    """OpenCV's ArucoDetector with its default parameters (CORNER_REFINE_SUBPIX with
    `subpix`): [(id, 4x2 corners)]."""
    p = cv2.aruco.DetectorParameters()
    if subpix:
        p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(dictionary(dname), p)
    cs, ids, _ = det.detectMarkers(img)
    if ids is None:
        return []
    return [(int(i), c.reshape(4, 2).astype(float)) for i, c in zip(ids.ravel(), cs)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["test", "bench"])
    ap.add_argument("out", nargs="?")
    ap.add_argument("--per-bin", type=int, default=8)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    if args.what == "test":
        make_test(args.out or os.path.join(DATA, "aruco"), seed=41)
    else:
        if not args.out:
            sys.exit("bench needs an output folder")
        make_bench(args.out, args.per_bin, seed=42)


if __name__ == "__main__":
    main()
