//! EPnP (Lepetit, Moreno-Noguer & Fua, IJCV 2009): a non-iterative pose from `N ≥ 4` points.
//!
//! Each world point is written in barycentric coordinates of four control points,
//! `Xᵢ = Σⱼ αᵢⱼ cⱼ`, `Σⱼ αᵢⱼ = 1`, with `c₀` the centroid and `c₁..₃ = c₀ + (σₖ/√N) vₖ` along the
//! principal axes (`σₖ`, `vₖ` from the SVD of the centred points). The camera-frame control
//! points `c'ⱼ` are then linear in the image: every normalised point `(uᵢ, vᵢ)` gives the two rows
//! `Σⱼ αᵢⱼ [1 0 -uᵢ; 0 1 -vᵢ] c'ⱼ = 0` of a `2N x 12` system `M x = 0`. Its near-null space is
//! spanned by four vectors `w₁..w₄`, `x = Σₖ βₖ wₖ`. The two rows of a point share `αᵢ`
//! (`αᵢ·x' = uᵢ αᵢ·z'` and `αᵢ·y' = vᵢ αᵢ·z'` over the control points' coordinates), so the
//! system is solved by Harker and O'Leary's paired reduction (`crate::linalg`'s `Reduced`: one
//! row `[αᵢ, uᵢ αᵢ, vᵢ αᵢ]` a point into a 12-column streaming QR, a 12x4 SVD for the `z'`,
//! back substitution for `x'` and `y'`, each `wₖ` scaled to unit length) instead of the SVD of
//! the 12x12 `R` of all `2N` rows; the exact null space is the same, and with noise the four
//! vectors move by a second-order amount. The `βₖ` follow from the six control-point distances,
//! `|c'ₐ - c'ᵦ|² = |cₐ - cᵦ|²`, linear in the products `βₖβₗ` (`L β̄ = ρ`, `L` 6x10). The cases
//! `N = 2, 3, 4` (of the paper) are solved approximately, each polished by Gauss-Newton on the
//! four `β`, and the candidate with the smallest reprojection error wins; the pose is the
//! absolute orientation (Procrustes) between `Xᵢ` and `X'ᵢ = Σⱼ αᵢⱼ c'ⱼ`.
//!
//! With exactly four points (a 4-dimensional null space the linearised cases do not solve)
//! the P3P poses of the first three points are candidates too ([`super::p3p()`]).
//!
//! Planar point sets (`σ₃ ≤ √ε σ₁`) are rejected: use [`super::solve_planar`] (IPPE) for them.

use nalgebra::{Matrix3, Point2, Point3, SMatrix, SVector, Vector3};

