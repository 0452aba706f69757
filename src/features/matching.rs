//! Brute-force descriptor matching under the Hamming distance (binary ORB descriptors) or the
//! Euclidean distance (float SIFT descriptors), one matching logic for both.
//!
//! `d(a, b) = popcount(a ⊕ b)` over the 256 bits of a [`Descriptor`] (8 `u32` words);
//! `d(a, b) = ‖a − b‖₂` over the 128 values of a [`FloatDescriptor`]
//! ([`match_float_descriptors`], [`match_float_descriptors_guided`]: the same options and
//! semantics, with the ratio test on distances and no distance cap).
//!
//! [`match_descriptors`] compares every query descriptor with every train descriptor — exactly
//! `n_query · n_train` distance computations, whatever the options — and keeps, per query `i`,
//! its nearest train descriptor `j` (the first one on ties) when:
//!
//! - `d₁ <= max_distance`;
//! - Lowe's ratio test: `d₁ < ratio · d₂` with `d₂` the second-nearest distance (skipped when
//!   `ratio >= 1` or there is a single train descriptor);
//! - cross-check: `i` is also the nearest query of `j` (the first one on ties), as
//!   `cv::BFMatcher(NORM_HAMMING, crossCheck = true)`.
//!
//! The reverse nearest neighbours of the cross-check are found in the same pass and kept in
//! caller scratch ([`scratch_len`] `u32` words: distance and index packed), so there is no
//! second pass over the pairs.
//!
//! [`match_descriptors_guided`] does the same among the pairs `(i, j)` a caller's predicate
//! admits, and only those: the nearest, the second-nearest (for the ratio test) and the
//! reverse nearest neighbour are taken over the admitted candidates. Structure from motion
//! admits the pairs that a geometry already verified explains (COLMAP's guided matching): with
//! a fundamental matrix `F` in pixels and the verification's threshold `t`, the pairs of
//! squared Sampson distance
//!
//! `d²(x, y) = (yᵀ F x)² / ((F x)₁² + (F x)₂² + (Fᵀ y)₁² + (Fᵀ y)₂²) < t²`,
//!
//! that is, `y` within about `t` pixels of the epipolar line `F x`; with a homography `H`, the
//! pairs of symmetric transfer error `(|H x − y|² + |H⁻¹ y − x|²) / 2 < t²`. Among the few
//! features near a line the ratio test separates far more matches than among all of an image's
//! (repeated texture elsewhere in the image no longer competes).

use crate::{Error, Result};

/// A 256-bit binary descriptor: bit `i` is bit `i % 32` of word `i / 32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Descriptor(pub [u32; 8]);

/// Hamming distance `popcount(a ⊕ b)`, `0..=256`.
#[inline]
#[doc(alias = "norm")]
#[doc(alias = "NORM_HAMMING")]
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    a.0.iter()
        .zip(b.0.iter())
        .map(|(x, y)| (x ^ y).count_ones())
        .sum()
}

/// Parameters of [`match_descriptors`], as the user writes them; checked by [`Self::check`]
/// into the [`MatchParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchConfig {
    /// Lowe's ratio `r > 0`: keep when `d₁ < r d₂`; `>= 1` disables the test. Default 0.8.
    pub ratio: f32,
    /// Keep only mutual nearest neighbours. Default `true`.
    pub cross_check: bool,
    /// Largest accepted distance. Default 256 (no limit).
    pub max_distance: u16,
}

impl Default for MatchConfig {
    fn default() -> Self {
        Self {
            ratio: 0.8,
            cross_check: true,
            max_distance: 256,
        }
    }
}

impl MatchConfig {
    /// Checks the ratio once: [`match_descriptors`] takes the checked [`MatchParams`].
    ///
    /// Errors: [`Error::InvalidParameter`]`("match.ratio")` for a ratio that is NaN or `≤ 0`
    /// (it would reject every match).
    pub fn check(&self) -> Result<MatchParams> {
        if self.ratio > 0.0 {
            Ok(MatchParams(*self))
        } else {
            Err(Error::InvalidParameter("match.ratio"))
        }
    }
}

