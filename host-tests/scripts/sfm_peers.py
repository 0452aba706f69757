#!/usr/bin/env python3
"""Structure from motion on real photographs, camgeom beside its peers (issue #37's "must show").

Three methods run on identical images and are scored by the same code against the true cameras
of a set under host-tests/data/multiview/ (README there):

  colmap   pycolmap (COLMAP 4.x): SIFT extraction, exhaustive matching, incremental mapping with
           the camera fixed to the set's K (one PINHOLE camera fx, fy, cx, cy shared by all views;
           focal length, principal point and extra parameters not refined), one thread, in a
           temporary workspace; the largest reconstruction is scored.
  opencv   the course's textbook pipeline, one thread (cv2.setNumThreads(1)): SIFT
           (cv2.SIFT_create, all features), brute-force L2 matching with the ratio test 0.75;
           first pair: findEssentialMat (RANSAC, prob 0.999, threshold 1 px) + recoverPose,
           triangulatePoints on its inliers; each next view: its matches to the previous
           registered view give 2D-3D correspondences for the points triangulated so far
           (tracks chained through those matches), solvePnPRansac registers it, and its new
           matches are triangulated. No bundle adjustment, no re-triangulation: only points in
           front of both cameras are kept. A view with fewer than 6 PnP inliers is reported as
           not registered.
  camgeom  `camgeom sfm --images <files in order> --intrinsics <set>/camera.json --out <tmp>`
           (given with --camgeom PATH); its stdout JSON is read; a non-zero exit is recorded as
           "refused: <last line of stderr>".

Scores, the same for every method (views registered is "k/n"):
  - every pair of registered views i < j: rotation error = angle of R_est_ij R_true_ij^T with
    R_ij = R_j R_i^T, translation-direction error = angle between t_ij directions
    (t_ij = t_j - R_ij t_i); median and max in degrees;
  - camera-centre error after a similarity alignment (Umeyama, scale included) of the estimated
    centres to the true ones (needs >= 3 registered views): median and max in metres;
  - 3D points; wall time in seconds (image reading included, Python start-up excluded).

Selections: --all (all views of the set in one run) and --triplets (every consecutive triplet
i, i+1, i+2, each a separate run; a summary row gives the worst value of each column over the
triplets, and the triplets' total time). --unrelated runs every method on views of different
buildings (two each, or --per-building N, of herz-jesus-p8, entry-p10 and sceaux-castle) and
reports which views each method put into one reconstruction; sceaux-castle's K differs from the others', and all views
are given herz-jesus-p8's camera.json.

    python3 host-tests/scripts/sfm_peers.py host-tests/data/multiview/herz-jesus-p8 --all --triplets
    python3 host-tests/scripts/sfm_peers.py host-tests/data/multiview/entry-p10 --all \\
        --methods colmap,opencv,camgeom --camgeom target/release/camgeom --json out.json
    python3 host-tests/scripts/sfm_peers.py --unrelated --camgeom target/release/camgeom

Installs pycolmap, opencv-python-headless and numpy with pip when they are missing
(requirements-sfm.txt pins the versions measured).
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DATA = os.path.join(ROOT, "host-tests", "data", "multiview")
REQUIREMENTS = os.path.join(HERE, "requirements-sfm.txt")
METHODS = ["colmap", "opencv", "camgeom"]


def ensure(modules):
    """pip-install the pinned requirements when one of `modules` does not import."""
    missing = []
    for m in modules:
        try:
            __import__(m)
        except ImportError:
            missing.append(m)
    if missing:
        print(f"{', '.join(missing)} missing: pip install -r {os.path.relpath(REQUIREMENTS, ROOT)}", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "-r", REQUIREMENTS], check=True)


ensure(["cv2", "numpy"])

import cv2  # noqa: E402
import numpy as np  # noqa: E402

# --- the data --------------------------------------------------------------------------------


def load_set(folder):
    """(K 3x3, [image file names], truth or None). truth: {file: (R 3x3, t 3)}."""
    with open(os.path.join(folder, "camera.json")) as fh:
        c = json.load(fh)
    k = np.array([[c["fx"], c.get("skew", 0.0), c["cx"]], [0.0, c["fy"], c["cy"]], [0.0, 0.0, 1.0]])
    truth = None
    path = os.path.join(folder, "cameras.json")
    if os.path.exists(path):
        with open(path) as fh:
            cams = json.load(fh)["cameras"]
        truth = {}
        for cam in cams:
            t = cam.get("t", cam.get("t_world_to_camera"))
            r = nearest_rotation(np.array(cam["R_world_to_camera"], dtype=np.float64))
            truth[cam["file"]] = (r, np.array(t, dtype=np.float64))
        files = [cam["file"] for cam in cams]
    else:
        files = sorted(f for f in os.listdir(folder) if f.lower().endswith((".jpg", ".jpeg", ".png")))
    return k, files, truth


def write_camera_json(k, path):
    with open(path, "w") as fh:
        json.dump({"fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2], "skew": k[0, 1], "distortion": [0, 0, 0, 0, 0]}, fh)


# --- one result ------------------------------------------------------------------------------


class Result:
    """What a method returned for the images in the order given: poses[i] is (R, t) with
    X_cam = R X_world + t, or None when view i is not registered (reasons[i] says why)."""

    def __init__(self, n):
        self.poses = [None] * n
        self.reasons = [""] * n
        self.points = 0
        self.seconds = float("nan")
        self.refused = None  # text when the method returned no reconstruction at all
        self.note = ""
        self.stages = {}

    def registered(self):
        return sum(p is not None for p in self.poses)


# --- COLMAP ----------------------------------------------------------------------------------


def run_colmap(images, k, threads=1, seed=0):
    """pycolmap 4.x. `images` are paths; they are linked into a temporary image folder under
    unique names (views of different sets may share a file name)."""
    ensure(["pycolmap"])
    import pycolmap

    if not os.environ.get("SFM_PEERS_COLMAP_LOG"):
        pycolmap.logging.minloglevel = 1  # warnings and errors only (INFO is a page per image)
    res = Result(len(images))
    work = tempfile.mkdtemp(prefix="sfm-colmap-")
    try:
        imdir = os.path.join(work, "images")
        os.makedirs(imdir)
        names = []
        for i, p in enumerate(images):
            name = f"{i:03d}_{os.path.basename(p)}"
            os.symlink(os.path.abspath(p), os.path.join(imdir, name))
            names.append(name)
        db = os.path.join(work, "database.db")
        out = os.path.join(work, "sparse")
        os.makedirs(out)
        pycolmap.set_random_seed(seed)

        reader = pycolmap.ImageReaderOptions()
        reader.camera_model = "PINHOLE"
        reader.camera_params = ",".join(repr(float(v)) for v in (k[0, 0], k[1, 1], k[0, 2], k[1, 2]))
        extraction = pycolmap.FeatureExtractionOptions()
        extraction.num_threads = threads
        extraction.use_gpu = False
        matching = pycolmap.FeatureMatchingOptions()
        matching.num_threads = threads
        matching.use_gpu = False
        verification = pycolmap.TwoViewGeometryOptions()
        verification.ransac.random_seed = seed
        pipeline = pycolmap.IncrementalPipelineOptions()
        pipeline.num_threads = threads
        pipeline.random_seed = seed
        pipeline.ba_refine_focal_length = False
        pipeline.ba_refine_principal_point = False
        pipeline.ba_refine_extra_params = False
        pipeline.mapper.abs_pose_refine_focal_length = False
        pipeline.mapper.abs_pose_refine_extra_params = False
        pipeline.mapper.num_threads = threads
        pipeline.mapper.random_seed = seed
        pipeline.triangulation.random_seed = seed

        # One camera for all views; but COLMAP skips an image whose size differs from the
        # single camera's (CAMERA_SINGLE_DIM_ERROR), as in --unrelated: there, one camera per
        # image, every one given the same fixed K.
        sizes = {cv2.imread(p, cv2.IMREAD_UNCHANGED).shape[:2] for p in images}
        mode = pycolmap.CameraMode.SINGLE if len(sizes) == 1 else pycolmap.CameraMode.PER_IMAGE
        if len(sizes) > 1:
            res.note = "images of different sizes: one camera per image, all with the same fixed K"
        t0 = time.perf_counter()
        pycolmap.extract_features(
            db, imdir, image_names=names, camera_mode=mode, reader_options=reader,
            extraction_options=extraction, device=pycolmap.Device.cpu,
        )
        t1 = time.perf_counter()
        pycolmap.match_exhaustive(db, matching_options=matching, verification_options=verification, device=pycolmap.Device.cpu)
        t2 = time.perf_counter()
        recs = pycolmap.incremental_mapping(db, imdir, out, options=pipeline)
        t3 = time.perf_counter()
        res.seconds = t3 - t0
        res.stages = {"features_s": t1 - t0, "matching_s": t2 - t1, "mapping_s": t3 - t2}
        if not recs:
            # COLMAP keeps no two-view model: an initial pair that no third view extends is
            # discarded as a "bad initial pair".
            res.refused = "no reconstruction"
            res.reasons = ["not in any model"] * len(images)
            return res
        sizes = {i: r.num_reg_images() for i, r in recs.items()}
        best = max(recs, key=lambda i: (sizes[i], recs[i].num_points3D()))
        rec = recs[best]
        if len(recs) > 1:
            res.note = (res.note + "; " if res.note else "") + f"{len(recs)} models, registered views {sorted(sizes.values(), reverse=True)}; the largest is scored"
        res.points = rec.num_points3D()
        cams = [list(map(float, c.params)) for c in rec.cameras.values()]
        res.stages["cameras_after"] = cams
        if not all(np.allclose(c, [k[0, 0], k[1, 1], k[0, 2], k[1, 2]], rtol=0, atol=1e-6) for c in cams):
            res.note = (res.note + "; " if res.note else "") + f"camera not fixed: {cams}"
        index = {n: i for i, n in enumerate(names)}
        for img in rec.images.values():
            if not img.has_pose:
                continue
            m = img.cam_from_world().matrix()  # 3x4 [R | t], X_cam = R X_world + t
            res.poses[index[img.name]] = (np.array(m[:, :3]), np.array(m[:, 3]))
        for i, p in enumerate(res.poses):
            if p is None:
                res.reasons[i] = "not in the largest model"
        return res
    finally:
        shutil.rmtree(work, ignore_errors=True)


# --- OpenCV ----------------------------------------------------------------------------------

RATIO = 0.75
MIN_PNP = 6


def ratio_matches(d1, d2):
    """Indices (i1, i2) of the matches passing Lowe's ratio test (brute force, L2)."""
    bf = cv2.BFMatcher(cv2.NORM_L2)
    out = []
    for pair in bf.knnMatch(d1, d2, k=2):
        if len(pair) == 2 and pair[0].distance < RATIO * pair[1].distance:
            out.append((pair[0].queryIdx, pair[0].trainIdx))
    return out


