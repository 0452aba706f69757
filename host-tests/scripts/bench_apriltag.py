#!/usr/bin/env python3
"""AprilTag detection time per frame, camgeom against AprilTag 3, measured in one run.

Runs camgeom's criterion bench (`cargo bench -p camgeom-host --bench apriltag`: a 320x240
frame of the rendered tag sequence and the 640x480 chessboard photo left01.jpg, decimation 1
and 2) and then times pupil-apriltags (libapriltag 3.1) on the same files with the same
settings: tag36h11, nthreads=1, refine_edges=1, the same quad_decimate, and
decode_sharpening 0.25 written into the detector struct (pupil's wrapper casts the value it is
given to int, which would turn sharpening off; docs/notes/apriltag.md). Prints a Markdown table
with both medians and their ratio.

    python3 host-tests/scripts/bench_apriltag.py            # run the bench, then pupil
    python3 host-tests/scripts/bench_apriltag.py --no-bench # reuse the last criterion results

camgeom's time is criterion's median (release build); AprilTag 3's is the median over 31
batches of `detect` calls timed with perf_counter_ns (Python's call overhead, well under a
microsecond, included). Both on one thread.
"""

import argparse
import ctypes
import os
import platform
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

import cv2  # noqa: E402
import pupil_apriltags  # noqa: E402

from cvbench import criterion_median, fmt_ns, median_ns  # noqa: E402

# (criterion id, file under host-tests/data/, tags expected): the bench's FRAMES.
FRAMES = [
    ("320x240_tag", "sequences/tag/0020.png", 1),
    ("640x480_left01", "chessboard/left01.jpg", 0),
]


def target_dir():
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT, check=True, capture_output=True, text=True).stdout
    import json
    return json.loads(out)["target_directory"]


def pupil_detector(decimate):
    det = pupil_apriltags.Detector("tag36h11", nthreads=1, quad_decimate=float(decimate),
                                   refine_edges=1)
    det.tag_detector_ptr.contents.decode_sharpening = ctypes.c_double(0.25)
    return det


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-bench", action="store_true", help="reuse the last criterion results")
    args = ap.parse_args()
    if not args.no_bench:
        subprocess.run(["cargo", "bench", "-p", "camgeom-host", "--bench", "apriltag"],
                       cwd=ROOT, check=True)
    crit = os.path.join(target_dir(), "criterion")
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"pupil-apriltags {getattr(pupil_apriltags, '__version__', '?')}, one thread\n")
    print("| frame | decimation | tags | camgeom | AprilTag 3 | camgeom / AprilTag 3 |")
    print("|---|---|---|---|---|---|")
    for cid, rel, tags in FRAMES:
        img = cv2.imread(os.path.join(ROOT, "host-tests", "data", rel), cv2.IMREAD_GRAYSCALE)
        for d in (1, 2):
            det = pupil_detector(d)
            found = det.detect(img)
            if len(found) != tags:
                sys.exit(f"AprilTag 3 found {len(found)} tags in {rel} at decimation {d}, "
                         f"expected {tags}")
            theirs = median_ns(lambda: det.detect(img))
            ours = criterion_median(crit, f"apriltag/{cid}/d{d}")
            ratio = "-" if ours is None else f"{ours / theirs:.2f}"
            h, w = img.shape
            print(f"| {w}x{h} `{rel}` | {d} | {tags} | {fmt_ns(ours)} | {fmt_ns(theirs)} "
                  f"| {ratio} |")


if __name__ == "__main__":
    main()