use super::p3p::p3p;
use crate::linalg::{Reduced, StreamingQr, closest_rotation};
use crate::scalar::{Real, above, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// Gauss-Newton steps on the four `β` per candidate (the reference implementation's 5).
pub const BETA_GAUSS_NEWTON_ITERATIONS: u8 = 5;

/// The control-point pairs of the six distance constraints.
const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The EPnP pose from world points and their undistorted normalised image points
/// (`x_n = distort⁻¹(K⁻¹ u)`), with its RMS reprojection error in normalised units.
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 4 points;
/// [`Error::NonFinite`]; [`Error::Degenerate`] for (nearly) planar or collinear world points
/// or when no candidate places the points in front of the camera; as [`crate::linalg::svd_jacobi`].
#[doc(alias = "solvePnP")]
#[doc(alias = "SOLVEPNP_EPNP")]
pub fn epnp<T: Real>(world: &[Point3<T>], normalized: &[Point2<T>]) -> Result<(Pose<T>, T)> {
    if world.len() != normalized.len() {
        return Err(Error::LengthMismatch);
    }
    epnp_with(world.len(), |i| Some((*world.get(i)?, *normalized.get(i)?)))
}

/// [`epnp`] over the pairs `pair(i)`, `i < n`; a `None` pair is left out (inlier masks).
pub(crate) fn epnp_with<T, F>(n: usize, pair: F) -> Result<(Pose<T>, T)>
where
    T: Real,
    F: Fn(usize) -> Option<(Point3<T>, Point2<T>)>,
{
    let pairs = || (0..n).filter_map(&pair);
    let mut count = 0usize;
    let mut centroid = Vector3::zeros();
    for (x, u) in pairs() {
        check_finite(&[x.x, x.y, x.z, u.x, u.y])?;
        centroid += x.coords;
        count += 1;
    }
    if count < 4 {
        return Err(Error::TooFewPoints);
    }
    let nf = T::lit(count as f64);
    centroid /= nf;
    let c0 = Point3::from(centroid);

    // Principal axes of the centred points, without forming the covariance.
    let mut qr = StreamingQr::<T, 3>::new();
    for (x, _) in pairs() {
        let d = x - c0;
        qr.push_row(&[d.x, d.y, d.z])?;
    }
    let pca = qr.svd()?;
    let [s1, _, s3]: [T; 3] = pca.singular_values.into();
    if !above(s3, T::EPSILON.sqrt() * s1) {
        return Err(Error::Degenerate);
    }
    // αₖ = vₖ·(X - c₀) √N / σₖ for k = 1..3, α₀ = 1 - α₁ - α₂ - α₃.
    let sqrt_n = nf.sqrt();
    let mut to_alpha = pca.v.transpose();
    for (mut row, s) in to_alpha.row_iter_mut().zip(pca.singular_values.iter()) {
        row *= sqrt_n / *s;
    }
    let alphas = |x: &Point3<T>| -> [T; 4] {
        let [a1, a2, a3]: [T; 3] = (to_alpha * (x - c0)).into();
        [T::one() - a1 - a2 - a3, a1, a2, a3]
    };
    // World control points and their squared distances.
    let mut ctrl = [c0; 4];
    for (k, c) in ctrl.iter_mut().skip(1).enumerate() {
        let (Some(s), col) = (pca.singular_values.get(k), pca.v.column(k)) else {
            continue;
        };
        *c = c0 + col * (*s / sqrt_n);
    }
    let rho: [T; 6] = PAIRS.map(|(a, b)| match (ctrl.get(a), ctrl.get(b)) {
        (Some(p), Some(q)) => (p - q).norm_squared(),
        _ => T::zero(),
    });

    // M x = 0, x the 12 camera-frame control-point coordinates: for each point the pair
    // `α·x = u α·z`, `α·y = v α·z` over the control points' x, y and z coordinates, solved by
    // the paired reduction (one row `[α, u α, v α]` a point, a 12x4 SVD instead of 12x12).
    let mut m = StreamingQr::<T, 12>::new();
    for (x, u) in pairs() {
        let a = alphas(&x);
        let mut row = [T::zero(); 12];
        for (j, aj) in a.iter().enumerate() {
            for (k, v) in [(0, *aj), (4, *aj * u.x), (8, *aj * u.y)] {
                if let Some(e) = row.get_mut(k + j) {
                    *e = v;
                }
            }
        }
        m.push_row(&row)?;
    }
    let red = Reduced::<T, 12, 4>::new(m.r())?;
    // w₁ = the null vector (smallest σ), w₂.. the next ones; each lifted to all 12
    // coordinates (control point j at 3j..3j+3) and scaled to unit length.
    let w: [SVector<T, 12>; 4] = core::array::from_fn(|k| {
        let z = red.r(k);
        let (px, py) = red.lift(&z);
        // Interleaved back: control point j's (x, y, z) at 3j, 3j + 1, 3j + 2.
        let mut v = SVector::<T, 12>::zeros();
        for (i, e) in v.iter_mut().enumerate() {
            let block = match i % 3 {
                0 => &px,
                1 => &py,
                _ => &z,
            };
            *e = block.get(i / 3).copied().unwrap_or(T::zero());
        }
        let n = v.norm();
        if n > T::zero() { v / n } else { v }
    });
    // `R₁₁` (the barycentric weights' block) is well conditioned for non-coplanar points
    // (the principal-axis test above); a non-finite lift would mean it is not.
    if !w.iter().all(|v| v.iter().all(|e| e.finite())) {
        return Err(Error::Degenerate);
    }
    // dₖ(a, b) = wₖ[a] - wₖ[b], the control-point differences of each basis vector.
    let diff = |k: usize, a: usize, b: usize| -> Vector3<T> {
        let wk = w.get(k).map_or_else(SVector::zeros, |v| *v);
        let p = wk.fixed_rows::<3>(3 * a.min(3)).into_owned();
        let q = wk.fixed_rows::<3>(3 * b.min(3)).into_owned();
        p - q
    };
    // L (6 x 10) on β̄ = [β₁₁ β₁₂ β₂₂ β₁₃ β₂₃ β₃₃ β₁₄ β₂₄ β₃₄ β₄₄].
    let l: [[T; 10]; 6] = PAIRS.map(|(a, b)| {
        let d: [Vector3<T>; 4] = core::array::from_fn(|k| diff(k, a, b));
        let [d1, d2, d3, d4] = d;
        let two = T::lit(2.0);
        [
            d1.dot(&d1),
            two * d1.dot(&d2),
            d2.dot(&d2),
            two * d1.dot(&d3),
            two * d2.dot(&d3),
            d3.dot(&d3),
            two * d1.dot(&d4),
            two * d2.dot(&d4),
            two * d3.dot(&d4),
            d4.dot(&d4),
        ]
    });

    let mut best: Option<(Pose<T>, T)> = None;
    for start in [
        approx_n4(&l, &rho),
        approx_n2(&l, &rho),
        approx_n3(&l, &rho),
    ]
    .into_iter()
    .flatten()
    {
        let betas = gauss_newton(&l, &rho, start);
        let x: SVector<T, 12> = w
            .iter()
            .zip(betas.iter())
            .fold(SVector::zeros(), |acc, (wk, b)| acc + wk * *b);
        let Ok(candidate) = pose_from_control_points(&x, &pairs, &alphas) else {
            continue;
        };
        let Some(err) = normalized_rms(&candidate, &pairs, nf) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| err < b.1) {
            best = Some((candidate, err));
        }
    }
    if count == 4 {
        // Eight equations leave a 4-dimensional null space, and the linearised β cases do not
        // reach the solution from there: P3P on three points, the fourth choosing, is exact.
        let mut it = pairs();
        if let (Some((x1, u1)), Some((x2, u2)), Some((x3, u3))) = (it.next(), it.next(), it.next())
        {
            let ray = |u: Point2<T>| Vector3::new(u.x, u.y, T::one());
            if let Ok(sols) = p3p(&[ray(u1), ray(u2), ray(u3)], &[x1, x2, x3]) {
                // By reference: `heapless::Vec`'s by-value iterator slices on drop (a bounds
                // check the optimiser cannot remove).
                for candidate in sols.iter() {
                    let Some(err) = normalized_rms(candidate, &pairs, nf) else {
                        continue;
                    };
                    if best.as_ref().is_none_or(|b| err < b.1) {
                        best = Some((*candidate, err));
                    }
                }
            }
        }
    }
    best.ok_or(Error::Degenerate)
}

