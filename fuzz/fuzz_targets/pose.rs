//! Cameras with arbitrary (singular, negative, skewed, non-finite) intrinsics and distortion,
//! projection and back-projection, and the pose solvers `solve_planar`,
//! `solve_planar_integer` and `refine_planar_integer`, `solve_pnp`, `solve_pnp_ransac`, `p3p` on
//! arbitrary points. Contract: no panic; `Ok` projections and
//! rays are finite (rays unit length); `Ok` poses are finite with an orthonormal rotation and
//! a finite, non-negative RMS.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::homography::dlt;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::pose::{
    PlanarConfig, PlanarPoint, p3p, refine_planar_integer, solve_planar, solve_planar_integer,
    solve_pnp, solve_pnp_ransac,
};
use camgeom::transform::Pose;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Edit, Num, Ransac, apply_edits, check_pose, pt2, pt3, vec3};

/// A world point and its pixel.
type Correspondence = ((Num, Num, Num), (Num, Num));

#[derive(Debug, Arbitrary)]
struct Input {
    k: [Num; 5],
    dist: Option<[Num; 5]>,
    rvec: (Num, Num, Num),
    tvec: (Num, Num, Num),
    world: std::vec::Vec<Correspondence>,
    world_edits: std::vec::Vec<Edit>,
    pixel_edits: std::vec::Vec<Edit>,
    /// Pixels: the projection of the world points (plus noise) rather than arbitrary values.
    project: bool,
    refine_iterations: u8,
    scratch_slack: i8,
    ransac: Ransac,
}

fn check_estimate(e: &camgeom::pose::PoseEstimate<f32>, what: &str) {
    check_pose(&e.pose, what);
    assert!(
        e.rms_px.is_finite() && e.rms_px >= 0.0,
        "{what}: rms {}",
        e.rms_px
    );
}

fuzz_target!(|inp: Input| {
    let [fx, fy, cx, cy, s] = inp.k.map(Num::get);
    let Ok(k) = Intrinsics::with_skew(fx, fy, cx, cy, s) else {
        return;
    };
    let dist = match inp.dist {
        Some(d) => match Distortion::from_opencv(d.map(Num::get)) {
            Ok(d) => d,
            Err(_) => return,
        },
        None => Distortion::none(),
    };
    let camera = Camera::new(k, dist);
    let pose = Pose::from_rodrigues(vec3(inp.rvec), vec3(inp.tvec)).ok();

    let n = inp.world.len().min(40);
    let mut world: std::vec::Vec<Point3<f32>> = inp.world[..n].iter().map(|w| pt3(w.0)).collect();
    apply_edits(&mut world, &inp.world_edits[..inp.world_edits.len().min(6)]);
    let mut pixels: std::vec::Vec<Point2<f32>> = inp.world[..n].iter().map(|w| pt2(w.1)).collect();
    if inp.project
        && let Some(pose) = &pose
    {
        for (u, x) in pixels.iter_mut().zip(&world) {
            if let Ok(p) = camera.project(pose, x) {
                assert!(p.x.is_finite() && p.y.is_finite(), "project: not finite");
                *u = Point2::new(p.x + u.x * 1e-3, p.y + u.y * 1e-3);
            }
        }
    }
    apply_edits(
        &mut pixels,
        &inp.pixel_edits[..inp.pixel_edits.len().min(6)],
    );

    for u in &pixels {
        if let Ok(ray) = camera.back_project(u) {
            let r: &Vector3<f32> = ray.as_ref();
            assert!(r.iter().all(|v| v.is_finite()), "back_project: not finite");
            assert!((r.norm() - 1.0).abs() < 1e-3, "back_project: not unit");
        }
        if let Ok(d) = camera.distort_pixel(u) {
            assert!(
                d.x.is_finite() && d.y.is_finite(),
                "distort_pixel: not finite"
            );
        }
    }

    let scratch_len = (n as i64 + i64::from(inp.scratch_slack % 3)).max(0) as usize;
    let mut scratch = std::vec![Point2::origin(); scratch_len];
    let model: std::vec::Vec<Point2<f32>> = world.iter().map(|w| Point2::new(w.x, w.y)).collect();
    let cfg = PlanarConfig {
        refine_iterations: inp.refine_iterations % 25,
        alternative_ratio: inp.refine_iterations.rotate_left(3),
    };
    if let Ok(pp) = solve_planar(&camera, &model, &pixels, &mut scratch, &cfg) {
        check_estimate(&pp.best, "solve_planar best");
        check_estimate(&pp.alternative, "solve_planar alternative");
    }
    // The integer path, from the DLT's homography as the loop's RANSAC would give it. Its
    // alternative's error is infinite when that solution leaves the integer range.
    let mut points = std::vec![PlanarPoint::ZERO; scratch_len];
    if let Ok(hint) = dlt(&model, &pixels)
        && let Ok(pp) = solve_planar_integer(&camera, &hint, &model, &pixels, &mut points, &cfg)
    {
        check_estimate(&pp.best, "solve_planar_integer best");
        check_pose(&pp.alternative.pose, "solve_planar_integer alternative");
        let e = pp.alternative.rms_px;
        assert!(
            e >= 0.0 && !e.is_nan(),
            "solve_planar_integer alternative: rms {e}"
        );
    }
    if let Some(start) = &pose {
        let normalized: std::vec::Vec<Point2<f32>> = pixels
            .iter()
            .map(|u| Point2::new(u.x * 1e-3, u.y * 1e-3))
            .collect();
        let f = [fx, fy];
        let it = inp.refine_iterations % 25;
        if let Ok(e) = refine_planar_integer(&model, &normalized, f, start, &mut points, it) {
            check_estimate(&e, "refine_planar_integer");
        }
    }
    if let Ok(e) = solve_pnp(&camera, &world, &pixels, &mut scratch) {
        check_estimate(&e, "solve_pnp");
    }
    let mut mask = std::vec![false; n];
    if let Some(rc) = inp.ransac.params()
        && let Ok((e, report)) =
            solve_pnp_ransac(&camera, &world, &pixels, &mut scratch, &rc, &mut mask)
    {
        check_estimate(&e, "solve_pnp_ransac");
        assert!(report.inliers <= n);
    }
    if n >= 3 {
        let bearings: [Vector3<f32>; 3] = core::array::from_fn(|i| {
            let p = pixels[i];
            Vector3::new(p.x, p.y, 1.0)
        });
        let w3: [Point3<f32>; 3] = core::array::from_fn(|i| world[i]);
        if let Ok(sols) = p3p(&bearings, &w3) {
            for p in &sols {
                check_pose(p, "p3p");
            }
        }
    }
});
