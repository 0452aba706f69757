#!/usr/bin/env python3
"""OpenCV reference results for camgeom's KLT tests (host-tests/tests/it/klt.rs).

Writes into host-tests/data/fixtures/klt/:

* rubberwhale{1,2}_gray.png: cv2.cvtColor(BGR2GRAY) of the Middlebury RGB frames (the
  grey frames every test uses, so that the colour conversion is not part of the comparison);
* {name}_pyr{1,2}.png: cv2.pyrDown of the first frame of each pair, once and twice;
* {name}_corners.csv: cv2.goodFeaturesToTrack(maxCorners=400, qualityLevel=0.01,
  minDistance=10, blockSize=3) on the first frame, `x,y`;
* {name}_{pair}_lk.csv: cv2.calcOpticalFlowPyrLK from the first frame's corners, winSize
  21x21, maxLevel 3, criteria COUNT|EPS 30 / 0.01, minEigThreshold 1e-4, `x0,y0,x1,y1,status,err`;
  `pair` is `real` (the recorded second frame) or one of the known warps below, applied to
  the first frame by `warp()` - the same f64 bilinear formula the Rust test evaluates, so
  both sides track on identical images;
* basketball_bench_pts.csv: 1000 goodFeaturesToTrack points (quality 0.001, min distance 5)
  of basketball1 for the speed benchmarks.

Run: python3 host-tests/scripts/make_klt_fixtures.py  (OpenCV 5.0.0, numpy 2.4.6 here)
"""

import math
import os

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "data")
OUT = os.path.join(DATA, "fixtures", "klt")

WIN = 21
LEVELS = 3
CRIT = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)


def mul(a, b):
    """3x3 product, summed k = 0, 1, 2 in order (as klt.rs, so both get the same bits)."""
    c = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += float(a[i][k]) * float(b[k][j])
            c[i, j] = s
    return c


def inverse(m):
    """3x3 inverse by cofactors, the same operations as `inverse()` in klt.rs."""
    m = [[float(v) for v in r] for r in m]
    det = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
           - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
           + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
    inv = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            r0, r1 = (i + 1) % 3, (i + 2) % 3
            c0, c1 = (j + 1) % 3, (j + 2) % 3
            inv[j, i] = (m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]) / det
    return inv


def about_centre(w, h, a):
    """A (3x3 affine/projective) applied about the image centre."""
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    t = np.array([[1, 0, cx], [0, 1, cy], [0, 0, 1]], dtype=np.float64)
    ti = np.array([[1, 0, -cx], [0, 1, -cy], [0, 0, 1]], dtype=np.float64)
    return mul(mul(t, a), ti)


def warps(w, h):
    """The known motions: name -> 3x3 H mapping frame-1 pixels to frame-2 pixels.

    Keep in sync with `warps()` in host-tests/tests/it/klt.rs (same numbers)."""
    out = {}
    out["shift_sub"] = np.array([[1, 0, 0.37], [0, 1, -0.61], [0, 0, 1]], dtype=np.float64)
    out["shift_big"] = np.array([[1, 0, 6.25], [0, 1, -3.8], [0, 0, 1]], dtype=np.float64)
    r = math.radians(3.0)
    rot = np.array([[math.cos(r), -math.sin(r), 0.8], [math.sin(r), math.cos(r), -0.4], [0, 0, 1]])
    out["rotate3"] = about_centre(w, h, rot)
    out["scale104"] = about_centre(w, h, np.array([[1.04, 0, 0], [0, 1.04, 0], [0, 0, 1]]))
    hom = np.array([[1.01, 0.02, 1.5], [-0.015, 0.995, 2.0], [2.0e-5, -1.5e-5, 1.0]])
    out["homography"] = about_centre(w, h, hom)
    return out


def warp(img, hmat):
    """out(x, y) = img(H⁻¹ (x, y)) by f64 bilinear interpolation, edges clamped, rounded
    half up. Mirrors `warp()` in klt.rs operation for operation."""
    h, w = img.shape
    inv = inverse(hmat)
    src = img.astype(np.float64)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    den = inv[2, 0] * xs + inv[2, 1] * ys + inv[2, 2]
    u = (inv[0, 0] * xs + inv[0, 1] * ys + inv[0, 2]) / den
    v = (inv[1, 0] * xs + inv[1, 1] * ys + inv[1, 2]) / den
    u = np.clip(u, 0.0, w - 1.0)
    v = np.clip(v, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(u), w - 2).astype(np.int64)
    y0 = np.minimum(np.floor(v), h - 2).astype(np.int64)
    a = u - x0
    b = v - y0
    p00 = src[y0, x0]
    p01 = src[y0, x0 + 1]
    p10 = src[y0 + 1, x0]
    p11 = src[y0 + 1, x0 + 1]
    val = (p00 * (1.0 - a) + p01 * a) * (1.0 - b) + (p10 * (1.0 - a) + p11 * a) * b
    return np.clip(np.floor(val + 0.5), 0, 255).astype(np.uint8)


