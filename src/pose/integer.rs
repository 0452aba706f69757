//! Planar pose with integer per-point arithmetic, for cores without an FPU.
//!
//! On a soft-float core every `f32` multiply is a library call (~40 instructions on a
//! Cortex-M3), and the float refinement ([`super::refine_pose`]) spends ~8k of them a point and
//! iteration: the projection through the lens model, its Jacobian, and two Givens sweeps of the
//! streaming QR. Here the per-point work is integer and the float work is per iteration:
//!
//! - **Frame.** The model is centred on its centroid `c` and scaled by its radius `s`:
//!   `qᵢ = (mᵢ - c) / s`, `|qᵢ| ≤ 1`, stored once as Q4.28 with the undistorted normalised
//!   observation `oᵢ` ([`PlanarPoint`]). A pose is held as its rotation `R` and the camera-frame
//!   centroid `C = R c + t`; everything is divided by the centroid's depth `d = C_z`, so a point
//!   is `Xᵢ = A qᵢ + b` with `A = (s/d) R[:, 0..2]` and `b = C / d` (`b_z = 1`).
//! - **Per point (integer).** `P = A q`, `Z = P_z + 1`, `x = (P_x + b_x) / Z`, `y` likewise;
//!   the residual `e = W (x - o)` with `W = diag(f_x, f_y) / max(f_x, f_y)` (errors in ideal
//!   pixels, up to the common factor); and for a step `(δω, δb)` that rotates about the centroid
//!   (`X ← exp([δω]ₓ)(X - b) + b + δb`, which keeps rotation and translation apart) the rows
//!
//!   `∂x = W₁₁/Z [-x P_y, P_z + x P_x, -P_y, 1, 0, -x]`,
//!   `∂y = W₂₂/Z [-y P_y - P_z, y P_x, P_x, 0, 1, -y]`,
//!
//!   accumulated exactly into `G = JᵀJ` and `g = Jᵀe` in `i64` (Q20 Jacobian, Q24 residuals).
//! - **Per iteration (`f64`).** The damped normal equations are solved by Cholesky in `f64`
//!   ([`GramSystem`]); `G` is exact, so the squared condition costs nothing an `f32` QR would
//!   not. The step updates `R ← exp([δω]ₓ) R` ([`rotation_step`]) and `C ← C + d δb` in `f32`.
//!
//! **Range.** Every product is bounded so no `i64` sum can wrap for up to [`MAX_PLANAR_POINTS`]
//! points: the target's radius at most 3/4 of the centroid's depth (`s/d ≤ 3/4`, so every point
//! lies deeper than a quarter of it), and every projection and observation within 4 normalised
//! units of the optical axis (76° off axis). A pose outside is undefined for the refinement (a
//! step there is refused); a start outside is [`Error::Overflow`].
//!
//! **What it minimises.** The error in the undistorted image (ideal pixels), where the float
//! path ([`super::solve_planar`]) measures it in the distorted one: the two agree for a pinhole
//! camera and differ by the lens' local change of scale otherwise (a few percent of the noise
//! for moderate distortion). `tests` and the host's box-sequence test bound the difference.

use nalgebra::{Point2, Rotation3, SVector, Vector3};

use super::PoseEstimate;
use super::ippe::{PlanarConfig, PlanarPose, from_homography, pick};
use crate::camera::Camera;
use crate::homography::Homography;
use crate::linalg::lm::{self, GramSystem, LeastSquares};
use crate::linalg::{hypot, rotation_step};
use crate::scalar::check_finite;
use crate::transform::Pose;
use crate::{Error, Result};

/// Fraction bits of positions (Q4.28).
const F: u32 = 28;
/// One in Q4.28.
const ONE: i64 = 1 << F;
/// Bits dropped from a Q4.28 Jacobian entry scaled by `W/Z` (Q4.28): Q20 entries.
const J_SHIFT: u32 = F + 8;
/// Bits dropped from Q4.28 residuals for the sums: Q24.
const E_SHIFT: u32 = 4;
/// Fraction bits of the pixel-aspect weights.
const W_BITS: u32 = 15;
/// Largest normalised coordinate of a projection or an observation.
const MAX_NORMALIZED: i64 = 4 * ONE;
/// Largest target radius over centroid depth, `s/d`.
const MAX_ANGULAR_SIZE: f32 = 0.75;

/// `√ε` of `f32` (`2⁻¹¹·⁵`), the float path's stopping tolerance.
const F32_SQRT_EPSILON: f64 = 3.452_669_830_012_439_3e-4;

