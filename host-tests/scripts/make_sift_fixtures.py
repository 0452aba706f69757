#!/usr/bin/env python3
"""OpenCV's SIFT on the box images, the reference of camgeom's SIFT tests (tests/it/sift.rs).

Run from the repository root:  python3 host-tests/scripts/make_sift_fixtures.py
Needs opencv-python-headless (5.0.0 measured) and numpy; `cargo test` only reads what this
writes.

Writes host-tests/data/features/sift_box.json:
  keypoints     the KEEP strongest keypoints of cv2.SIFT_create() (defaults: 3 layers, contrast
                0.04, edge 10, sigma 1.6, the image doubled first, enable_precise_upscale) on
                box_in_scene.png, each
                [x, y, size, angle in degrees, response]
  descriptors   their 128-byte descriptors, hex
  H             the homography box.png -> box_in_scene.png: that SIFT on both, brute-force L2
                matching with the ratio test 0.75, cv2.findHomography (RANSAC, 3 px)
  matches       how many ratio-test matches OpenCV found, and how many of those are within 3 px
                of H (the figure camgeom's matching is compared with)
"""
import json
import os

import cv2
import numpy as np

FEAT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "features")
KEEP = 150


def main():
    cv2.setNumThreads(1)
    box = cv2.imread(os.path.join(FEAT, "box.png"), cv2.IMREAD_GRAYSCALE)
    scene = cv2.imread(os.path.join(FEAT, "box_in_scene.png"), cv2.IMREAD_GRAYSCALE)
    # Precise upscaling: pixel x of the doubled image is input pixel x / 2, as camgeom's (the
    # default resize shifts every keypoint by a quarter of a pixel).
    sift = cv2.SIFT_create(enable_precise_upscale=True)
    kb, db = sift.detectAndCompute(box, None)
    ks, ds = sift.detectAndCompute(scene, None)
    order = sorted(range(len(ks)), key=lambda i: -ks[i].response)[:KEEP]
    keypoints = [
        [ks[i].pt[0], ks[i].pt[1], ks[i].size, ks[i].angle, ks[i].response] for i in order
    ]
    descriptors = [bytes(ds[i].astype(np.uint8)).hex() for i in order]
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(db, ds, k=2)
    good = [m for m, n in pairs if m.distance < 0.75 * n.distance]
    src = np.float32([kb[m.queryIdx].pt for m in good])
    dst = np.float32([ks[m.trainIdx].pt for m in good])
    H, _ = cv2.findHomography(src, dst, cv2.RANSAC, 3.0)
    proj = cv2.perspectiveTransform(src.reshape(-1, 1, 2), H).reshape(-1, 2)
    inliers = int((np.linalg.norm(proj - dst, axis=1) < 3.0).sum())
    out = {
        "opencv": cv2.__version__,
        "keypoints": keypoints,
        "descriptors": descriptors,
        "H": [float(v) for v in H.reshape(-1)],
        "matches": len(good),
        "inliers": inliers,
        "box_keypoints": len(kb),
        "scene_keypoints": len(ks),
    }
    path = os.path.join(FEAT, "sift_box.json")
    with open(path, "w") as f:
        json.dump(out, f, separators=(",", ":"))
    print(f"{path}: {len(kb)} + {len(ks)} keypoints, {len(good)} matches, {inliers} within 3 px")


if __name__ == "__main__":
    main()
