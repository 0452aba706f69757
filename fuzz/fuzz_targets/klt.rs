//! Pyramidal Lucas-Kanade (`calc_flow`, fixed point and `f32`, per-window and per-level
//! derivatives) on small arbitrary images, arbitrary points (NaN, inf, far outside) and
//! arbitrary configurations. Contract: no panic; on `Ok`, every tracked point is finite and
//! its error is finite and non-negative. And `FlowBuffers` over three frames (there and back
//! twice) with `Templates::Compute` and `Templates::Keep` (a buffer of `templates_len` with
//! slack either way; a short one is `BufferTooSmall("templates")`, then the exact length
//! runs): the same result, flow for flow, to the bit. And `calc_flow` with `Borders::Copy` of a buffer
//! of arbitrary length: the same result as with `Borders::None`, to the bit, or (only when the
//! buffer is shorter than the level-1 copies) `BufferTooSmall("borders")`.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::image::ImageView;
use camgeom::klt::{
    Borders, Coordinate, Fixed, Flow, FlowArith, FlowBuffers, FlowStatus, Gradients, LkConfig,
    LkParams, Q16, Templates, bordered_len, calc_flow, level_gradient_len, scratch_len,
    templates_len,
};
use camgeom::pyramid::{Pyramid, buffer_len};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::Num;

#[derive(Debug, Arbitrary)]
struct Input {
    w: u8,
    h: u8,
    /// Second frame a different size (must be rejected, not crash).
    other_size: bool,
    levels: u8,
    pixels: std::vec::Vec<u8>,
    shift: (i8, i8),
    win: u8,
    max_level: u8,
    max_iter: u8,
    epsilon: Num,
    min_eigenvalue: Num,
    use_initial_flow: bool,
    compute_error: bool,
    fb: Option<Num>,
    /// Derivative source: `% 3` per window, per level, `Auto` (its buffer halved
    /// `derivs / 3 % 4` times).
    derivs: u8,
    scratch_slack: i8,
    /// Length of the `Borders::Copy` buffer: the level-0 copies' halved `borders % 4` times,
    /// less `borders / 4 % 3` bytes.
    borders: u8,
    /// Slack of the `Templates::Keep` buffer of the `FlowBuffers` run.
    kept_slack: i16,
    points: std::vec::Vec<(Num, Num)>,
    fixed_points: std::vec::Vec<(i32, i32)>,
}

fn frame(w: usize, h: usize, px: &[u8], dx: i32, dy: i32) -> std::vec::Vec<u8> {
    let mut v = std::vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            // The pattern (tiled from the fuzzer's bytes plus a ramp), shifted.
            let (sx, sy) = (
                (x as i32 - dx).rem_euclid(w as i32),
                (y as i32 - dy).rem_euclid(h as i32),
            );
            let i = (sy as usize * w + sx as usize) % px.len().max(1);
            v[y * w + x] = px
                .get(i)
                .copied()
                .unwrap_or(0)
                .wrapping_add((sx * 3 + sy * 5) as u8);
        }
    }
    v
}

fn grads(derivs: u8, g: &mut [[i16; 2]]) -> Gradients<'_> {
    match derivs % 3 {
        0 => Gradients::PerWindow,
        1 => Gradients::PerLevel(g),
        _ => Gradients::Auto(g),
    }
}

fn grad_len(derivs: u8, w: usize, h: usize) -> usize {
    match derivs % 3 {
        0 => 0,
        1 => level_gradient_len(w, h),
        _ => level_gradient_len(w, h) >> (derivs / 3 % 4),
    }
}

/// One arithmetic's flow on the fuzzed pyramids and buffers.
struct Run<'a, 'p> {
    pyramids: (&'a Pyramid<'p>, &'a Pyramid<'p>),
    params: &'a LkParams,
    /// The flows start at the points ([`LkConfig::use_initial_flow`]).
    initial: bool,
    derivs: u8,
    grad: &'a mut [[i16; 2]],
    borders: &'a mut [u8],
    scratch: &'a mut [i16],
    what: &'static str,
}

