//! A generic, allocation-free RANSAC loop (MSAC scoring, adaptive stopping, local optimisation).
//!
//! A problem plugs in through [`Estimator`]: a minimal solver over index samples, a squared
//! residual per data point, and optional least-squares refits. [`ransac`] then runs
//!
//! 1. draw a minimal sample of `s` distinct indices (Floyd's algorithm, seeded [`Pcg32`]),
//! 2. reject it if [`Estimator::is_sample_valid`] says so, else solve it,
//! 3. score each model by MSAC (Torr & Zisserman 2000): `C = Σᵢ min(rᵢ², t²)`, lower is better,
//!    or, per [`Estimator::scoring`], by the number of inliers with `C` breaking ties, or both
//!    side by side with the winner picked by how much of the band the noise fills,
//! 4. on a new best model, locally optimise it (Chum et al., LO-RANSAC 2003, with the iterated
//!    least squares of Lebeda et al. 2012): refit with [`Estimator::refit`] on its inliers at a
//!    threshold shrinking from `m t` to `t`, keeping refits that rank better, and lower the
//!    iteration budget to `N = ⌈log(1 - p) / log(1 - wˢ)⌉` for inlier ratio `w` and confidence `p`,
//! 5. stop after `min(N, max_iterations)` samples, then polish the best model once with
//!    [`Estimator::refine`] (e.g. Levenberg-Marquardt) and write its inlier mask.
//!
//! The same loop serves homographies ([`crate::homography::find_homography`]), fundamental and
//! essential matrices ([`crate::twoview`]) and PnP ([`crate::pose::solve_pnp_ransac`]): only the
//! [`Estimator`] changes.
//!
//! A line `y = a x + b` through points with outliers, as a minimal [`Estimator`]:
//!
//! ```
//! use camgeom::ransac::{Estimator, RansacParams, ransac};
//!
//! struct Line<'a>(&'a [[f32; 2]]);
//! impl Estimator for Line<'_> {
//!     type Model = [f32; 2]; // (a, b)
//!     type Scalar = f32;
//!     fn num_points(&self) -> usize { self.0.len() }
//!     fn sample_size(&self) -> usize { 2 }
//!     fn fit_minimal(&self, s: &[usize], emit: &mut dyn FnMut([f32; 2])) {
//!         let ([x0, y0], [x1, y1]) = (self.0[s[0]], self.0[s[1]]);
//!         if x1 != x0 {
//!             let a = (y1 - y0) / (x1 - x0);
//!             emit([a, y0 - a * x0]);
//!         }
//!     }
//!     fn residual_sq(&self, [a, b]: &[f32; 2], i: usize) -> Option<f32> {
//!         let [x, y] = *self.0.get(i)?;
//!         Some((y - a * x - b).powi(2))
//!     }
//! }
//!
//! // y = 2x + 1 at x = 0..20, with every fifth point thrown 50 units off it.
//! let pts: [[f32; 2]; 20] = core::array::from_fn(|i| {
//!     let x = i as f32;
//!     [x, 2.0 * x + 1.0 + if i % 5 == 0 { 50.0 } else { 0.0 }]
//! });
//! let mut mask = [false; 20];
//! let ([a, b], report) = ransac(&Line(&pts), &RansacParams::default(), &mut mask)?;
//! assert!((a - 2.0).abs() < 1e-5 && (b - 1.0).abs() < 1e-4);
//! assert_eq!(report.inliers, 16);
//! assert!(mask.iter().enumerate().all(|(i, &m)| m == (i % 5 != 0)));
//! # Ok::<(), camgeom::Error>(())
//! ```

use crate::rng::Pcg32;
use crate::scalar::{Real, larger};
use crate::{Error, Result};

/// Largest minimal sample an [`Estimator`] may ask for (the 8-point algorithm).
pub const MAX_SAMPLE_SIZE: usize = 8;

/// Most models a minimal solver may return per sample (the 5-point essential solver's 10);
/// extra models are ignored.
pub const MAX_MODELS_PER_SAMPLE: usize = 10;

/// How [`ransac`] ranks two models (and accepts a local-optimisation refit or the final
/// polish).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Scoring {
    /// The lower MSAC cost `Σᵢ min(rᵢ², t²)` wins (Torr & Zisserman 2000).
    #[default]
    Msac,
    /// More inliers (`rᵢ² < t²`) win; equal counts go to the lower MSAC cost (COLMAP's
    /// default support measure). Ranks better than MSAC when the noise fills the band
    /// (`σ ≳ t / 2`): the residual inside the band then carries more noise than information
    /// about the model, and weighting inliers by `t² - rᵢ²` only adds variance. Worse when
    /// `σ ≪ t`: a model bent to take in one more point beats the exact one.
    InlierCount,
    /// Both rankings side by side (each with its own local optimisation); the result is the
    /// MSAC winner when its inliers' mean squared residual is below `(t/4)²` (the noise well
    /// inside the band), else the [`Scoring::InlierCount`] winner. The iteration budget
    /// follows the larger inlier count.
    Adaptive,
}

