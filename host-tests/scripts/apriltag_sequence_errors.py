#!/usr/bin/env python3
"""Pose errors on the rendered tag sequence against truth.csv: detecting every frame
(`camgeom apriltag --frames`) against detecting and tracking (`camgeom ar --tag`, the AR loop
the board's tag job runs: a detection every 5 frames and after a loss, KLT in between).

    python3 host-tests/scripts/apriltag_sequence_errors.py [--camgeom PATH]

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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--camgeom", default="cargo run --release -q -p camgeom-host --bin camgeom --")
    args = ap.parse_args()
    cmd = shlex.split(args.camgeom)
    cam = os.path.join(SEQ, "camera.yml")
    gt = truth()
    out = subprocess.run(cmd + ["apriltag", "--frames", SEQ, "--intrinsics", cam, "--tag-size",
                                str(SIZE)], cwd=ROOT, check=True, capture_output=True, text=True)
    det_r, det_t = [], []
    for f, (rt, tt) in zip(json.loads(out.stdout)["frames"], gt):
        for d in f["detections"]:
            if d["id"] == 42 and d["R"] is not None:
                e = errors(np.reshape(d["R"], (3, 3)), np.array(d["t"]), rt, tt)
                det_r.append(e[0])
                det_t.append(e[1])
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(cmd + ["ar", "--frames", SEQ, "--tag", "42", "--family", "tag36h11",
                              "--tag-size", str(SIZE), "--intrinsics", cam, "--out", tmp],
                       cwd=ROOT, check=True, capture_output=True, text=True)
        rows = list(csv.DictReader(open(os.path.join(tmp, "poses.csv"))))
    ar_r, ar_t = [], []
    for r, (rt, tt) in zip(rows, gt):
        if r["state"] != "tracking":
            continue
        rot = rodrigues([float(r[k]) for k in ("rx", "ry", "rz")])
        t = np.array([float(r[k]) for k in ("tx", "ty", "tz")]) + rot @ np.array([SIZE / 2, SIZE / 2, 0])
        e = errors(rot, t, rt, tt)
        ar_r.append(e[0])
        ar_t.append(e[1])
    print(f"| method (160 frames) | frames with a pose | rotation error, median / p95 / max "
          f"| translation error, median / p95 / max |\n|---|---|---|---|")
    print(row("detect every frame (`camgeom apriltag --frames`)", len(det_r), det_r, det_t))
    print(row("detect + KLT (`camgeom ar --tag`, detection every 5 frames)", len(ar_r), ar_r, ar_t))


if __name__ == "__main__":
    main()