/// A [`MatchConfig`] that passed [`MatchConfig::check`]: a ratio `> 0` (`∞` allowed: no test).
/// What [`match_descriptors`] takes, so that no call checks it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchParams(MatchConfig);

impl MatchParams {
    /// The checked configuration.
    pub const fn config(&self) -> &MatchConfig {
        &self.0
    }
}

impl Default for MatchParams {
    /// The checked [`MatchConfig::default`].
    fn default() -> Self {
        Self(MatchConfig::default())
    }
}

impl TryFrom<MatchConfig> for MatchParams {
    type Error = Error;
    fn try_from(c: MatchConfig) -> Result<Self> {
        c.check()
    }
}

/// A match: `query[query]` ↔ `train[train]` at Hamming distance `distance`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Match {
    /// Index into the query descriptors.
    pub query: u16,
    /// Index into the train descriptors.
    pub train: u16,
    /// Hamming distance.
    pub distance: u16,
}

/// `u32` words of scratch [`match_descriptors`] needs for `n_train` train descriptors (one per
/// train descriptor; none without cross-check, but passing them is harmless).
pub const fn scratch_len(n_train: usize) -> usize {
    n_train
}

/// Most descriptors on either side (indices are `u16`).
pub const MAX_DESCRIPTORS: usize = u16::MAX as usize;

/// Matches `query` against `train` (module docs), writing the matches in query order into
/// `out` and returning how many there are.
///
/// `out` must hold `query.len()` matches (the most there can be); `scratch` must hold
/// [`scratch_len`]`(train.len())` words when `config.cross_check`.
///
/// Errors: [`Error::InvalidParameter`] for more than [`MAX_DESCRIPTORS`] descriptors on a
/// side; [`Error::BufferTooSmall`] for a short `scratch`; [`Error::LengthMismatch`]
/// when `out` is shorter than `query`.
#[doc(alias = "BFMatcher")]
#[doc(alias = "NORM_HAMMING")]
pub fn match_descriptors(
    query: &[Descriptor],
    train: &[Descriptor],
    params: &MatchParams,
    scratch: &mut [u32],
    out: &mut [Match],
) -> Result<usize> {
    match_descriptors_guided(query, train, params, |_, _| true, scratch, out)
}