/// RMS of `|π(R X + t) - x_n|` over the pairs; `None` if a point is behind the camera.
fn normalized_rms<T, I>(pose: &Pose<T>, pairs: &impl Fn() -> I, nf: T) -> Option<T>
where
    T: Real,
    I: Iterator<Item = (Point3<T>, Point2<T>)>,
{
    let mut sum = T::zero();
    for (x, u) in pairs() {
        let c = pose.apply(&x);
        if !above(c.z, T::zero()) {
            return None;
        }
        sum += (Point2::new(c.x / c.z, c.y / c.z) - u).norm_squared();
    }
    let rms = (sum / nf).sqrt();
    rms.finite().then_some(rms)
}

/// The pose aligning `Xᵢ` with `X'ᵢ = Σⱼ αᵢⱼ c'ⱼ` (sign fixed so the points are in front):
/// `R = closest_rotation(Σ (X'ᵢ - μ')(Xᵢ - μ)ᵀ)`, `t = μ' - R μ`.
fn pose_from_control_points<T, I>(
    x: &SVector<T, 12>,
    pairs: &impl Fn() -> I,
    alphas: &impl Fn(&Point3<T>) -> [T; 4],
) -> Result<Pose<T>>
where
    T: Real,
    I: Iterator<Item = (Point3<T>, Point2<T>)>,
{
    let ctrl: [Vector3<T>; 4] = core::array::from_fn(|j| x.fixed_rows::<3>(3 * j).into_owned());
    let camera_point = |p: &Point3<T>| -> Vector3<T> {
        alphas(p)
            .iter()
            .zip(ctrl.iter())
            .fold(Vector3::zeros(), |acc, (a, c)| acc + c * *a)
    };
    let (mut mw, mut mc, mut depth) = (Vector3::zeros(), Vector3::zeros(), T::zero());
    let mut count = 0usize;
    for (p, _) in pairs() {
        let c = camera_point(&p);
        mw += p.coords;
        mc += c;
        depth += c.z;
        count += 1;
    }
    let nf = T::lit(count as f64);
    // x and -x solve the same system: the one with the points in front is right.
    let sign = if depth < T::zero() {
        -T::one()
    } else {
        T::one()
    };
    mw /= nf;
    mc *= sign / nf;
    let mut h = Matrix3::zeros();
    for (p, _) in pairs() {
        let c = camera_point(&p) * sign;
        h += (c - mc) * (p.coords - mw).transpose();
    }
    let r = closest_rotation(&h)?;
    let t = mc - r * mw;
    Pose::new(r, t)
}

