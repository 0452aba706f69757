#!/usr/bin/env python3
"""camgeom's AprilTag detector beside AprilTag 3 and OpenCV on rendered stills with exact corners.

    python3 host-tests/scripts/apriltag_study.py            # the study: 760 stills, tables
    python3 host-tests/scripts/apriltag_study.py --fixture  # the committed stills: peers.csv
    python3 host-tests/scripts/apriltag_study.py --sequence # the tag sequence: pose errors
    python3 host-tests/scripts/apriltag_study.py --sequence --fixture  # also apriltag3.csv

The stills come from apriltag_render.py (the study's 40 a bin into target/apriltag-study/, seed
12; --fixture: the 3 a bin committed in host-tests/data/apriltag/stills/). Detectors, all on the
same 8-bit files, tag36h11 only, decimation 1:

  camgeom    `cargo run -p camgeom-host --example apriltag_detect` (default configuration: edge
             refinement on, 2 bits corrected, sharpening 0.25; the board workspace
             Workspace320x240);
  AprilTag 3 pupil-apriltags (libapriltag 3.1), nthreads=1, quad_decimate=1, refine_edges=1,
             decode_sharpening 0.25 written into the detector struct (pupil's wrapper casts the
             value to int, which would turn sharpening off); corners shifted by -0.5 px
             (AprilTag's pixel centres are at i + 0.5);
  OpenCV     cv2.aruco.ArucoDetector with DICT_APRILTAG_36h11, default parameters plus
             cornerRefinementMethod = CORNER_REFINE_SUBPIX (its default, NONE, gives whole
             pixels); OpenCV's corner k is AprilTag's (1, 0, 3, 2)[k] (OpenCV draws the tags
             turned by 180 degrees).

A still counts as detected when a detection has the true id and its four corners are within
max(2 px, side / 4) of the truth (the id decides; the threshold only rules out a right id in a
wrong place); any other detection is false. Corner error: the distance of each corner to the
exact projection, over the detected stills (4 per still).

--sequence runs camgeom and AprilTag 3 on every frame of host-tests/data/sequences/tag with the
pose (camgeom: `tag_pose`, IPPE + LM through the sequence camera; AprilTag 3: its
estimate_tag_pose, orthogonal iteration) and prints per-frame rotation / translation errors
against truth.csv and their summary; --csv PATH writes the per-frame table; with --fixture it
writes AprilTag 3's per-frame errors to host-tests/data/sequences/tag/apriltag3.csv
(`frame,detected,rot_deg,t_mm`), which the host test compares camgeom with.
"""
import argparse
import csv
import ctypes
import math
import os
import subprocess
import sys

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import apriltag_render as ar  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(HERE))
CV_TO_AT = (1, 0, 3, 2)


def camgeom(images, extra=()):
    """camgeom's detections: {image: [(id, corners 4x2, row)]}."""
    cmd = ["cargo", "run", "-q", "-p", "camgeom-host", "--example", "apriltag_detect", "--", *extra, *images]
    out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
    res = {im: [] for im in images}
    for row in csv.DictReader(out.splitlines()):
        c = np.array([[float(row[f"x{i}"]), float(row[f"y{i}"])] for i in range(4)])
        res[row["image"]].append((int(row["id"]), c, row))
    return res


def apriltag3(nthreads=1):
    import pupil_apriltags as pa

    det = pa.Detector("tag36h11", nthreads=nthreads, quad_decimate=1.0, refine_edges=1)
    det.tag_detector_ptr.contents.decode_sharpening = ctypes.c_double(0.25)
    return det


def run_apriltag3(det, images, pose=None):
    res = {}
    for im in images:
        img = cv2.imread(im, cv2.IMREAD_GRAYSCALE)
        if pose:
            ds = det.detect(img, estimate_tag_pose=True, camera_params=pose[0], tag_size=pose[1])
        else:
            ds = det.detect(img)
        res[im] = [(d.tag_id, d.corners - 0.5, d) for d in ds]
    return res


def run_opencv(images):
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    p = cv2.aruco.DetectorParameters()
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(d, p)
    res = {}
    for im in images:
        img = cv2.imread(im, cv2.IMREAD_GRAYSCALE)
        corners, ids, _ = det.detectMarkers(img)
        out = []
        if ids is not None:
            for c, i in zip(corners, ids.ravel()):
                c = c.reshape(4, 2)
                out.append((int(i), np.array([c[CV_TO_AT[k]] for k in range(4)], dtype=float), None))
        res[im] = out
    return res


