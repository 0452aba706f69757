#!/usr/bin/env python3
"""Reference outputs of OpenCV for camgeom's features, matching and warp tests.

Run from the repository root:  python3 host-tests/scripts/make_feature_fixtures.py
Needs opencv-python-headless and numpy; `cargo test` only reads what this writes.

Writes into host-tests/data/features/:
  fast_box_in_scene.csv     x,y,score: cv2.FastFeatureDetector (threshold 20, nonmax on, TYPE_9_16)
                            on box_in_scene.png
  opencv_orb_figures.json   OpenCV's figures for the ORB/matching/RANSAC tests (see below)
  warp_checker_opencv.png   cv2.warpPerspective of the synthetic checker logo into the grey
                            frame (INTER_LINEAR, BORDER_TRANSPARENT), see warp_case()
and the graf PNGs' grayscale copies are made by the copy step documented in data/README.md.
"""
import json
import os
import sys

import cv2
import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data")
FEAT = os.path.join(ROOT, "features")
GRAF = os.path.join(ROOT, "oxford-graf")


def gray(path):
    im = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if im is None:
        sys.exit(f"cannot read {path}")
    return im


def h1to3():
    fs = cv2.FileStorage(os.path.join(GRAF, "H1to3p.xml"), cv2.FILE_STORAGE_READ)
    h = fs.getNode("H13").mat()
    fs.release()
    return h


def transfer(h, pts):
    p = np.hstack([pts, np.ones((len(pts), 1))]) @ h.T
    return p[:, :2] / p[:, 2:]


def graf_grid(h_true, w, h, step=40):
    """graf1 pixels on a `step` grid whose true image lies inside graf3."""
    xs, ys = np.meshgrid(np.arange(0, w, step), np.arange(0, h, step))
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    q = transfer(h_true, pts)
    inside = (q[:, 0] >= 0) & (q[:, 0] <= w - 1) & (q[:, 1] >= 0) & (q[:, 1] <= h - 1)
    return pts[inside]


def fast_fixture():
    img = gray(os.path.join(FEAT, "box_in_scene.png"))
    det = cv2.FastFeatureDetector_create(threshold=20, nonmaxSuppression=True,
                                         type=cv2.FAST_FEATURE_DETECTOR_TYPE_9_16)
    kps = det.detect(img)
    rows = sorted((int(round(k.pt[0])), int(round(k.pt[1])), int(round(k.response))) for k in kps)
    with open(os.path.join(FEAT, "fast_box_in_scene.csv"), "w") as f:
        f.write("x,y,score\n")
        for r in rows:
            f.write("%d,%d,%d\n" % r)
    return len(rows)


def orb_match(a, b, cross_check=True, n=500):
    orb = cv2.ORB_create(nfeatures=n)
    ka, da = orb.detectAndCompute(a, None)
    kb, db = orb.detectAndCompute(b, None)
    bf = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=cross_check)
    m = bf.match(da, db)
    pa = np.array([ka[x.queryIdx].pt for x in m], np.float64)
    pb = np.array([kb[x.trainIdx].pt for x in m], np.float64)
    return len(ka), len(kb), pa, pb


