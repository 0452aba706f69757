//! Exact image motions for measuring KLT accuracy: known 3x3 warps of a real frame (shifts, a
//! rotation, a scale, a homography) and an f64 bilinear warp independent of camgeom's own
//! sampling. `scripts/make_klt_fixtures.py` has the same numbers and the same formula, so a
//! warped frame is bit-identical on both sides (the KLT test checks its checksum).

#![allow(clippy::needless_range_loop)] // 3x3 matrix code reads best with indices.

use crate::images::GrayImage;

/// A 3x3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// `a b`.
pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `a` about the image centre: `T a T⁻¹` with `T` the shift to `((w-1)/2, (h-1)/2)`.
pub fn about_centre(w: usize, h: usize, a: Mat3) -> Mat3 {
    let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    let t = [[1.0, 0.0, cx], [0.0, 1.0, cy], [0.0, 0.0, 1.0]];
    let ti = [[1.0, 0.0, -cx], [0.0, 1.0, -cy], [0.0, 0.0, 1.0]];
    mul(&mul(&t, &a), &ti)
}

/// The known motions (same numbers as `warps()` in `scripts/make_klt_fixtures.py`):
/// frame-1 to frame-2 pixels.
pub fn warps(w: usize, h: usize) -> Vec<(&'static str, Mat3)> {
    let r = 3f64.to_radians();
    vec![
        (
            "shift_sub",
            [[1.0, 0.0, 0.37], [0.0, 1.0, -0.61], [0.0, 0.0, 1.0]],
        ),
        (
            "shift_big",
            [[1.0, 0.0, 6.25], [0.0, 1.0, -3.8], [0.0, 0.0, 1.0]],
        ),
        (
            "rotate3",
            about_centre(
                w,
                h,
                [
                    [r.cos(), -r.sin(), 0.8],
                    [r.sin(), r.cos(), -0.4],
                    [0.0, 0.0, 1.0],
                ],
            ),
        ),
        (
            "scale104",
            about_centre(w, h, [[1.04, 0.0, 0.0], [0.0, 1.04, 0.0], [0.0, 0.0, 1.0]]),
        ),
        (
            "homography",
            about_centre(
                w,
                h,
                [
                    [1.01, 0.02, 1.5],
                    [-0.015, 0.995, 2.0],
                    [2.0e-5, -1.5e-5, 1.0],
                ],
            ),
        ),
    ]
}

/// The inverse by cofactors (the same operations as the fixture script's).
pub fn inverse(m: &Mat3) -> Mat3 {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let c = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
    };
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv[j][i] = c(i, j) / det;
        }
    }
    inv
}

/// `m (x, y, 1)`, dehomogenised.
pub fn apply(m: &Mat3, x: f64, y: f64) -> (f64, f64) {
    let d = m[2][0] * x + m[2][1] * y + m[2][2];
    (
        (m[0][0] * x + m[0][1] * y + m[0][2]) / d,
        (m[1][0] * x + m[1][1] * y + m[1][2]) / d,
    )
}

/// `out(p) = img(H⁻¹ p)`: f64 bilinear, edges clamped, rounded half up. An independent path
/// from camgeom's own sampling; the same formula as the fixture script (checked by checksum).
pub fn warp(img: &GrayImage, h: &Mat3) -> GrayImage {
    let inv = inverse(h);
    let (w, hh) = (img.width, img.height);
    let mut out = GrayImage::filled(w, hh, 0);
    for y in 0..hh {
        for x in 0..w {
            let (xs, ys) = (x as f64, y as f64);
            let den = inv[2][0] * xs + inv[2][1] * ys + inv[2][2];
            let u =
                ((inv[0][0] * xs + inv[0][1] * ys + inv[0][2]) / den).clamp(0.0, w as f64 - 1.0);
            let v =
                ((inv[1][0] * xs + inv[1][1] * ys + inv[1][2]) / den).clamp(0.0, hh as f64 - 1.0);
            let x0 = (u.floor() as usize).min(w - 2);
            let y0 = (v.floor() as usize).min(hh - 2);
            let (a, b) = (u - x0 as f64, v - y0 as f64);
            let p = |xx: usize, yy: usize| f64::from(img.at(xx, yy));
            let val = (p(x0, y0) * (1.0 - a) + p(x0 + 1, y0) * a) * (1.0 - b)
                + (p(x0, y0 + 1) * (1.0 - a) + p(x0 + 1, y0 + 1) * a) * b;
            out.data[y * w + x] = (val + 0.5).floor().clamp(0.0, 255.0) as u8;
        }
    }
    out
}