/// Most point pairs one refinement takes: with the range above, the `i64` sums of `G`
/// (`2·2⁴⁸` a point), `g` and the cost (`2⁵⁵` a point) stay below `2⁶³`.
pub const MAX_PLANAR_POINTS: usize = 256;

/// One point pair in the integer refinement's format: the model point centred and scaled,
/// `q = (m - c) / s`, and its undistorted normalised observation `o`, both Q4.28.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlanarPoint {
    q: [i32; 2],
    o: [i32; 2],
}

impl PlanarPoint {
    /// All zeros (a `const` initialiser for scratch in a `static`).
    pub const ZERO: Self = Self {
        q: [0; 2],
        o: [0; 2],
    };
}

/// `round(v 2²⁸)` for `|v| ≤ 4`; `None` beyond (or NaN).
fn q28(v: f32) -> Option<i32> {
    (v.abs() <= 4.0).then(|| libm::roundf(v * ONE as f32) as i32)
}

/// The integer form of the model: its centroid, its radius and the pixel-aspect weights.
#[derive(Debug, Clone, Copy)]
struct Model {
    centroid: Vector3<f32>,
    radius: f32,
    /// `(f_x, f_y) / max(f_x, f_y)`, Q15.
    weights: [i64; 2],
    /// `max(f_x, f_y)`: one normalised unit in ideal pixels.
    focal: f32,
}

/// A pose as the refinement moves it: the rotation and the camera-frame centroid `C = R c + t`.
#[derive(Debug, Clone, Copy)]
struct State {
    rotation: Rotation3<f32>,
    centre: Vector3<f32>,
}

/// `A` and `b` of the module docs for one pose, Q4.28.
struct Frame {
    /// Rows of `A`'s first two columns.
    a: [[i32; 2]; 3],
    b: [i32; 2],
}

/// One point's projection: `P`, `1/Z`, `x`, `y` (Q4.28) and the weighted residuals (Q4.28,
/// up to `2³¹`).
struct Projected {
    p: [i32; 3],
    iz: i32,
    x: i32,
    y: i32,
    e: [i64; 2],
}

/// `a b` widened: one multiply-long on Arm (`SMULL`/`SMLAL`), two instructions on RV32IM.
#[inline(always)]
fn mul(a: i32, b: i32) -> i64 {
    i64::from(a) * i64::from(b)
}

/// `⌊2⁵⁶ / z⌋` (Q4.28 of `1/Z`) for `2²⁶ ≤ z < 2³¹`, to within 2 units, without a 64-bit
/// division (a library call of 100-300 instructions on 32-bit cores): `z` is normalised to
/// `x ∈ [½, 1)`, `1/x` starts from the minimax line `48/17 - 32/17 x` (error below 1/17) and
/// three Newton steps `r ← r (2 - x r)` square the error each (below 2⁻³⁰ after them), in
/// Q2.30 with 32 x 32 → 64-bit products.
fn reciprocal(z: i32) -> Option<i32> {
    if z < 1 << 26 {
        return None;
    }
    let z = z.unsigned_abs();
    // x = z 2^s in [2³⁰, 2³¹): Q31 of a value in [½, 1).
    let s = z.leading_zeros() - 1;
    let x = u64::from(z << s);
    // Q30: 48/17 and 32/17.
    let mut r = 3_031_741_621u64 - ((2_021_161_081u64 * x) >> 31);
    for _ in 0..3 {
        // x r in Q61 → Q30; 2 - x r in Q30 (positive: x r < 2 throughout).
        let e = (2u64 << 30).saturating_sub((x * r) >> 31);
        r = (r * e) >> 30;
    }
    // r ≈ 2⁶¹ / (z 2^s) in Q30 units, so 2⁵⁶ / z = r 2^(s - 5).
    let q = if s >= 5 { r << (s - 5) } else { r >> (5 - s) };
    i32::try_from(q).ok()
}

impl Model {
    fn state(&self, pose: &Pose<f32>) -> State {
        let rotation = pose.rotation();
        State {
            rotation,
            centre: rotation * self.centroid + pose.translation(),
        }
    }

    fn pose(&self, s: &State) -> Result<Pose<f32>> {
        Pose::new(s.rotation, s.centre - s.rotation * self.centroid)
    }

