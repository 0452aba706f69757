#!/usr/bin/env python3
"""OpenCV's side of the `camgeom calibrate` / `camgeom undistort` tests (tests/it/calib_cli.rs).

    calib_cli_opencv.py read CAMERA.yml
        Reads the file with cv2.FileStorage and prints JSON: K (9, row-major), dist (as stored),
        image_width, image_height, avg_reprojection_error, per_view (list), flags,
        fisheye_model, board_width, board_height, square_size.
    calib_cli_opencv.py undistort CAMERA.yml IMAGE A OUT.png [FX,FY,CX,CY]
        The undistorted image as OpenCV makes it: new camera matrix by
        cv2.getOptimalNewCameraMatrix(alpha=A) (Brown-Conrady) or
        cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(balance=A) (fisheye_model: 1),
        map by initUndistortRectifyMap (CV_16SC2), cv2.remap INTER_LINEAR, BORDER_CONSTANT 0.
        With FX,FY,CX,CY the map uses that new camera matrix instead (to compare the map and
        the remap alone). Writes OUT.png and prints JSON {"K_new": [9]} (OpenCV's).

OpenCV and numpy only, never camgeom.
"""

import json
import sys

import cv2
import numpy as np


def read(path):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        sys.exit(f"cannot open {path}")
    K = fs.getNode("camera_matrix").mat()
    d = fs.getNode("distortion_coefficients").mat()
    pv = fs.getNode("per_view_reprojection_errors").mat()
    fm = fs.getNode("fisheye_model")
    out = {
        "K": K.reshape(-1).tolist(),
        "dist": d.reshape(-1).tolist(),
        "dist_shape": list(d.shape),
        "image_width": int(fs.getNode("image_width").real()),
        "image_height": int(fs.getNode("image_height").real()),
        "board_width": int(fs.getNode("board_width").real()),
        "board_height": int(fs.getNode("board_height").real()),
        "square_size": fs.getNode("square_size").real(),
        "flags": int(fs.getNode("flags").real()),
        "fisheye_model": int(fm.real()) if not fm.empty() else 0,
        "avg_reprojection_error": fs.getNode("avg_reprojection_error").real(),
        "per_view": pv.reshape(-1).tolist() if pv is not None else None,
    }
    fs.release()
    return out, K, d


def undistort(path, image, a, out_path, given=None):
    info, K, d = read(path)
    img = cv2.imread(image, cv2.IMREAD_GRAYSCALE)
    h, w = img.shape
    if info["fisheye_model"] == 1:
        D = d.reshape(4, 1)
        k_new = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, D, (w, h), np.eye(3), balance=a)
        k_map = k_new if given is None else given
        m1, m2 = cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), k_map, (w, h), cv2.CV_16SC2)
    else:
        k_new, _ = cv2.getOptimalNewCameraMatrix(K, d, (w, h), a, (w, h))
        k_map = k_new if given is None else given
        m1, m2 = cv2.initUndistortRectifyMap(K, d, None, k_map, (w, h), cv2.CV_16SC2)
    res = cv2.remap(img, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    cv2.imwrite(out_path, res)
    return {"K_new": np.asarray(k_new).reshape(-1).tolist()}


def main():
    if len(sys.argv) >= 3 and sys.argv[1] == "read":
        print(json.dumps(read(sys.argv[2])[0]))
    elif len(sys.argv) in (6, 7) and sys.argv[1] == "undistort":
        given = None
        if len(sys.argv) == 7:
            fx, fy, cx, cy = (float(v) for v in sys.argv[6].split(","))
            given = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float64)
        print(json.dumps(undistort(sys.argv[2], sys.argv[3], float(sys.argv[4]), sys.argv[5], given)))
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