/// Least squares `A y = b` for `A` the columns `cols` of `L` and `b = ρ`, through the QR of
/// `[A | b]`; `K` is `cols.len() + 1`.
fn solve_columns<T: Real, const K: usize>(
    l: &[[T; 10]; 6],
    rho: &[T; 6],
    cols: &[usize],
) -> Option<SVector<T, K>> {
    let mut qr = StreamingQr::<T, K>::new();
    for (row, r) in l.iter().zip(rho) {
        let mut a = [T::zero(); K];
        for (dst, c) in a.iter_mut().zip(cols) {
            *dst = *row.get(*c)?;
        }
        *a.last_mut()? = *r;
        qr.push_row(&a).ok()?;
    }
    back_substitute(qr.r())
}

/// Solves the upper-left `(K-1)²` triangle of `R` against its last column; the result's last
/// entry is zero.
fn back_substitute<T: Real, const K: usize>(r: &SMatrix<T, K, K>) -> Option<SVector<T, K>> {
    let mut y = SVector::<T, K>::zeros();
    let scale = r.amax();
    for i in (0..K.saturating_sub(1)).rev() {
        let mut acc = *r.get((i, K - 1))?;
        for j in (i + 1)..(K - 1) {
            acc -= *r.get((i, j))? * *y.get(j)?;
        }
        let d = *r.get((i, i))?;
        if !above(d.abs(), T::EPSILON * scale) {
            return None;
        }
        *y.get_mut(i)? = acc / d;
    }
    y.iter().all(|v| v.finite()).then_some(y)
}

/// Case N = 4 (approximated): `[β₁₁ β₁₂ β₁₃ β₁₄]` from L's columns 0, 1, 3, 6.
fn approx_n4<T: Real>(l: &[[T; 10]; 6], rho: &[T; 6]) -> Option<[T; 4]> {
    let y = solve_columns::<T, 5>(l, rho, &[0, 1, 3, 6])?;
    let [b11, b12, b13, b14, _]: [T; 5] = y.into();
    let (s, b1) = if b11 < T::zero() {
        (-T::one(), (-b11).sqrt())
    } else {
        (T::one(), b11.sqrt())
    };
    if !above(b1, T::zero()) {
        return None;
    }
    Some([b1, s * b12 / b1, s * b13 / b1, s * b14 / b1])
}

/// `β₁`, `β₂` from `β₁₁`, `β₁₂`, `β₂₂` (signs as in the reference implementation).
fn first_two<T: Real>(b11: T, b12: T, b22: T) -> [T; 2] {
    let root = |v: T| if v > T::zero() { v.sqrt() } else { T::zero() };
    let (mut b1, b2) = if b11 < T::zero() {
        (root(-b11), root(-b22))
    } else {
        (root(b11), root(b22))
    };
    if b12 < T::zero() {
        b1 = -b1;
    }
    [b1, b2]
}

