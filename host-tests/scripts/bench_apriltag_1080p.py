#!/usr/bin/env python3
"""AprilTag on large frames at decimation 1 and 2: camgeom against AprilTag 3, one thread.

The frames are made here (not committed) by OpenCV, for each size asked (`--size`, 1920x1080
by default): each of the AprilTag library's three test photos (host-tests/data/apriltag,
799x533) and the 640x480 chessboard photo left01.jpg (tag-free, textured) resized by
cv2.resize (INTER_LINEAR, INTER_AREA when shrinking) to the frame's height and centred in a
grey (128) frame of that size (at 1920x1080: 1619x1080 at x = 150, left01 1440x1080 at
x = 240).

camgeom: the release example `apriltag_detect` (the CLI's host workspace, sized for the frame,
u32 labels) with `--repeat N --time`: the median of N detections of each frame. AprilTag 3:
pupil-apriltags (libapriltag 3.1), nthreads=1, the same quad_decimate, refine_edges=1 (both),
decode_sharpening 0.25 written into the detector struct (bench_apriltag.py says why), the
median of N `detect` calls. tag36h11, max Hamming 2 for both. Prints a Markdown table.

    python3 host-tests/scripts/bench_apriltag_1080p.py [--repeat 15] [--size 1280x720 ...]

Run it on an otherwise idle machine (the script holds nothing else).
"""

import argparse
import ctypes
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np
import pupil_apriltags

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DATA = os.path.join(ROOT, "host-tests", "data")

PHOTOS = [
    "apriltag/33369213973_9d9bb4cc96_c.jpg",
    "apriltag/34085369442_304b6bafd9_c.jpg",
    "apriltag/34139872896_defdb2f8d9_c.jpg",
    "chessboard/left01.jpg",
]


def make_frames(out, fw, fh):
    paths = []
    for rel in PHOTOS:
        img = cv2.imread(os.path.join(DATA, rel), cv2.IMREAD_GRAYSCALE)
        h, w = img.shape
        nw = min(round(w * fh / h), fw)
        interp = cv2.INTER_AREA if fh < h else cv2.INTER_LINEAR
        big = cv2.resize(img, (nw, fh), interpolation=interp)
        frame = np.full((fh, fw), 128, np.uint8)
        x = (fw - nw) // 2
        frame[:, x:x + nw] = big
        p = os.path.join(out, f"{os.path.splitext(os.path.basename(rel))[0]}_{fw}x{fh}.png")
        cv2.imwrite(p, frame)
        paths.append(p)
    return paths


def camgeom(paths, decimate, repeat):
    exe = os.path.join(ROOT, "target", "release", "examples", "apriltag_detect")
    r = subprocess.run([exe, "--decimate", str(decimate), "--repeat", str(repeat), "--time"]
                       + paths, check=True, capture_output=True, text=True)
    rows = [l.split(",") for l in r.stdout.splitlines()[1:]]
    out = {}
    for line in r.stderr.splitlines():
        if line.startswith("time,"):
            _, p, ns, ws = line.split(",")
            out[p] = (sum(1 for row in rows if row[0] == p), int(ns), int(ws))
    return out


def pupil(paths, decimate, repeat):
    det = pupil_apriltags.Detector("tag36h11", nthreads=1, quad_decimate=float(decimate),
                                   refine_edges=1)
    det.tag_detector_ptr.contents.decode_sharpening = ctypes.c_double(0.25)
    out = {}
    for p in paths:
        img = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
        times = []
        for _ in range(repeat):
            t = time.perf_counter_ns()
            tags = det.detect(img)
            times.append(time.perf_counter_ns() - t)
        tags = [t for t in tags if t.hamming <= 2]
        out[p] = (len(tags), sorted(times)[len(times) // 2])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--size", nargs="+", default=["1920x1080"], metavar="WxH",
                    help="frame sizes (default 1920x1080)")
    a = ap.parse_args()
    sizes = [tuple(int(v) for v in s.lower().split("x")) for s in a.size]
    subprocess.run(["cargo", "build", "--release", "-p", "camgeom-host", "--example",
                    "apriltag_detect"], cwd=ROOT, check=True)
    with tempfile.TemporaryDirectory() as tmp:
        print("| frame | size | decimation | camgeom tags | AprilTag 3 tags | camgeom ms | "
              "AprilTag 3 ms | ratio | camgeom workspace |")
        print("|---|---|---|---|---|---|---|---|---|")
        for fw, fh in sizes:
            paths = make_frames(tmp, fw, fh)
            for d in (1, 2):
                c = camgeom(paths, d, a.repeat)
                p = pupil(paths, d, a.repeat)
                for path in paths:
                    (cn, cns, ws), (pn, pns) = c[path], p[path]
                    name = os.path.basename(path).replace(f"_{fw}x{fh}.png", "")
                    # 0: the frame (decimated) fits the board's fixed Workspace320x240.
                    ws = f"{ws / 1e3:.0f} KB" if ws else "Workspace320x240"
                    print(f"| {name} | {fw}x{fh} | {d} | {cn} | {pn} | {cns / 1e6:.2f} | "
                          f"{pns / 1e6:.2f} | {cns / pns:.2f} | {ws} |", flush=True)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
