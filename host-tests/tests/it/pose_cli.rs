//! `camgeom pose` on the chessboard corners (against OpenCV's `solvePnP` in
//! `chessboard/opencv_pnp.csv`), on a non-planar scene with a known pose, with outliers
//! (`--ransac`), and on bad input.

use crate::common::camgeom;
use camgeom::nalgebra::{Rotation3, Vector3};
use serde_json::Value;

/// Runs `camgeom pose` and parses its JSON (asserting success).
fn pose(intrinsics: &str, points: &str, extra: &[&str]) -> Value {
    let mut args = vec!["pose", "--intrinsics", intrinsics, "--points", points];
    args.extend_from_slice(extra);
    let out = camgeom(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn rot(v: &Value) -> Rotation3<f64> {
    let r = nums(&v["R"]);
    Rotation3::from_matrix_unchecked(camgeom::nalgebra::Matrix3::from_row_slice(&r))
}

/// The angle between two rotations, from `|A - B|_F = 2√2 sin(θ/2)`: unlike
/// `acos((tr - 1) / 2)` it stays accurate near zero.
fn rot_deg(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    let d = (a.matrix() - b.matrix()).norm();
    (2.0 * (d / (2.0 * 2f64.sqrt())).min(1.0).asin()).to_degrees()
}

#[test]
fn chessboard_poses_equal_opencv_iterative() {
    let corners = std::fs::read_to_string(crate::common::chessboard("corners.csv")).unwrap();
    let opencv = std::fs::read_to_string(crate::common::chessboard("opencv_pnp.csv")).unwrap();
    let intr = crate::common::chessboard("left_intrinsics.yml");
    let mut images: Vec<&str> = corners
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    images.dedup();
    assert_eq!(images.len(), 13);
    for name in images {
        let mut csv = String::from("X,Y,Z,u,v\n");
        for l in corners.lines().skip(1).filter(|l| l.starts_with(name)) {
            let f: Vec<&str> = l.split(',').collect();
            let (i, j): (f64, f64) = (f[1].parse().unwrap(), f[2].parse().unwrap());
            csv.push_str(&format!(
                "{},{},0,{},{}\n",
                0.025 * i,
                0.025 * j,
                f[3],
                f[4]
            ));
        }
        let pts = crate::common::scratch_file(&format!("{name}.csv"), &csv);
        let v = pose(intr.to_str().unwrap(), pts.to_str().unwrap(), &[]);
        assert_eq!(v["solver"], "planar");
        assert!(v["alternative"].is_object());
        let row: Vec<f64> = opencv
            .lines()
            .find(|l| l.starts_with(&format!("{name},iterative,")))
            .unwrap()
            .split(',')
            .skip(2)
            .map(|s| s.parse().unwrap())
            .collect();
        let r_cv = Rotation3::new(Vector3::new(row[0], row[1], row[2]));
        let t = nums(&v["t"]);
        let dt = (Vector3::new(t[0], t[1], t[2]) - Vector3::new(row[3], row[4], row[5])).norm();
        let dr = rot_deg(&rot(&v), &r_cv);
        let rms = v["rms_px"].as_f64().unwrap();
        // The same minimum as OpenCV's LM (bounds as in tests/it/pose_chessboard.rs: 10x the
        // observed differences; RMS to 1e-6 px, both stop on a relative-decrease test).
        assert!(dr < 0.01 && dt < 5e-5, "{name}: {dr} deg, {dt} m");
        assert!(rms <= row[6] + 1e-6, "{name}: {rms} vs {}", row[6]);
        // rvec is the same rotation as R.
        let rv = nums(&v["rvec"]);
        assert!(rot_deg(&Rotation3::new(Vector3::new(rv[0], rv[1], rv[2])), &rot(&v)) < 1e-6);
        // The alternative explains the corners clearly worse (the board is not ambiguous).
        assert!(v["alternative"]["rms_px"].as_f64().unwrap() > 2.0 * rms);
        // --f32 lands on the same pose (0.3 px corner noise dominates f32 rounding).
        let f = pose(intr.to_str().unwrap(), pts.to_str().unwrap(), &["--f32"]);
        let tf = nums(&f["t"]);
        assert!((Vector3::new(tf[0], tf[1], tf[2]) - Vector3::new(t[0], t[1], t[2])).norm() < 1e-5);
    }
}

/// A pinhole camera (no distortion) written as camgeom JSON, and projection through it done
/// here, independently of camgeom: `u = fx X_c/Z_c + cx`.
const CAMERA: &str = r#"{"fx": 500.0, "fy": 510.0, "cx": 320.0, "cy": 240.0}"#;

fn project(r: &Rotation3<f64>, t: &Vector3<f64>, p: &Vector3<f64>) -> (f64, f64) {
    let c = r * p + t;
    (500.0 * c.x / c.z + 320.0, 510.0 * c.y / c.z + 240.0)
}

/// 30 points in a 1 m box in front of the camera, deterministic (a small LCG).
fn scene() -> (Rotation3<f64>, Vector3<f64>, Vec<Vector3<f64>>) {
    let mut s = 12345u64;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let r = Rotation3::new(Vector3::new(0.3, -0.5, 0.2));
    let t = Vector3::new(0.1, -0.05, 2.5);
    let pts = (0..30)
        .map(|_| Vector3::new(next(), next(), next()))
        .collect();
    (r, t, pts)
}

#[test]
fn non_planar_scene_gives_the_true_pose() {
    let cam = crate::common::scratch_file("pinhole.json", CAMERA);
    let (r, t, pts) = scene();
    let mut csv = String::from("X,Y,Z,u,v\n");
    for p in &pts {
        let (u, v) = project(&r, &t, p);
        csv.push_str(&format!("{},{},{},{u},{v}\n", p.x, p.y, p.z));
    }
    let file = crate::common::scratch_file("scene.csv", &csv);
    let v = pose(cam.to_str().unwrap(), file.to_str().unwrap(), &[]);
    assert_eq!(v["solver"], "pnp");
    assert!(v["alternative"].is_null());
    let te = nums(&v["t"]);
    // Exact data: the pose to rounding (f64 EPnP + LM; 1e-9 leaves room for the decimal text).
    assert!(rot_deg(&rot(&v), &r) < 1e-7);
    assert!((Vector3::new(te[0], te[1], te[2]) - t).norm() < 1e-8);
    assert!(v["rms_px"].as_f64().unwrap() < 1e-6);

    // A third of the points moved by 20..60 px: --ransac 2 finds the others and the true pose.
    let mut csv = String::from("X,Y,Z,u,v\n");
    for (k, p) in pts.iter().enumerate() {
        let (mut u, v) = project(&r, &t, p);
        if k % 3 == 0 {
            u += 20.0 + k as f64;
        }
        csv.push_str(&format!("{},{},{},{u},{v}\n", p.x, p.y, p.z));
    }
    let file = crate::common::scratch_file("outliers.csv", &csv);
    let v = pose(
        cam.to_str().unwrap(),
        file.to_str().unwrap(),
        &["--ransac", "2"],
    );
    assert_eq!(v["solver"], "pnp_ransac");
    assert_eq!(v["inliers"], 20);
    let mask: Vec<bool> = v["inlier_mask"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_bool().unwrap())
        .collect();
    assert!(mask.iter().enumerate().all(|(k, m)| *m == (k % 3 != 0)));
    let te = nums(&v["t"]);
    assert!(rot_deg(&rot(&v), &r) < 1e-6);
    assert!((Vector3::new(te[0], te[1], te[2]) - t).norm() < 1e-7);
}

#[test]
fn bad_input_is_a_one_line_error() {
    let cam = crate::common::scratch_file("pinhole.json", CAMERA);
    let cam = cam.to_str().unwrap();
    let check = |csv: &str, camera: &str, extra: &[&str], expect: &str| {
        let file = crate::common::scratch_file("bad.csv", csv);
        let mut args = vec![
            "pose",
            "--intrinsics",
            camera,
            "--points",
            file.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = camgeom(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{csv}: {err}");
        assert!(out.stdout.is_empty());
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(expect), "{err} lacks {expect}");
    };
    let square = "0,0,0,300,200\n1,0,0,340,200\n1,1,0,340,240\n0,1,0,300,240\n";
    check("0,0,0,1,2\n1,0,0,3,4\n", cam, &[], "at least 4 points");
    check("0,0,0,1,2\n1,0,0,3,nan\n", cam, &[], "not finite");
    check("0,0,0,1,2\n1,0,0,3\n", cam, &[], "expected 5");
    check(square, cam, &["--ransac", "0"], "--ransac");
    // Collinear planar points: no pose.
    check(
        "0,0,0,300,200\n1,0,0,340,200\n2,0,0,380,200\n3,0,0,420,200\n",
        cam,
        &[],
        "degenerate",
    );
    // A camera with a zero focal length is rejected when it is read.
    let singular = crate::common::scratch_file(
        "singular.json",
        r#"{"fx": 0.0, "fy": 510.0, "cx": 320.0, "cy": 240.0}"#,
    );
    check(
        square,
        singular.to_str().unwrap(),
        &[],
        "invalid_intrinsics",
    );
}