    fn frame(&self, s: &State) -> Option<Frame> {
        let d = s.centre.z;
        let k = self.radius / d;
        if !(d > 0.0 && k <= MAX_ANGULAR_SIZE) {
            return None;
        }
        let m = s.rotation.matrix();
        let q = |v: f32| q28(k * v);
        Some(Frame {
            a: [
                [q(m.m11)?, q(m.m12)?],
                [q(m.m21)?, q(m.m22)?],
                [q(m.m31)?, q(m.m32)?],
            ],
            b: [q28(s.centre.x / d)?, q28(s.centre.y / d)?],
        })
    }

    /// The projection of one point, `None` outside the range of the module docs.
    fn project(&self, f: &Frame, pt: &PlanarPoint) -> Option<Projected> {
        let [qx, qy] = pt.q;
        // |A| ≤ 3/4, |q| ≤ 1: every product below 2⁵⁶, every P below 3/4 (2²⁸ units).
        let p =
            f.a.map(|[a0, a1]| ((mul(a0, qx) + mul(a1, qy)) >> F) as i32);
        // |P| ≤ 3/4 |q|: Z ≥ 1/4, so 1/Z ≤ 4 (Q4.28 below 2³⁰).
        let iz = reciprocal(p[2] + ONE as i32)?;
        // |P + b| < 4.75 (2²⁸ units), 1/Z ≤ 2³⁰: below 2⁶¹; |x| ≤ 4 is checked before the
        // narrowing.
        let x = (mul(p[0] + f.b[0], iz)) >> F;
        let y = (mul(p[1] + f.b[1], iz)) >> F;
        if x.abs() > MAX_NORMALIZED || y.abs() > MAX_NORMALIZED {
            return None;
        }
        let (x, y) = (x as i32, y as i32);
        let [ox, oy] = pt.o;
        let e = [
            ((i64::from(x) - i64::from(ox)) * self.weights[0]) >> W_BITS,
            ((i64::from(y) - i64::from(oy)) * self.weights[1]) >> W_BITS,
        ];
        Some(Projected { p, iz, x, y, e })
    }
}

/// The refinement problem over the pairs in `points`.
struct Problem<'a> {
    model: Model,
    points: &'a [PlanarPoint],
}

impl Problem<'_> {
    /// `Σ |eᵢ|²` in Q48 (weighted normalised units).
    fn cost_q48(&self, s: &State) -> Option<i64> {
        let f = self.model.frame(s)?;
        let mut c = 0i64;
        for pt in self.points {
            let pr = self.model.project(&f, pt)?;
            let [ex, ey] = pr.e.map(|e| e >> E_SHIFT);
            c += ex * ex + ey * ey;
        }
        Some(c)
    }

    /// RMS error in ideal pixels of a Q48 cost.
    fn rms_px(&self, cost_q48: f64) -> f32 {
        let n = self.points.len().max(1) as f64;
        let mean = cost_q48 / (1u64 << (2 * (F - E_SHIFT))) as f64 / n;
        libm::sqrt(mean) as f32 * self.model.focal
    }
}

