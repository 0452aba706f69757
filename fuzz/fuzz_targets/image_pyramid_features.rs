//! Image views of arbitrary geometry over buffers of arbitrary length, Gaussian pyramids (and
//! the frame loop's pyramid pair) into
//! buffers of arbitrary length, Shi-Tomasi corners with arbitrary parameters and scratch, FAST
//! corners and ORB features with arbitrary parameters and scratch, their descriptors matched
//! with an arbitrary configuration, the view warped into a frame through an arbitrary
//! quadrilateral and an arbitrary homography in both arithmetics.
//! Contract: no panic; a view exists only for a valid geometry; a pyramid's levels have the
//! documented sizes; corners lie inside the image and respect the output capacity; FAST
//! corners keep the border, score at least the threshold, come in row-major order and (with
//! suppression) are never 8-neighbours; ORB keypoints (any grid, sub-pixel or not, into a
//! heapless vector or a slice of any length) lie inside the frame, within the caps;
//! matches index both sides and carry the descriptors' Hamming distance; SIFT features (any
//! settings, scratch and output length) lie inside the frame with finite scales and unit
//! descriptors, within the caps, and their float matches index both sides; a warp writes at
//! most the frame's pixels.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::arith::Fixed;
use camgeom::corners::{Corner, CornerConfig, good_features};
use camgeom::features::matching::{
    FloatDescriptor, FloatMatch, float_scratch_len, match_float_descriptors,
};
use camgeom::features::sift::{self, SiftConfig, SiftFeature, sift_detect};
use camgeom::features::{
    Descriptor, FastConfig, Feature, Match, MatchConfig, OrbConfig, fast_detect, hamming,
    match_descriptors, match_descriptors_guided, orb_detect, orb_detect_into,
};
use camgeom::heapless::Vec;
use camgeom::homography::Homography;
use camgeom::image::{ImageMut, ImageView, buffer_len};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::pyramid::{self, Pyramid, PyramidPair};
use camgeom::warp::{WarpConfig, warp_into_quad, warp_perspective_into};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    width: u16,
    height: u16,
    stride: u16,
    /// Buffer length minus the length the geometry needs (may be negative).
    slack: i16,
    levels: u8,
    pyr_slack: i16,
    quality: f32,
    min_distance: u16,
    max_corners: u8,
    candidates: u8,
    scratch_slack: i16,
    existing: [(u8, u8); 3],
    seed: u32,
    quad: [(f32, f32); 4],
    /// A homography for `warp_perspective_into` (any matrix `from_matrix` accepts).
    map: [f32; 9],
    alpha: u8,
    fast_threshold: u8,
    fast_nonmax: bool,
    fast_border: u16,
    fast_slack: i16,
    orb_levels: u8,
    orb_scale_q8: u16,
    orb_threshold: u8,
    orb_border: u16,
    orb_max: u16,
    orb_slack: i16,
    orb_grid_cell: u16,
    orb_cell_keep: u8,
    orb_subpixel: bool,
    /// Length of the output slice of `orb_detect_into`.
    orb_out_len: u8,
    ratio: f32,
    cross_check: bool,
    max_distance: u16,
    match_slack: i16,
    /// The pairs `match_descriptors_guided` admits: `(i, j)` when bit `(7 i + j) mod 64` is set.
    admit: u64,
    sift_octaves: u8,
    sift_intervals: u8,
    sift_sigma: f32,
    sift_contrast: f32,
    sift_edge: f32,
    sift_upsample: bool,
    sift_root: bool,
    sift_max: u8,
    sift_slack: i16,
    sift_out_len: u8,
}

fn grow(len: usize, slack: i16) -> usize {
    (len as i64 + i64::from(slack)).clamp(0, 1 << 17) as usize
}

