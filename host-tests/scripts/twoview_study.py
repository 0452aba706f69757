#!/usr/bin/env python3
"""Two-view noise study: camgeom `twoview` vs OpenCV findEssentialMat + recoverPose.

The scene of scripts/fixtures/twoview.py (imported, not copied: K f = 520, 80 points, the same
relative pose), 30 % outliers, Gaussian pixel noise 0 / 0.5 / 1 / 2 px on both images, `--draws`
independent draws per level (numpy generator seeded with (STUDY_SEED, noise in 1/1000 px,
draw): deterministic, nothing stored). Per draw:

- OpenCV in-process, exactly as the fixture: cv2.setRNGSeed(1),
  findEssentialMat(x1, x2, K, RANSAC, 0.999, 1.0), recoverPose(E, x1, x2, K, mask);
- camgeom through its CLI: `camgeom twoview --matches FILE.csv --intrinsics1 K.json
  --threshold 1 --confidence 0.999 --seed S` (S: RansacConfig's default seed, as in
  tests/it/twoview_opencv.rs).

`--threshold PX` changes the RANSAC threshold of both sides (default 1 px, as the fixture).

Errors against the ground truth: rotation angle of R_est R_trueᵀ, angle between t_est and
t_true (deg). Prints Markdown tables per level: median, mean, p90 of both errors for both,
the fraction of draws where camgeom <= OpenCV (ties within 1e-6 deg count as <=), the gross
failures (> 10 deg); the paired differences camgeom - OpenCV of the mean and the median with
95 % bootstrap intervals (2000 resamples of the draws, seeded); inlier statistics.

Usage (from the repository root):
    python3 host-tests/scripts/twoview_study.py --camgeom target/release/camgeom --draws 200
    [--levels 0,0.5,1,2] [--threshold 1] [--jobs 2] [--dump draws.csv]
"""

import argparse
import concurrent.futures as cf
import json
import pathlib
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "scripts" / "fixtures"))
import twoview as tv  # noqa: E402  (the fixture generator: scene, draws, OpenCV's side)

STUDY_SEED = 20250612
# RansacConfig::default().seed (0x5eed_ca4e_0000_0001), what tests/it/twoview_opencv.rs uses.
CAMGEOM_SEED = 0x5EEDCA4E00000001
TIE = 1e-6
# OpenCV one call at a time (its RNG state is reset before each call; no interleaving).
CV_LOCK = threading.Lock()
GROSS = 10.0