impl Run<'_, '_> {
    /// `calc_flow` of `pts` without and with bordered copies: every tracked point of the first
    /// finite ([`check`]); the second the same outcome, and on `Ok` the same flows to the bit
    /// (each coordinate's `bits`), unless its buffer is shorter than the level-1 copies and
    /// it says so.
    fn both<A: FlowArith>(&mut self, pts: &[[A::Coord; 2]], bits: impl Fn(A::Coord) -> u32) {
        let (pa, pb) = self.pyramids;
        let mut initial = std::vec![Flow::<A::Coord>::default(); pts.len()];
        if self.initial {
            for (f, p) in initial.iter_mut().zip(pts) {
                (f.x, f.y) = (p[0], p[1]);
            }
        }
        let mut flows = initial.clone();
        let g = grads(self.derivs, self.grad);
        let none = Borders::None;
        let plain = calc_flow::<A>(pa, pb, pts, &mut flows, self.params, g, none, self.scratch);
        if plain.is_ok() {
            check(&flows, A::Coord::to_f32, self.what);
        }
        let mut bordered = initial;
        let g = grads(self.derivs, self.grad);
        let (b, s) = (Borders::Copy(&mut *self.borders), &mut *self.scratch);
        let with = calc_flow::<A>(pa, pb, pts, &mut bordered, self.params, g, b, s);
        let what = self.what;
        if with == Err(camgeom::Error::BufferTooSmall("borders")) {
            // Only a buffer shorter than level 1's copies is refused.
            let win = self.params.config().win;
            let level1 = pa
                .level(1)
                .map(|l| bordered_len(l.width(), l.height(), win));
            assert!(
                level1.is_some_and(|n| self.borders.len() < n),
                "{what}: a border buffer of {} bytes refused",
                self.borders.len()
            );
            return;
        }
        assert_eq!(
            plain.is_ok(),
            with.is_ok(),
            "{what} bordered: {with:?} against {plain:?}"
        );
        if plain.is_ok() {
            let key = |f: &[Flow<A::Coord>]| -> std::vec::Vec<_> {
                f.iter()
                    .map(|f| (bits(f.x), bits(f.y), f.status, bits(f.err)))
                    .collect()
            };
            assert_eq!(
                key(&bordered),
                key(&flows),
                "{what}: bordered copies changed a flow"
            );
        }
    }
}

fn check<C: Copy>(flows: &[Flow<C>], to_f32: impl Fn(C) -> f32, what: &str) {
    for f in flows {
        if f.status == FlowStatus::Tracked {
            let (x, y, e) = (to_f32(f.x), to_f32(f.y), to_f32(f.err));
            assert!(
                x.is_finite() && y.is_finite(),
                "{what}: tracked point not finite"
            );
            assert!(e.is_finite() && e >= 0.0, "{what}: error {e}");
        }
    }
}

