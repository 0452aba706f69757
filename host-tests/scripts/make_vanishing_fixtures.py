#!/usr/bin/env python3
"""Makes the vanishing-point fixtures in host-tests/data/fixtures/vanishing/ (OpenCV projects,
camgeom is not involved).

Nothing here runs during `cargo test`: the outputs are committed. Regenerate from the
repository root with

    pip install opencv-python-headless numpy
    python3 host-tests/scripts/make_vanishing_fixtures.py

The scene: a building (two facades with a grid of windows and the building's own vertical and
horizontal edges) and three boxes on the ground, every edge along one of the world axes X, Y,
Z (Y vertical, pointing down as the camera's y does). A pinhole camera (K below, no
distortion, 640x480) looks at the building's corner from 1.6 units above the ground, turned
about the vertical (yaw) and rolled about its optical axis, so the horizon is tilted. The
3D segments are projected with cv2.projectPoints; a segment is kept when both its endpoints
are in front of the camera and inside the image with a 2 px margin. Gaussian noise of
0.5 px is added to every endpoint (numpy seed per scene) and random segments (anywhere in
the image, any direction, 30..120 px) are added as outliers.

Outputs (one pair per scene, and the camera):
  camera.json        K in camgeom's camera form (fx, fy, cx, cy, width, height; no distortion).
  <scene>.csv        x1,y1,x2,y2,group: one segment a row, pixels (4 decimals); group is the
                     world axis of the segment (0 = X, 1 = Y vertical, 2 = Z) or -1 for an
                     outlier.
  <scene>_truth.json the camera (K, rvec, tvec, R: X_cam = R X_world + t), and the truth:
                     "vanishing_points", one per axis i: "h" = K R e_i (homogeneous, unit
                     norm, w >= 0), "x", "y" (null when ideal), "ideal", "direction_camera" =
                     R e_i (the sign with z >= 0); "horizon": the vanishing line of the
                     horizontal planes, l = K^-T R e_Y scaled to a^2 + b^2 = 1, and its
                     "roll_deg" = atan2(-a, b) in degrees folded into (-90, 90] (the angle of
                     the line's direction (b, -a) from the image x axis, y down: positive
                     descends to the right).

Scenes:
  building  the camera pitched up 10 deg, yaw 35 deg, roll 7 deg: three finite vanishing
            points, 12 outliers (seed 21).
  level     the optical axis horizontal (pitch 0), yaw 30 deg, roll -5 deg: the images of the
            vertical edges are parallel, their vanishing point is ideal; 8 outliers (seed 22).
"""

import json
import os

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "data", "fixtures", "vanishing")
W, H = 640, 480
K = np.array([[700.0, 0.0, 322.5], [0.0, 700.0, 236.0], [0.0, 0.0, 1.0]])
NOISE_PX = 0.5


