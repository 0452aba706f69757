#!/usr/bin/env python3
"""ArUco detection, camgeom against OpenCV's ArucoDetector, measured side by side in one run.

    python3 host-tests/scripts/bench_aruco.py             # render, detect, bench, print
    python3 host-tests/scripts/bench_aruco.py --no-bench  # reuse the last criterion results

1. Renders the sweep (`aruco_render.py bench`, seed 42; kept in --dir and reused): for each of
   DICT_4X4_50, DICT_5X5_100, DICT_6X6_250 and DICT_7X7_1000 one marker a 320x240 still over
   crops of the bundled photos, a size sweep (side 10..96 px = distance 3.0..0.31 m for a
   0.1 m marker, tilt 0..30 deg) and a tilt sweep (0..70 deg at 40 px), --per-bin a bin.
2. Detects every still with camgeom's CLI (`camgeom apriltag --frames DIR --family DICT`, the
   release binary, OpenCV's decoding defaults) and with OpenCV's `ArucoDetector` (one thread,
   default `DetectorParameters`, and again with `cornerRefinementMethod =
   CORNER_REFINE_SUBPIX`). A marker is found when a detection has its id and every corner, in
   OpenCV's order, within max(2 px, side/4) of the truth; any other detection is false.
3. False positives: every dictionary on the 231 tag-free real frames (the box and tree
   sequences, the chessboard views but left10) for each method.
4. Time: camgeom's criterion bench (`cargo bench -p camgeom-host --bench apriltag -- aruco`:
   aruco/0002.png with DICT_6X6_250 and chessboard/left01.jpg with DICT_4X4_50) against the
   median of OpenCV's `detectMarkers` on the same files (perf_counter_ns batches).

Prints Markdown tables.
"""

import argparse
import csv
import glob
import json
import os
import platform
import subprocess
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DATA = os.path.join(ROOT, "host-tests", "data")
sys.path.insert(0, HERE)

from cvbench import criterion_median, fmt_ns, median_ns  # noqa: E402

DICTS = ["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250", "DICT_7X7_1000"]
ALL = [
    "DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_4X4_1000",
    "DICT_5X5_50", "DICT_5X5_100", "DICT_5X5_250", "DICT_5X5_1000",
    "DICT_6X6_50", "DICT_6X6_100", "DICT_6X6_250", "DICT_6X6_1000",
    "DICT_7X7_50", "DICT_7X7_100", "DICT_7X7_250", "DICT_7X7_1000",
    "DICT_ARUCO_ORIGINAL", "DICT_ARUCO_MIP_36h12",
]
TIME_FRAMES = [
    ("320x240_6x6_250", "aruco/0002.png", "DICT_6X6_250"),
    ("640x480_left01_4x4_50", "chessboard/left01.jpg", "DICT_4X4_50"),
]
METHODS = ["camgeom", "OpenCV", "OpenCV subpix"]


def target_dir():
    out = subprocess.run(["cargo", "metadata", "--format-version", "1", "--no-deps"],
                         cwd=ROOT, check=True, capture_output=True, text=True).stdout
    return json.loads(out)["target_directory"]


def opencv(dname, subpix):
    p = cv2.aruco.DetectorParameters()
    if subpix:
        p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dname))
    return cv2.aruco.ArucoDetector(d, p)


def cv_found(det, img):
    cs, ids, _ = det.detectMarkers(img)
    if ids is None:
        return []
    return [(int(i), c.reshape(4, 2).astype(float)) for i, c in zip(ids.ravel(), cs)]


def camgeom_frames(binary, folder, families):
    out = subprocess.run([binary, "apriltag", "--frames", folder, "--family", ",".join(families)],
                         check=True, capture_output=True, text=True).stdout
    res = {}
    for f in json.loads(out)["frames"]:
        res[os.path.basename(f["image"])] = [(d["id"], np.array(d["corners"], float))
                                             for d in f["detections"]]
    return res


def match(truth, found):
    """(corner errors of the hit or None, number of other detections)."""
    tol = max(2.0, truth["side"] / 4)
    hit = None
    for i, c in found:
        e = np.linalg.norm(c - truth["corners"], axis=1)
        if i == truth["id"] and (e <= tol).all() and hit is None:
            hit = e
    return hit, len(found) - (hit is not None)