impl Scoring {
    /// Whether support `a` (MSAC cost, inlier count) ranks strictly above `b`.
    pub fn better<T: Real>(self, a: (T, usize), b: (T, usize)) -> bool {
        match self {
            Self::Msac => a.0 < b.0,
            Self::InlierCount => a.1 > b.1 || (a.1 == b.1 && a.0 < b.0),
            // The adaptive ranking decides between two winners at the end; pairwise it
            // ranks by MSAC.
            Self::Adaptive => a.0 < b.0,
        }
    }
}

/// A model-fitting problem over `num_points` data points addressed by index.
pub trait Estimator {
    /// The estimated model (e.g. a homography and its inverse).
    type Model: Clone;
    /// Scalar type of residuals.
    type Scalar: Real;

    /// Number of data points.
    fn num_points(&self) -> usize;

    /// Size `s` of a minimal sample, `1..=MAX_SAMPLE_SIZE`.
    fn sample_size(&self) -> usize;

    /// Cheap test run before [`Self::fit_minimal`] (degenerate samples); default: accept all.
    fn is_sample_valid(&self, _sample: &[usize]) -> bool {
        true
    }

    /// Solves the minimal sample (`sample.len() == sample_size()`), passing every solution to
    /// `emit` (none if the sample is degenerate).
    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Self::Model));

    /// Squared residual of point `i` under `model`, in the units of the threshold squared;
    /// `None` when it cannot be evaluated (e.g. the point maps to infinity): an outlier.
    fn residual_sq(&self, model: &Self::Model, i: usize) -> Option<Self::Scalar>;

    /// Non-minimal least-squares fit on the points with `inliers[i]` (local optimisation);
    /// `None` to skip. Default: none.
    fn refit(&self, _model: &Self::Model, _inliers: &[bool]) -> Option<Self::Model> {
        None
    }

    /// Whether [`Self::refit`] depends on the inlier mask only (a linear fit such as a DLT), not
    /// on the model it starts from (an iterative fit). Local optimisation then skips a refit of
    /// a mask it has just refitted. Default: `false`.
    fn refit_is_mask_only(&self) -> bool {
        false
    }

    /// Final polish of the best model on its inliers (e.g. nonlinear least squares); `None`
    /// to keep it. Default: none.
    fn refine(&self, _model: &Self::Model, _inliers: &[bool]) -> Option<Self::Model> {
        None
    }

    /// How models are ranked. Default: [`Scoring::Msac`].
    fn scoring(&self) -> Scoring {
        Scoring::Msac
    }
}

/// Parameters of [`ransac`], as the user writes them; checked by [`Self::check`] into the
/// [`RansacParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RansacConfig<T: Real = f32> {
    /// Inlier threshold `t` on the residual (`r² < t²`), in data units (pixels), `> 0` with a
    /// finite `t²`.
    pub threshold: T,
    /// Probability `p` of having drawn at least one all-inlier sample when the loop stops
    /// early, in `(0, 1]` (`1`: never stop early, run `max_iterations` samples).
    pub confidence: T,
    /// Hard cap on the samples drawn (degenerate ones included), `≥ 1`. Bounds the run time.
    pub max_iterations: u32,
    /// Refit rounds of local optimisation per new best model (0 disables it).
    pub local_optimization: u8,
    /// Local optimisation starts refitting on the inliers at `multiplier · threshold` and
    /// shrinks to `threshold` over its rounds; `≥ 1` (1: always at the threshold).
    pub lo_threshold_multiplier: T,
    /// Whether to apply [`Estimator::refine`] to the final model.
    pub refine: bool,
    /// Seed of the sampler: the same seed and data give the same result on every target.
    pub seed: u64,
}

impl<T: Real> Default for RansacConfig<T> {
    /// `t = 3` px (OpenCV's default), `p = 0.995`, at most 2000 samples, 4 refit rounds from
    /// `3 t` down to `t`, refinement on.
    fn default() -> Self {
        Self {
            threshold: T::lit(3.0),
            confidence: T::lit(0.995),
            max_iterations: 2000,
            local_optimization: 4,
            lo_threshold_multiplier: T::lit(3.0),
            refine: true,
            seed: 0x5eed_ca4e_0000_0001,
        }
    }
}

