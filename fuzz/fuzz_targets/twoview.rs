//! Two-view geometry on arbitrary correspondences: `find_fundamental`, `find_essential` (with
//! arbitrary intrinsics), and the three triangulations from arbitrary poses. Contract: no
//! panic; `Ok` matrices are finite; `Ok` triangulations are finite with positive depths and
//! finite, non-negative errors.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::camera::Intrinsics;
use camgeom::nalgebra::Point2;
use camgeom::transform::{Camera as CameraFrame, Transform, World};
use camgeom::twoview::{
    Triangulated, find_essential, find_fundamental, triangulate_dlt, triangulate_midpoint,
    triangulate_optimal,
};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Edit, Num, Ransac, apply_edits, finite, pt2, vec3};

#[derive(Debug, Arbitrary)]
struct Input {
    pairs: std::vec::Vec<((Num, Num), (Num, Num))>,
    edits1: std::vec::Vec<Edit>,
    edits2: std::vec::Vec<Edit>,
    k1: [Num; 4],
    k2: [Num; 4],
    ransac: Ransac,
    pose1: ((Num, Num, Num), (Num, Num, Num)),
    pose2: ((Num, Num, Num), (Num, Num, Num)),
}

fn check_tri(t: &Triangulated<f32>, what: &str) {
    assert!(
        finite(t.point.coords.as_slice()),
        "{what}: point not finite"
    );
    assert!(
        t.depth1 > 0.0 && t.depth2 > 0.0,
        "{what}: depths {} {}",
        t.depth1,
        t.depth2
    );
    assert!(
        t.depth1.is_finite() && t.depth2.is_finite(),
        "{what}: depth not finite"
    );
    assert!(
        t.error1 >= 0.0 && t.error2 >= 0.0,
        "{what}: negative or NaN error"
    );
    assert!(
        t.error1.is_finite() && t.error2.is_finite(),
        "{what}: error not finite"
    );
}

fuzz_target!(|inp: Input| {
    let n = inp.pairs.len().min(48);
    let mut x1: std::vec::Vec<Point2<f32>> = inp.pairs[..n].iter().map(|p| pt2(p.0)).collect();
    let mut x2: std::vec::Vec<Point2<f32>> = inp.pairs[..n].iter().map(|p| pt2(p.1)).collect();
    apply_edits(&mut x1, &inp.edits1[..inp.edits1.len().min(8)]);
    apply_edits(&mut x2, &inp.edits2[..inp.edits2.len().min(8)]);
    let cfg = inp.ransac.params();
    let mut mask = std::vec![false; n];
    if let Some(cfg) = &cfg
        && let Ok((f, r)) = find_fundamental(&x1, &x2, cfg, &mut mask)
    {
        assert!(finite(f.matrix().as_slice()), "F not finite");
        assert!(r.inliers <= n);
    }
    let [a, b, c, d] = inp.k1.map(Num::get);
    let [e, f, g, h] = inp.k2.map(Num::get);
    if let (Some(cfg), Ok(k1), Ok(k2)) = (
        &cfg,
        Intrinsics::new(a, b, c, d),
        Intrinsics::new(e, f, g, h),
    ) && let Ok((e, r)) = find_essential(&k1, &k2, &x1, &x2, cfg, &mut mask)
    {
        assert!(finite(e.matrix().as_slice()), "E not finite");
        assert!(r.inliers <= n);
    }
    let p1 =
        Transform::<World, CameraFrame, f32>::from_rodrigues(vec3(inp.pose1.0), vec3(inp.pose1.1));
    let p2 =
        Transform::<World, CameraFrame, f32>::from_rodrigues(vec3(inp.pose2.0), vec3(inp.pose2.1));
    if let (Ok(p1), Ok(p2)) = (p1, p2) {
        for (a, b) in x1.iter().zip(&x2).take(8) {
            if let Ok(t) = triangulate_dlt(&p1, &p2, a, b) {
                check_tri(&t, "dlt");
            }
            if let Ok(t) = triangulate_midpoint(&p1, &p2, a, b) {
                check_tri(&t, "midpoint");
            }
            if let Ok(t) = triangulate_optimal(&p1, &p2, a, b) {
                check_tri(&t, "optimal");
            }
        }
    }
});