def tag_free():
    files = sorted(glob.glob(os.path.join(DATA, "sequences", "box", "*.png")))
    files += sorted(glob.glob(os.path.join(DATA, "sequences", "tree", "*.png")))
    files += [os.path.join(DATA, "chessboard", f"left{i:02d}.jpg") for i in range(1, 15) if i != 10]
    return files


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default=os.path.join(ROOT, "target", "aruco-bench"))
    ap.add_argument("--per-bin", type=int, default=8)
    ap.add_argument("--no-bench", action="store_true", help="reuse the last criterion results")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    if not os.path.isdir(os.path.join(args.dir, DICTS[-1])):
        subprocess.run([sys.executable, os.path.join(HERE, "aruco_render.py"), "bench", args.dir,
                        "--per-bin", str(args.per_bin)], check=True)
    subprocess.run(["cargo", "build", "--release", "-p", "camgeom-host", "--bin", "camgeom"],
                   cwd=ROOT, check=True)
    binary = os.path.join(target_dir(), "release", "camgeom")

    # Rate and corner error on the sweep.
    rows = []  # (dict, sweep, bin, {method: (errors or None, false)})
    for dname in DICTS:
        sub = os.path.join(args.dir, dname)
        ours = camgeom_frames(binary, sub, [dname])
        dets = {"OpenCV": opencv(dname, False), "OpenCV subpix": opencv(dname, True)}
        with open(os.path.join(sub, "truth.csv")) as f:
            for r in csv.DictReader(f):
                t = {"id": int(r["id"]), "side": float(r["side_px"]),
                     "corners": np.array([[float(r[f"x{i}"]), float(r[f"y{i}"])] for i in range(4)])}
                img = cv2.imread(os.path.join(sub, r["image"]), cv2.IMREAD_GRAYSCALE)
                res = {"camgeom": match(t, ours.get(r["image"], []))}
                for m, det in dets.items():
                    res[m] = match(t, cv_found(det, img))
                b = int(r["size_px"]) if r["sweep"] == "size" else round(float(r["tilt_deg"]))
                rows.append((dname, r["sweep"], b, float(r["distance_m"]), res))

    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"OpenCV {cv2.__version__}, one thread; {len(rows)} stills, "
          f"{len(rows) // len(DICTS)} a dictionary ({', '.join(DICTS)})\n")
    for sweep, label in (("size", "side (px) / distance (m)"), ("tilt", "tilt (deg), 40 px")):
        print(f"| {label} | stills | " + " | ".join(METHODS) + " |")
        print("|---" * (2 + len(METHODS)) + "|")
        bins = sorted({r[2] for r in rows if r[1] == sweep})
        for b in bins:
            sel = [r for r in rows if r[1] == sweep and r[2] == b]
            cells = [f"{sum(r[4][m][0] is not None for r in sel)}" for m in METHODS]
            name = f"{b} / {sel[0][3]:.2f}" if sweep == "size" else f"{b}"
            print(f"| {name} | {len(sel)} | " + " | ".join(cells) + " |")
        print()
    print("| | " + " | ".join(METHODS) + " |")
    print("|---" * (1 + len(METHODS)) + "|")
    found = {m: sum(r[4][m][0] is not None for r in rows) for m in METHODS}
    false = {m: sum(r[4][m][1] for r in rows) for m in METHODS}
    print(f"| found (of {len(rows)}) | " + " | ".join(str(found[m]) for m in METHODS) + " |")
    print("| false detections on the stills | " + " | ".join(str(false[m]) for m in METHODS) + " |")
    for what, sel in (("its own", None), ("all three find", "common")):
        for stat, fn in (("median", np.median), ("max", np.max)):
            cells = []
            for m in METHODS:
                e = [r[4][m][0] for r in rows if r[4][m][0] is not None
                     and (sel is None or all(r[4][k][0] is not None for k in METHODS))]
                cells.append(f"{fn(np.concatenate(e)):.3f}" if e else "-")
            n = sum(all(r[4][k][0] is not None for k in METHODS) for r in rows)
            label = f"corner error {stat}, px (markers {what}" + (f": {n})" if sel else ")")
            print(f"| {label} | " + " | ".join(cells) + " |")

    # False positives on the tag-free real frames, every dictionary.
    frames = tag_free()
    link = os.path.join(args.dir, "tag-free")
    os.makedirs(link, exist_ok=True)
    for i, f in enumerate(frames):
        p = os.path.join(link, f"{i:04d}{os.path.splitext(f)[1]}")
        if not os.path.exists(p):
            os.symlink(f, p)
    fp = {m: 0 for m in METHODS}
    for k in range(0, len(ALL), 4):
        group = ALL[k:k + 4]
        ours = camgeom_frames(binary, link, group)
        fp["camgeom"] += sum(len(v) for v in ours.values())
    imgs = [cv2.imread(f, cv2.IMREAD_GRAYSCALE) for f in frames]
    for dname in ALL:
        for m, sp in (("OpenCV", False), ("OpenCV subpix", True)):
            det = opencv(dname, sp)
            fp[m] += sum(len(cv_found(det, im)) for im in imgs)
    print(f"| false positives, {len(frames)} tag-free real frames x {len(ALL)} dictionaries | "
          + " | ".join(str(fp[m]) for m in METHODS) + " |")

    # Time.
    if not args.no_bench:
        subprocess.run(["cargo", "bench", "-p", "camgeom-host", "--bench", "apriltag", "--",
                        "aruco"], cwd=ROOT, check=True)
    crit = os.path.join(target_dir(), "criterion")
    print()
    print("| frame | dictionary | markers | camgeom | OpenCV | OpenCV subpix | camgeom / OpenCV |")
    print("|---|---|---|---|---|---|---|")
    for cid, rel, dname in TIME_FRAMES:
        img = cv2.imread(os.path.join(DATA, rel), cv2.IMREAD_GRAYSCALE)
        t = {}
        for m, sp in (("OpenCV", False), ("OpenCV subpix", True)):
            det = opencv(dname, sp)
            n = len(cv_found(det, img))
            t[m] = median_ns(lambda: det.detectMarkers(img))
        ours = criterion_median(crit, f"aruco/{cid}/d1")
        ratio = "-" if ours is None else f"{ours / t['OpenCV']:.2f}"
        h, w = img.shape
        print(f"| {w}x{h} `{rel}` | {dname} | {n} | {fmt_ns(ours)} | {fmt_ns(t['OpenCV'])} "
              f"| {fmt_ns(t['OpenCV subpix'])} | {ratio} |")


if __name__ == "__main__":
    main()