def triangulate(k, pa, pb, xa, xb):
    """Points (N x 3) from two views (R, t) and pixel arrays (N x 2); a mask of those in front
    of both cameras."""
    pa_m = k @ np.hstack([pa[0], pa[1].reshape(3, 1)])
    pb_m = k @ np.hstack([pb[0], pb[1].reshape(3, 1)])
    h = cv2.triangulatePoints(pa_m, pb_m, xa.T.astype(np.float64), xb.T.astype(np.float64))
    x = (h[:3] / h[3]).T
    za = (x @ pa[0].T + pa[1])[:, 2]
    zb = (x @ pb[0].T + pb[1])[:, 2]
    return x, np.isfinite(x).all(axis=1) & (za > 0) & (zb > 0)


def run_opencv(images, k):
    cv2.setNumThreads(1)
    n = len(images)
    res = Result(n)
    t0 = time.perf_counter()
    sift = cv2.SIFT_create()
    kps, descs = [], []
    for p in images:
        g = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
        kp, d = sift.detectAndCompute(g, None)
        kps.append(np.array([q.pt for q in kp], dtype=np.float64).reshape(-1, 2))
        descs.append(d)
    t1 = time.perf_counter()
    res.stages["features_s"] = t1 - t0

    points = []  # 3D points
    track = [dict() for _ in range(n)]  # per view: keypoint index -> point index

    def add_points(a, b, pairs):
        xa = kps[a][[i for i, _ in pairs]]
        xb = kps[b][[j for _, j in pairs]]
        x, ok = triangulate(k, res.poses[a], res.poses[b], xa, xb)
        for (i, j), xi, good in zip(pairs, x, ok):
            if good:
                track[a][i] = track[b][j] = len(points)
                points.append(xi)

    # the first pair
    m = ratio_matches(descs[0], descs[1]) if n >= 2 else []
    if len(m) < 5:
        res.refused = f"{len(m)} ratio-test matches between the first two views"
        res.seconds = time.perf_counter() - t0
        return res
    x0 = kps[0][[i for i, _ in m]]
    x1 = kps[1][[j for _, j in m]]
    e, mask = cv2.findEssentialMat(x0, x1, k, method=cv2.RANSAC, prob=0.999, threshold=1.0)
    if e is None or e.shape != (3, 3):
        res.refused = "findEssentialMat found no essential matrix"
        res.seconds = time.perf_counter() - t0
        return res
    ninl, r, t, mask = cv2.recoverPose(e, x0, x1, k, mask=mask)
    res.poses[0] = (np.eye(3), np.zeros(3))
    res.poses[1] = (r, t.ravel())
    inl = [mm for mm, ok in zip(m, mask.ravel()) if ok]
    res.stages["first_pair"] = {"matches": len(m), "inliers": int(ninl)}
    add_points(0, 1, inl)
    prev = 1
    for v in range(2, n):
        m = ratio_matches(descs[prev], descs[v])
        known = [(i, j) for i, j in m if i in track[prev]]
        if len(known) < MIN_PNP:
            res.reasons[v] = f"{len(known)} 2D-3D matches"
            continue
        obj = np.array([points[track[prev][i]] for i, _ in known])
        img = kps[v][[j for _, j in known]]
        ok, rvec, tvec, pnp_inl = cv2.solvePnPRansac(
            obj, img, k, None, iterationsCount=1000, reprojectionError=2.0, confidence=0.999
        )
        if not ok or pnp_inl is None or len(pnp_inl) < MIN_PNP:
            res.reasons[v] = f"solvePnPRansac: {0 if pnp_inl is None else len(pnp_inl)} inliers of {len(known)}"
            continue
        res.poses[v] = (cv2.Rodrigues(rvec)[0], tvec.ravel())
        for q in pnp_inl.ravel():
            i, j = known[q]
            track[v][j] = track[prev][i]
        new = [(i, j) for i, j in m if i not in track[prev] and j not in track[v]]
        add_points(prev, v, new)
        prev = v
    res.points = len(points)
    res.seconds = time.perf_counter() - t0
    res.stages["mapping_s"] = res.seconds - res.stages["features_s"]
    return res


