#!/usr/bin/env python3
"""Chessboards at every scale, rendered by OpenCV, with the truth and OpenCV's own detections.

For camgeom's scale-free chessboard detection (issue: chessboards at 720p to 4K). Each case is
one 9x6 board rendered by `make_calib_fixtures.render` (OpenCV undistorts every supersample,
intersects its ray with the board plane and samples the board with cv2.remap; no camgeom
code), at one of five frame sizes, three board sizes in the view (the board's width about 90 %,
50 % and 22 % of the frame's: about 60 %, 20 % and 5 % of its area), three lenses (none,
Brown-Conrady barrel, Kannala-Brandt fisheye) and a blur that grows with the frame (the same
optics on a finer sensor: sigma = 0.7 px at 640 wide, times width / 640).

    python3 host-tests/scripts/render_chessboard_scales.py OUT_DIR [SIZE ...]

SIZE is one of 320x240 640x480 1280x960 1920x1440 4032x3024 (default: all). Writes
OUT_DIR/<case>.png, OUT_DIR/truth.csv (case,k,u,v: cv2.projectPoints of corner k, OpenCV's
order) and OUT_DIR/opencv.csv (case,width,height,in_view,cv_found,cv_ms,cv_rms,sb_found,sb_ms,
sb_rms): cv2.findChessboardCorners (default flags) + cv2.cornerSubPix (see subpix_half;
30 iterations / 0.001) and cv2.findChessboardCornersSB (default flags),
one thread, each with its time and its RMS corner error against the truth.
"""

import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_calib_fixtures import render  # noqa: E402

SIZES = [(320, 240), (640, 480), (1280, 960), (1920, 1440), (4032, 3024)]
BOARD = (9, 6)
# Distance of the board's centre: its width is 0.9 * 10 / z of the frame's.
FILLS = {"full": 10.0, "half": 18.0, "small": 40.0}
POSES = [(0.25, -0.3, 0.1), (-0.35, 0.2, -0.4)]


def cases(sizes):
    out = []
    for w, h in sizes:
        for fill, z in FILLS.items():
            for lens in ("none", "brown", "fisheye"):
                if lens == "fisheye" and fill == "full":
                    z = 8.0  # the fisheye's shorter focal length
                for p, rvec in enumerate(POSES):
                    R, _ = cv2.Rodrigues(np.array(rvec))
                    centre = np.array([4.0, 2.5, 0.0])
                    # Off-centre for the smaller boards, so they are not all in the middle.
                    shift = np.array([0.0, 0.0, 0.0]) if fill == "full" else np.array(
                        [(-1) ** p * 0.18 * z, 0.1 * z, 0.0])
                    tvec = np.array([0.0, 0.0, z]) + shift - R @ centre
                    blur = 0.7 * w / 640
                    name = f"{w}x{h}-{fill}-{lens}-{p}"
                    out.append((name, (w, h), BOARD, lens, tuple(rvec), tuple(tvec),
                                {"blur": blur, "noise": 1.5}))
    return out


def rms(found, truth):
    """RMS distance of each true corner to the found corner nearest it (the order is a separate
    question: camgeom's tests check it against OpenCV's)."""
    if found is None:
        return ""
    found = found.reshape(-1, 2)
    d = np.linalg.norm(found[None, :, :] - truth[:, None, :], axis=2).min(axis=1)
    return f"{np.sqrt(np.mean(d ** 2)):.4f}"


def subpix_half(w, corners):
    """cornerSubPix's half window: OpenCV's sample's 5 px (11x11) at 640 wide, scaled with the
    frame, but at most a third of the smallest corner spacing found (a larger window reaches
    the next corner and pulls the estimate off), at least 2."""
    c = corners.reshape(-1, 2)
    d = np.linalg.norm(c[None, :, :] - c[:, None, :], axis=2)
    spacing = np.min(d[d > 0])
    return int(max(2, min(round(5 * w / 640), spacing // 3)))


def main():
    cv2.setNumThreads(1)
    out = sys.argv[1]
    want = [tuple(int(v) for v in s.split("x")) for s in sys.argv[2:]] or SIZES
    os.makedirs(out, exist_ok=True)
    truth_rows, cv_rows = [], []
    for case in cases(want):
        name, (w, h) = case[0], case[1]
        ss = 2 if w * h <= 1920 * 1440 else 1
        img, tr, inside = render(case, ss=ss, sq=64)
        cv2.imwrite(os.path.join(out, name + ".png"), img)
        for k, (u, v) in enumerate(tr):
            truth_rows.append(f"{name},{k},{float(u)!r},{float(v)!r}")
        t = time.perf_counter()
        ok, c = cv2.findChessboardCorners(img, BOARD)
        if ok:
            half = subpix_half(w, c)
            c = cv2.cornerSubPix(img, c, (half, half), (-1, -1),
                                 (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001))
        cv_ms = 1e3 * (time.perf_counter() - t)
        t = time.perf_counter()
        oksb, sb = cv2.findChessboardCornersSB(img, BOARD)
        sb_ms = 1e3 * (time.perf_counter() - t)
        cv_rows.append(f"{name},{w},{h},{int(inside)},{int(ok)},{cv_ms:.1f},"
                       f"{rms(c if ok else None, tr)},{int(oksb)},{sb_ms:.1f},"
                       f"{rms(sb if oksb else None, tr)}")
        print(cv_rows[-1], flush=True)
    with open(os.path.join(out, "truth.csv"), "w") as f:
        f.write("case,k,u,v\n" + "\n".join(truth_rows) + "\n")
    with open(os.path.join(out, "opencv.csv"), "w") as f:
        f.write("case,width,height,in_view,cv_found,cv_ms,cv_rms,sb_found,sb_ms,sb_rms\n")
        f.write("\n".join(cv_rows) + "\n")


if __name__ == "__main__":
    main()