impl LeastSquares<f64, 6> for Problem<'_> {
    type Params = State;
    type System = GramSystem<6>;

    fn cost(&self, s: &State) -> Option<f64> {
        self.cost_q48(s).map(|c| c as f64)
    }

    fn linearise(&self, s: &State) -> Option<GramSystem<6>> {
        let f = self.model.frame(s)?;
        let [wx, wy] = self.model.weights;
        let mut gram = [[0i64; 6]; 6];
        let mut grad = [0i64; 6];
        for pt in self.points {
            let Projected { p, iz, x, y, e } = self.model.project(&f, pt)?;
            let [px, py, pz] = p;
            let one = ONE as i32;
            // W/Z below 2³⁰ (Q4.28).
            let (sx, sy) = (
                ((i64::from(iz) * wx) >> W_BITS) as i32,
                ((i64::from(iz) * wy) >> W_BITS) as i32,
            );
            // Entries below 4 (Q4.28, 2³⁰): |x| ≤ 4, |P| ≤ 3/4.
            let xp = |a: i32, b: i32| ((mul(a, b)) >> F) as i32;
            let rows = [
                (
                    sx,
                    [-xp(x, py), pz + xp(x, px), -py, one, 0, -x],
                    (e[0] >> E_SHIFT) as i32,
                ),
                (
                    sy,
                    [-xp(y, py) - pz, xp(y, px), px, 0, one, -y],
                    (e[1] >> E_SHIFT) as i32,
                ),
            ];
            for (scale, entries, r) in rows {
                // Entries below 2³⁰ times W/Z below 2³⁰: Q20 entries below 2²⁴.
                let j = entries.map(|v| (mul(v, scale) >> J_SHIFT) as i32);
                for (k, ((row, gk), &jk)) in gram.iter_mut().zip(&mut grad).zip(&j).enumerate() {
                    for (g, &jl) in row.iter_mut().zip(&j).skip(k) {
                        *g += mul(jk, jl);
                    }
                    *gk += mul(jk, r);
                }
            }
        }
        // G in Q40, g in Q44 (Q20 · Q24); the upper triangle was summed.
        let (qg, qb) = (1.0 / (1u64 << 40) as f64, 1.0 / (1u64 << 44) as f64);
        let mut out = GramSystem {
            gram: [[0.0; 6]; 6],
            gradient: grad.map(|v| v as f64 * qb),
        };
        for (k, row) in gram.iter().enumerate() {
            for (l, v) in row.iter().enumerate().skip(k) {
                let v = *v as f64 * qg;
                if let Some(x) = out.gram.get_mut(k).and_then(|r| r.get_mut(l)) {
                    *x = v;
                }
                if let Some(x) = out.gram.get_mut(l).and_then(|r| r.get_mut(k)) {
                    *x = v;
                }
            }
        }
        Some(out)
    }

    fn step(&self, s: &State, d: &SVector<f64, 6>) -> Option<State> {
        let [w1, w2, w3, b1, b2, b3]: [f64; 6] = (*d).into();
        let w = Vector3::new(w1 as f32, w2 as f32, w3 as f32);
        let shift = Vector3::new(b1 as f32, b2 as f32, b3 as f32) * s.centre.z;
        let next = State {
            rotation: rotation_step(&w) * s.rotation,
            centre: s.centre + shift,
        };
        next.centre.iter().all(|v| v.is_finite()).then_some(next)
    }

    fn tolerance(&self) -> f64 {
        // The float path's, √ε of f32 (= 2⁻¹¹·⁵), so both stop at the same relative decrease.
        F32_SQRT_EPSILON
    }
}

/// Fills `scratch` with the pairs `(model[i], normalized[i])` in the integer format and
/// returns the model's frame. Errors: [`Error::LengthMismatch`] (also for `scratch` shorter
/// than the pairs); [`Error::TooFewPoints`] below 3; [`Error::InvalidParameter`] above
/// [`MAX_PLANAR_POINTS`]; [`Error::NonFinite`]; [`Error::Degenerate`] for a model of one point;
/// [`Error::Overflow`] for an observation beyond the range.
fn load(
    model: &[Point2<f32>],
    normalized: impl ExactSizeIterator<Item = Result<Point2<f32>>>,
    focal: [f32; 2],
    scratch: &mut [PlanarPoint],
) -> Result<Model> {
    let n = model.len();
    if normalized.len() != n || scratch.len() < n {
        return Err(Error::LengthMismatch);
    }
    if n < 3 {
        return Err(Error::TooFewPoints);
    }
    if n > MAX_PLANAR_POINTS {
        return Err(Error::InvalidParameter("points"));
    }
    check_finite(&focal)?;
    let fmax = focal[0].max(focal[1]);
    if !(focal[0] > 0.0 && focal[1] > 0.0) {
        return Err(Error::InvalidIntrinsics);
    }
    let mut c = Vector3::zeros();
    for p in model {
        check_finite(&[p.x, p.y])?;
        c += Vector3::new(p.x, p.y, 0.0);
    }
    c /= n as f32;
    let radius = model
        .iter()
        .map(|p| hypot(p.x - c.x, p.y - c.y))
        .fold(0.0f32, f32::max);
    // Coincident points (to f32 rounding of their centroid) have no extent to turn.
    if !(radius > 1e-5 * (c.norm() + radius) && radius.is_finite()) {
        return Err(Error::Degenerate);
    }
    for ((slot, m), o) in scratch.iter_mut().zip(model).zip(normalized) {
        let o = o?;
        check_finite(&[o.x, o.y])?;
        let q = [(m.x - c.x) / radius, (m.y - c.y) / radius];
        *slot = PlanarPoint {
            q: [
                q28(q[0]).ok_or(Error::Overflow)?,
                q28(q[1]).ok_or(Error::Overflow)?,
            ],
            o: [
                q28(o.x).ok_or(Error::Overflow)?,
                q28(o.y).ok_or(Error::Overflow)?,
            ],
        };
    }
    let weight = |f: f32| libm::roundf(f / fmax * (1 << W_BITS) as f32) as i64;
    Ok(Model {
        centroid: c,
        radius,
        weights: [weight(focal[0]), weight(focal[1])],
        focal: fmax,
    })
}