/// [`match_descriptors`] among the pairs `candidate(i, j)` admits (`i` into `query`, `j` into
/// `train`; module docs): per query `i`, the nearest admitted train descriptor `j` (the first
/// on ties) when `d₁ <= max_distance`, `d₁ < ratio · d₂` with `d₂` the second-nearest
/// admitted distance (skipped when `ratio >= 1` or `i` has a single candidate), and, with
/// cross-check, `i` is the nearest admitted query of `j`. A query without candidates has no
/// match. `candidate` is called once per pair, before any distance, so the distances computed
/// are those of the admitted pairs only; a predicate that admits every pair gives
/// [`match_descriptors`] exactly.
///
/// Buffers and errors as [`match_descriptors`].
///
/// ```
/// use camgeom::features::matching::{Descriptor, Match, MatchParams, match_descriptors_guided};
///
/// // Three queries and three train descriptors; train 1 and 2 are query 0 with two bits
/// // flipped: unguided, they are too alike for the ratio test, and nothing else matches.
/// let q = [Descriptor([0; 8]), Descriptor([u32::MAX; 8]), Descriptor([0xFFFF; 8])];
/// let t = [Descriptor([0xF0F0_F0F0; 8]), Descriptor([3, 0, 0, 0, 0, 0, 0, 0]),
///          Descriptor([5, 0, 0, 0, 0, 0, 0, 0])];
/// let (mut out, mut scratch) = ([Match::default(); 3], [0u32; 3]);
/// let p = MatchParams::default();
/// assert_eq!(match_descriptors_guided(&q, &t, &p, |_, _| true, &mut scratch, &mut out)?, 0);
/// // A geometry that puts query 0 near train 1 only (say, its epipolar line) keeps the match.
/// let near = |i: usize, j: usize| (i, j) == (0, 1);
/// let n = match_descriptors_guided(&q, &t, &p, near, &mut scratch, &mut out)?;
/// assert_eq!(out[..n], [Match { query: 0, train: 1, distance: 2 }]);
/// # Ok::<(), camgeom::Error>(())
/// ```
#[doc(alias = "BFMatcher")]
pub fn match_descriptors_guided(
    query: &[Descriptor],
    train: &[Descriptor],
    params: &MatchParams,
    candidate: impl FnMut(usize, usize) -> bool,
    scratch: &mut [u32],
    out: &mut [Match],
) -> Result<usize> {
    let config = params.config();
    let max = u32::from(config.max_distance);
    let ratio = config.ratio;
    let distance = |i: usize, j: usize| match (query.get(i), train.get(j)) {
        (Some(q), Some(t)) => hamming(q, t),
        _ => u32::MAX,
    };
    let sizes = (query.len(), train.len());
    let reverse = Reverse::Packed;
    let keep = |d1: u32, d2: u32| {
        d1 <= max && (ratio >= 1.0 || d2 == u32::MAX || (d1 as f32) < ratio * d2 as f32)
    };
    let make = |i: usize, j: usize, d: u32| Match {
        query: i as u16,
        train: j as u16,
        distance: d as u16,
    };
    let ids = |m: &Match| (usize::from(m.query), usize::from(m.train));
    let core = Core {
        sizes,
        cross_check: config.cross_check,
        reverse,
    };
    core.run(candidate, distance, keep, make, ids, scratch, out)
}

/// Queries matched together by [`Core::run`].
const BLOCK: usize = 32;

/// How [`Core::run`] keeps each train descriptor's nearest query: one `u32` word of distance
/// and index packed (distances below 2¹⁶), or two words (a distance key of 32 bits).
#[derive(Clone, Copy)]
enum Reverse {
    Packed,
    Wide,
}

/// The matching logic shared by the Hamming and the float matchers: sizes, cross-check and the
/// reverse bookkeeping; the distance, the acceptance test (threshold and ratio) and the output
/// type are the caller's.
struct Core {
    sizes: (usize, usize),
    cross_check: bool,
    reverse: Reverse,
}

