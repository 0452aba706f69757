#!/usr/bin/env python3
"""OpenCV's baseline for examples/pair_accuracy.rs: SIFT + Lowe's ratio 0.75 +
findEssentialMat (RANSAC, p = 0.999, 1 px) + recoverPose on every pair (i, i + 1) and
(i, i + 2) of the sets in data/multiview/, scored against the true cameras, printing the same
table (pairs, features, matches, inliers, rotation and translation-direction errors in
degrees, time in ms including both views' features).

    python3 host-tests/scripts/pair_accuracy_opencv.py [SET ...]

SET is a folder under data/multiview/ (default: herz-jesus-p8 entry-p10). A set without
cameras.json (sceaux-castle: K only) is scored by its inlier ratio. One thread
(cv2.setNumThreads(1)), as the Rust example.
"""

import json
import os
import sys
import time

import cv2
import numpy as np

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "multiview")


def views(folder):
    path = os.path.join(folder, "cameras.json")
    if os.path.exists(path):
        with open(path) as f:
            cams = json.load(f)["cameras"]
        return [
            (
                os.path.join(folder, c["file"]),
                np.array(c["K"], float),
                (np.array(c["R_world_to_camera"], float), np.array(c["t_world_to_camera"], float)),
            )
            for c in cams
        ]
    with open(os.path.join(folder, "camera.json")) as f:
        cam = json.load(f)
    k = np.array(cam["K"], float) if "K" in cam else None
    if k is None:
        i = cam["intrinsics"] if "intrinsics" in cam else cam
        k = np.array([[i["fx"], 0, i["cx"]], [0, i["fy"], i["cy"]], [0, 0, 1]], float)
    files = sorted(f for f in os.listdir(folder) if f.endswith((".jpg", ".png")))
    return [(os.path.join(folder, f), k, None) for f in files]


def angle_deg(r):
    return np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def main():
    cv2.setNumThreads(1)
    sets = sys.argv[1:] or ["herz-jesus-p8", "entry-p10"]
    sift = cv2.SIFT_create()
    bf = cv2.BFMatcher(cv2.NORM_L2)
    for s in sets:
        vs = views(os.path.join(DATA, s))
        feats, feat_ms = [], []
        for path, _, _ in vs:
            img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
            t0 = time.perf_counter()
            kp, des = sift.detectAndCompute(img, None)
            feat_ms.append((time.perf_counter() - t0) * 1e3)
            feats.append((np.array([k.pt for k in kp], float), des))
        print(f"== {s} (OpenCV {cv2.__version__} SIFT)")
        print(f"{'pair':>7} {'features':>11} {'matches':>7} {'inliers':>7} {'ratio':>6} "
              f"{'rot_deg':>8} {'t_deg':>8} {'ms':>8}")
        rots, trs, ratios = [], [], []
        for step in (1, 2):
            for i in range(len(vs) - step):
                j = i + step
                t0 = time.perf_counter()
                (pa, da), (pb, db) = feats[i], feats[j]
                knn = bf.knnMatch(da, db, k=2)
                good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.75 * m[1].distance]
                x1 = pa[[m.queryIdx for m in good]]
                x2 = pb[[m.trainIdx for m in good]]
                k1, k2 = vs[i][1], vs[j][1]
                # Normalised coordinates with the pixel threshold scaled by the mean focal
                # length, as findEssentialMat does with one K (the views may differ).
                n1 = cv2.undistortPoints(x1.reshape(-1, 1, 2), k1, None).reshape(-1, 2)
                n2 = cv2.undistortPoints(x2.reshape(-1, 1, 2), k2, None).reshape(-1, 2)
                f = (k1[0, 0] + k1[1, 1] + k2[0, 0] + k2[1, 1]) / 4
                e, mask = cv2.findEssentialMat(n1, n2, np.eye(3), cv2.RANSAC, 0.999, 1.0 / f)
                if e is None or e.shape != (3, 3):
                    print(f"{i}-{j:<5} failed")
                    continue
                n, r, t, mask = cv2.recoverPose(e, n1, n2, np.eye(3), mask=mask)
                ms = (time.perf_counter() - t0) * 1e3 + feat_ms[i] + feat_ms[j]
                ratio = n / max(len(good), 1)
                ratios.append(ratio)
                rot = tr = float("nan")
                if vs[i][2] is not None:
                    (ri, ti), (rj, tj) = vs[i][2], vs[j][2]
                    rij = rj @ ri.T
                    tij = tj - rij @ ti
                    rot = angle_deg(r @ rij.T)
                    cos = float(t.ravel() @ tij / np.linalg.norm(t) / np.linalg.norm(tij))
                    tr = np.degrees(np.arccos(np.clip(cos, -1, 1)))
                    rots.append(rot)
                    trs.append(tr)
                nf = f"{len(pa)}/{len(pb)}"
                print(f"{f'{i}-{j}':>7} {nf:>11} {len(good):>7} {n:>7} {ratio:>6.3f} "
                      f"{rot:>8.3f} {tr:>8.3f} {ms:>8.0f}")
        med = lambda v: float(np.median(v)) if v else float("nan")
        mx = lambda v: float(np.max(v)) if v else float("nan")
        print(f"{s}: {len(ratios)} pairs; rotation median {med(rots):.3f} max {mx(rots):.3f} deg; "
              f"translation median {med(trs):.3f} max {mx(trs):.3f} deg; inlier ratio median "
              f"{med(ratios):.3f} min {min(ratios) if ratios else float('nan'):.3f}; "
              f"features/view median {med([len(p) for p, _ in feats]):.0f}; "
              f"ms/view {med(feat_ms):.0f}")


if __name__ == "__main__":
    main()