fuzz_target!(|inp: Input| {
    // Any geometry (the size checks see zero, huge and odd values), but at most 64 KiB of
    // pixels: larger geometries meet a buffer that is too short, and each run stays short.
    let (w, h, s) = (
        usize::from(inp.width),
        usize::from(inp.height),
        usize::from(inp.stride),
    );
    let need = buffer_len(w, h, s);
    let len = grow(need.min(1 << 16), inp.slack);
    let mut state = inp.seed | 1;
    let data: std::vec::Vec<u8> = (0..len)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            // Smooth ramps and noise: corners exist.
            (state as u8 & 0x3f).wrapping_add(((i % 97) * 2) as u8)
        })
        .collect();
    let Ok(view) = ImageView::new(&data[..], w, h, s) else {
        return;
    };
    assert!(
        w > 0 && h > 0 && s >= w && data.len() >= need,
        "view accepted a bad geometry"
    );
    assert_eq!((view.width(), view.height(), view.stride()), (w, h, s));

    let levels = usize::from(inp.levels % 10);
    let mut pbuf = std::vec![0u8; grow(pyramid::buffer_len(w, h, levels.min(8)), inp.pyr_slack)];
    if let Ok(p) = Pyramid::build(view, &mut pbuf[..], levels) {
        assert!(
            !p.is_empty() && p.len() <= levels.max(1),
            "pyramid level count"
        );
        for l in 0..p.len() {
            let lv = p.level(l).expect("level below len() exists");
            assert_eq!(
                (lv.width(), lv.height()),
                pyramid::level_size(w, h, l),
                "level {l} size"
            );
        }
        assert!(p.level(p.len()).is_none());
    }

    // The frame loop's pair over buffers of the fuzzed slack: accepted exactly when they hold
    // the geometry; a frame copied in comes back as the next pyramid's base.
    let frame_len = grow(w * h, inp.slack);
    let pyr_len = grow(pyramid::buffer_len(w, h, levels.min(8)), inp.pyr_slack);
    let mut pair = PyramidPair::new(
        [std::vec![0u8; frame_len], std::vec![0u8; frame_len]],
        [std::vec![0u8; pyr_len], std::vec![0u8; pyr_len]],
    );
    let fits = (1..=pyramid::MAX_LEVELS).contains(&levels)
        && frame_len >= w * h
        && pyr_len >= pyramid::buffer_len(w, h, levels);
    assert_eq!(
        pair.set_geometry(w, h, levels).is_ok(),
        fits,
        "pair geometry"
    );
    if fits {
        for k in 0..3 {
            pair.capture()
                .expect("capture")
                .copy_from(&view)
                .expect("copy");
            let ps = pair.advance().expect("advance");
            assert_eq!(ps.previous.is_some(), k > 0);
            assert_eq!(ps.next.level(0).and_then(|l| l.get(0, 0)), view.get(0, 0));
            drop(ps);
            if k == 1 {
                pair.rewind();
            }
        }
        assert!(pair.previous_mut().expect("previous").is_some());
    } else {
        assert!(pair.advance().is_err() || pair.geometry() != (w, h, levels));
    }

    let cfg = CornerConfig {
        quality: inp.quality,
        min_distance: u32::from(inp.min_distance),
        max_corners: usize::from(inp.max_corners),
    };
    let mut cand = std::vec![Corner::default(); usize::from(inp.candidates)];
    let mut scratch = std::vec![0u32; grow(camgeom::corners::scratch_len(w), inp.scratch_slack)];
    let existing = inp.existing.map(|(x, y)| [i32::from(x), i32::from(y)]);
    let mut out: Vec<Corner, 16> = Vec::new();
    if let Ok(params) = cfg.check()
        && let Ok(n) = good_features(
            &view,
            &params,
            existing.iter().copied(),
            &mut out,
            &mut cand[..],
            &mut scratch[..],
        )
    {
        assert_eq!(n, out.len(), "count returned");
        for c in &out {
            assert!(
                usize::from(c.x) < w && usize::from(c.y) < h,
                "corner outside the image"
            );
        }
        if cfg.max_corners > 0 {
            assert!(n <= cfg.max_corners);
        }
    }

    fast_and_orb(&view, &inp);

    let quad = inp.quad.map(|(x, y)| Point2::new(x, y));
    for fixed in [false, true] {
        let mut frame = [0u8; 64 * 48];
        let Ok(mut dst) = ImageMut::packed(&mut frame[..], 64, 48) else {
            return;
        };
        let cfg = WarpConfig { alpha: inp.alpha };
        let into_quad = if fixed {
            warp_into_quad::<Fixed>(&view, &mut dst, &quad, &cfg)
        } else {
            warp_into_quad::<f32>(&view, &mut dst, &quad, &cfg)
        };
        if let Ok(r) = into_quad {
            assert!(r.written <= 64 * 48, "written beyond the frame");
        }
        if let Ok(map) = Homography::from_matrix(&Matrix3::from_row_slice(&inp.map)) {
            let through = if fixed {
                warp_perspective_into::<Fixed>(&view, &mut dst, &map, &cfg)
            } else {
                warp_perspective_into::<f32>(&view, &mut dst, &map, &cfg)
            };
            if let Ok(r) = through {
                assert!(r.written <= 64 * 48, "written beyond the frame");
            }
        }
    }
});