/// Refines one start; its RMS error in ideal pixels.
fn refine(problem: &Problem<'_>, start: &Pose<f32>, iterations: u8) -> Result<PoseEstimate<f32>> {
    let state = problem.model.state(start);
    let m = lm::minimise(problem, state, iterations)?.ok_or(Error::Overflow)?;
    let rms_px = problem.rms_px(m.final_cost);
    if !rms_px.is_finite() {
        // An error beyond f32 in pixels (a focal length near f32::MAX).
        return Err(Error::NonFinite);
    }
    Ok(PoseEstimate {
        pose: problem.model.pose(&m.params)?,
        rms_px,
    })
}

/// A pose unrefined, with its RMS error in ideal pixels: infinite outside the range.
fn evaluate(problem: &Problem<'_>, pose: &Pose<f32>) -> PoseEstimate<f32> {
    let c = problem.cost_q48(&problem.model.state(pose));
    PoseEstimate {
        pose: *pose,
        rms_px: c.map_or(f32::INFINITY, |c| problem.rms_px(c as f64)),
    }
}

/// Levenberg-Marquardt refinement of the pose of a planar target (`Z = 0`) from `start`, at
/// most `max_iterations` steps, on the error `W (π(R mᵢ + t) - oᵢ)` in ideal pixels between
/// the projections and the undistorted normalised observations `normalized` (`focal =
/// [f_x, f_y]`), with integer per-point arithmetic (the module docs). `scratch` holds the pairs
/// in integer form (at least `model.len()`).
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 3 pairs;
/// [`Error::InvalidParameter`] (`points`) above [`MAX_PLANAR_POINTS`]; [`Error::NonFinite`];
/// [`Error::InvalidIntrinsics`] for a focal length that is not positive; [`Error::NonFinite`]
/// also for an error beyond `f32` in pixels;
/// [`Error::Degenerate`] when every model point is the same; [`Error::Overflow`] for
/// observations or a start outside the range of the module docs.
pub fn refine_planar_integer(
    model: &[Point2<f32>],
    normalized: &[Point2<f32>],
    focal: [f32; 2],
    start: &Pose<f32>,
    scratch: &mut [PlanarPoint],
    max_iterations: u8,
) -> Result<PoseEstimate<f32>> {
    let m = load(model, normalized.iter().map(|p| Ok(*p)), focal, scratch)?;
    let points = scratch.get(..model.len()).ok_or(Error::LengthMismatch)?;
    refine(&Problem { model: m, points }, start, max_iterations)
}