def write_csv(path, header, rows):
    with open(path, "w") as f:
        f.write(header + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) if isinstance(v, (float, np.floating)) else str(v) for v in r) + "\n")


def lk(a, b, pts):
    nxt, st, err = cv2.calcOpticalFlowPyrLK(
        a, b, pts, None, winSize=(WIN, WIN), maxLevel=LEVELS, criteria=CRIT, minEigThreshold=1e-4
    )
    rows = []
    # OpenCV leaves garbage (even NaN) in the outputs of lost points: write 0 there.
    fin = lambda v: float(v) if math.isfinite(float(v)) else 0.0
    for p, q, s, e in zip(pts.reshape(-1, 2), nxt.reshape(-1, 2), st.ravel(), err.ravel()):
        rows.append((float(p[0]), float(p[1]), fin(q[0]), fin(q[1]), int(s), fin(e)))
    return rows


def main():
    cv2.setNumThreads(1)
    os.makedirs(OUT, exist_ok=True)
    mb = os.path.join(DATA, "middlebury")
    rw1 = cv2.cvtColor(cv2.imread(os.path.join(mb, "rubberwhale1.png")), cv2.COLOR_BGR2GRAY)
    rw2 = cv2.cvtColor(cv2.imread(os.path.join(mb, "rubberwhale2.png")), cv2.COLOR_BGR2GRAY)
    cv2.imwrite(os.path.join(OUT, "rubberwhale1_gray.png"), rw1)
    cv2.imwrite(os.path.join(OUT, "rubberwhale2_gray.png"), rw2)
    bb1 = cv2.imread(os.path.join(mb, "basketball1.png"), cv2.IMREAD_GRAYSCALE)
    bb2 = cv2.imread(os.path.join(mb, "basketball2.png"), cv2.IMREAD_GRAYSCALE)
    for name, a, b in (("rubberwhale", rw1, rw2), ("basketball", bb1, bb2)):
        p1 = cv2.pyrDown(a)
        p2 = cv2.pyrDown(p1)
        cv2.imwrite(os.path.join(OUT, f"{name}_pyr1.png"), p1)
        cv2.imwrite(os.path.join(OUT, f"{name}_pyr2.png"), p2)
        pts = cv2.goodFeaturesToTrack(a, maxCorners=400, qualityLevel=0.01, minDistance=10, blockSize=3)
        pts = pts.astype(np.float32)
        write_csv(os.path.join(OUT, f"{name}_corners.csv"), "x,y", [(float(p[0]), float(p[1])) for p in pts.reshape(-1, 2)])
        write_csv(os.path.join(OUT, f"{name}_real_lk.csv"), "x0,y0,x1,y1,status,err", lk(a, b, pts))
        if name == "basketball":
            # 1000 points for the speed benchmarks (benches/klt.rs, bench_klt_opencv.py).
            many = cv2.goodFeaturesToTrack(a, maxCorners=1000, qualityLevel=0.001, minDistance=5, blockSize=3)
            write_csv(os.path.join(OUT, "basketball_bench_pts.csv"), "x,y", [(float(p[0]), float(p[1])) for p in many.reshape(-1, 2)])
        h, w = a.shape
        for wname, hm in warps(w, h).items():
            wb = warp(a, hm)
            rows = lk(a, wb, pts)
            write_csv(os.path.join(OUT, f"{name}_{wname}_lk.csv"), "x0,y0,x1,y1,status,err", rows)
            # Report OpenCV's endpoint error against the exact motion.
            e = []
            for x0, y0, x1, y1, s, _ in rows:
                if s:
                    q = hm @ np.array([x0, y0, 1.0])
                    e.append(math.hypot(x1 - q[0] / q[2], y1 - q[1] / q[2]))
            e = np.array(e)
            print(f"{name:12s} {wname:11s} tracked {len(e):3d}/{len(rows)}  median {np.median(e):.4f}  p95 {np.percentile(e, 95):.4f}")
            # A checksum of the warped image, so the Rust test can tell if its warp differs.
            with open(os.path.join(OUT, f"{name}_{wname}_sum.txt"), "w") as f:
                f.write(f"{int(wb.astype(np.int64).sum())}\n")


if __name__ == "__main__":
    main()