/// FAST, ORB and matching on the view (see the contract above).
fn fast_and_orb(view: &ImageView<'_, u8>, inp: &Input) {
    let (w, h) = (view.width(), view.height());
    let fcfg = FastConfig {
        threshold: inp.fast_threshold,
        nonmax: inp.fast_nonmax,
        border: inp.fast_border,
    };
    let mut fscratch =
        std::vec![0u8; grow(camgeom::features::fast::scratch_len(w), inp.fast_slack)];
    let mut corners = std::vec::Vec::new();
    if let Ok(fparams) = fcfg.check()
        && fast_detect(view, &fparams, &mut fscratch[..], |c| corners.push(c)).is_ok()
    {
        let b = usize::from(inp.fast_border).max(3);
        for c in &corners {
            let (x, y) = (usize::from(c.x), usize::from(c.y));
            assert!(
                x >= b && x + b < w && y >= b && y + b < h,
                "FAST corner in the border"
            );
            assert!(
                c.score >= inp.fast_threshold,
                "FAST score below the threshold"
            );
        }
        for p in corners.windows(2) {
            assert!(
                (p[0].y, p[0].x) < (p[1].y, p[1].x),
                "FAST corners out of order"
            );
        }
        if inp.fast_nonmax {
            for (i, a) in corners.iter().enumerate() {
                for c in &corners[i + 1..] {
                    let (dx, dy) = (a.x.abs_diff(c.x), a.y.abs_diff(c.y));
                    assert!(
                        dx > 1 || dy > 1,
                        "two suppressed FAST corners are neighbours"
                    );
                }
            }
        }
    }

    let ocfg = OrbConfig {
        max_features: inp.orb_max,
        levels: inp.orb_levels,
        scale_q8: inp.orb_scale_q8,
        fast_threshold: inp.orb_threshold,
        border: inp.orb_border,
        grid_cell: inp.orb_grid_cell,
        cell_keep: inp.orb_cell_keep,
        subpixel: inp.orb_subpixel,
    };
    let need = camgeom::features::orb::scratch_len(w, h, inp.orb_scale_q8.max(1));
    let mut oscratch = std::vec![0u8; grow(need.min(1 << 18), inp.orb_slack)];
    let mut features: Vec<Feature, 32> = Vec::new();
    if let Ok(oparams) = ocfg.check()
        && orb_detect(view, &oparams, &mut oscratch[..], &mut features).is_ok()
    {
        assert!(
            features.len() <= usize::from(inp.orb_max),
            "ORB over max_features"
        );
        for f in &features {
            let k = &f.keypoint;
            assert!(
                k.x >= 0.0 && k.y >= 0.0 && k.x < w as f32 && k.y < h as f32,
                "ORB keypoint outside the frame"
            );
            assert!(
                k.angle.is_finite() && k.scale.is_finite(),
                "ORB keypoint not finite"
            );
        }
    }

    // The slice entry point, any output length: the same contract, at most `len` features.
    if let Ok(oparams) = ocfg.check() {
        let mut slice = std::vec![Feature::default(); usize::from(inp.orb_out_len)];
        if let Ok(n) = orb_detect_into(view, &oparams, &mut oscratch[..], &mut slice) {
            assert!(
                n <= slice.len() && n <= usize::from(inp.orb_max),
                "orb_detect_into over its caps"
            );
            for f in &slice[..n] {
                let k = &f.keypoint;
                assert!(
                    k.x >= 0.0 && k.y >= 0.0 && k.x < w as f32 && k.y < h as f32,
                    "ORB keypoint outside the frame (slice)"
                );
            }
        }
    }

    // SIFT, any settings, scratch and output length: features inside the frame, finite, of
    // unit descriptors, within the caps; their float descriptors matched against themselves
    // shifted by one.
    let scfg = SiftConfig {
        octaves: inp.sift_octaves,
        intervals: inp.sift_intervals,
        sigma: inp.sift_sigma,
        contrast_threshold: inp.sift_contrast,
        edge_threshold: inp.sift_edge,
        upsample: inp.sift_upsample,
        root: inp.sift_root,
        max_features: u32::from(inp.sift_max),
    };
    if let Ok(sparams) = scfg.check() {
        let need = sift::scratch_len(w, h, inp.sift_intervals, inp.sift_upsample);
        let mut sscratch = std::vec![0.0f32; grow(need.min(1 << 20), inp.sift_slack)];
        let mut sout = std::vec![SiftFeature::default(); usize::from(inp.sift_out_len)];
        if let Ok(n) = sift_detect(view, &sparams, &mut sscratch, &mut sout) {
            assert!(n <= sout.len(), "SIFT over the output");
            assert!(
                inp.sift_max == 0 || n <= usize::from(inp.sift_max),
                "SIFT over max_features"
            );
            for f in &sout[..n] {
                let k = &f.keypoint;
                assert!(
                    k.x >= 0.0 && k.y >= 0.0 && k.x < w as f32 && k.y < h as f32,
                    "SIFT keypoint outside the frame"
                );
                assert!(
                    k.sigma.is_finite() && k.sigma > 0.0 && k.angle.is_finite(),
                    "SIFT keypoint not finite"
                );
                let norm: f32 = f.descriptor.0.iter().map(|v| v * v).sum();
                assert!(
                    norm.is_finite() && norm <= 1.001,
                    "SIFT descriptor not unit"
                );
            }
            let q: std::vec::Vec<FloatDescriptor> =
                sout[..n].iter().map(|f| f.descriptor).collect();
            let t: std::vec::Vec<FloatDescriptor> = q.iter().skip(1).copied().collect();
            if let Ok(mparams) = (MatchConfig {
                ratio: inp.ratio,
                cross_check: inp.cross_check,
                max_distance: inp.max_distance,
            })
            .check()
            {
                let mut ms = std::vec![0u32; grow(float_scratch_len(t.len()), inp.match_slack)];
                let mut fm = std::vec![FloatMatch::default(); q.len()];
                if let Ok(k) = match_float_descriptors(&q, &t, &mparams, &mut ms, &mut fm) {
                    for m in &fm[..k] {
                        assert!(
                            usize::from(m.query) < q.len() && usize::from(m.train) < t.len(),
                            "float match out of range"
                        );
                    }
                }
            }
        }
    }

    // The descriptors against themselves shifted by one (so not all distances are 0).
    let query: std::vec::Vec<Descriptor> = features.iter().map(|f| f.descriptor).collect();
    let train: std::vec::Vec<Descriptor> = query.iter().skip(1).copied().collect();
    let mcfg = MatchConfig {
        ratio: inp.ratio,
        cross_check: inp.cross_check,
        max_distance: inp.max_distance,
    };
    let mlen = grow(
        camgeom::features::matching::scratch_len(train.len()),
        inp.match_slack,
    );
    let mut mscratch = std::vec![0u32; mlen];
    let mut out = std::vec![Match::default(); grow(query.len(), inp.match_slack)];
    if let Ok(mparams) = mcfg.check()
        && let Ok(n) = match_descriptors(&query, &train, &mparams, &mut mscratch[..], &mut out[..])
    {
        assert!(n <= query.len(), "more matches than queries");
        for m in &out[..n] {
            let (q, t) = (usize::from(m.query), usize::from(m.train));
            assert!(
                q < query.len() && t < train.len(),
                "match index out of range"
            );
            assert_eq!(
                u32::from(m.distance),
                hamming(&query[q], &train[t]),
                "distance"
            );
            assert!(m.distance <= inp.max_distance, "match beyond max_distance");
        }
    }

    // Guided: only admitted pairs come out, with their distance; admitting every pair is the
    // unguided matcher.
    let admit = |i: usize, j: usize| inp.admit >> ((7 * i + j) % 64) & 1 == 1;
    let mut guided = std::vec![Match::default(); out.len()];
    if let Ok(mparams) = mcfg.check()
        && let Ok(n) =
            match_descriptors_guided(&query, &train, &mparams, admit, &mut mscratch, &mut guided)
    {
        assert!(n <= query.len(), "more guided matches than queries");
        for m in &guided[..n] {
            let (q, t) = (usize::from(m.query), usize::from(m.train));
            assert!(
                q < query.len() && t < train.len() && admit(q, t),
                "guided match not admitted"
            );
            assert_eq!(
                u32::from(m.distance),
                hamming(&query[q], &train[t]),
                "guided distance"
            );
        }
    }
    if let Ok(mparams) = mcfg.check() {
        let mut all = std::vec![Match::default(); out.len()];
        let mut s2 = mscratch.clone();
        let a = match_descriptors(&query, &train, &mparams, &mut mscratch, &mut out);
        let b = match_descriptors_guided(&query, &train, &mparams, |_, _| true, &mut s2, &mut all);
        assert_eq!(a, b, "guided with every pair admitted");
        if let Ok(n) = a {
            assert_eq!(out[..n], all[..n], "guided with every pair admitted");
        }
    }
}