/// The pose of a planar target seen through `camera`, as [`super::solve_planar`] but for
/// cores without an FPU: both IPPE solutions from `hint` (a homography from the model plane to
/// the pixels, e.g. RANSAC's over these pairs), each refined over all pairs by
/// [`refine_planar_integer`] (the second only when it is within
/// [`PlanarConfig::alternative_ratio`] of the first). Errors are RMS in ideal pixels.
///
/// The starts come from four points only: the corners of the model's bounding box mapped by
/// `hint` and undistorted give the homography to normalised coordinates that IPPE decomposes,
/// with no DLT and no SVD; the float path's DLT over every pair is most of its cost on a
/// soft-float core. The refinement makes up the difference.
///
/// Errors: as [`refine_planar_integer`]; as [`Homography::from_four_points`] and
/// [`super::ippe()`] for a hint that maps the box to a degenerate quadrilateral; as
/// [`Camera::undistort_to_normalized`].
pub fn solve_planar_integer(
    camera: &Camera<f32>,
    hint: &Homography<f32>,
    model: &[Point2<f32>],
    pixels: &[Point2<f32>],
    scratch: &mut [PlanarPoint],
    cfg: &PlanarConfig,
) -> Result<PlanarPose<f32>> {
    if model.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    let k = &camera.intrinsics;
    let normalized = pixels.iter().map(|u| camera.undistort_to_normalized(u));
    let m = load(model, normalized, [k.fx(), k.fy()], scratch)?;
    let points = scratch.get(..model.len()).ok_or(Error::LengthMismatch)?;
    let problem = Problem { model: m, points };
    // The bounding box of the model, through the hint, undistorted.
    let (mut lo, mut hi) = (
        Point2::new(f32::MAX, f32::MAX),
        Point2::new(f32::MIN, f32::MIN),
    );
    for p in model {
        (lo.x, lo.y) = (lo.x.min(p.x), lo.y.min(p.y));
        (hi.x, hi.y) = (hi.x.max(p.x), hi.y.max(p.y));
    }
    let boxed = [lo, Point2::new(hi.x, lo.y), hi, Point2::new(lo.x, hi.y)];
    let mut seen = [Point2::origin(); 4];
    for (s, b) in seen.iter_mut().zip(&boxed) {
        *s = camera.undistort_to_normalized(&hint.transfer(b)?)?;
    }
    let h = Homography::from_four_points(&boxed, &seen)?;
    let centre = Vector3::new((lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5, 0.0);
    let [(s0, _), (s1, _)] = from_homography(&h, &centre, &boxed, &seen)?;
    // Order the starts by their error over every pair, then refine. A start outside the range
    // (the far solution of a steep view can put points behind the camera) has an infinite
    // error: it is reported unrefined, and never refined.
    let (e0, e1) = (evaluate(&problem, &s0), evaluate(&problem, &s1));
    let (first, second) = if e0.rms_px <= e1.rms_px {
        (e0, e1)
    } else {
        (e1, e0)
    };
    let iterations = cfg.refine_iterations;
    let a = refine(&problem, &first.pose, iterations)?;
    pick(a, second, cfg, |p| refine(&problem, p, iterations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Distortion, Intrinsics};
    use crate::homography::dlt;
    use crate::pose::solve_planar;
    use crate::rng::Pcg32;

    /// A 0.1 m target, 8x4 points, seen from 0.3-0.5 m: the board's box lid.
    fn model() -> [Point2<f32>; 32] {
        core::array::from_fn(|k| {
            Point2::new(0.1 * (k % 8) as f32 / 7.0, 0.06 * (k / 8) as f32 / 3.0)
        })
    }

    fn truths() -> [Pose<f32>; 3] {
        [
            Pose::from_rodrigues(
                Vector3::new(0.3, -0.2, 0.1),
                Vector3::new(-0.05, -0.03, 0.35),
            ),
            Pose::from_rodrigues(Vector3::new(-0.6, 0.4, 1.2), Vector3::new(0.02, -0.04, 0.5)),
            Pose::from_rodrigues(
                Vector3::new(0.05, 0.02, -0.4),
                Vector3::new(-0.05, -0.02, 0.45),
            ),
        ]
        .map(|p| p.unwrap())
    }

    fn rot_deg(a: &Pose<f32>, b: &Pose<f32>) -> f32 {
        (a.isometry().rotation.inverse() * b.isometry().rotation)
            .angle()
            .to_degrees()
    }

    fn rel_t(a: &Pose<f32>, b: &Pose<f32>) -> f32 {
        (a.translation() - b.translation()).norm() / b.translation().norm()
    }

    fn observe(
        cam: &Camera<f32>,
        truth: &Pose<f32>,
        sigma: f32,
        g: &mut Pcg32,
    ) -> [Point2<f32>; 32] {
        model().map(|m| {
            let u = cam
                .project(truth, &nalgebra::Point3::new(m.x, m.y, 0.0))
                .unwrap();
            Point2::new(
                u.x + sigma * g.normal() as f32,
                u.y + sigma * g.normal() as f32,
            )
        })
    }

    fn pinhole() -> Camera<f32> {
        Camera::pinhole(Intrinsics::new(520.0, 515.0, 320.0, 240.0).unwrap())
    }

    #[test]
    fn tolerance_is_the_float_paths() {
        assert_eq!(F32_SQRT_EPSILON, libm::sqrt(f64::from(f32::EPSILON)));
    }

    #[test]
    fn reciprocal_is_the_division_to_two_units() {
        let mut worst = 0i64;
        let mut z = 1i64 << 26;
        while z < i64::from(i32::MAX) {
            for d in [0, 1, 7, 12345] {
                let zz = (z + d).min(i64::from(i32::MAX)) as i32;
                let exact = (1i64 << 56) / i64::from(zz);
                worst = worst.max((i64::from(reciprocal(zz).unwrap()) - exact).abs());
            }
            z = z * 1001 / 1000 + 1;
        }
        assert!(worst <= 2, "{worst}");
        assert_eq!(reciprocal((1 << 26) - 1), None);
        assert_eq!(reciprocal(-5), None);
    }

    #[test]
    fn exact_data_converge_to_the_truth() {
        let cam = pinhole();
        let mut g = Pcg32::new(1);
        for truth in truths() {
            let pixels = observe(&cam, &truth, 0.0, &mut g);
            let normalized = pixels.map(|u| cam.undistort_to_normalized(&u).unwrap());
            let start = Pose::new(
                rotation_step(&Vector3::new(0.03, -0.02, 0.02)) * truth.rotation(),
                truth.translation() + Vector3::new(0.01, -0.005, 0.02),
            )
            .unwrap();
            let mut scratch = [PlanarPoint::ZERO; 32];
            let k = &cam.intrinsics;
            let est = refine_planar_integer(
                &model(),
                &normalized,
                [k.fx(), k.fy()],
                &start,
                &mut scratch,
                20,
            )
            .unwrap();
            // Q4.28 positions (4e-9 normalised, 2e-6 px) and f32 pose arithmetic (6e-8):
            // the truth to f32 rounding of the pixels (~3e-5 px at 320 px).
            assert!(est.rms_px < 1e-3, "{est:?}");
            assert!(
                rot_deg(&est.pose, &truth) < 2e-3,
                "{}",
                rot_deg(&est.pose, &truth)
            );
            assert!(
                rel_t(&est.pose, &truth) < 2e-5,
                "{}",
                rel_t(&est.pose, &truth)
            );
        }
    }

    /// The float and the integer planar pose of the model seen at `pixels`, default settings,
    /// the integer path's hint the DLT over every pair.
    fn both_paths(cam: &Camera<f32>, pixels: &[Point2<f32>; 32]) -> (PlanarPose, PlanarPose) {
        let cfg = PlanarConfig::default();
        let mut fs = [Point2::origin(); 32];
        let float = solve_planar(cam, &model(), pixels, &mut fs, &cfg).unwrap();
        let hint = dlt(&model(), pixels).unwrap();
        let mut is = [PlanarPoint::ZERO; 32];
        let int = solve_planar_integer(cam, &hint, &model(), pixels, &mut is, &cfg).unwrap();
        (float, int)
    }

    /// With a pinhole camera both paths minimise the same pixel error: the integer path's pose
    /// is the float path's to within their arithmetic (a thousandth of the noise's effect).
    #[test]
    fn matches_the_float_path_on_a_pinhole_camera() {
        let cam = pinhole();
        let mut g = Pcg32::new(7);
        for truth in truths() {
            for _ in 0..10 {
                let pixels = observe(&cam, &truth, 0.5, &mut g);
                let (float, int) = both_paths(&cam, &pixels);
                let (dr, dt) = (
                    rot_deg(&int.best.pose, &float.best.pose),
                    rel_t(&int.best.pose, &float.best.pose),
                );
                // Both reach the same minimum: the RMS errors agree to 1e-4 (measured 6e-6). The
                // poses agree to 1e-3 deg and 2e-5 of the distance on most draws; where the
                // noise leaves the rotation poorly determined (the steep view, 2-5 deg from the
                // truth) the valley is flat, and the two LMs, stopping at the same relative
                // decrease from different starts, end up to 7 % of that error apart (one draw:
                // 0.127 deg at 1.85 deg from the truth, RMS errors 3e-6 apart); bound 10 %.
                let noise = rot_deg(&float.best.pose, &truth);
                assert!(
                    dr < 0.005 + 0.1 * noise && dt < 2e-4,
                    "{dr} deg, {dt}, noise {noise}"
                );
                let drms = (int.best.rms_px - float.best.rms_px).abs();
                assert!(drms < 1e-4 * float.best.rms_px, "{drms}");
            }
        }
    }

    /// With lens distortion the integer path measures the error in the undistorted image: the
    /// poses differ by a fraction of what the noise does to either.
    #[test]
    fn stays_near_the_float_path_with_distortion() {
        let k = Intrinsics::new(535.9f32, 535.9, 342.3, 235.6).unwrap();
        let d = Distortion::from_opencv([-0.266, -0.0386, 1.78e-3, -2.81e-4, 0.238]).unwrap();
        let cam = Camera::new(k, d);
        let mut g = Pcg32::new(3);
        let (mut err_int, mut err_float) = (0.0f32, 0.0f32);
        for truth in truths() {
            for _ in 0..10 {
                let pixels = observe(&cam, &truth, 0.5, &mut g);
                let (float, int) = both_paths(&cam, &pixels);
                let (dr, dt) = (
                    rot_deg(&int.best.pose, &float.best.pose),
                    rel_t(&int.best.pose, &float.best.pose),
                );
                let noise = rot_deg(&float.best.pose, &truth);
                // Strong barrel distortion (k₁ = -0.27) changes the local scale by up to ~20 %
                // across this target: measured up to 0.18 deg apart where the noise moves the
                // pose 0.94 deg, 3e-4 of the distance.
                assert!(
                    dr < 0.02 + 0.25 * noise && dt < 1e-3,
                    "{dr} deg, {dt}, noise {noise}"
                );
                err_int += rot_deg(&int.best.pose, &truth);
                err_float += noise;
            }
        }
        // Neither weighting is the better estimator here: the sums of rotation errors over the
        // 30 draws are within 5 % of each other.
        assert!(
            (err_int - err_float).abs() < 0.05 * err_float,
            "{err_int} vs {err_float}"
        );
    }

    #[test]
    fn ambiguous_fronto_parallel_target_is_flagged() {
        let cam = pinhole();
        let small: [Point2<f32>; 4] = [
            Point2::new(-0.02, -0.02),
            Point2::new(0.02, -0.02),
            Point2::new(0.02, 0.02),
            Point2::new(-0.02, 0.02),
        ];
        let truth = Pose::from_rodrigues(Vector3::new(0.05, 0.0, 0.0), Vector3::new(0.0, 0.0, 2.0))
            .unwrap();
        let mut g = Pcg32::new(9);
        let pixels = small.map(|m| {
            let u = cam
                .project(&truth, &nalgebra::Point3::new(m.x, m.y, 0.0))
                .unwrap();
            Point2::new(u.x + 0.3 * g.normal() as f32, u.y + 0.3 * g.normal() as f32)
        });
        let hint = Homography::from_four_points(&small, &pixels).unwrap();
        let mut is = [PlanarPoint::ZERO; 4];
        let sol = solve_planar_integer(
            &cam,
            &hint,
            &small,
            &pixels,
            &mut is,
            &PlanarConfig::default(),
        )
        .unwrap();
        assert!(sol.is_ambiguous(2.0), "{sol:?}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let cam = pinhole();
        let m = model();
        let truth = truths()[0];
        let pixels = observe(&cam, &truth, 0.0, &mut Pcg32::new(2));
        let normalized = pixels.map(|u| cam.undistort_to_normalized(&u).unwrap());
        let mut scratch = [PlanarPoint::ZERO; 32];
        let f = [520.0, 515.0];
        let refine =
            |m: &[Point2<f32>], n: &[Point2<f32>], f, start: &Pose<f32>, s: &mut [PlanarPoint]| {
                refine_planar_integer(m, n, f, start, s, 10)
            };
        assert_eq!(
            refine(&m, &normalized[..31], f, &truth, &mut scratch).err(),
            Some(Error::LengthMismatch)
        );
        assert_eq!(
            refine(&m, &normalized, f, &truth, &mut scratch[..31]).err(),
            Some(Error::LengthMismatch)
        );
        assert_eq!(
            refine(&m[..2], &normalized[..2], f, &truth, &mut scratch).err(),
            Some(Error::TooFewPoints)
        );
        assert_eq!(
            refine(&m, &normalized, [0.0, 1.0], &truth, &mut scratch).err(),
            Some(Error::InvalidIntrinsics)
        );
        let mut nan = normalized;
        nan[3].x = f32::NAN;
        assert_eq!(
            refine(&m, &nan, f, &truth, &mut scratch).err(),
            Some(Error::NonFinite)
        );
        let same = [Point2::new(0.1f32, 0.1); 32];
        assert_eq!(
            refine(&same, &normalized, f, &truth, &mut scratch).err(),
            Some(Error::Degenerate)
        );
        // An observation 80 deg off axis, and a start with the target as wide as it is far.
        let mut far = normalized;
        far[0].x = 5.7;
        assert_eq!(
            refine(&m, &far, f, &truth, &mut scratch).err(),
            Some(Error::Overflow)
        );
        let close = Pose::new(truth.rotation(), Vector3::new(-0.05, -0.03, 0.05)).unwrap();
        assert_eq!(
            refine(&m, &normalized, f, &close, &mut scratch).err(),
            Some(Error::Overflow)
        );
        // Errors beyond f32 in pixels (scrambled pairs seen with a focal length of f32::MAX).
        let mut scrambled = normalized.map(|p| Point2::new(p.y * -20.0, p.x * 20.0));
        scrambled.reverse();
        let huge = [f32::MAX, f32::MAX];
        assert_eq!(
            refine(&m, &scrambled, huge, &truth, &mut scratch).err(),
            Some(Error::NonFinite)
        );
        let many = [Point2::new(0.0f32, 0.0); MAX_PLANAR_POINTS + 1];
        let mut big = [PlanarPoint::ZERO; MAX_PLANAR_POINTS + 1];
        assert_eq!(
            refine(&many, &many, f, &truth, &mut big).err(),
            Some(Error::InvalidParameter("points"))
        );
    }
}