def rot_err(r_est, r_true):
    c = (np.trace(np.asarray(r_est) @ r_true.T) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def t_err(t):
    t = np.asarray(t, float).ravel()
    t = t / np.linalg.norm(t)
    u = tv.TVEC / np.linalg.norm(tv.TVEC)
    return float(np.degrees(np.arccos(np.clip(t @ u, -1, 1))))


def run_camgeom(exe, kfile, csv, seed, threshold):
    out = subprocess.run(
        [
            exe,
            "twoview",
            "--matches",
            str(csv),
            "--intrinsics1",
            str(kfile),
            "--threshold",
            repr(float(threshold)),
            "--confidence",
            "0.999",
            "--seed",
            str(seed),
        ],
        capture_output=True,
        text=True,
    )
    if out.returncode != 0:
        return None, out.stderr.strip()
    return json.loads(out.stdout), None


def one_draw(args):
    exe, kfile, tmp, r_true, clean1, clean2, noise, d, threshold = args
    rng = np.random.default_rng([STUDY_SEED, int(round(noise * 1000)), d])
    x1, x2, inlier = tv.draw(rng, clean1, clean2, noise)
    csv = pathlib.Path(tmp) / f"m{int(round(noise * 1000))}_{d}.csv"
    with open(csv, "w") as f:
        f.write("x1,y1,x2,y2\n")
        for a, b in zip(x1, x2):
            f.write(",".join(repr(float(v)) for v in (a[0], a[1], b[0], b[1])) + "\n")
    t0 = time.perf_counter()
    js, err = run_camgeom(exe, kfile, csv, CAMGEOM_SEED, threshold)
    t_cg = time.perf_counter() - t0
    csv.unlink()
    with CV_LOCK:
        t0 = time.perf_counter()
        _, emask, rr, tt, count, pmask = tv.opencv_pose(x1, x2, threshold)
        t_cv = time.perf_counter() - t0
    row = dict(noise=noise, draw=d, t_cg=t_cg, t_cv=t_cv)
    emask = emask.ravel().astype(bool)
    pmask = pmask.ravel().astype(bool)
    row.update(
        cv_rot=rot_err(rr, r_true),
        cv_t=t_err(tt),
        cv_e_inliers=int(emask.sum()),
        cv_outliers=int((pmask & ~inlier).sum()),
        cv_count=int(count),
    )
    if js is None:
        # A camgeom failure counts as a gross failure of 180 deg.
        row.update(cg_rot=180.0, cg_t=180.0, cg_e_inliers=0, cg_outliers=0, cg_count=0, err=err)
    else:
        m = np.array(js["inlier_mask"], bool)
        row.update(
            cg_rot=rot_err(np.array(js["R"]).reshape(3, 3), r_true),
            cg_t=t_err(js["t"]),
            cg_e_inliers=int(js["e_inliers"]),
            cg_outliers=int((m & ~inlier).sum()),
            cg_count=int(js["inliers"]),
            err="",
        )
    return row


def stats(v):
    v = np.asarray(v)
    return np.median(v), v.mean(), np.percentile(v, 90)


def fmt(x):
    if x == 0:
        return "0"
    if abs(x) < 1e-3:
        return f"{x:.1e}"
    if abs(x) < 10:
        return f"{x:.3f}"
    return f"{x:.1f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--camgeom", required=True, help="path of the camgeom binary")
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--levels", default="0,0.5,1,2")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--threshold", type=float, default=1.0, help="RANSAC threshold, px")
    ap.add_argument("--dump", help="write every draw as CSV here (for investigation)")
    a = ap.parse_args()
    levels = [float(x) for x in a.levels.split(",")]

    r_true, _, clean1, clean2 = tv.scene(np.random.default_rng(tv.SEED))
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        kfile = pathlib.Path(tmp) / "K.json"
        k = tv.K
        kfile.write_text(json.dumps(dict(fx=k[0, 0], fy=k[1, 1], cx=k[0, 2], cy=k[1, 2])))
        jobs = [
            (a.camgeom, kfile, tmp, r_true, clean1, clean2, noise, d, a.threshold)
            for noise in levels
            for d in range(a.draws)
        ]
        with cf.ThreadPoolExecutor(max_workers=a.jobs) as pool:
            rows = list(pool.map(one_draw, jobs))
    wall = time.perf_counter() - start

    if a.dump:
        keys = list(rows[0].keys())
        with open(a.dump, "w") as f:
            f.write(",".join(keys) + "\n")
            for r in rows:
                f.write(",".join(str(r[k]) for k in keys) + "\n")

    print(
        f"{a.draws} draws per level, threshold {a.threshold:g} px, OpenCV {tv.cv2.__version__}, numpy {np.__version__}; "
        f"wall time {wall:.0f} s ({a.jobs} jobs); camgeom CLI mean {np.mean([r['t_cg'] for r in rows]) * 1e3:.1f} ms "
        f"a call (process start included), OpenCV mean {np.mean([r['t_cv'] for r in rows]) * 1e3:.1f} ms"
    )
    failures = [r for r in rows if r["err"]]
    if failures:
        print(f"camgeom errors: {len(failures)}, first: {failures[0]['err']}")
    print()
    for what, key, unit in (("rotation error", "rot", "°"), ("translation direction error", "t", "°")):
        print(f"{what} ({unit}), camgeom / OpenCV:")
        print()
        print(
            "| noise (px) | median | mean | p90 | camgeom ≤ OpenCV | gross (> 10°) |"
        )
        print("|---:|---:|---:|---:|---:|---:|")
        for noise in levels:
            sel = [r for r in rows if r["noise"] == noise]
            cg = [r["cg_" + key] for r in sel]
            cv = [r["cv_" + key] for r in sel]
            sc, sv = stats(cg), stats(cv)
            le = np.mean([c <= v + TIE for c, v in zip(cg, cv)])
            gc = sum(c > GROSS for c in cg)
            gv = sum(v > GROSS for v in cv)
            print(
                f"| {noise:g} | {fmt(sc[0])} / {fmt(sv[0])} | {fmt(sc[1])} / {fmt(sv[1])} | "
                f"{fmt(sc[2])} / {fmt(sv[2])} | {100 * le:.0f} % | {gc} / {gv} |"
            )
        print()
    print("camgeom - OpenCV, paired over the draws (°), with 95 % bootstrap intervals:")
    print()
    print("| noise (px) | rotation, mean | rotation, median | translation, mean | translation, median |")
    print("|---:|---:|---:|---:|---:|")
    boot = np.random.default_rng(STUDY_SEED)
    for noise in levels:
        sel = [r for r in rows if r["noise"] == noise]
        cells = []
        for key in ("rot", "t"):
            cg = np.array([r["cg_" + key] for r in sel])
            cv = np.array([r["cv_" + key] for r in sel])
            idx = boot.integers(0, len(sel), (2000, len(sel)))
            for f in (np.mean, np.median):
                d = f(cg[idx], axis=1) - f(cv[idx], axis=1)
                lo, hi = np.percentile(d, [2.5, 97.5])
                cells.append(f"{f(cg) - f(cv):+.3f} [{lo:+.3f}, {hi:+.3f}]")
        print(f"| {noise:g} | " + " | ".join(cells) + " |")
    print()
    print("Means over the draws, camgeom / OpenCV:")
    print()
    print("| noise (px) | E inliers | cheirality count | true outliers among those |")
    print("|---:|---:|---:|---:|")
    for noise in levels:
        sel = [r for r in rows if r["noise"] == noise]
        m = lambda k: np.mean([r[k] for r in sel])  # noqa: E731
        print(
            f"| {noise:g} | {m('cg_e_inliers'):.1f} / {m('cv_e_inliers'):.1f} | "
            f"{m('cg_count'):.1f} / {m('cv_count'):.1f} | "
            f"{m('cg_outliers'):.2f} / {m('cv_outliers'):.2f} |"
        )


if __name__ == "__main__":
    main()
