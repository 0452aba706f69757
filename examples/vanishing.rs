//! Vanishing points and the horizon from line segments: sequential RANSAC groups the segments
//! by the point their lines meet at, each point is fitted by least squares, and the horizon is
//! the line through the two horizontal points (or, with `K`, the polar of the vertical one).
//!
//! `cargo run --example vanishing`
//!
//! The segments are made here: the edges of a few boxes along three orthogonal world axes
//! (`y` vertical), projected by plain matrix products through a known camera `K [R | t]` that
//! is turned, tilted up and rolled, with 0.5 px of noise on every endpoint and some random
//! segments. The answers are compared with the truth of that camera: the vanishing point of
//! axis `i` is `K R eᵢ`, the horizon `K⁻ᵀ R e_y`. Buffers are fixed arrays, as on a
//! microcontroller (`f32`, no allocation).

use camgeom::camera::Intrinsics;
use camgeom::nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use camgeom::rng::Pcg32;
use camgeom::vanishing::{
    NO_POINT, Segment, VanishingConfig, VanishingPoint, find_vanishing_points, horizon,
};

/// Segments of the scene: 3 boxes x 12 edges, and the random ones.
const BOXES: usize = 3;
const CLUTTER: usize = 8;
const N: usize = BOXES * 12 + CLUTTER;

fn main() -> camgeom::Result<()> {
    let k = Matrix3::new(600.0, 0.0, 320.0, 0.0, 600.0, 240.0, 0.0, 0.0, 1.0);
    // Yaw 40° about the vertical, 12° up, 6° of roll (world to camera; camera y down, as the
    // world's y).
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), 6f64.to_radians())
        * Rotation3::from_axis_angle(&Vector3::x_axis(), 12f64.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), 40f64.to_radians());
    let t = Vector3::new(-0.5, 0.8, 14.0);
    let project = |x: Vector3<f64>| {
        let p = k * (r * x + t);
        Point2::new(p.x / p.z, p.y / p.z)
    };
    let mut rng = Pcg32::new(5);
    let mut segments = [Segment::new(Point2::new(0.0f32, 0.0), Point2::new(1.0, 0.0)); N];
    let noisy = |p: Point2<f64>, rng: &mut Pcg32| {
        Point2::new(
            (p.x + 0.5 * rng.normal()) as f32,
            (p.y + 0.5 * rng.normal()) as f32,
        )
    };
    // Boxes: a corner and three side lengths each; every edge runs along one axis.
    let boxes = [
        (Vector3::new(-3.0, -2.0, -1.0), [3.0, 2.0, 2.0]),
        (Vector3::new(1.0, -1.0, 1.0), [2.0, 1.0, 3.0]),
        (Vector3::new(-1.0, -3.5, 3.0), [1.5, 3.5, 1.5]),
    ];
    let mut n = 0;
    for (corner, size) in boxes {
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for (i, j) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let mut a = corner;
                a[u] += i * size[u];
                a[v] += j * size[v];
                let mut b = a;
                b[axis] += size[axis];
                segments[n] =
                    Segment::new(noisy(project(a), &mut rng), noisy(project(b), &mut rng));
                n += 1;
            }
        }
    }
    for s in &mut segments[n..] {
        let a = Point2::new(rng.uniform(0.0, 640.0), rng.uniform(0.0, 480.0));
        let angle = rng.uniform(0.0, std::f64::consts::PI);
        let b = a + 80.0 * camgeom::nalgebra::Vector2::new(angle.cos(), angle.sin());
        *s = Segment::new(a.cast::<f32>(), b.cast::<f32>());
    }

    let params = VanishingConfig::<f32>::default().check()?;
    let (mut labels, mut index, mut mask) = ([0u8; N], [0u32; N], [false; N]);
    let mut found = [VanishingPoint::default(); 3];
    let count = find_vanishing_points(
        &segments,
        &params,
        &mut labels,
        &mut index,
        &mut mask,
        &mut found,
    )?;
    let unassigned = labels.iter().filter(|&&l| l == NO_POINT).count();
    println!("{count} vanishing points from {N} segments ({unassigned} unassigned)");
    let k_inv = k.try_inverse().ok_or(camgeom::Error::Degenerate)?;
    for (i, v) in found[..count].iter().enumerate() {
        // The nearest true direction R e_axis to the found one, K⁻¹ v.
        let d = (k_inv * v.point.coords().cast::<f64>()).normalize();
        let (axis, angle) = (0..3)
            .map(|a| {
                let e = r * Vector3::ith(a, 1.0);
                (a, d.dot(&e).abs().min(1.0).acos().to_degrees())
            })
            .fold((0, f64::INFINITY), |m, c| if c.1 < m.1 { c } else { m });
        let at = match v.point.to_euclidean() {
            Ok(p) => format!("({:.1}, {:.1})", p.x, p.y),
            Err(_) => "at infinity".to_string(),
        };
        println!(
            "  point {i} {at}: {} segments, rms {:.2} px, {}; {angle:.2}° from the true \
             direction of axis {}",
            v.segments,
            v.rms_px,
            if v.is_vertical() {
                "vertical"
            } else {
                "horizontal"
            },
            ["x", "y", "z"][axis],
        );
    }

    // The true horizon, K⁻ᵀ R e_y, as a tilt and a height at the image's centre column.
    let truth = k_inv.transpose() * (r * Vector3::y());
    let describe = |l: &Vector3<f64>| {
        // The angle of the line's direction (b, -a), folded into (-90°, 90°].
        let roll = (-l.x).atan2(l.y).to_degrees();
        let roll = if roll > 90.0 {
            roll - 180.0
        } else if roll <= -90.0 {
            roll + 180.0
        } else {
            roll
        };
        let y_mid = -(l.x * 320.0 + l.z) / l.y;
        (roll, y_mid)
    };
    let (roll_true, y_true) = describe(&truth);
    println!("true horizon: roll {roll_true:.2}°, crosses x = 320 at y = {y_true:.1}");
    let intrinsics = Intrinsics::new(600.0f32, 600.0, 320.0, 240.0)?;
    for (what, camera) in [
        ("two horizontal points", None),
        ("with K", Some(&intrinsics)),
    ] {
        let (line, source) = horizon(&found[..count], camera)?;
        let (roll, y_mid) = describe(&line.coords().cast::<f64>());
        println!(
            "horizon ({what}, {source:?}): roll {roll:.2}°, crosses x = 320 at y = {y_mid:.1}"
        );
    }
    // The vertical point alone needs K: without it the horizon is not determined.
    let vertical: Vec<VanishingPoint<f32>> = found[..count]
        .iter()
        .copied()
        .filter(|v| v.is_vertical())
        .collect();
    let (line, _) = horizon(&vertical, Some(&intrinsics))?;
    let (roll, y_mid) = describe(&line.coords().cast::<f64>());
    println!("horizon (vertical point and K): roll {roll:.2}°, crosses x = 320 at y = {y_mid:.1}");
    println!(
        "horizon (vertical point, no K): {:?}",
        horizon(&vertical, None).map(|_| ())
    );
    Ok(())
}