impl<T: Real> RansacConfig<T> {
    /// Checks the ranges documented on each field once: [`ransac`] and the robust estimators
    /// built on it take the checked [`RansacParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field (`ransac.threshold`,
    /// `ransac.confidence`, `ransac.max_iterations`, `ransac.lo_threshold_multiplier`).
    pub fn check(&self) -> Result<RansacParams<T>> {
        let (zero, one) = (T::zero(), T::one());
        let checks = [
            (
                // Its square is the bound residuals are compared with: it must be finite too.
                (self.threshold * self.threshold).finite() && self.threshold > zero,
                "ransac.threshold",
            ),
            (
                self.confidence > zero && self.confidence <= one,
                "ransac.confidence",
            ),
            (
                self.lo_threshold_multiplier.finite() && self.lo_threshold_multiplier >= one,
                "ransac.lo_threshold_multiplier",
            ),
            (self.max_iterations > 0, "ransac.max_iterations"),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, name)) => Err(Error::InvalidParameter(name)),
            None => Ok(RansacParams(*self)),
        }
    }
}

/// A [`RansacConfig`] that passed [`RansacConfig::check`]: a threshold `t > 0` with a finite
/// `t²`, a confidence in `(0, 1]`, at least one sample, a finite local-optimisation multiplier
/// `≥ 1`. What [`ransac`], [`find_homography`](crate::homography::find_homography), the
/// [`twoview`](crate::twoview) estimators and
/// [`solve_pnp_ransac`](crate::pose::solve_pnp_ransac) take, so that no call checks it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RansacParams<T: Real = f32>(RansacConfig<T>);

impl<T: Real> RansacParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &RansacConfig<T> {
        &self.0
    }

    /// `config` taken as checked without checking it: only for the `Default` of a checked
    /// configuration that embeds a RANSAC configuration other than [`RansacConfig::default`]
    /// (a test of that configuration checks its default).
    pub(crate) const fn assume_checked(config: RansacConfig<T>) -> Self {
        Self(config)
    }
}

impl<T: Real> Default for RansacParams<T> {
    /// The checked [`RansacConfig::default`].
    fn default() -> Self {
        Self(RansacConfig::default())
    }
}

impl<T: Real> TryFrom<RansacConfig<T>> for RansacParams<T> {
    type Error = Error;
    fn try_from(c: RansacConfig<T>) -> Result<Self> {
        c.check()
    }
}

/// What [`ransac`] found besides the model.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RansacReport<T: Real = f32> {
    /// Number of inliers of the returned model (`true` entries of the mask).
    pub inliers: usize,
    /// MSAC cost `Σ min(r², t²)` of the returned model (whatever the [`Scoring`]).
    pub cost: T,
    /// Samples drawn.
    pub iterations: u32,
}