def score(truth, dets):
    """Per still: (detected, corner errors or None, false detections)."""
    out = {}
    for im, t in truth.items():
        side = t["side"]
        tol = max(2.0, side / 4)
        hit, false = None, 0
        for tid, c, _ in dets.get(im, []):
            e = np.linalg.norm(c - t["corners"], axis=1)
            if tid == t["id"] and (e <= tol).all() and hit is None:
                hit = e
            else:
                false += 1
        out[im] = (hit is not None, hit, false)
    return out


def load_truth(d):
    truth = {}
    with open(os.path.join(d, "truth.csv")) as f:
        for r in csv.DictReader(f):
            im = os.path.join(d, r["image"])
            truth[im] = {
                "id": int(r["id"]),
                "sweep": r["sweep"],
                "size": int(r["size_px"]),
                "side": float(r["side_px"]),
                "tilt": float(r["tilt_deg"]),
                "distance": float(r["distance_m"]),
                "corners": np.array([[float(r[f"x{i}"]), float(r[f"y{i}"])] for i in range(4)]),
            }
    return truth


def table(truth, scores, names):
    """Markdown tables per sweep bin: detection rate, median / p90 corner error per method."""
    lines = []
    for sweep, key, label in (("size", "size", "side (px) / distance (m)"), ("tilt", "tilt", "tilt (deg), 40 px")):
        bins = sorted({t[key] if sweep == "size" else round(t[key]) for t in truth.values() if t["sweep"] == sweep})
        hdr = f"| {label} | n | " + " | ".join(f"{n} rate" for n in names) + " | " + \
              " | ".join(f"{n} err med / p90 (px)" for n in names) + " |"
        lines += [hdr, "|" + "---|" * (2 + 2 * len(names))]
        for b in bins:
            ims = [im for im, t in truth.items() if t["sweep"] == sweep and
                   (t[key] if sweep == "size" else round(t[key])) == b]
            cells = []
            errs = []
            for n in names:
                s = scores[n]
                cells.append(f"{sum(s[i][0] for i in ims) / len(ims):.2f}")
                e = np.concatenate([s[i][1] for i in ims if s[i][0]] or [np.zeros(0)])
                errs.append(f"{np.median(e):.3f} / {np.percentile(e, 90):.3f}" if e.size else "-")
            lab = f"{b} / {ar.FOCAL * ar.TAG_SIZE / b:.2f}" if sweep == "size" else f"{b}"
            lines.append(f"| {lab} | {len(ims)} | " + " | ".join(cells) + " | " + " | ".join(errs) + " |")
        lines.append("")
    # Totals and the paired comparison with AprilTag 3.
    lines.append("| method | detected | false | corner err median / p90 / max (px) | on stills both detect: median vs AprilTag 3 |")
    lines.append("|---|---|---|---|---|")
    at = scores.get("AprilTag 3")
    for n in names:
        s = scores[n]
        det = sum(v[0] for v in s.values())
        false = sum(v[2] for v in s.values())
        e = np.concatenate([v[1] for v in s.values() if v[0]] or [np.zeros(0)])
        both = [i for i in s if s[i][0] and at and at[i][0]]
        if both and n != "AprilTag 3":
            pe = np.concatenate([s[i][1] for i in both])
            pa = np.concatenate([at[i][1] for i in both])
            paired = f"{np.median(pe):.3f} vs {np.median(pa):.3f} ({len(both)} stills)"
        else:
            paired = "-"
        lines.append(f"| {n} | {det}/{len(s)} | {false} | {np.median(e):.3f} / {np.percentile(e, 90):.3f} / {e.max():.3f} | {paired} |")
    return "\n".join(lines)


