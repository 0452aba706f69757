//! Projects the bundled chessboard's 9x6 inner corners through its calibrated camera.
//!
//! `cargo run --example project_points`
//!
//! The camera is OpenCV's calibration of the bundled `left*.jpg` views
//! (`host-tests/data/chessboard/left_intrinsics.yml`), the pose its first view's. A corner
//! `(i, j)` of the board is the world point `(0.025 i, 0.025 j, 0)` metres; its pixel is
//! `u = K distort(π(R X + t))`, which `Camera::project` computes (and `project_points` for
//! many points at once, a status per point).

#[path = "common.rs"]
mod common;

use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::transform::Pose;

fn main() -> camgeom::Result<()> {
    let camera = common::chessboard_camera()?;
    // The first view's pose (extrinsic_parameters row 0: Rodrigues vector, then translation).
    let pose = Pose::from_rodrigues(
        Vector3::new(0.168_7, 0.275_7, 0.013_5),
        Vector3::new(-0.075_2, -0.109_0, 0.399_7),
    )?;
    let world: Vec<Point3<f32>> = (0..6)
        .flat_map(|j| (0..9).map(move |i| Point3::new(0.025 * i as f32, 0.025 * j as f32, 0.0)))
        .collect();
    let mut projected = vec![Ok(Point2::origin()); world.len()];
    camera.project_points(&pose, &world, &mut projected)?;
    let pixels = projected.into_iter().collect::<camgeom::Result<Vec<_>>>()?;
    for (x, u) in world.iter().zip(&pixels).step_by(8) {
        println!(
            "corner ({:.3}, {:.3}) m -> pixel ({:7.2}, {:7.2})",
            x.x, x.y, u.x, u.y
        );
    }
    // Back-projection inverts it: the ray through the first pixel hits the first corner.
    let ray = camera.back_project(&pixels[0])?;
    let c = pose.apply(&world[0]).coords.normalize();
    // atan2(|a × b|, a · b): accurate for small angles, where acos(a · b) in f32 is not.
    let angle = ray.cross(&c).norm().atan2(ray.dot(&c));
    println!("ray through pixel 0 misses corner 0 by {:.2e} rad", angle);
    Ok(())
}