/// Runs RANSAC (see the module docs) and writes the returned model's inlier mask into `mask`.
///
/// Errors: [`Error::LengthMismatch`] if `mask.len() != num_points()`,
/// [`Error::InvalidParameter`] for a sample size outside `1..=MAX_SAMPLE_SIZE`,
/// [`Error::TooFewPoints`] with fewer points than a sample, [`Error::Degenerate`] when no
/// sample produced a model.
pub fn ransac<T: Real, E: Estimator<Scalar = T>>(
    estimator: &E,
    params: &RansacParams<T>,
    mask: &mut [bool],
) -> Result<(E::Model, RansacReport<T>)> {
    let config = params.config();
    let n = estimator.num_points();
    let s = estimator.sample_size();
    if mask.len() != n {
        return Err(Error::LengthMismatch);
    }
    if s == 0 || s > MAX_SAMPLE_SIZE {
        return Err(Error::InvalidParameter("sample_size"));
    }
    if n < s {
        return Err(Error::TooFewPoints);
    }
    let t2 = config.threshold * config.threshold;
    let scoring = estimator.scoring();
    let mut rng = Pcg32::new(config.seed);
    // The best model of each ranking: (model, MSAC cost, inliers). `Adaptive` runs both.
    let (first, second) = match scoring {
        Scoring::Msac => (Scoring::Msac, None),
        Scoring::InlierCount => (Scoring::InlierCount, None),
        Scoring::Adaptive => (Scoring::Msac, Some(Scoring::InlierCount)),
    };
    let mut best: Option<(E::Model, T, usize)> = None;
    let mut best_second: Option<(E::Model, T, usize)> = None;
    let mut budget = config.max_iterations;
    let mut iterations = 0u32;
    let mut sample_buf = [0usize; MAX_SAMPLE_SIZE];

    while iterations < budget {
        iterations += 1;
        let Some(sample) = sample_buf
            .get_mut(..s)
            .and_then(|buf| draw_sample(&mut rng, n, buf))
        else {
            return Err(Error::InvalidParameter("sample_size"));
        };
        if !estimator.is_sample_valid(sample) {
            continue;
        }
        let mut models: heapless::Vec<E::Model, MAX_MODELS_PER_SAMPLE> = heapless::Vec::new();
        estimator.fit_minimal(sample, &mut |m| {
            // A full buffer drops the extra solutions: documented on the constant.
            let _ = models.push(m);
        });
        // The support each ranking must beat; a model that can no longer beat any of them is
        // dropped part-way through scoring ([`score_bounded`]).
        let tracks = 1 + usize::from(second.is_some());
        for model in models.iter() {
            let rivals = [
                best.as_ref().map(|b| (first, b.1, b.2)),
                second.and_then(|o| best_second.as_ref().map(|b| (o, b.1, b.2))),
            ];
            let bounds = rivals.get(..tracks).unwrap_or(&[]);
            let Some((cost, count)) = score_bounded(estimator, model, t2, bounds) else {
                continue;
            };
            let tracks = [(&mut best, Some(first)), (&mut best_second, second)];
            for (slot, order) in tracks {
                let Some(order) = order else {
                    continue;
                };
                if slot
                    .as_ref()
                    .is_some_and(|b| !order.better((cost, count), (b.1, b.2)))
                {
                    continue;
                }
                let current = local_optimisation(
                    estimator,
                    config,
                    order,
                    (model.clone(), cost, count),
                    mask,
                );
                budget = budget.min(iterations_needed(
                    current.2,
                    n,
                    s,
                    config.confidence,
                    config.max_iterations,
                ));
                *slot = Some(current);
            }
        }
    }

    // `Adaptive`: the MSAC winner while the noise sits well inside the band (its inliers'
    // mean squared residual below `(t/4)²`), else the inlier-count winner.
    let (chosen, order) = match (second, best, best_second) {
        (Some(order), Some(m), Some(c)) => {
            let in_band = m.1 - T::lit((n - m.2.min(n)) as f64) * t2;
            if m.2 > 0 && in_band * T::lit(16.0) < T::lit(m.2 as f64) * t2 {
                (Some(m), first)
            } else {
                (Some(c), order)
            }
        }
        (_, b, _) => (b, first),
    };
    let Some((mut model, mut cost, count)) = chosen else {
        mask.iter_mut().for_each(|m| *m = false);
        return Err(Error::Degenerate);
    };
    write_mask(estimator, &model, t2, mask);
    if config.refine
        && let Some(polished) = estimator.refine(&model, mask)
    {
        // Kept unless it scores worse.
        let (c, k) = score(estimator, &polished, t2);
        if !order.better((cost, count), (c, k)) {
            model = polished;
            cost = c;
        }
    }
    let inliers = write_mask(estimator, &model, t2, mask);
    Ok((
        model,
        RansacReport {
            inliers,
            cost,
            iterations,
        },
    ))
}

/// Local optimisation by iterated least squares (Lebeda, Matas & Chum 2012) of a new best
/// model `(model, cost, inliers)`: refit on the inliers at a threshold shrinking from `m t` to
/// `t`, so noisy true inliers just beyond `t` still pull the fit; a refit is kept only if it
/// ranks better under `order` at `t`. Uses `mask` as scratch.
// Never inlined: it runs only on a new best model, and kept out of the sampling loop it leaves
// that loop's registers alone (on the Cortex-M7 the homography stage costs 4 % more when it
// is inlined; BENCHMARKS.md).
#[inline(never)]
fn local_optimisation<T: Real, E: Estimator<Scalar = T>>(
    estimator: &E,
    config: &RansacConfig<T>,
    order: Scoring,
    mut current: (E::Model, T, usize),
    mask: &mut [bool],
) -> (E::Model, T, usize) {
    let one = T::one();
    let t2 = config.threshold * config.threshold;
    let rounds = config.local_optimization;
    // After a refit: whether it replaced `current`. `mask` then holds the mask it was fitted on.
    let mut last: Option<bool> = None;
    for k in 0..rounds {
        let m = config.lo_threshold_multiplier;
        let frac = if rounds > 1 {
            T::lit(f64::from(k)) / T::lit(f64::from(rounds - 1))
        } else {
            one
        };
        let tk = config.threshold * (m - (m - one) * frac);
        let changed = rewrite_mask(estimator, &current.0, tk * tk, mask);
        // The same mask as the last refit's and the same start (the refit was rejected, or
        // the fit ignores its start): the refit would reproduce a model already ranked, and
        // leave `current` as it is. Skipping it changes no result.
        if let Some(accepted) = last
            && !changed
            && (!accepted || estimator.refit_is_mask_only())
        {
            continue;
        }
        let Some(refit) = estimator.refit(&current.0, mask) else {
            break;
        };
        let (c, k) = score(estimator, &refit, t2);
        let accepted = order.better((c, k), (current.1, current.2));
        if accepted {
            current = (refit, c, k);
        }
        last = Some(accepted);
    }
    current
}