def orb_ratio(a, b, ratio=0.8, n=500):
    orb = cv2.ORB_create(nfeatures=n)
    ka, da = orb.detectAndCompute(a, None)
    kb, db = orb.detectAndCompute(b, None)
    bf = cv2.BFMatcher(cv2.NORM_HAMMING)
    good = [p[0] for p in bf.knnMatch(da, db, k=2) if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    pa = np.array([ka[x.queryIdx].pt for x in good], np.float64)
    pb = np.array([kb[x.trainIdx].pt for x in good], np.float64)
    return pa, pb


def graf_figures():
    g1 = gray(os.path.join(GRAF, "graf1.png"))
    g3 = gray(os.path.join(GRAF, "graf3.png"))
    ht = h1to3()
    n1, n3, pa, pb = orb_match(g1, g3)
    err = np.linalg.norm(transfer(ht, pa) - pb, axis=1)
    ra, rb = orb_ratio(g1, g3)
    rerr = np.linalg.norm(transfer(ht, ra) - rb, axis=1)
    h_est, mask = cv2.findHomography(pa, pb, cv2.RANSAC, 3.0)
    grid = graf_grid(ht, g1.shape[1], g1.shape[0])
    gerr = np.linalg.norm(transfer(h_est, grid) - transfer(ht, grid), axis=1)
    return {
        "orb_features": [n1, n3],
        "crosscheck_matches": int(len(pa)),
        "crosscheck_correct_3px": int((err < 3).sum()),
        "crosscheck_fraction_3px": float((err < 3).mean()),
        "ratio08_matches": int(len(ra)),
        "ratio08_fraction_3px": float((rerr < 3).mean()) if len(ra) else 0.0,
        "ransac_inliers": int(mask.sum()),
        "grid_points": int(len(grid)),
        "grid_mean_transfer_error_px": float(gerr.mean()),
        "grid_max_transfer_error_px": float(gerr.max()),
    }


def box_figures():
    box = gray(os.path.join(FEAT, "box.png"))
    scene = gray(os.path.join(FEAT, "box_in_scene.png"))
    h, w = box.shape
    corners = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float64)
    # Reference outline: SIFT + ratio 0.75 + RANSAC 3 px, the most accurate detector OpenCV has.
    sift = cv2.SIFT_create()
    ka, da = sift.detectAndCompute(box, None)
    kb, db = sift.detectAndCompute(scene, None)
    good = [p[0] for p in cv2.BFMatcher(cv2.NORM_L2).knnMatch(da, db, k=2)
            if len(p) == 2 and p[0].distance < 0.75 * p[1].distance]
    pa = np.array([ka[x.queryIdx].pt for x in good])
    pb = np.array([kb[x.trainIdx].pt for x in good])
    hs, ms = cv2.findHomography(pa, pb, cv2.RANSAC, 3.0)
    ref = transfer(hs, corners)
    # OpenCV ORB + cross-check + RANSAC, for the side-by-side figure.
    _, _, oa, ob = orb_match(box, scene)
    ho, mo = cv2.findHomography(oa, ob, cv2.RANSAC, 3.0)
    orb_out = transfer(ho, corners)
    return {
        "sift_inliers": int(ms.sum()),
        "reference_outline_sift": ref.tolist(),
        "orb_crosscheck_matches": int(len(oa)),
        "orb_ransac_inliers": int(mo.sum()),
        "orb_outline": orb_out.tolist(),
        "orb_outline_max_corner_error_px": float(np.linalg.norm(orb_out - ref, axis=1).max()),
    }


def checker_logo(n=128, cell=16):
    y, x = np.mgrid[0:n, 0:n]
    return np.where(((x // cell) + (y // cell)) % 2 == 0, 230, 30).astype(np.uint8)


def warp_case():
    """Frame 320x240 of value 100; the logo's corner pixel centres go to the quad below."""
    logo = checker_logo()
    frame = np.full((240, 320), 100, np.uint8)
    src = np.array([[0, 0], [127, 0], [127, 127], [0, 127]], np.float32)
    dst = np.array([[60.3, 40.7], [250.2, 62.9], [231.6, 205.1], [41.8, 180.4]], np.float32)
    h = cv2.getPerspectiveTransform(src, dst)
    out = cv2.warpPerspective(logo, h, (320, 240), dst=frame.copy(), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_TRANSPARENT)
    cv2.imwrite(os.path.join(FEAT, "warp_checker_opencv.png"), out)
    return {"quad": dst.tolist(), "H": h.tolist()}


def main():
    cv2.setNumThreads(1)
    figures = {
        "opencv_version": cv2.__version__,
        "numpy_version": np.__version__,
        "fast_box_in_scene_corners": fast_fixture(),
        "graf1_to_graf3": graf_figures(),
        "box_in_scene": box_figures(),
        "warp_checker": warp_case(),
    }
    with open(os.path.join(FEAT, "opencv_orb_figures.json"), "w") as f:
        json.dump(figures, f, indent=2)
        f.write("\n")
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