def rot_err_deg(Ra, Rb):
    c = (np.trace(Ra @ Rb.T) - 1) / 2
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def sequence(csv_out, fixture=False):
    d = os.path.join(ROOT, "host-tests", "data", "sequences", "tag")
    frames = sorted(os.path.join(d, f) for f in os.listdir(d) if f.endswith(".png"))
    truth = {}
    with open(os.path.join(d, "truth.csv")) as f:
        for r in csv.DictReader(f):
            R = np.array([float(r[k]) for k in ("r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")]).reshape(3, 3)
            t = np.array([float(r["tx"]), float(r["ty"]), float(r["tz"])])
            truth[os.path.join(d, f"{int(r['frame']):04d}.png")] = (R, t, r)
    size = ar.SEQ_TAG_SIZE
    cg = camgeom(frames, ["--pose", str(size), "--camera", os.path.join(d, "camera.yml")])
    K = ar.K
    at = run_apriltag3(apriltag3(), frames, pose=((K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5), size))
    rows = []
    for im in frames:
        R, t, r = truth[im]
        row = {"frame": int(r["frame"]), "in_view": int(r["in_view"]), "occluded": int(r["occluded"]),
               "gain": float(r["gain"])}
        for name, dets in (("camgeom", cg), ("apriltag3", at)):
            hit = [x for x in dets[im] if x[0] == ar.SEQ_ID]
            if not hit:
                row[f"{name}_rot_deg"] = row[f"{name}_t_mm"] = ""
                continue
            if name == "camgeom":
                q = hit[0][2]
                Re = np.array([float(q[k]) for k in ("r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33")]).reshape(3, 3)
                te = np.array([float(q["tx"]), float(q["ty"]), float(q["tz"])])
            else:
                Re, te = hit[0][2].pose_R, hit[0][2].pose_t.ravel()
            row[f"{name}_rot_deg"] = f"{rot_err_deg(Re, R):.4f}"
            row[f"{name}_t_mm"] = f"{1000 * np.linalg.norm(te - t):.3f}"
        rows.append(row)
    if csv_out:
        with open(csv_out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    if fixture:
        # AprilTag 3's side only: what the host test compares camgeom with.
        with open(os.path.join(d, "apriltag3.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["frame", "detected", "rot_deg", "t_mm"])
            for r in rows:
                ok = r["apriltag3_rot_deg"] != ""
                w.writerow([r["frame"], int(ok), r["apriltag3_rot_deg"], r["apriltag3_t_mm"]])
    print("| method | frames detected (of 160; tag fully in view: {}) | rotation err median / p90 / max (deg) | translation err median / p90 / max (mm) |".format(
        sum(r["in_view"] for r in rows)))
    print("|---|---|---|---|")
    for name in ("camgeom", "apriltag3"):
        re = np.array([float(r[f"{name}_rot_deg"]) for r in rows if r[f"{name}_rot_deg"] != ""])
        te = np.array([float(r[f"{name}_t_mm"]) for r in rows if r[f"{name}_t_mm"] != ""])
        print(f"| {name} | {len(re)} | {np.median(re):.3f} / {np.percentile(re, 90):.3f} / {re.max():.3f} | "
              f"{np.median(te):.2f} / {np.percentile(te, 90):.2f} / {te.max():.2f} |")
    both = [r for r in rows if r["camgeom_rot_deg"] != "" and r["apriltag3_rot_deg"] != ""]
    better = sum(float(r["camgeom_rot_deg"]) <= float(r["apriltag3_rot_deg"]) for r in both)
    print(f"\nframes both detect: {len(both)}; camgeom's rotation error <= AprilTag 3's on {better}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fixture", action="store_true")
    ap.add_argument("--sequence", action="store_true")
    ap.add_argument("--csv")
    ap.add_argument("--dir")
    args = ap.parse_args()
    if args.sequence:
        sequence(args.csv, args.fixture)
        return
    if args.fixture:
        d = os.path.join(ROOT, "host-tests", "data", "apriltag", "stills")
    else:
        d = args.dir or os.path.join(ROOT, "target", "apriltag-study")
        if not os.path.exists(os.path.join(d, "truth.csv")):
            ar.make_stills(d, 40, seed=12)
    truth = load_truth(d)
    images = sorted(truth)
    scores = {
        "camgeom": score(truth, camgeom(images)),
        "AprilTag 3": score(truth, run_apriltag3(apriltag3(), images)),
        "OpenCV": score(truth, run_opencv(images)),
    }
    if args.fixture:
        with open(os.path.join(d, "peers.csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["image", "method", "detected", "false", "e0", "e1", "e2", "e3"])
            for n in ("AprilTag 3", "OpenCV"):
                for im in images:
                    ok, e, false = scores[n][im]
                    w.writerow([os.path.basename(im), n, int(ok), false]
                               + ([f"{v:.6f}" for v in e] if ok else ["", "", "", ""]))
    print(table(truth, scores, list(scores)))


if __name__ == "__main__":
    main()