# --- camgeom ---------------------------------------------------------------------------------


def read_camgeom_json(text, n):
    """camgeom sfm's stdout: {"views": [{"image", "registered", "reason", "R": [9 row-major],
    "t": [3], ...}], "points": N, ...}, views in the order the images were given."""
    out = json.loads(text)
    res = Result(n)
    views = out.get("views", [])
    if len(views) != n:
        res.note = f"{len(views)} views in the output for {n} images"
    for i, v in enumerate(views[:n]):
        if v.get("registered"):
            res.poses[i] = (np.array(v["R"], dtype=np.float64).reshape(3, 3), np.array(v["t"], dtype=np.float64).reshape(3))
        else:
            res.reasons[i] = v.get("reason") or "not registered"
    res.points = int(out.get("points", 0) or 0)
    res.raw = out
    return res


def run_camgeom(images, camera_json, binary):
    work = tempfile.mkdtemp(prefix="sfm-camgeom-")
    try:
        cmd = [binary, "sfm", "--images", *images, "--intrinsics", camera_json, "--out", work]
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        dt = time.perf_counter() - t0
        if p.returncode != 0:
            res = Result(len(images))
            lines = [line for line in p.stderr.strip().splitlines() if line.strip()]
            res.refused = "refused: " + (lines[-1] if lines else f"exit {p.returncode}")
            res.reasons = ["refused"] * len(images)
        else:
            try:
                res = read_camgeom_json(p.stdout, len(images))
            except (ValueError, KeyError, TypeError) as e:
                res = Result(len(images))
                res.refused = f"exit 0 but unreadable output: {e}"
                res.reasons = ["unreadable output"] * len(images)
        res.seconds = dt
        return res
    finally:
        shutil.rmtree(work, ignore_errors=True)