impl Core {
    /// Per query, the nearest admitted train descriptor under `distance` (a key that orders as
    /// the distance: Hamming counts or the bits of a squared Euclidean distance), kept when
    /// `keep(d₁, d₂)` and, with cross-check, when it is its train descriptor's nearest query.
    #[allow(clippy::too_many_arguments)]
    fn run<M: Copy>(
        &self,
        mut candidate: impl FnMut(usize, usize) -> bool,
        mut distance: impl FnMut(usize, usize) -> u32,
        keep: impl Fn(u32, u32) -> bool,
        make: impl Fn(usize, usize, u32) -> M,
        ids: impl Fn(&M) -> (usize, usize),
        scratch: &mut [u32],
        out: &mut [M],
    ) -> Result<usize> {
        let (nq, nt) = self.sizes;
        if nq > MAX_DESCRIPTORS || nt > MAX_DESCRIPTORS {
            return Err(Error::InvalidParameter("descriptors"));
        }
        if out.len() < nq {
            return Err(Error::LengthMismatch);
        }
        let words = match self.reverse {
            Reverse::Packed => 1,
            Reverse::Wide => 2,
        };
        let reverse: &mut [u32] = if self.cross_check {
            let r = scratch
                .get_mut(..words * nt)
                .ok_or(Error::BufferTooSmall("scratch"))?;
            r.fill(u32::MAX);
            r
        } else {
            &mut []
        };
        let mut n = 0usize;
        // Queries in blocks of `BLOCK`, each block against every train descriptor: a train
        // descriptor is read once a block instead of once a query (the train set of a large
        // image does not fit in cache). Within a block the queries and, per query, the train
        // descriptors are still visited in increasing order, so the ties resolve as unblocked.
        let mut start = 0usize;
        while start < nq {
            let end = (start + BLOCK).min(nq);
            // Per query of the block: nearest and second-nearest distance, nearest index.
            let mut best = [(u32::MAX, u32::MAX, 0usize); BLOCK];
            for j in 0..nt {
                for (i, b) in (start..end).zip(best.iter_mut()) {
                    if !candidate(i, j) {
                        continue;
                    }
                    let d = distance(i, j);
                    if d < b.0 {
                        *b = (d, b.0, j);
                    } else if d < b.1 {
                        b.1 = d;
                    }
                    // Reverse nearest query of j, the smallest distance, the first on ties.
                    match self.reverse {
                        Reverse::Packed => {
                            if let Some(r) = reverse.get_mut(j) {
                                *r = (*r).min((d << 16) | i as u32);
                            }
                        }
                        Reverse::Wide => {
                            if let Some([rd, ri]) = reverse.get_mut(2 * j..2 * j + 2)
                                && d < *rd
                            {
                                (*rd, *ri) = (d, i as u32);
                            }
                        }
                    }
                }
            }
            for (i, &(d1, d2, j1)) in (start..end).zip(best.iter()) {
                // `u32::MAX`: no candidate.
                if d1 == u32::MAX || !keep(d1, d2) {
                    continue;
                }
                if let Some(slot) = out.get_mut(n) {
                    *slot = make(i, j1, d1);
                    n += 1;
                }
            }
            start = end;
        }
        if self.cross_check {
            let mut kept = 0usize;
            for k in 0..n {
                let Some(m) = out.get(k).copied() else { break };
                let (q, t) = ids(&m);
                let nearest = match self.reverse {
                    Reverse::Packed => reverse.get(t).map(|r| (r & 0xffff) as usize),
                    Reverse::Wide => reverse.get(2 * t + 1).map(|&r| r as usize),
                };
                if nearest == Some(q) {
                    if let Some(slot) = out.get_mut(kept) {
                        *slot = m;
                    }
                    kept += 1;
                }
            }
            n = kept;
        }
        Ok(n)
    }
}

/// A 128-value float descriptor ([`super::sift`]'s 4x4x8 gradient histogram), of unit
/// Euclidean length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloatDescriptor(pub [f32; 128]);

impl Default for FloatDescriptor {
    fn default() -> Self {
        Self([0.0; 128])
    }
}

/// Squared Euclidean distance `Σ (aₖ − bₖ)²` (`[0, 4]` for unit descriptors, `[0, 2]` for
/// non-negative ones). Summed in eight lanes, which LLVM keeps in vector registers (measured
/// on x86-64: 21 ns a pair, against 40 ns with 32 lanes and 27 ns with 16).
#[inline]
#[doc(alias = "NORM_L2SQR")]
pub fn l2_squared(a: &FloatDescriptor, b: &FloatDescriptor) -> f32 {
    let mut acc = [0.0f32; 8];
    for (x, y) in a.0.chunks_exact(8).zip(b.0.chunks_exact(8)) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            let d = p - q;
            *s += d * d;
        }
    }
    acc.iter().sum()
}

/// A float-descriptor match: `query[query]` ↔ `train[train]` at Euclidean distance `distance`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FloatMatch {
    /// Index into the query descriptors.
    pub query: u16,
    /// Index into the train descriptors.
    pub train: u16,
    /// Euclidean distance `‖q − t‖`.
    pub distance: f32,
}

/// `u32` words of scratch [`match_float_descriptors`] needs for `n_train` train descriptors
/// (two per train descriptor: a distance and an index; none without cross-check).
pub const fn float_scratch_len(n_train: usize) -> usize {
    2 * n_train
}

