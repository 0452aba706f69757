#!/usr/bin/env python3
"""Pose errors on the rendered tag sequence against truth.csv: detecting every frame
(`camgeom apriltag --frames`) against tracking (`camgeom ar --tag`, the AR loop the board's tag
job runs: the tag tracked by detection, a full detection after a loss and every 30 frames) and
the loop before it (`camgeom ar --tag --klt`: a detection every 5 frames and after a loss, KLT
in between).

    python3 host-tests/scripts/apriltag_sequence_errors.py [--camgeom PATH] [--plot OUT.png]

`--plot` draws each frame's rotation and translation error of the three methods (log scale,
errors below 0.01 drawn at 0.01; a gap where a method has no pose; tracking's poses from a
partly seen tag ringed), with OpenCV.

Runs the camgeom CLI (default: `cargo run --release -q -p camgeom-host --bin camgeom --`),
prints a Markdown table: frames with a pose, rotation error (angle of R R_true^T) and
translation error (of the tag centre) median / p95 / max, quantiles by nearest rank.
"""

import argparse
import csv
import json
import os
import shlex
import subprocess
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SEQ = os.path.join(ROOT, "host-tests", "data", "sequences", "tag")
SIZE = 0.08


def truth():
    rows = list(csv.DictReader(open(os.path.join(SEQ, "truth.csv"))))
    return [(np.array([float(r[f"r{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3),
             np.array([float(r[k]) for k in ("tx", "ty", "tz")])) for r in rows]


def errors(r, t, rt, tt):
    c = np.clip((np.trace(r @ rt.T) - 1) / 2, -1, 1)
    return float(np.degrees(np.arccos(c))), float(1000 * np.linalg.norm(t - tt))


def rodrigues(v):
    v = np.asarray(v, float)
    a = np.linalg.norm(v)
    if a == 0:
        return np.eye(3)
    k = v / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * kx + (1 - np.cos(a)) * kx @ kx


def q(v, p):
    v = sorted(v)
    return v[int(round((len(v) - 1) * p))]


def row(name, n, dr, dt):
    return (f"| {name} | {n} | {q(dr, .5):.3f}° / {q(dr, .95):.3f}° / {q(dr, 1):.3f}° "
            f"| {q(dt, .5):.2f} / {q(dt, .95):.2f} / {q(dt, 1):.2f} mm |")


def ar(cmd, cam, gt, extra):
    """Per frame, (rotation, translation) error of `camgeom ar --tag` (None without a pose),
    and the frames whose pose is from a partly seen tag (`partial` 1)."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(cmd + ["ar", "--frames", SEQ, "--tag", "42", "--family", "tag36h11",
                              "--tag-size", str(SIZE), "--intrinsics", cam, "--out", tmp,
                              "--no-overlay"] + extra,
                       cwd=ROOT, check=True, capture_output=True, text=True)
        rows = list(csv.DictReader(open(os.path.join(tmp, "poses.csv"))))
    out, partial = [], set()
    for k, (r, (rt, tt)) in enumerate(zip(rows, gt)):
        if r["state"] != "tracking":
            out.append(None)
            continue
        if r.get("partial") == "1":
            partial.add(k)
        rot = rodrigues([float(r[k]) for k in ("rx", "ry", "rz")])
        t = np.array([float(r[k]) for k in ("tx", "ty", "tz")]) + rot @ np.array([SIZE / 2, SIZE / 2, 0])
        out.append(errors(rot, t, rt, tt))
    return out, partial


def plot(path, series, partial=()):
    """Two log-scale panels (rotation in degrees, translation in mm) of per-frame errors; the
    last series' frames in `partial` (a pose from a partly seen tag) ringed."""
    import cv2
    w, ph, left, top, gap = 1100, 300, 70, 40, 60
    img = np.full((2 * ph + top + gap + 50, w, 3), 255, np.uint8)
    colours = [(40, 40, 40), (40, 40, 220), (200, 120, 0)]
    n = max(len(v) for _, v in series)
    x = lambda k: int(left + (w - left - 20) * k / max(n - 1, 1))
    for panel, (label, lo, hi) in enumerate([("rotation error (deg)", 0.01, 10.0),
                                             ("translation error (mm)", 0.01, 10.0)]):
        y0 = top + panel * (ph + gap)
        y = lambda v: int(y0 + ph * (np.log10(hi) - np.log10(min(max(v, lo), hi)))
                          / (np.log10(hi) - np.log10(lo)))
        cv2.rectangle(img, (left, y0), (w - 20, y0 + ph), (0, 0, 0), 1)
        for d in range(int(np.log10(lo)), int(np.log10(hi)) + 1):
            v = 10.0 ** d
            cv2.line(img, (left, y(v)), (w - 20, y(v)), (210, 210, 210), 1)
            cv2.putText(img, f"{v:g}", (5, y(v) + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
        for k in range(0, n, 20):
            cv2.putText(img, str(k), (x(k) - 8, y0 + ph + 18), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                        (0, 0, 0), 1)
        cv2.putText(img, label + ", frame", (left, y0 - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                    (0, 0, 0), 1)
        for (name, vals), c in zip(series, colours):
            prev = None
            for k, e in enumerate(vals):
                if e is None:
                    prev = None
                    continue
                p = (x(k), y(e[panel]))
                if prev is not None:
                    cv2.line(img, prev, p, c, 1, cv2.LINE_AA)
                cv2.circle(img, p, 2, c, -1, cv2.LINE_AA)
                if name == series[-1][0] and k in partial:
                    cv2.circle(img, p, 5, c, 1, cv2.LINE_AA)
                prev = p
    for i, ((name, _), c) in enumerate(zip(series, colours)):
        yy = 2 * ph + top + gap + 35
        cv2.line(img, (left + 360 * i, yy - 5), (left + 360 * i + 30, yy - 5), c, 2)
        cv2.putText(img, name, (left + 360 * i + 36, yy), cv2.FONT_HERSHEY_SIMPLEX, 0.5, c, 1)
    cv2.imwrite(path, img)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--camgeom", default="cargo run --release -q -p camgeom-host --bin camgeom --")
    ap.add_argument("--plot", help="write the per-frame errors as a PNG")
    args = ap.parse_args()
    cmd = shlex.split(args.camgeom)
    cam = os.path.join(SEQ, "camera.yml")
    gt = truth()
    out = subprocess.run(cmd + ["apriltag", "--frames", SEQ, "--intrinsics", cam, "--tag-size",
                                str(SIZE)], cwd=ROOT, check=True, capture_output=True, text=True)
    det = []
    for f, (rt, tt) in zip(json.loads(out.stdout)["frames"], gt):
        e = None
        for d in f["detections"]:
            if d["id"] == 42 and d["R"] is not None:
                e = errors(np.reshape(d["R"], (3, 3)), np.array(d["t"]), rt, tt)
        det.append(e)
    klt, _ = ar(cmd, cam, gt, ["--klt"])
    tracked, partial = ar(cmd, cam, gt, [])
    series = [("detect every frame", det),
              ("detect + KLT (ar --tag --klt)", klt),
              ("ar --tag (ringed: partly seen)", tracked)]
    print(f"| method (160 frames) | frames with a pose | rotation error, median / p95 / max "
          f"| translation error, median / p95 / max |\n|---|---|---|---|")
    names = ["detect every frame (`camgeom apriltag --frames`)",
             "detect + KLT (`camgeom ar --tag --klt`, detection every 5 frames)",
             "tracking by detection (`camgeom ar --tag`, a full detection every 30 frames)"]
    for name, (_, v) in zip(names, series):
        got = [e for e in v if e is not None]
        print(row(name, len(got), [e[0] for e in got], [e[1] for e in got]))
    part = [tracked[k] for k in sorted(partial)]
    if part:
        print(row("of which partly seen (`partial` 1 in `poses.csv`)", len(part),
                  [e[0] for e in part], [e[1] for e in part]))
    if args.plot:
        plot(args.plot, series, partial)


if __name__ == "__main__":
    main()