# --- scoring: the same code for every method -------------------------------------------------


def nearest_rotation(r):
    """The rotation nearest to r (Frobenius): the truth is given to 6 digits, so its R R^T
    differs from I by up to 1e-6."""
    u, _, vt = np.linalg.svd(r)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def angle_deg(r):
    """Rotation angle of r (deg) as atan2(|axis part|, cosine part). The usual
    arccos((trace - 1) / 2) turns a 1e-6 departure from orthonormality into a 0.06° floor
    (arccos(1 - e) ~ sqrt(2 e)): measured on the truth against itself."""
    s = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return float(np.degrees(math.atan2(0.5 * np.linalg.norm(s), 0.5 * (np.trace(r) - 1.0))))


def dir_angle_deg(a, b):
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na == 0 or nb == 0:
        return float("nan")
    return float(np.degrees(np.arccos(np.clip(a @ b / (na * nb), -1.0, 1.0))))


def relative(pi, pj):
    r = pj[0] @ pi[0].T
    return r, pj[1] - r @ pi[1]


def umeyama(src, dst):
    """Similarity (s, R, t) minimising sum |s R src + t - dst|^2 (Umeyama 1991)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    u, d, vt = np.linalg.svd(b.T @ a / len(src))
    s_fix = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    r = u @ s_fix @ vt
    var = (a * a).sum() / len(src)
    s = float(np.trace(np.diag(d) @ s_fix) / var) if var > 0 else float("nan")
    return s, r, md - s * r @ ms


def centre(p):
    return -p[0].T @ p[1]


def score(res, truth_poses):
    """truth_poses[i]: (R, t) of view i. Returns a dict of the table's numbers."""
    n = len(truth_poses)
    reg = [i for i in range(n) if res.poses[i] is not None]
    res.poses = [None if p is None else (nearest_rotation(p[0]), p[1]) for p in res.poses]
    s = {"registered": len(reg), "views": n, "points": res.points, "seconds": res.seconds}
    rot, tdir = [], []
    for a in range(len(reg)):
        for b in range(a + 1, len(reg)):
            i, j = reg[a], reg[b]
            re, te = relative(res.poses[i], res.poses[j])
            rt, tt = relative(truth_poses[i], truth_poses[j])
            rot.append(angle_deg(re @ rt.T))
            tdir.append(dir_angle_deg(te, tt))
    s["pairs"] = len(rot)
    s["rot_med"], s["rot_max"] = (float(np.median(rot)), float(np.max(rot))) if rot else (None, None)
    s["tdir_med"], s["tdir_max"] = (float(np.median(tdir)), float(np.max(tdir))) if tdir else (None, None)
    s["centre_med"] = s["centre_max"] = None
    if len(reg) >= 3:
        est = np.array([centre(res.poses[i]) for i in reg])
        tru = np.array([centre(truth_poses[i]) for i in reg])
        sc, r, t = umeyama(est, tru)
        err = np.linalg.norm((sc * (r @ est.T)).T + t - tru, axis=1)
        s["centre_med"], s["centre_max"] = float(np.median(err)), float(np.max(err))
    return s