/// Case N = 2: `[β₁₁ β₁₂ β₂₂]`.
fn approx_n2<T: Real>(l: &[[T; 10]; 6], rho: &[T; 6]) -> Option<[T; 4]> {
    let [b11, b12, b22, _]: [T; 4] = solve_columns::<T, 4>(l, rho, &[0, 1, 2])?.into();
    let [b1, b2] = first_two(b11, b12, b22);
    Some([b1, b2, T::zero(), T::zero()])
}

/// Case N = 3: `[β₁₁ β₁₂ β₂₂ β₁₃ β₂₃]`.
fn approx_n3<T: Real>(l: &[[T; 10]; 6], rho: &[T; 6]) -> Option<[T; 4]> {
    let [b11, b12, b22, b13, _, _]: [T; 6] =
        solve_columns::<T, 6>(l, rho, &[0, 1, 2, 3, 4])?.into();
    let [b1, b2] = first_two(b11, b12, b22);
    let b3 = if above(b1.abs(), T::zero()) {
        b13 / b1
    } else {
        T::zero()
    };
    Some([b1, b2, b3, T::zero()])
}

/// At most [`BETA_GAUSS_NEWTON_ITERATIONS`] Gauss-Newton steps on
/// `eₐᵦ(β) = L(β̄)ₐᵦ - ρₐᵦ`, each kept only if it lowers `|e|²`.
fn gauss_newton<T: Real>(l: &[[T; 10]; 6], rho: &[T; 6], mut b: [T; 4]) -> [T; 4] {
    let products = |b: &[T; 4]| -> [T; 10] {
        let [b1, b2, b3, b4] = *b;
        [
            b1 * b1,
            b1 * b2,
            b2 * b2,
            b1 * b3,
            b2 * b3,
            b3 * b3,
            b1 * b4,
            b2 * b4,
            b3 * b4,
            b4 * b4,
        ]
    };
    let cost = |b: &[T; 4]| -> T {
        let p = products(b);
        l.iter()
            .zip(rho)
            .map(|(row, r)| {
                let e = row.iter().zip(&p).fold(T::zero(), |a, (x, y)| a + *x * *y) - *r;
                e * e
            })
            .fold(T::zero(), |a, e| a + e)
    };
    let mut c = cost(&b);
    for _ in 0..BETA_GAUSS_NEWTON_ITERATIONS {
        if !above(c, T::zero()) {
            break;
        }
        let p = products(&b);
        let [b1, b2, b3, b4] = b;
        let two = T::lit(2.0);
        let mut qr = StreamingQr::<T, 5>::new();
        let mut ok = true;
        for (row, r) in l.iter().zip(rho) {
            let [l0, l1, l2, l3, l4, l5, l6, l7, l8, l9] = *row;
            let e = row.iter().zip(&p).fold(T::zero(), |a, (x, y)| a + *x * *y) - *r;
            let j = [
                two * l0 * b1 + l1 * b2 + l3 * b3 + l6 * b4,
                l1 * b1 + two * l2 * b2 + l4 * b3 + l7 * b4,
                l3 * b1 + l4 * b2 + two * l5 * b3 + l8 * b4,
                l6 * b1 + l7 * b2 + l8 * b3 + two * l9 * b4,
                -e,
            ];
            ok &= qr.push_row(&j).is_ok();
        }
        let Some(d) = ok.then(|| back_substitute(qr.r())).flatten() else {
            break;
        };
        let [d1, d2, d3, d4, _]: [T; 5] = d.into();
        let cand = [b1 + d1, b2 + d2, b3 + d3, b4 + d4];
        let nc = cost(&cand);
        if nc < c {
            b = cand;
            c = nc;
        } else {
            break;
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use std::vec::Vec;

    fn random_scene(g: &mut Pcg32, n: usize) -> (Pose<f64>, Vec<Point3<f64>>) {
        let truth = Pose::from_rodrigues(
            Vector3::new(
                g.uniform(-2.0, 2.0),
                g.uniform(-2.0, 2.0),
                g.uniform(-2.0, 2.0),
            ),
            Vector3::new(
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
            ),
        )
        .unwrap();
        let inv = truth.inverse();
        let world = (0..n)
            .map(|_| {
                let z = g.uniform(2.0, 6.0);
                inv.apply(&Point3::new(
                    g.uniform(-0.7, 0.7) * z,
                    g.uniform(-0.5, 0.5) * z,
                    z,
                ))
            })
            .collect();
        (truth, world)
    }

    fn project(p: &Pose<f64>, x: &Point3<f64>) -> Point2<f64> {
        let c = p.apply(x);
        Point2::new(c.x / c.z, c.y / c.z)
    }

    #[test]
    fn exact_data_gives_the_true_pose() {
        let mut g = Pcg32::new(21);
        let mut worst = (0.0f64, 0.0f64);
        for k in 0..300 {
            let n = 4 + k % 30;
            let (truth, world) = random_scene(&mut g, n);
            let img: Vec<_> = world.iter().map(|x| project(&truth, x)).collect();
            let (pose, rms) = epnp(&world, &img).unwrap();
            let r = (pose.isometry().rotation * truth.isometry().rotation.inverse()).angle();
            let t = (pose.translation() - truth.translation()).norm() / truth.translation().norm();
            worst = (worst.0.max(r), worst.1.max(t));
            assert!(rms < 1e-9, "{n} {rms}");
        }
        // Exact data: the null space is exact (σ₁₂ ~ 1e-16) and Gauss-Newton on the betas
        // converges to rounding; 1e-8 allows for the worst conditioning among 300 scenes.
        assert!(worst.0 < 1e-8 && worst.1 < 1e-8, "{worst:?}");
    }

    #[test]
    fn noisy_data_and_f32() {
        let mut g = Pcg32::new(22);
        let mut sum = 0.0;
        for _ in 0..100 {
            let (truth, world) = random_scene(&mut g, 50);
            // 1 px at f = 500.
            let img: Vec<_> = world
                .iter()
                .map(|x| {
                    let u = project(&truth, x);
                    Point2::new(u.x + 0.002 * g.normal(), u.y + 0.002 * g.normal())
                })
                .collect();
            let (pose, _) = epnp(&world, &img).unwrap();
            sum += (pose.isometry().rotation * truth.isometry().rotation.inverse())
                .angle()
                .to_degrees();
            let w32: Vec<_> = world.iter().map(|p| p.cast::<f32>()).collect();
            let i32: Vec<_> = img.iter().map(|p| p.cast::<f32>()).collect();
            let (p32, _) = epnp(&w32, &i32).unwrap();
            let d = (p32.isometry().rotation.cast::<f64>() * pose.isometry().rotation.inverse())
                .angle()
                .to_degrees();
            // f32 vs f64 on the same data: far below the noise-induced error.
            assert!(d < 0.05, "{d} deg");
        }
        // 1 px noise, 50 points over a ±35° field at depth 2..6: EPnP's mean rotation error is
        // a few hundredths of a degree to a tenth; 0.3° bounds it.
        assert!(sum / 100.0 < 0.3, "{}", sum / 100.0);
    }

    #[test]
    fn bad_inputs() {
        let w = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        let u = [Point2::new(0.0, 0.0); 4];
        assert_eq!(epnp(&w, &u).unwrap_err(), Error::Degenerate);
        assert_eq!(epnp(&w[..3], &u[..3]).unwrap_err(), Error::TooFewPoints);
        assert_eq!(epnp(&w, &u[..3]).unwrap_err(), Error::LengthMismatch);
        let mut nan = w;
        nan[1].z = f64::NAN;
        assert_eq!(epnp(&nan, &u).unwrap_err(), Error::NonFinite);
        // Garbage image points: any result but no panic.
        let mut g = Pcg32::new(3);
        for _ in 0..200 {
            let w: [Point3<f64>; 6] =
                core::array::from_fn(|_| Point3::new(g.normal(), g.normal(), g.normal()));
            let u: [Point2<f64>; 6] = core::array::from_fn(|_| Point2::new(g.normal(), g.normal()));
            let _ = epnp(&w, &u);
            let _ = epnp(&w.map(|p| p.cast::<f32>()), &u.map(|p| p.cast::<f32>()));
        }
    }
}