/// [`write_mask`] that also says whether any entry changed.
fn rewrite_mask<E: Estimator>(e: &E, model: &E::Model, t2: E::Scalar, mask: &mut [bool]) -> bool {
    let mut changed = false;
    for (i, m) in mask.iter_mut().enumerate() {
        let new = e.residual_sq(model, i).is_some_and(|r| r < t2);
        changed |= new != *m;
        *m = new;
    }
    changed
}

/// `⌈log(1 - p) / log(1 - wˢ)⌉` samples for inlier ratio `w = inliers / n`, capped at `cap`.
pub fn iterations_needed<T: Real>(inliers: usize, n: usize, s: usize, p: T, cap: u32) -> u32 {
    if n == 0 || inliers == 0 {
        return cap;
    }
    let w = T::lit(inliers as f64) / T::lit(n as f64);
    let ws = w.powi(i32::try_from(s).unwrap_or(i32::MAX));
    if ws >= T::one() {
        return 1.min(cap);
    }
    let denom = (T::one() - ws).ln();
    if denom >= T::zero() {
        // 1 - wˢ rounds to 1: no finite number of samples reaches the confidence.
        return cap;
    }
    let k = ((T::one() - p).ln() / denom).ceil();
    // Compared and converted in `T` and `f32`, never through `f64` (software on a
    // single-precision FPU): at or above the cap → the cap (a cap rounded up in `f32` gives
    // the same, through the saturating `as` and the clamp); NaN fails the comparison and
    // `as` maps it to 0 (then at least one sample), as it does a negative `k`.
    let cap = cap.max(1);
    if k >= nalgebra::convert::<f32, T>(cap as f32) {
        return cap;
    }
    let k: f32 = nalgebra::convert_unchecked(k);
    (k as u32).clamp(1, cap)
}

/// MSAC cost and inlier count of a model.
fn score<T: Real, E: Estimator<Scalar = T>>(e: &E, model: &E::Model, t2: T) -> (T, usize) {
    let mut cost = T::zero();
    let mut count = 0;
    for i in 0..e.num_points() {
        match e.residual_sq(model, i) {
            Some(r) if r < t2 => {
                cost += r;
                count += 1;
            }
            _ => cost += t2,
        }
    }
    (cost, count)
}

/// [`score`], or `None` as soon as the model cannot rank above any of `rivals` (each a
/// ranking with the support of its best model so far; `None` there: no model yet, so
/// everything is scored in full).
///
/// Exact, not a heuristic: every point adds a non-negative amount (`r²` or `t²`) to the cost,
/// and floating-point addition of a non-negative term never lowers a non-negative sum, so a
/// partial cost already at the rival's is final-or-worse; the inlier count can grow by at
/// most the points left. A model dropped here would have lost every comparison in full.
///
/// The rivals are reduced once to two bounds: the MSAC cost a model must stay under to beat
/// every cost ranking's best (the largest of their costs), and the outliers it may have to
/// beat every inlier-count ranking's best (the largest `n - best_count`; at exactly that many,
/// the cost decides). They are tested at outliers only, where the outlier count moves: a model
/// that turns hopeless at an inlier is dropped at the next outlier, or scored in full and then
/// loses the comparison in [`ransac`]; either way the result is the same.
fn score_bounded<T: Real, E: Estimator<Scalar = T>>(
    e: &E,
    model: &E::Model,
    t2: T,
    rivals: &[Option<(Scoring, T, usize)>],
) -> Option<(T, usize)> {
    let n = e.num_points();
    if rivals.iter().any(Option::is_none) {
        return Some(score(e, model, t2));
    }
    // `None`: no rival of that kind, the condition holds.
    let mut cost_bound: Option<T> = None;
    let mut count_bound: Option<(usize, T)> = None;
    for &(order, best_cost, best_count) in rivals.iter().flatten() {
        match order {
            Scoring::Msac | Scoring::Adaptive => {
                cost_bound = Some(cost_bound.map_or(best_cost, |c| larger(c, best_cost)));
            }
            Scoring::InlierCount => {
                let allowed = n.saturating_sub(best_count);
                count_bound = Some(match count_bound {
                    Some((a, c)) if (a, c) > (allowed, best_cost) => (a, c),
                    _ => (allowed, best_cost),
                });
            }
        }
    }
    let hopeless = |cost: T, outliers: usize| {
        cost_bound.is_none_or(|c| cost >= c)
            && count_bound
                .is_none_or(|(allowed, c)| outliers > allowed || (outliers == allowed && cost >= c))
    };
    let mut cost = T::zero();
    let mut count = 0;
    for i in 0..n {
        match e.residual_sq(model, i) {
            Some(r) if r < t2 => {
                cost += r;
                count += 1;
            }
            _ => {
                cost += t2;
                if hopeless(cost, i + 1 - count) {
                    return None;
                }
            }
        }
    }
    Some((cost, count))
}

