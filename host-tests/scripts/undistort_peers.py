#!/usr/bin/env python3
"""`camgeom undistort` against OpenCV's initUndistortRectifyMap + remap at camera resolutions.

    python3 host-tests/scripts/undistort_peers.py [--bin target/release/camgeom] [--runs 5]
        Makes a 1920x1080 and a 4032x3024 colour frame from a bundled photograph
        (multiview/herz-jesus-p8/0000.jpg, 1536x1024: cropped to the frame's aspect, upscaled
        with INTER_CUBIC) and a camera for each (the bundled chessboard camera,
        chessboard/left_intrinsics.yml, scaled to the frame; the 16:9 frame is the 4:3 sensor
        cropped top and bottom), writes them in a temporary folder, undistorts each with
        `camgeom undistort --alpha 0` (grey and colour) and with OpenCV
        (getOptimalNewCameraMatrix, initUndistortRectifyMap CV_16SC2, remap INTER_LINEAR,
        BORDER_CONSTANT 0, cv2.setNumThreads(1)), and prints a Markdown table: the pixel
        comparison through camgeom's new camera matrix (the map and the remap alone) and
        through OpenCV's own, and the times (medians over --runs runs).
        Build camgeom first: cargo build --release -p camgeom-host.

    python3 host-tests/scripts/undistort_peers.py opencv CAMERA.yml IMAGE A OUT.png [FX,FY,CX,CY]
        OpenCV's undistorted image (grey stays grey, colour stays colour): new camera matrix by
        getOptimalNewCameraMatrix(alpha=A), or FX,FY,CX,CY when given; map and remap as above.
        Prints JSON {"K_new": [9]} (OpenCV's own). Used by tests/it/calib_cli.rs.

OpenCV and numpy only on the reference side, never camgeom.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DATA = os.path.join(ROOT, "host-tests", "data")
PHOTO = os.path.join(DATA, "multiview", "herz-jesus-p8", "0000.jpg")
CAMERA = os.path.join(DATA, "chessboard", "left_intrinsics.yml")
SIZES = [(1920, 1080), (4032, 3024)]


def read_camera(path):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    K = fs.getNode("camera_matrix").mat()
    d = fs.getNode("distortion_coefficients").mat()
    size = (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
    fs.release()
    return K, d, size


def write_camera(path, K, d, w, h):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", w)
    fs.write("image_height", h)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", d)
    fs.release()


def scaled_camera(w, h):
    """The bundled 640x480 camera on a w x h frame: a 4:3 sensor of width w, cropped to h."""
    K, d, (w0, h0) = read_camera(CAMERA)
    s = w / w0
    K = K.copy()
    K[0, 0] *= s
    K[1, 1] *= s
    K[0, 2] = (K[0, 2] + 0.5) * s - 0.5
    K[1, 2] = (K[1, 2] + 0.5) * s - 0.5 - (h0 * s - h) / 2
    return K, d


def make_frame(w, h):
    img = cv2.imread(PHOTO, cv2.IMREAD_COLOR)
    ph, pw = img.shape[:2]
    if pw * h > ph * w:  # too wide: crop the sides
        cw = ph * w // h
        img = img[:, (pw - cw) // 2 : (pw - cw) // 2 + cw]
    else:
        ch = pw * h // w
        img = img[(ph - ch) // 2 : (ph - ch) // 2 + ch]
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)


def opencv_undistort(K, d, img, alpha, given=None):
    h, w = img.shape[:2]
    k_new, _ = cv2.getOptimalNewCameraMatrix(K, d, (w, h), alpha, (w, h))
    k_map = k_new if given is None else given
    m1, m2 = cv2.initUndistortRectifyMap(K, d, None, k_map, (w, h), cv2.CV_16SC2)
    res = cv2.remap(img, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return res, k_new


def opencv_main(argv):
    cam, image, a, out = argv[:4]
    K, d, _ = read_camera(cam)
    img = cv2.imread(image, cv2.IMREAD_ANYCOLOR)
    given = None
    if len(argv) == 5:
        fx, fy, cx, cy = (float(v) for v in argv[4].split(","))
        given = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float64)
    res, k_new = opencv_undistort(K, d, img, float(a), given)
    cv2.imwrite(out, res)
    print(json.dumps({"K_new": np.asarray(k_new).reshape(-1).tolist()}))


def compare(a, b):
    """Largest difference, share of samples more than 1 apart, share equal."""
    diff = np.abs(a.astype(np.int32) - b.astype(np.int32))
    return int(diff.max()), float((diff > 1).mean()), float((diff == 0).mean())


def median_time(f, runs):
    ts = []
    for _ in range(runs):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def camgeom_runs(binary, cam, image, out, runs):
    """JSON of the last run, median map and remap seconds, median wall seconds."""
    maps, remaps, walls = [], [], []
    for _ in range(runs):
        t = time.perf_counter()
        o = subprocess.run(
            [binary, "undistort", "--intrinsics", cam, "--image", image, "--out", out, "--alpha", "0"],
            capture_output=True,
            text=True,
        )
        walls.append(time.perf_counter() - t)
        if o.returncode != 0:
            sys.exit(f"camgeom undistort failed: {o.stderr}")
        j = json.loads(o.stdout)
        maps.append(j["seconds"][0])
        remaps.append(j["seconds"][1])
    return j, statistics.median(maps), statistics.median(remaps), statistics.median(walls)


def bench(args):
    cv2.setNumThreads(1)
    binary = os.path.abspath(args.bin)
    if not os.path.exists(binary):
        sys.exit(f"{binary} not found: cargo build --release -p camgeom-host")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for w, h in SIZES:
            K, d = scaled_camera(w, h)
            cam = os.path.join(tmp, f"camera_{w}x{h}.yml")
            write_camera(cam, K, d, w, h)
            colour = make_frame(w, h)
            for kind, img in [("grey", cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY)), ("colour", colour)]:
                src = os.path.join(tmp, f"frame_{w}x{h}_{kind}.png")
                cv2.imwrite(src, img)
                out = os.path.join(tmp, f"camgeom_{w}x{h}_{kind}.png")
                j, t_map, t_remap, t_wall = camgeom_runs(binary, cam, src, out, args.runs)
                ours = cv2.imread(out, cv2.IMREAD_ANYCOLOR)
                assert ours.shape == img.shape, (ours.shape, img.shape)
                assert j["channels"] == (3 if kind == "colour" else 1)
                k = j["new_camera_matrix"]
                given = np.array([[k[0], 0, k[2]], [0, k[4], k[5]], [0, 0, 1]], dtype=np.float64)
                same, _ = opencv_undistort(K, d, img, 0.0, given)
                own, k_cv = opencv_undistort(K, d, img, 0.0)
                dk = float(np.abs(np.asarray(k) - k_cv.reshape(-1)).max())
                # OpenCV's times: the map, the remap, and the whole chain from file to file.
                m = {}
                cv_map = median_time(
                    lambda: m.update(
                        maps=cv2.initUndistortRectifyMap(K, d, None, k_cv, (w, h), cv2.CV_16SC2)
                    ),
                    args.runs,
                )
                m1, m2 = m["maps"]
                cv_remap = median_time(
                    lambda: cv2.remap(img, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0),
                    args.runs,
                )
                cv_out = os.path.join(tmp, f"opencv_{w}x{h}_{kind}.png")

                def chain():
                    im = cv2.imread(src, cv2.IMREAD_ANYCOLOR)
                    res, _ = opencv_undistort(K, d, im, 0.0)
                    cv2.imwrite(cv_out, res)

                cv_wall = median_time(chain, args.runs)
                rows.append(
                    dict(
                        size=f"{w}x{h}",
                        kind=kind,
                        same=compare(ours, same),
                        own=compare(ours, own),
                        dk=dk,
                        t=(t_map, t_remap, t_wall),
                        cv=(cv_map, cv_remap, cv_wall),
                    )
                )
                print(f"{w}x{h} {kind}: done", file=sys.stderr)
    print(f"OpenCV {cv2.__version__}, one thread; camgeom `undistort --alpha 0`; medians of {args.runs} runs\n")
    print(
        "| frame | pixels equal, max diff, > 1 apart: through camgeom's new K | through OpenCV's own new K (K within) "
        "| map ms: camgeom / OpenCV | remap ms: camgeom / OpenCV (ratio) | file to file ms: camgeom CLI / OpenCV |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        s, o = r["same"], r["own"]
        t, c = r["t"], r["cv"]
        print(
            f"| {r['size']} {r['kind']} | {100 * s[2]:.3f} %, {s[0]}, {100 * s[1]:.3f} % "
            f"| {100 * o[2]:.2f} %, {o[0]}, {100 * o[1]:.3f} % ({r['dk']:.4f} px) "
            f"| {1e3 * t[0]:.0f} / {1e3 * c[0]:.0f} | {1e3 * t[1]:.0f} / {1e3 * c[1]:.0f} ({t[1] / c[1]:.1f}x) "
            f"| {1e3 * t[2]:.0f} / {1e3 * c[2]:.0f} |"
        )


def main():
    if len(sys.argv) >= 2 and sys.argv[1] == "opencv":
        if len(sys.argv) not in (6, 7):
            sys.exit(__doc__)
        return opencv_main(sys.argv[2:])
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "camgeom"))
    p.add_argument("--runs", type=int, default=5)
    bench(p.parse_args())


if __name__ == "__main__":
    main()
