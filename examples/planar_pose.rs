//! The pose of a planar target from its image points: both IPPE solutions refined on the
//! pixel reprojection error through the lens model, the planar ambiguity reported.
//!
//! `cargo run --example planar_pose`
//!
//! The observations are the 54 inner corners OpenCV found in the bundled `left01.jpg`
//! (`host-tests/data/chessboard/corners.csv`), the camera its calibration of those views.

#[path = "common.rs"]
mod common;

use camgeom::nalgebra::Point2;
use camgeom::pose::{PlanarConfig, solve_planar};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let camera = common::chessboard_camera()?;
    // image,i,j,u,v rows; corner (i, j) is at (0.025 i, 0.025 j) on the board.
    let text = std::fs::read_to_string(common::data_dir().join("chessboard/corners.csv"))?;
    let (mut model, mut pixels) = (Vec::new(), Vec::new());
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        if f.first() != Some(&"left01") {
            continue;
        }
        let n = |k: usize| -> Result<f32, Box<dyn std::error::Error>> { Ok(f[k].trim().parse()?) };
        model.push(Point2::new(0.025 * n(1)?, 0.025 * n(2)?));
        pixels.push(Point2::new(n(3)?, n(4)?));
    }
    let mut scratch = vec![Point2::origin(); model.len()];
    let p = solve_planar(
        &camera,
        &model,
        &pixels,
        &mut scratch,
        &PlanarConfig::default(),
    )?;
    let (r, t) = (p.best.pose.rotation_vector(), p.best.pose.translation());
    println!("{} corners of left01.jpg", model.len());
    println!("rotation vector ({:.4}, {:.4}, {:.4})", r.x, r.y, r.z);
    println!("translation ({:.4}, {:.4}, {:.4}) m", t.x, t.y, t.z);
    println!(
        "RMS reprojection error {:.3} px; the other IPPE solution {:.3} px{}",
        p.best.rms_px,
        p.alternative.rms_px,
        if p.is_ambiguous(1.5) {
            " (ambiguous)"
        } else {
            ""
        }
    );
    Ok(())
}
