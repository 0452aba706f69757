//! Step 2 of the detection: the corner test on a ring of samples around a candidate.

use nalgebra::{Point2, Vector2};

use crate::image::ImageView;

/// Ring samples of the corner test.
const RING: usize = 32;

/// Radius of the corner test's outer ring (pixels): the test sees an x-corner best when the
/// four squares around it are at least this wide.
pub(super) const OUTER_RADIUS: f32 = 5.0;

/// Radius of the inner ring, tried when the outer one meets other squares.
const INNER_RADIUS: f32 = 3.0;

/// The corner test of a candidate at `p`: the two edge lines through it from the ring of
/// radius 5 px, else from the ring of 3 px (when the larger one meets other squares); `None`
/// when neither shows an x-corner.
pub(super) fn corner_lines(
    image: &ImageView<'_, u8>,
    p: &Point2<f32>,
    min_contrast: u8,
) -> Option<[Vector2<f32>; 2]> {
    [OUTER_RADIUS, INNER_RADIUS]
        .into_iter()
        .find_map(|radius| ring_lines(image, p, radius, min_contrast))
}

/// The two edge lines through an x-corner at `p` from the dark/bright transitions on a ring.
fn ring_lines(
    image: &ImageView<'_, u8>,
    p: &Point2<f32>,
    radius: f32,
    min_contrast: u8,
) -> Option<[Vector2<f32>; 2]> {
    let step = core::f32::consts::TAU / RING as f32;
    let mut raw = [0.0f32; RING];
    for (k, v) in raw.iter_mut().enumerate() {
        let a = k as f32 * step;
        *v = image.sample_bilinear(p.x + radius * libm::cosf(a), p.y + radius * libm::sinf(a))?;
    }
    // Circular [1 2 1] smoothing against noise.
    let mut v = [0.0f32; RING];
    for (k, o) in v.iter_mut().enumerate() {
        let g = |i: usize| raw.get(i % RING).copied().unwrap_or(0.0);
        *o = 0.25 * (g(k + RING - 1) + 2.0 * g(k) + g(k + 1));
    }
    let (lo, hi) = v
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    if hi - lo < min_contrast as f32 {
        return None;
    }
    let t = 0.5 * (lo + hi);
    let mut angles = [0.0f32; 4];
    let mut n = 0usize;
    for k in 0..RING {
        let a = v.get(k).copied().unwrap_or(0.0) - t;
        let b = v.get((k + 1) % RING).copied().unwrap_or(0.0) - t;
        if (a > 0.0) != (b > 0.0) {
            let slot = angles.get_mut(n)?;
            *slot = (k as f32 + a / (a - b)) * step;
            n += 1;
        }
    }
    if n != 4 {
        return None;
    }
    let pi = core::f32::consts::PI;
    let [a1, a2, a3, a4] = angles;
    let tol = 0.6;
    if ((a3 - a1) - pi).abs() > tol || ((a4 - a2) - pi).abs() > tol {
        return None;
    }
    let dir = |x: f32, y: f32| {
        let m = 0.5 * (x + (y - pi));
        Vector2::new(libm::cosf(m), libm::sinf(m))
    };
    Some([dir(a1, a3), dir(a2, a4)])
}
