//! camgeom's projection against OpenCV's `cv2.projectPoints` on the bundled calibration: 13 real
//! poses x 54 board corners, with the full 5-coefficient distortion.
//!
//! The reference is `data/chessboard/opencv_projections.csv`, made by
//! `python3 host-tests/scripts/make_fixtures.py` (see data/README.md); it is committed, so this
//! test needs neither Python nor OpenCV.

use crate::common::{bundled_camera, bundled_poses, chessboard};
use camgeom::Real;
use camgeom::camera::Camera;
use camgeom::nalgebra::{Point3, Vector3};
use camgeom::transform::Pose;
use camgeom_host::points::read_csv;

/// Square size of the board, metres (as in `left_intrinsics.yml` and the fixture script).
const SQUARE: f64 = 0.025;

struct Reference {
    view: usize,
    i: f64,
    j: f64,
    u: f64,
    v: f64,
}

fn reference() -> Vec<Reference> {
    let t = read_csv(
        chessboard("opencv_projections.csv"),
        &["view", "i", "j", "u", "v"],
    )
    .unwrap();
    let rows: Vec<Reference> = t
        .rows
        .iter()
        .map(|r| Reference {
            view: r[0] as usize,
            i: r[1],
            j: r[2],
            u: r[3],
            v: r[4],
        })
        .collect();
    // 13 views x 9 x 6 corners.
    assert_eq!(rows.len(), 13 * 54);
    rows
}

/// The largest pixel error (max over u and v) of camgeom in `T` against OpenCV, and where.
fn max_error<T: Real>(camera: &Camera<T>) -> (f64, String) {
    let poses = bundled_poses();
    let mut worst = (0.0f64, String::new());
    for r in reference() {
        let p = &poses[r.view];
        let v3 = |a: &[f64]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));
        let pose = Pose::<T>::from_rodrigues(v3(&p[..3]), v3(&p[3..])).unwrap();
        // The same products as the script's `SQUARE * i`, so the world points are bit-identical
        // in f64.
        let x = Point3::new(T::lit(SQUARE * r.i), T::lit(SQUARE * r.j), T::lit(0.0));
        let uv = camera.project(&pose, &x).unwrap();
        let err = (uv.x.to_f64() - r.u).abs().max((uv.y.to_f64() - r.v).abs());
        if err > worst.0 {
            worst = (
                err,
                format!(
                    "view {} corner ({}, {}): camgeom ({:?}, {:?}), OpenCV ({}, {})",
                    r.view, r.i, r.j, uv.x, uv.y, r.u, r.v
                ),
            );
        }
    }
    worst
}

#[test]
fn f64_projection_matches_opencv() {
    let (err, at) = max_error(&bundled_camera().camera);
    println!("f64: max |camgeom - OpenCV| = {err:.3e} px at {at}");
    // Both sides evaluate the same formula in double precision; they differ only in rounding
    // (OpenCV builds R from rvec with Rodrigues' formula, camgeom through a unit quaternion), a
    // few ulp of coordinates below 700 px, i.e. ~1e-13 px. 1e-9 px leaves four orders of
    // magnitude for that and still catches any modelling difference (a wrong sign or a missing
    // term of the distortion moves pixels by 1e-3 px or far more).
    assert!(err < 1e-9, "f64 error {err:e} px at {at}");
}

#[test]
fn f32_projection_matches_opencv() {
    let (err, at) = max_error(&bundled_camera().camera_f32());
    println!("f32: max |camgeom - OpenCV| = {err:.3e} px at {at}");
    // In f32 every input is rounded (relative 6e-8) and every operation adds a rounding of the
    // same relative size. At pixel coordinates up to ~600 px one rounding is ~4e-5 px; the chain
    // rvec -> rotation -> R X + t -> division by Z -> distortion polynomial -> K adds a few tens
    // of such roundings, amplified up to ~2x by the distortion's derivative near the corners, so
    // the expected error is ~1e-4 px (measured: see the printed value, ~1.2e-4 px). 2e-3 px is a
    // 10x margin over that and still two orders of magnitude below the accuracy of a corner
    // detector (~0.1 px), which is what the firmware's projections are compared with.
    assert!(err < 2e-3, "f32 error {err:e} px at {at}");
}

#[test]
fn corners_file_matches_the_board() {
    // board_corners.csv (the CLI's example input) holds the same corners, j outer, i inner.
    let t = read_csv(chessboard("board_corners.csv"), &["X", "Y", "Z"]).unwrap();
    assert_eq!(t.rows.len(), 54);
    for (n, row) in t.rows.iter().enumerate() {
        let (i, j) = ((n % 9) as f64, (n / 9) as f64);
        assert_eq!(row, &vec![SQUARE * i, SQUARE * j, 0.0]);
    }
}