/// [`match_descriptors`] for float descriptors under the Euclidean distance (OpenCV's
/// `BFMatcher(NORM_L2)`): per query the nearest train descriptor, kept when Lowe's ratio test
/// `d₁ < ratio · d₂` holds (on distances, not their squares) and, with cross-check, when the
/// match is mutual. [`MatchConfig::max_distance`] (a Hamming bound) is not applied.
///
/// `out` must hold `query.len()` matches; `scratch` [`float_scratch_len`]`(train.len())`
/// words when `cross_check`. Errors as [`match_descriptors`].
///
/// ```
/// use camgeom::features::matching::{FloatDescriptor, FloatMatch, MatchParams};
/// use camgeom::features::matching::{float_scratch_len, match_float_descriptors};
///
/// let unit = |k: usize| {
///     let mut d = FloatDescriptor::default();
///     d.0[k] = 1.0;
///     d
/// };
/// let (q, t) = ([unit(0), unit(5)], [unit(5), unit(9), unit(0)]);
/// let (mut out, mut s) = ([FloatMatch::default(); 2], [0u32; float_scratch_len(3)]);
/// let n = match_float_descriptors(&q, &t, &MatchParams::default(), &mut s, &mut out)?;
/// assert_eq!((n, out[0].train, out[1].train, out[0].distance), (2, 2, 0, 0.0));
/// # Ok::<(), camgeom::Error>(())
/// ```
#[doc(alias = "BFMatcher")]
#[doc(alias = "NORM_L2")]
pub fn match_float_descriptors(
    query: &[FloatDescriptor],
    train: &[FloatDescriptor],
    params: &MatchParams,
    scratch: &mut [u32],
    out: &mut [FloatMatch],
) -> Result<usize> {
    match_float_descriptors_guided(query, train, params, |_, _| true, scratch, out)
}