def rotation(forward, roll_deg):
    """World-to-camera rotation of a camera looking along `forward` (world), its y axis as
    near world down (+Y) as it can be, then rolled by `roll_deg` about its optical axis."""
    z = forward / np.linalg.norm(forward)
    down = np.array([0.0, 1.0, 0.0])
    x = np.cross(down, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    r = np.stack([x, y, z])
    c, s = np.cos(np.radians(roll_deg)), np.sin(np.radians(roll_deg))
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rz @ r


def scene_segments():
    """3D segments (a, b, axis) of the building and the boxes."""
    segs = []

    def edge(a, b):
        a, b = np.array(a, float), np.array(b, float)
        axis = int(np.argmax(np.abs(b - a)))
        segs.append((a, b, axis))

    # The building: X in [0, 12], Z in [0, 9], from the ground (Y = 0) to Y = -10.
    top = -10.0
    for x, z in [(0, 0), (12, 0), (0, 9)]:
        edge((x, 0, z), (x, top, z))
    edge((0, top, 0), (12, top, 0))
    edge((0, top, 0), (0, top, 9))
    edge((0, 0, 0), (12, 0, 0))
    edge((0, 0, 0), (0, 0, 9))
    # Windows 1.2 wide, 1.5 high: on the facade Z = 0 (along X) and on X = 0 (along Z).
    for floor in range(4):
        y0 = -1.5 - 2.2 * floor
        y1 = y0 - 1.5
        for col in range(4):
            u0 = 1.2 + 2.6 * col
            u1 = u0 + 1.2
            edge((u0, y0, 0), (u1, y0, 0))
            edge((u0, y1, 0), (u1, y1, 0))
            edge((u0, y0, 0), (u0, y1, 0))
            edge((u1, y0, 0), (u1, y1, 0))
        for col in range(3):
            u0 = 1.0 + 2.6 * col
            u1 = u0 + 1.2
            edge((0, y0, u0), (0, y0, u1))
            edge((0, y1, u0), (0, y1, u1))
            edge((0, y0, u0), (0, y1, u0))
            edge((0, y0, u1), (0, y1, u1))
    # Boxes on the ground in front of the building: (x, z, sx, sy, sz).
    for bx, bz, sx, sy, sz in [(-4.0, -6.0, 1.5, 1.0, 2.0), (3.0, -7.0, 2.0, 1.2, 1.0), (-1.0, -3.0, 1.0, 0.8, 1.2)]:
        c = [(bx + i * sx, -j * sy, bz + k * sz) for i in (0, 1) for j in (0, 1) for k in (0, 1)]
        for p in range(8):
            for q in range(p + 1, 8):
                d = np.abs(np.array(c[p]) - np.array(c[q]))
                if np.count_nonzero(d > 1e-9) == 1:
                    edge(c[p], c[q])
    return segs


def make(name, centre, target, roll_deg, outliers, seed):
    rng = np.random.default_rng(seed)
    centre = np.array(centre, float)
    r = rotation(np.array(target, float) - centre, roll_deg)
    t = -r @ centre
    rvec, _ = cv2.Rodrigues(r)
    rows = []
    margin = 2.0
    for a, b, axis in scene_segments():
        if (r @ a + t)[2] <= 0.1 or (r @ b + t)[2] <= 0.1:
            continue
        img, _ = cv2.projectPoints(np.stack([a, b]), rvec, t, K, None)
        img = img.reshape(2, 2)
        inside = np.all((img[:, 0] >= margin) & (img[:, 0] <= W - 1 - margin)
                        & (img[:, 1] >= margin) & (img[:, 1] <= H - 1 - margin))
        if not inside or np.linalg.norm(img[1] - img[0]) < 12.0:
            continue
        img = img + rng.normal(0.0, NOISE_PX, size=(2, 2))
        rows.append((*img[0], *img[1], axis))
    for _ in range(outliers):
        length = rng.uniform(30.0, 120.0)
        angle = rng.uniform(0.0, np.pi)
        d = length * np.array([np.cos(angle), np.sin(angle)])
        a = rng.uniform([margin, margin], [W - 1 - margin, H - 1 - margin] - np.abs(d))
        rows.append((*a, *(a + d), -1))
    with open(os.path.join(OUT, f"{name}.csv"), "w") as f:
        f.write("x1,y1,x2,y2,group\n")
        for x1, y1, x2, y2, g in rows:
            f.write(f"{x1:.4f},{y1:.4f},{x2:.4f},{y2:.4f},{g}\n")

    points = []
    for i in range(3):
        d = r[:, i]
        h = K @ d
        h = h / np.linalg.norm(h)
        if h[2] < 0:
            h = -h
        ideal = abs(h[2]) < 1e-12
        points.append({
            "axis": "XYZ"[i],
            "h": h.tolist(),
            "x": None if ideal else h[0] / h[2],
            "y": None if ideal else h[1] / h[2],
            "ideal": bool(ideal),
            "direction_camera": (d if d[2] >= 0 else -d).tolist(),
            "segments": sum(1 for row in rows if row[4] == i),
        })
    line = np.linalg.inv(K).T @ r[:, 1]
    line = line / np.hypot(line[0], line[1])
    roll = np.degrees(np.arctan2(-line[0], line[1]))
    if roll <= -90.0:
        roll += 180.0
    elif roll > 90.0:
        roll -= 180.0
    truth = {
        "scene": name,
        "K": K.reshape(-1).tolist(),
        "width": W,
        "height": H,
        "rvec": rvec.reshape(-1).tolist(),
        "tvec": t.tolist(),
        "R": r.reshape(-1).tolist(),
        "noise_px": NOISE_PX,
        "segments": len(rows),
        "outliers": outliers,
        "vanishing_points": points,
        "horizon": {"line": line.tolist(), "roll_deg": roll},
    }
    with open(os.path.join(OUT, f"{name}_truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
        f.write("\n")
    print(name, len(rows), "segments;", [(p["axis"], p["segments"], p["x"], p["y"]) for p in points],
          "roll", round(roll, 3))


def main():
    os.makedirs(OUT, exist_ok=True)
    camera = {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2], "width": W, "height": H}
    with open(os.path.join(OUT, "camera.json"), "w") as f:
        json.dump(camera, f, indent=1)
        f.write("\n")
    # Building: the camera 25 units from the corner, looking up at it.
    make("building", centre=(-15.0, -1.6, -20.0), target=(2.0, -5.5, 2.5), roll_deg=7.0,
         outliers=12, seed=21)
    # Level: the optical axis horizontal (target at the camera's height).
    make("level", centre=(-16.0, -4.0, -24.0), target=(2.0, -4.0, 1.0), roll_deg=-5.0,
         outliers=8, seed=22)


if __name__ == "__main__":
    main()
