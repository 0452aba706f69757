//! Helpers shared by the integration tests.

use std::path::PathBuf;
use std::process::{Command, Output};

use camgeom_host::CameraSpec;

/// `host-tests/data/chessboard/<name>`.
pub fn chessboard(name: &str) -> PathBuf {
    camgeom_host::data_dir().join("chessboard").join(name)
}

/// The bundled calibration (OpenCV's `left_intrinsics.yml`).
pub fn bundled_camera() -> CameraSpec {
    camgeom_host::load_camera(chessboard("left_intrinsics.yml")).expect("bundled camera")
}

/// The 13 bundled poses, `[rx, ry, rz, tx, ty, tz]` (rows of `extrinsic_parameters`).
pub fn bundled_poses() -> Vec<[f64; 6]> {
    let fs = camgeom_host::FileStorage::open(chessboard("left_intrinsics.yml")).unwrap();
    let m = fs.matrix("extrinsic_parameters").unwrap();
    assert_eq!((m.rows, m.cols), (13, 6));
    (0..m.rows)
        .map(|r| m.row(r).unwrap().try_into().unwrap())
        .collect()
}

/// Writes `content` to a fresh file `name` under the test's scratch directory.
///
/// The file name is made unique per process and call, so tests running at the same time (in
/// one binary, or in two checkouts sharing a target directory) never read each other's files.
pub fn scratch_file(name: &str, content: &str) -> PathBuf {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("camgeom-host-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{}-{n}-{name}", std::process::id()));
    std::fs::write(&path, content).unwrap();
    path
}

/// The pixel grid over the whole `w x h` image with spacing `step`, always including the last
/// row and column (`w - 1`, `h - 1`).
pub fn pixel_grid(w: u32, h: u32, step: u32) -> Vec<(f64, f64)> {
    let axis = |n: u32| {
        let mut v: Vec<u32> = (0..n).step_by(step as usize).collect();
        if *v.last().unwrap() != n - 1 {
            v.push(n - 1);
        }
        v
    };
    let (xs, ys) = (axis(w), axis(h));
    ys.iter()
        .flat_map(|&y| xs.iter().map(move |&x| (x as f64, y as f64)))
        .collect()
}

/// Runs the `camgeom` binary with `args` and collects its status and output.
pub fn camgeom(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_camgeom"))
        .args(args)
        .output()
        .expect("run camgeom")
}

/// The JSON standard output of a `camgeom` run that must have succeeded.
pub fn json(o: &Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "camgeom failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}