/// Writes `mask[i] = r_i² < t²`; returns the number of inliers.
fn write_mask<E: Estimator>(e: &E, model: &E::Model, t2: E::Scalar, mask: &mut [bool]) -> usize {
    let mut count = 0;
    for (i, m) in mask.iter_mut().enumerate() {
        *m = e.residual_sq(model, i).is_some_and(|r| r < t2);
        count += usize::from(*m);
    }
    count
}

/// `out.len()` distinct uniform indices in `0..n` by Floyd's algorithm: exactly `out.len()`
/// draws, no rejection of repeats. `None` if `out` is longer than `n` or `n` exceeds `u32`.
fn draw_sample<'a>(rng: &mut Pcg32, n: usize, out: &'a mut [usize]) -> Option<&'a [usize]> {
    let k = out.len();
    if k > n {
        return None;
    }
    // For j = n-k .. n-1: pick t uniform in 0..=j; take t unless already taken, else take j.
    for (filled, j) in ((n - k)..n).enumerate() {
        let t = rng.below(u32::try_from(j + 1).ok()?) as usize;
        let pick = if out.get(..filled)?.contains(&t) {
            j
        } else {
            t
        };
        *out.get_mut(filled)? = pick;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1-D "line through the origin" toy problem: y = a x, minimal sample of one point.
    struct Slope<'a> {
        x: &'a [f64],
        y: &'a [f64],
    }

    impl Estimator for Slope<'_> {
        type Model = f64;
        type Scalar = f64;
        fn num_points(&self) -> usize {
            self.x.len()
        }
        fn sample_size(&self) -> usize {
            1
        }
        fn is_sample_valid(&self, s: &[usize]) -> bool {
            self.x[s[0]] != 0.0
        }
        fn fit_minimal(&self, s: &[usize], emit: &mut dyn FnMut(f64)) {
            emit(self.y[s[0]] / self.x[s[0]]);
        }
        fn residual_sq(&self, a: &f64, i: usize) -> Option<f64> {
            let r = self.y[i] - a * self.x[i];
            Some(r * r)
        }
        fn refit(&self, _: &f64, inliers: &[bool]) -> Option<f64> {
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for ((x, y), _) in self.x.iter().zip(self.y).zip(inliers).filter(|(_, m)| **m) {
                sxy += x * y;
                sxx += x * x;
            }
            (sxx > 0.0).then(|| sxy / sxx)
        }
    }

    #[test]
    fn finds_the_slope_among_outliers() {
        let mut g = Pcg32::new(99);
        let x: [f64; 100] = core::array::from_fn(|i| i as f64 - 50.0);
        let y: [f64; 100] = core::array::from_fn(|i| {
            if i % 3 == 0 {
                g.uniform(-100.0, 100.0)
            } else {
                2.5 * x[i] + 0.01 * g.normal()
            }
        });
        let est = Slope { x: &x, y: &y };
        let mut mask = [false; 100];
        let cfg = RansacConfig {
            threshold: 0.1,
            ..Default::default()
        }
        .check()
        .unwrap();
        let (a, report) = ransac(&est, &cfg, &mut mask).unwrap();
        assert!((a - 2.5).abs() < 1e-3, "{a}");
        assert!(report.inliers >= 66 && report.inliers == mask.iter().filter(|m| **m).count());
        assert!(report.iterations < 50, "{}", report.iterations);
        // Deterministic.
        let mut mask2 = [false; 100];
        assert_eq!(ransac(&est, &cfg, &mut mask2).unwrap(), (a, report));
        assert_eq!(mask, mask2);
    }

    #[test]
    fn bounded_scoring_drops_only_models_that_lose() {
        // Random residual tables against random rivals: whenever `score_bounded` gives up,
        // the full score loses to every rival under its ranking; otherwise it is the full
        // score, bit for bit.
        let mut g = Pcg32::new(7);
        let t2 = 1.0;
        let mut dropped = 0;
        for _ in 0..2000 {
            let n = 1 + g.below(40) as usize;
            let x: std::vec::Vec<f64> = (0..n).map(|_| 1.0).collect();
            let y: std::vec::Vec<f64> = (0..n)
                .map(|_| {
                    if g.uniform(0.0, 1.0) < 0.5 {
                        g.uniform(-1.0, 1.0)
                    } else {
                        g.uniform(-5.0, 5.0)
                    }
                })
                .collect();
            let est = Slope { x: &x, y: &y };
            let full = score(&est, &0.0, t2);
            let rival = |g: &mut Pcg32, order| {
                let count = g.below(n as u32 + 1) as usize;
                Some((order, g.uniform(0.0, n as f64), count))
            };
            let orders = [Scoring::Msac, Scoring::InlierCount, Scoring::Adaptive];
            let a = orders[g.below(3) as usize];
            let rivals = [rival(&mut g, a), rival(&mut g, Scoring::InlierCount)];
            let k = 1 + g.below(2) as usize;
            match score_bounded(&est, &0.0, t2, &rivals[..k]) {
                Some(got) => assert_eq!(got, full),
                None => {
                    dropped += 1;
                    for (order, c, m) in rivals[..k].iter().flatten() {
                        assert!(!order.better(full, (*c, *m)));
                    }
                }
            }
            assert_eq!(score_bounded(&est, &0.0, t2, &[None]), Some(full));
        }
        // Both outcomes are exercised.
        assert!(dropped > 200 && dropped < 1800, "{dropped}");
    }

    /// Two fixed candidate models over a table of squared residuals: model 0 has three
    /// inliers at `r² = exact` (and a lower MSAC cost), model 1 five at `r² = 0.81 t²`.
    struct Table {
        scoring: Scoring,
        exact: f64,
    }

    impl Estimator for Table {
        type Model = usize;
        type Scalar = f64;
        fn num_points(&self) -> usize {
            7
        }
        fn sample_size(&self) -> usize {
            1
        }
        fn fit_minimal(&self, s: &[usize], emit: &mut dyn FnMut(usize)) {
            emit(s[0] % 2);
        }
        fn residual_sq(&self, m: &usize, i: usize) -> Option<f64> {
            let e = self.exact;
            let r = [
                [e, e, e, 4.0, 4.0, 4.0, 4.0],
                [0.81, 0.81, 0.81, 0.81, 0.81, 4.0, 4.0],
            ];
            r.get(*m)?.get(i).copied()
        }
        fn scoring(&self) -> Scoring {
            self.scoring
        }
    }

    #[test]
    fn scoring_ranks_by_cost_or_by_count() {
        let cfg = RansacConfig {
            threshold: 1.0,
            confidence: 1.0,
            max_iterations: 50,
            ..RansacConfig::default()
        }
        .check()
        .unwrap();
        let run = |scoring, exact| {
            let mut mask = [false; 7];
            let (m, rep) = ransac(&Table { scoring, exact }, &cfg, &mut mask).unwrap();
            assert_eq!(rep.inliers, mask.iter().filter(|m| **m).count());
            (m, rep.inliers, rep.cost)
        };
        // MSAC: 3 · 0 + 4 t² = 4 beats 5 · 0.81 + 2 t² = 6.05; the count ranking takes the
        // five inliers.
        assert_eq!(run(Scoring::Msac, 0.0), (0, 3, 4.0));
        let (m, k, c) = run(Scoring::InlierCount, 0.0);
        assert_eq!((m, k), (1, 5));
        assert!((c - 6.05).abs() < 1e-12);
        // Adaptive: exact inliers (noise well inside the band) keep the MSAC winner; inliers
        // at 0.5 t² (the band full of noise) give the count winner.
        assert_eq!(run(Scoring::Adaptive, 0.0), (0, 3, 4.0));
        assert_eq!(run(Scoring::Adaptive, 0.01).0, 0);
        assert_eq!(run(Scoring::Adaptive, 0.5).0, 1);
        assert_eq!(run(Scoring::Msac, 0.5).0, 0);
        // Equal counts: the lower cost wins.
        assert!(Scoring::InlierCount.better((1.0f64, 5), (2.0, 5)));
        assert!(!Scoring::InlierCount.better((1.0f64, 4), (2.0, 5)));
        assert!(!Scoring::Msac.better((2.0f64, 5), (2.0, 4)));
    }

    #[test]
    fn parameters_are_validated() {
        let x = [1.0, 2.0];
        let y = [2.0, 4.0];
        let est = Slope { x: &x, y: &y };
        let mut mask = [false; 2];
        let ok = RansacConfig::<f64>::default();
        assert_eq!(ok.check(), Ok(RansacParams::default()));
        let params = RansacParams::try_from(ok).unwrap();
        assert!(ransac(&est, &params, &mut mask).is_ok());
        assert_eq!(
            ransac(&est, &params, &mut [false; 3]).unwrap_err(),
            Error::LengthMismatch
        );
        for (bad, name) in [
            (
                RansacConfig {
                    threshold: 0.0,
                    ..ok
                },
                "ransac.threshold",
            ),
            (
                RansacConfig {
                    threshold: f64::NAN,
                    ..ok
                },
                "ransac.threshold",
            ),
            (
                RansacConfig {
                    threshold: 1e160,
                    ..ok
                },
                "ransac.threshold",
            ),
            (
                RansacConfig {
                    confidence: 1.5,
                    ..ok
                },
                "ransac.confidence",
            ),
            (
                RansacConfig {
                    lo_threshold_multiplier: 0.5,
                    ..ok
                },
                "ransac.lo_threshold_multiplier",
            ),
            (
                RansacConfig {
                    max_iterations: 0,
                    ..ok
                },
                "ransac.max_iterations",
            ),
        ] {
            assert_eq!(bad.check(), Err(Error::InvalidParameter(name)));
            assert_eq!(
                RansacParams::try_from(bad),
                Err(Error::InvalidParameter(name))
            );
        }
        // Confidence 1 means "never stop early" once there is an outlier: exactly
        // max_iterations samples.
        let (x3, y3) = ([1.0, 2.0, 3.0], [2.0, 4.0, 100.0]);
        let est3 = Slope { x: &x3, y: &y3 };
        let all = RansacConfig {
            confidence: 1.0,
            max_iterations: 37,
            ..ok
        }
        .check()
        .unwrap();
        let mut mask3 = [false; 3];
        assert_eq!(ransac(&est3, &all, &mut mask3).unwrap().1.iterations, 37);
        // Every sample degenerate.
        let zeros = [0.0, 0.0];
        let est = Slope { x: &zeros, y: &y };
        assert_eq!(
            ransac(&est, &params, &mut mask).unwrap_err(),
            Error::Degenerate
        );
        let est = Slope { x: &[], y: &[] };
        assert_eq!(
            ransac(&est, &params, &mut []).unwrap_err(),
            Error::TooFewPoints
        );
    }

    #[test]
    fn iteration_count_formula() {
        // w = 0.5, s = 4, p = 0.99: log(0.01) / log(1 - 1/16) = 71.4 -> 72.
        assert_eq!(iterations_needed(50, 100, 4, 0.99f64, 10_000), 72);
        assert_eq!(iterations_needed(50, 100, 4, 0.99f32, 10_000), 72);
        assert_eq!(iterations_needed(100, 100, 4, 0.99f64, 10_000), 1);
        assert_eq!(iterations_needed(0, 100, 4, 0.99f64, 500), 500);
        // w = 1e-3: 1 - w⁴ rounds to 1 in f32.
        assert_eq!(iterations_needed(1, 1000, 4, 0.99f32, 777), 777);
        assert_eq!(iterations_needed(10, 100, 8, 0.999f64, 300), 300);
    }

    #[test]
    fn samples_are_distinct_and_uniform() {
        let mut g = Pcg32::new(5);
        let mut counts = [0u32; 10];
        let mut buf = [0usize; 4];
        for _ in 0..10_000 {
            let s = draw_sample(&mut g, 10, &mut buf).unwrap();
            for (i, a) in s.iter().enumerate() {
                assert!(*a < 10);
                assert!(!s[..i].contains(a));
                counts[*a] += 1;
            }
        }
        // Each index appears in 40% of the samples: 4000 ± 4.5σ (σ ≈ 49).
        for c in counts {
            assert!((3780..4220).contains(&c), "{c}");
        }
        assert!(draw_sample(&mut g, 3, &mut buf).is_none());
        let all = draw_sample(&mut g, 4, &mut buf).unwrap();
        let mut sorted = [0usize; 4];
        sorted.copy_from_slice(all);
        sorted.sort_unstable();
        assert_eq!(sorted, [0, 1, 2, 3]);
    }
}