/// [`match_float_descriptors`] among the pairs `candidate(i, j)` admits, as
/// [`match_descriptors_guided`].
#[doc(alias = "BFMatcher")]
pub fn match_float_descriptors_guided(
    query: &[FloatDescriptor],
    train: &[FloatDescriptor],
    params: &MatchParams,
    candidate: impl FnMut(usize, usize) -> bool,
    scratch: &mut [u32],
    out: &mut [FloatMatch],
) -> Result<usize> {
    let config = params.config();
    // Squared distances, non-negative: their bits order as the values.
    let r2 = config.ratio * config.ratio;
    let ratio_on = config.ratio < 1.0;
    let distance = |i: usize, j: usize| match (query.get(i), train.get(j)) {
        (Some(q), Some(t)) => {
            let d = l2_squared(q, t);
            if d.is_nan() {
                u32::MAX - 1
            } else {
                d.max(0.0).to_bits()
            }
        }
        _ => u32::MAX - 1,
    };
    let keep = |d1: u32, d2: u32| {
        d1 < u32::MAX - 1
            && (!ratio_on || d2 >= u32::MAX - 1 || f32::from_bits(d1) < r2 * f32::from_bits(d2))
    };
    let make = |i: usize, j: usize, d: u32| FloatMatch {
        query: i as u16,
        train: j as u16,
        distance: libm::sqrtf(f32::from_bits(d)),
    };
    let ids = |m: &FloatMatch| (usize::from(m.query), usize::from(m.train));
    let core = Core {
        sizes: (query.len(), train.len()),
        cross_check: config.cross_check,
        reverse: Reverse::Wide,
    };
    core.run(candidate, distance, keep, make, ids, scratch, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn random(n: usize, seed: u64) -> Vec<Descriptor> {
        let mut g = crate::rng::Pcg32::new(seed);
        (0..n)
            .map(|_| Descriptor(core::array::from_fn(|_| g.next_u32())))
            .collect()
    }

    fn flip(d: &Descriptor, bits: &[usize]) -> Descriptor {
        let mut o = *d;
        for &b in bits {
            o.0[b / 32] ^= 1 << (b % 32);
        }
        o
    }

    /// The definition, written plainly.
    fn reference(q: &[Descriptor], t: &[Descriptor], cfg: &MatchConfig) -> Vec<Match> {
        let best = |d: &Descriptor, set: &[Descriptor]| -> (usize, u32, u32) {
            let mut ds: Vec<(u32, usize)> = set
                .iter()
                .enumerate()
                .map(|(j, s)| (hamming(d, s), j))
                .collect();
            ds.sort();
            (ds[0].1, ds[0].0, ds.get(1).map_or(u32::MAX, |x| x.0))
        };
        let mut out = Vec::new();
        for (i, d) in q.iter().enumerate() {
            let (j, d1, d2) = best(d, t);
            if d1 > u32::from(cfg.max_distance) {
                continue;
            }
            if cfg.ratio < 1.0 && d2 != u32::MAX && d1 as f32 >= cfg.ratio * d2 as f32 {
                continue;
            }
            if cfg.cross_check && best(&t[j], q).0 != i {
                continue;
            }
            out.push(Match {
                query: i as u16,
                train: j as u16,
                distance: d1 as u16,
            });
        }
        out
    }

    #[test]
    fn hamming_counts_bits() {
        let a = Descriptor([0; 8]);
        assert_eq!(hamming(&a, &a), 0);
        assert_eq!(hamming(&a, &Descriptor([u32::MAX; 8])), 256);
        assert_eq!(hamming(&a, &flip(&a, &[0, 31, 32, 255])), 4);
    }

    #[test]
    fn agrees_with_the_definition() {
        let train = random(60, 1);
        // Half the queries are noisy copies of train descriptors, half are random.
        let mut query: Vec<Descriptor> = train
            .iter()
            .step_by(2)
            .enumerate()
            .map(|(k, d)| flip(d, &[k, 40 + 3 * k, 200 - k]))
            .collect();
        query.extend(random(30, 2));
        for cfg in [
            MatchConfig::default(),
            MatchConfig {
                ratio: 1.0,
                cross_check: false,
                max_distance: 256,
            },
            MatchConfig {
                ratio: 0.7,
                cross_check: false,
                max_distance: 256,
            },
            MatchConfig {
                ratio: 1.0,
                cross_check: true,
                max_distance: 100,
            },
        ] {
            let mut out = std::vec![Match::default(); query.len()];
            let mut scratch = std::vec![0u32; scratch_len(train.len())];
            let params = cfg.check().unwrap();
            let n = match_descriptors(&query, &train, &params, &mut scratch, &mut out).unwrap();
            assert_eq!(out[..n], reference(&query, &train, &cfg)[..], "{cfg:?}");
        }
        // The noisy copies all match their original with the defaults.
        let mut out = std::vec![Match::default(); query.len()];
        let mut scratch = std::vec![0u32; train.len()];
        let n = match_descriptors(
            &query,
            &train,
            &MatchParams::default(),
            &mut scratch,
            &mut out,
        )
        .unwrap();
        assert_eq!(n, 30);
        assert!(
            out[..n]
                .iter()
                .all(|m| usize::from(m.train) == 2 * usize::from(m.query) && m.distance == 3)
        );
    }

    /// The guided matcher against the definition applied to the admitted pairs only: each
    /// query's candidates and each train descriptor's candidate queries, as separate sets.
    #[test]
    fn guided_agrees_with_the_definition_on_the_admitted_pairs() {
        let train = random(60, 3);
        let mut query: Vec<Descriptor> = train
            .iter()
            .step_by(2)
            .enumerate()
            .map(|(k, d)| flip(d, &[k, 40 + 3 * k]))
            .collect();
        query.extend(random(30, 4));
        // A band: pairs whose indices are close (as features near an epipolar line).
        let admit = |i: usize, j: usize| (2 * i).abs_diff(j) <= 7 || (i + j).is_multiple_of(11);
        for cfg in [
            MatchConfig::default(),
            MatchConfig {
                ratio: 1.0,
                cross_check: false,
                max_distance: 256,
            },
            MatchConfig {
                ratio: 0.7,
                cross_check: true,
                max_distance: 120,
            },
        ] {
            let mut expect = Vec::new();
            let nearest = |d: &Descriptor, set: &[(usize, &Descriptor)]| {
                let mut ds: Vec<(u32, usize)> =
                    set.iter().map(|(j, s)| (hamming(d, s), *j)).collect();
                ds.sort();
                (ds.first().copied(), ds.get(1).map_or(u32::MAX, |x| x.0))
            };
            for (i, q) in query.iter().enumerate() {
                let cands: Vec<(usize, &Descriptor)> = train
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| admit(i, *j))
                    .collect();
                let (Some((d1, j)), d2) = nearest(q, &cands) else {
                    continue;
                };
                if d1 > u32::from(cfg.max_distance)
                    || (cfg.ratio < 1.0 && d2 != u32::MAX && d1 as f32 >= cfg.ratio * d2 as f32)
                {
                    continue;
                }
                let back: Vec<(usize, &Descriptor)> = query
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| admit(*k, j))
                    .collect();
                if cfg.cross_check && nearest(&train[j], &back).0.map(|x| x.1) != Some(i) {
                    continue;
                }
                expect.push(Match {
                    query: i as u16,
                    train: j as u16,
                    distance: d1 as u16,
                });
            }
            let mut out = std::vec![Match::default(); query.len()];
            let mut scratch = std::vec![0u32; scratch_len(train.len())];
            let params = cfg.check().unwrap();
            let n =
                match_descriptors_guided(&query, &train, &params, admit, &mut scratch, &mut out)
                    .unwrap();
            assert_eq!(out[..n], expect[..], "{cfg:?}");
        }
        // Admitting every pair is the unguided matcher; admitting none matches nothing.
        let params = MatchParams::default();
        let (mut a, mut b) = (
            std::vec![Match::default(); query.len()],
            std::vec![Match::default(); query.len()],
        );
        let mut s = std::vec![0u32; train.len()];
        let n = match_descriptors(&query, &train, &params, &mut s, &mut a).unwrap();
        let m =
            match_descriptors_guided(&query, &train, &params, |_, _| true, &mut s, &mut b).unwrap();
        assert_eq!(a[..n], b[..m]);
        let none = match_descriptors_guided(&query, &train, &params, |_, _| false, &mut s, &mut b);
        assert_eq!(none, Ok(0));
    }

    /// The float matcher against the definition: nearest by Euclidean distance, the ratio test
    /// on distances, the mutual check.
    #[test]
    fn float_matching_agrees_with_the_definition() {
        let mut g = crate::rng::Pcg32::new(9);
        let mut unit = || {
            let mut d = FloatDescriptor::default();
            for v in d.0.iter_mut() {
                *v = (g.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
            }
            let n = libm::sqrtf(d.0.iter().map(|v| v * v).sum());
            d.0.iter_mut().for_each(|v| *v /= n);
            d
        };
        // Train descriptors; queries: noisy copies of every third one (more than BLOCK of
        // them), then random ones.
        let train: Vec<FloatDescriptor> = (0..150).map(|_| unit()).collect();
        let mut query: Vec<FloatDescriptor> = train
            .iter()
            .step_by(3)
            .map(|t| {
                let mut q = *t;
                let noise = unit();
                q.0.iter_mut()
                    .zip(noise.0)
                    .for_each(|(a, b)| *a += 0.05 * b);
                q
            })
            .collect();
        query.extend((0..40).map(|_| unit()));
        let dist = |a: &FloatDescriptor, b: &FloatDescriptor| libm::sqrtf(l2_squared(a, b));
        let nearest = |d: &FloatDescriptor, set: &[FloatDescriptor]| {
            let mut ds: Vec<(f32, usize)> = set
                .iter()
                .enumerate()
                .map(|(j, s)| (dist(d, s), j))
                .collect();
            ds.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            (ds[0].1, ds[0].0, ds.get(1).map_or(f32::INFINITY, |x| x.0))
        };
        for (ratio, cross_check) in [(0.8, true), (1.0, false), (0.9, false)] {
            let cfg = MatchConfig {
                ratio,
                cross_check,
                max_distance: 0,
            };
            let mut expect = Vec::new();
            for (i, q) in query.iter().enumerate() {
                let (j, d1, d2) = nearest(q, &train);
                if ratio < 1.0 && d1 >= ratio * d2 {
                    continue;
                }
                if cross_check && nearest(&train[j], &query).0 != i {
                    continue;
                }
                expect.push((i, j));
            }
            let mut out = std::vec![FloatMatch::default(); query.len()];
            let mut scratch = std::vec![0u32; float_scratch_len(train.len())];
            let n = match_float_descriptors(
                &query,
                &train,
                &cfg.check().unwrap(),
                &mut scratch,
                &mut out,
            )
            .unwrap();
            let got: Vec<(usize, usize)> = out[..n]
                .iter()
                .map(|m| (usize::from(m.query), usize::from(m.train)))
                .collect();
            assert_eq!(got, expect, "{cfg:?}");
            for m in &out[..n] {
                let d = dist(&query[usize::from(m.query)], &train[usize::from(m.train)]);
                assert!((m.distance - d).abs() < 1e-5);
            }
        }
        // The noisy copies all match their originals with the defaults.
        let mut out = std::vec![FloatMatch::default(); query.len()];
        let mut scratch = std::vec![0u32; float_scratch_len(train.len())];
        let p = MatchParams::default();
        let n = match_float_descriptors(&query, &train, &p, &mut scratch, &mut out).unwrap();
        let copies = out[..n]
            .iter()
            .filter(|m| usize::from(m.train) == 3 * usize::from(m.query))
            .count();
        assert_eq!(copies, 50);
        assert_eq!(
            match_float_descriptors(&query, &train, &p, &mut scratch[..10], &mut out),
            Err(Error::BufferTooSmall("scratch"))
        );
    }

    #[test]
    fn edge_cases() {
        let d = random(3, 5);
        let mut out = [Match::default(); 3];
        let mut s = [0u32; 3];
        // Empty sides.
        assert_eq!(
            match_descriptors(&[], &d, &MatchParams::default(), &mut s, &mut out),
            Ok(0)
        );
        assert_eq!(
            match_descriptors(&d, &[], &MatchParams::default(), &mut s, &mut out),
            Ok(0)
        );
        // One train descriptor: the ratio test is skipped.
        let cfg = MatchConfig {
            cross_check: false,
            ..Default::default()
        };
        assert_eq!(
            match_descriptors(&d, &d[..1], &cfg.check().unwrap(), &mut s, &mut out),
            Ok(3)
        );
        // Errors.
        assert_eq!(
            match_descriptors(&d, &d, &MatchParams::default(), &mut s, &mut out[..2]),
            Err(Error::LengthMismatch)
        );
        assert_eq!(
            match_descriptors(&d, &d, &MatchParams::default(), &mut s[..2], &mut out),
            Err(Error::BufferTooSmall("scratch"))
        );
        for ratio in [f32::NAN, 0.0, -1.0] {
            let bad = MatchConfig {
                ratio,
                ..Default::default()
            };
            assert_eq!(bad.check(), Err(Error::InvalidParameter("match.ratio")));
        }
        let no_test = MatchConfig {
            ratio: f32::INFINITY,
            ..Default::default()
        };
        assert!(no_test.check().is_ok());
    }
}