# --- the table -------------------------------------------------------------------------------

COLUMNS = [
    ("method", "method"),
    ("selection", "views"),
    ("reg", "registered"),
    ("rot", "rotation error median / max (°)"),
    ("tdir", "translation-direction error median / max (°)"),
    ("centre", "centre error after similarity median / max (m)"),
    ("points", "points"),
    ("time", "time (s)"),
    ("note", "note"),
]


def f2(a, b, digits):
    if a is None:
        return "—"
    return f"{a:.{digits}f} / {b:.{digits}f}"


def row_cells(r):
    if r.get("refused") and r["registered"] < 2:
        return [r["method"], r["selection"], f"{r['registered']}/{r['views']}", "—", "—", "—", str(r["points"]), f"{r['seconds']:.1f}", r["refused"]]
    return [
        r["method"],
        r["selection"],
        f"{r['registered']}/{r['views']}",
        f2(r["rot_med"], r["rot_max"], 3),
        f2(r["tdir_med"], r["tdir_max"], 3),
        f2(r["centre_med"], r["centre_max"], 3),
        str(r["points"]),
        f"{r['seconds']:.1f}",
        r.get("note", ""),
    ]


def markdown(rows):
    head = [c[1] for c in COLUMNS]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join(row_cells(r)) + " |")
    return "\n".join(lines)


