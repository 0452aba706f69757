//! Homography solvers on arbitrary `f32` points (NaN, inf, huge, tiny, duplicated, collinear):
//! `from_four_points`, `dlt`, `find_homography`. Contract: no panic; an `Ok` homography is
//! finite and invertible, and transfers its own source points to finite points or a typed
//! error.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::homography::{Homography, dlt, find_homography};
use camgeom::nalgebra::Point2;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Edit, Num, Ransac, apply_edits, finite, pt2};

#[derive(Debug, Arbitrary)]
struct Input {
    pairs: std::vec::Vec<((Num, Num), (Num, Num))>,
    src_edits: std::vec::Vec<Edit>,
    dst_edits: std::vec::Vec<Edit>,
    ransac: Ransac,
    mask_slack: i8,
}

fn check(h: &Homography<f32>, src: &[Point2<f32>], what: &str) {
    assert!(finite(h.matrix().as_slice()), "{what}: matrix not finite");
    for p in src {
        if let Ok(q) = h.transfer(p) {
            assert!(
                q.x.is_finite() && q.y.is_finite(),
                "{what}: transfer not finite"
            );
        }
    }
    if let Ok(inv) = h.inverse() {
        assert!(
            finite(inv.matrix().as_slice()),
            "{what}: inverse not finite"
        );
    }
}

fuzz_target!(|inp: Input| {
    let n = inp.pairs.len().min(64);
    let mut src: std::vec::Vec<Point2<f32>> = inp.pairs[..n].iter().map(|p| pt2(p.0)).collect();
    let mut dst: std::vec::Vec<Point2<f32>> = inp.pairs[..n].iter().map(|p| pt2(p.1)).collect();
    apply_edits(&mut src, &inp.src_edits[..inp.src_edits.len().min(8)]);
    apply_edits(&mut dst, &inp.dst_edits[..inp.dst_edits.len().min(8)]);

    if let (Ok(s4), Ok(d4)) = (
        <&[Point2<f32>; 4]>::try_from(src.get(..4).unwrap_or(&[])),
        <&[Point2<f32>; 4]>::try_from(dst.get(..4).unwrap_or(&[])),
    ) && let Ok(h) = Homography::from_four_points(s4, d4)
    {
        check(&h, s4, "four_point");
    }
    if let Ok(h) = dlt(&src, &dst) {
        check(&h, &src, "dlt");
    }
    let cfg = inp.ransac.config();
    let mask_len = (n as i64 + i64::from(inp.mask_slack % 3)).max(0) as usize;
    let mut mask = std::vec![false; mask_len];
    if let Some(params) = inp.ransac.params()
        && let Ok((h, report)) = find_homography(&src, &dst, &params, &mut mask)
    {
        check(&h, &src, "find_homography");
        assert!(report.inliers <= n, "more inliers than points");
        assert_eq!(
            report.inliers,
            mask.iter().filter(|&&m| m).count(),
            "mask vs count"
        );
        assert!(
            report.iterations <= cfg.max_iterations.max(1),
            "iteration cap"
        );
    }
});