fuzz_target!(|inp: Input| {
    let (w, h) = (usize::from(inp.w % 72) + 1, usize::from(inp.h % 72) + 1);
    let (w2, h2) = if inp.other_size { (w + 1, h) } else { (w, h) };
    let levels = usize::from(inp.levels % 6);
    let a = frame(w, h, &inp.pixels, 0, 0);
    let b = frame(
        w2,
        h2,
        &inp.pixels,
        i32::from(inp.shift.0 % 8),
        i32::from(inp.shift.1 % 8),
    );
    let (Ok(va), Ok(vb)) = (
        ImageView::packed(&a[..], w, h),
        ImageView::packed(&b[..], w2, h2),
    ) else {
        return;
    };
    let mut ba = std::vec![0u8; buffer_len(w, h, levels.min(8))];
    let mut bb = std::vec![0u8; buffer_len(w2, h2, levels.min(8))];
    let (Ok(pa), Ok(pb)) = (
        Pyramid::build(va, &mut ba[..], levels),
        Pyramid::build(vb, &mut bb[..], levels),
    ) else {
        return;
    };
    let cfg = LkConfig {
        win: usize::from(inp.win % 70),
        max_level: usize::from(inp.max_level % 6),
        max_iter: u32::from(inp.max_iter % 110),
        epsilon: inp.epsilon.get(),
        min_eigenvalue: inp.min_eigenvalue.get(),
        use_initial_flow: inp.use_initial_flow,
        fb_threshold: inp.fb.map(Num::get),
        compute_error: inp.compute_error,
    };
    // A configuration out of range is rejected once, here; the flow never sees it.
    let Ok(params) = cfg.check() else {
        return;
    };
    let slen =
        (scratch_len(cfg.win.min(63)) as i64 + i64::from(inp.scratch_slack % 3)).max(0) as usize;
    let mut scratch = std::vec![0i16; slen];
    let mut grad = std::vec![[0i16; 2]; grad_len(inp.derivs, w, h)];

    let pts: std::vec::Vec<[f32; 2]> = inp
        .points
        .iter()
        .take(16)
        .map(|p| [p.0.get(), p.1.get()])
        .collect();
    let blen = (bordered_len(w, h, cfg.win.min(63)) >> (inp.borders % 4))
        .saturating_sub(usize::from(inp.borders / 4 % 3));
    let mut borders = std::vec![0u8; blen];
    let fpts: std::vec::Vec<[Q16; 2]> = inp
        .fixed_points
        .iter()
        .take(16)
        .map(|p| [Q16::from_bits(p.0), Q16::from_bits(p.1)])
        .collect();
    for (what, fixed) in [("f32", false), ("fixed", true)] {
        let mut run = Run {
            pyramids: (&pa, &pb),
            params: &params,
            initial: inp.use_initial_flow,
            derivs: inp.derivs,
            grad: &mut grad,
            borders: &mut borders,
            scratch: &mut scratch,
            what,
        };
        match fixed {
            false => run.both::<f32>(&pts, f32::to_bits),
            true => run.both::<Fixed>(&fpts, |q| q.to_bits() as u32),
        }
    }

    // FlowBuffers, frames a -> b -> a -> b, without and with kept templates.
    if w2 != w || h2 != h {
        return;
    }
    let win = cfg.win.min(63);
    let mut s = std::vec![0i16; scratch_len(win)];
    // The slack makes the templates' buffer short (an error, checked once) or long.
    let need = templates_len(win, cfg.max_level, 16);
    let kept_len = (need as i64 + i64::from(inp.kept_slack)).max(0) as usize;
    let mut kept = std::vec![0i16; kept_len];
    let (mut b1, mut b2) = (FlowBuffers::<f32, 16>::new(), FlowBuffers::<f32, 16>::new());
    let (mut v1, mut v2) = (b1.as_mut_view(), b2.as_mut_view());
    let mut p1 = pts.clone();
    let mut p2 = pts.clone();
    if kept_len < need {
        let t = Templates::Keep(&mut kept);
        let r = v2.run(&pa, &pb, p2.iter().copied(), &params, t, &mut s);
        assert_eq!(
            r.err(),
            Some(camgeom::Error::BufferTooSmall("templates")),
            "a templates buffer of {kept_len} elements for {need}"
        );
        kept = std::vec![0i16; need];
    }
    for (prev, next) in [(&pa, &pb), (&pb, &pa), (&pa, &pb)] {
        let t = Templates::Compute;
        let r1 = v1.run(prev, next, p1.iter().copied(), &params, t, &mut s);
        let t = Templates::Keep(&mut kept);
        let r2 = v2.run(prev, next, p2.iter().copied(), &params, t, &mut s);
        match (r1, r2) {
            (Ok(f1), Ok(f2)) => {
                let bits = |f: &[Flow<f32>]| -> std::vec::Vec<_> {
                    f.iter()
                        .map(|f| (f.x.to_bits(), f.y.to_bits(), f.status, f.err.to_bits()))
                        .collect()
                };
                assert_eq!(bits(f1), bits(f2), "kept templates changed a flow");
                p1 = f1.iter().map(|f| [f.x, f.y]).collect();
                p2 = f2.iter().map(|f| [f.x, f.y]).collect();
            }
            (Err(e1), Err(e2)) => {
                assert_eq!(e1, e2);
                return;
            }
            (r1, r2) => panic!("{:?} against {:?}", r1.err(), r2.err()),
        }
    }
});