def worst(rows, method, label):
    """The worst value of each column over the triplet rows of one method; total time."""
    def mx(key):
        v = [r[key] for r in rows if r.get(key) is not None]
        return max(v) if v else None

    out = {
        "method": method,
        "selection": label,
        "registered": min(r["registered"] for r in rows),
        "views": rows[0]["views"],
        "points": min(r["points"] for r in rows),
        "seconds": sum(r["seconds"] for r in rows),
        "note": "worst per column over the triplets (fewest registered, fewest points, largest errors); total time",
    }
    for key in ("rot_med", "rot_max", "tdir_med", "tdir_max", "centre_med", "centre_max"):
        out[key] = mx(key)
    refused = [r["selection"] for r in rows if r.get("refused") and r["registered"] < 2]
    incomplete = [r["selection"] for r in rows if r["registered"] < r["views"]]
    if refused:
        out["note"] += f"; no reconstruction on {', '.join(refused)}"
    elif incomplete:
        out["note"] += f"; views missing on {', '.join(incomplete)}"
    return out


# --- running ---------------------------------------------------------------------------------


def run(method, images, k, camera_json, args):
    if method == "colmap":
        return run_colmap(images, k)
    if method == "opencv":
        return run_opencv(images, k)
    if method == "camgeom":
        return run_camgeom(images, camera_json, args.camgeom)
    raise ValueError(method)


def run_selection(method, folder, files, k, truth, label, args):
    images = [os.path.join(folder, f) for f in files]
    res = run(method, images, k, os.path.join(folder, "camera.json"), args)
    s = score(res, [truth[f] for f in files])
    s.update({"method": method, "selection": label, "files": files, "refused": res.refused, "note": res.note or "", "stages": res.stages})
    s["unregistered"] = {f: res.reasons[i] for i, f in enumerate(files) if res.poses[i] is None}
    s["poses"] = {f: {"R": p[0].ravel().tolist(), "t": p[1].ravel().tolist()} for f, p in zip(files, res.poses) if p is not None}
    if s["unregistered"] and not res.refused:
        miss = ", ".join(f"{f} ({why})" for f, why in s["unregistered"].items())
        s["note"] = (s["note"] + "; " if s["note"] else "") + f"not registered: {miss}"
    print(f"  {method} {label}: {s['registered']}/{s['views']} registered, rot max {s['rot_max']}, {s['seconds']:.1f} s", file=sys.stderr)
    return s


def bench_set(folder, args):
    k, files, truth = load_set(folder)
    if truth is None:
        sys.exit(f"{folder} has no cameras.json: nothing to score against")
    name = os.path.basename(os.path.normpath(folder))
    rows = []
    for method in args.methods:
        if args.all:
            rows.append(run_selection(method, folder, files, k, truth, f"all {len(files)}", args))
        if args.triplets:
            trip = []
            for i in range(len(files) - 2):
                sel = files[i : i + 3]
                label = "triplet " + ",".join(os.path.splitext(f)[0] for f in sel)
                trip.append(run_selection(method, folder, sel, k, truth, label, args))
            rows.extend(trip)
            rows.append(worst(trip, method, f"worst of {len(trip)} triplets"))
    return name, rows


UNRELATED = [("herz-jesus-p8", 2), ("entry-p10", 2), ("sceaux-castle", 0)]  # (set, first view)


