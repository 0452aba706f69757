#!/usr/bin/env python3
"""OpenCV-rendered images with known sub-pixel corner positions, for the ORB sub-pixel
keypoint tests (tests/it/features.rs).

Run from the repository root:  python3 host-tests/scripts/make_subpixel_fixtures.py
Needs opencv-python(-headless) and numpy; `cargo test` only reads what this writes.

A 320x240 scene of 40 random polygons (3 to 5 vertices, grey levels 20..235 on a grey
background) is filled with cv2.fillPoly at 16x the resolution (vertices with 4 fractional
bits, shift=4, on the 16x grid) and reduced by cv2.resize(INTER_AREA): a pixel is the mean
of its 16x16 block, so a vertex at 16x position X lands at (X + 0.5) / 16 - 0.5 in the
image. The same scene is rendered moved by each shift of SHIFTS (image pixels).

Writes into host-tests/data/features/:
  subpixel_scene_<dx>_<dy>.png   the scene moved by (dx, dy) (dx, dy in hundredths of a pixel)
  subpixel_vertices.csv          x,y of every polygon vertex in the unmoved image's pixels
"""
import os

import cv2
import numpy as np

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "features")
W, H, S = 320, 240, 16
SHIFTS = [(0.0, 0.0), (0.25, 0.5), (0.5, 0.25), (0.75, 0.75)]


def scene(rng):
    polys = []
    for _ in range(40):
        n = int(rng.integers(3, 6))
        c = rng.uniform([20, 20], [W - 20, H - 20])
        r = rng.uniform(8, 30)
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
        pts = c + r * np.stack([np.cos(ang), np.sin(ang)], 1) * rng.uniform(0.6, 1.0, (n, 1))
        polys.append((pts, int(rng.integers(20, 236))))
    return polys


def render(polys, dx, dy):
    hi = np.full((H * S, W * S), 128, np.uint8)
    for pts, v in polys:
        # Image pixel p maps to the 16x grid at (p + 0.5) S - 0.5; 4 fractional bits.
        q = ((pts + [dx, dy] + 0.5) * S - 0.5) * 16
        cv2.fillPoly(hi, [np.round(q).astype(np.int32)], v, cv2.LINE_8, 4)
    return cv2.resize(hi, (W, H), interpolation=cv2.INTER_AREA)


def main():
    rng = np.random.default_rng(20240517)
    polys = scene(rng)
    os.makedirs(OUT, exist_ok=True)
    for dx, dy in SHIFTS:
        name = f"subpixel_scene_{round(dx * 100):03d}_{round(dy * 100):03d}.png"
        cv2.imwrite(os.path.join(OUT, name), render(polys, dx, dy))
    with open(os.path.join(OUT, "subpixel_vertices.csv"), "w") as f:
        f.write("x,y\n")
        for pts, _ in polys:
            for x, y in pts:
                # The rendered vertex: rounded to the 1/256 px of the 16x grid's 4 bits.
                xr = (np.round(((x + 0.5) * S - 0.5) * 16) / 16 + 0.5) / S - 0.5
                yr = (np.round(((y + 0.5) * S - 0.5) * 16) / 16 + 0.5) / S - 0.5
                f.write(f"{xr:.6f},{yr:.6f}\n")


if __name__ == "__main__":
    main()