def bench_unrelated(args):
    """Views of three buildings in one run. The right answer is no reconstruction joining views
    of different buildings (a model of two views of one building is not wrong)."""
    camera_json = os.path.join(DATA, "herz-jesus-p8", "camera.json")
    k, _, _ = load_set(os.path.join(DATA, "herz-jesus-p8"))
    per = args.per_building
    chosen = [(b, load_set(os.path.join(DATA, b))[1][first : first + per]) for b, first in UNRELATED]
    entries = [(b, f) for b, fs in chosen for f in fs]
    if args.interleave:
        entries = [(b, fs[i]) for i in range(per) for b, fs in chosen]
    images = [os.path.join(DATA, b, f) for b, f in entries]
    labels = [f"{b}/{f}" for b, f in entries]
    rows = []
    for method in args.methods:
        res = run(method, images, k, camera_json, args)
        reg = [labels[i] for i in range(len(images)) if res.poses[i] is not None]
        buildings = sorted({lab.split("/")[0] for lab in reg})
        verdict = "no reconstruction" if len(reg) < 2 else ("one building" if len(buildings) == 1 else "JOINS DIFFERENT BUILDINGS")
        row = {
            "method": method,
            "registered": len(reg),
            "views": len(images),
            "registered_views": reg,
            "buildings": buildings,
            "verdict": verdict,
            "points": res.points,
            "seconds": res.seconds,
            "refused": res.refused,
            "note": res.note or "",
            "reasons": {labels[i]: res.reasons[i] for i in range(len(images)) if res.poses[i] is None},
        }
        fp = res.stages.get("first_pair")
        if fp:
            row["note"] = (row["note"] + "; " if row["note"] else "") + f"first pair: {fp['matches']} ratio-test matches, {fp['inliers']} pose inliers"
        print(f"  {method} unrelated: {verdict}, {reg}", file=sys.stderr)
        rows.append(row)
    lines = [
        "| method | registered (largest model) | views registered | verdict | points | time (s) | note |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        note = "; ".join(x for x in (r["refused"], r["note"]) if x)
        lines.append(
            f"| {r['method']} | {r['registered']}/{r['views']} | {', '.join(r['registered_views']) or '—'} | {r['verdict']} | {r['points']} | {r['seconds']:.1f} | {note} |"
        )
    order = "interleaved (A1 B1 C1 A2 B2 C2 ...)" if args.interleave else "grouped (A1 A2 ... B1 B2 ... C1 C2 ...)"
    head = f"### unrelated views: {', '.join(labels)}; order {order}; all given herz-jesus-p8's camera.json (sceaux-castle's true K differs)"
    return head, rows, "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sets", nargs="*", help="set folders (host-tests/data/multiview/<name>)")
    ap.add_argument("--all", action="store_true", help="all views of each set in one run")
    ap.add_argument("--triplets", action="store_true", help="every consecutive triplet, one run each")
    ap.add_argument("--unrelated", action="store_true", help="views of three different buildings in one run")
    ap.add_argument("--interleave", action="store_true", help="--unrelated: order A1 B1 C1 A2 B2 C2 (default A1 A2 B1 B2 C1 C2)")
    ap.add_argument("--per-building", type=int, default=2, help="--unrelated: consecutive views of each building (default 2)")
    ap.add_argument("--methods", default="colmap,opencv", help="comma-separated: colmap,opencv,camgeom (default colmap,opencv; camgeom needs --camgeom)")
    ap.add_argument("--camgeom", help="path to the camgeom binary (adds camgeom to --methods)")
    ap.add_argument("--json", help="write the rows as JSON here")
    args = ap.parse_args()
    args.methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    for m in args.methods:
        if m not in METHODS:
            ap.error(f"unknown method {m}")
    if args.camgeom and "camgeom" not in args.methods:
        args.methods.append("camgeom")
    if "camgeom" in args.methods and not args.camgeom:
        ap.error("camgeom needs --camgeom PATH")
    if args.sets and not (args.all or args.triplets):
        ap.error("give --all and/or --triplets")
    if not args.sets and not args.unrelated:
        ap.error("give a set folder or --unrelated")
    if "colmap" in args.methods:
        ensure(["pycolmap"])

    report = {"threads": 1, "cpus": os.cpu_count(), "sets": {}}
    try:
        import pycolmap

        report["pycolmap"] = pycolmap.__version__
    except ImportError:
        pass
    report["opencv"] = cv2.__version__
    out = []
    for folder in args.sets:
        name, rows = bench_set(folder, args)
        report["sets"][name] = rows
        out.append(f"### {name}\n\n{markdown(rows)}\n")
    if args.unrelated:
        head, rows, table = bench_unrelated(args)
        report["unrelated"] = {"title": head, "rows": rows}
        out.append(f"{head}\n\n{table}\n")
    print("\n".join(out))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)


if __name__ == "__main__":
    main()
