//! Structured inputs shared by the fuzz targets.
#![allow(dead_code)]

use arbitrary::Arbitrary;
use camgeom::apriltag::{Detection, Family};
use camgeom::homography::Homography;
use camgeom::nalgebra::{Point, Point2, Point3, Vector3};

/// An `f32` that is usually an ordinary coordinate but can be any bit pattern (NaN, ±inf,
/// subnormal) or one of the values that break careless numerics.
#[derive(Debug, Clone, Copy, Arbitrary)]
pub enum Num {
    /// A plain coordinate in eighths: -4096 ..= 4096.
    Grid(i16),
    /// A value in [0, 1) of 1/65536 steps, scaled by 2^(exp mod 40 - 20).
    Scaled(u16, u8),
    /// One of [`SPECIAL`].
    Special(u8),
    /// Any bit pattern.
    Raw(f32),
}

pub const SPECIAL: [f32; 12] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    f32::MIN_POSITIVE,
    1.0e-40, // subnormal
    1.0e30,
    -1.0e-30,
];

impl Num {
    pub fn get(self) -> f32 {
        match self {
            Num::Grid(v) => f32::from(v) / 8.0,
            Num::Scaled(m, e) => f32::from(m) / 65536.0 * libm_pow2(i32::from(e % 40) - 20),
            Num::Special(i) => SPECIAL[usize::from(i) % SPECIAL.len()],
            Num::Raw(v) => v,
        }
    }
}

fn libm_pow2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// Edits that make point sets degenerate: the fuzzer chooses which.
#[derive(Debug, Clone, Copy, Arbitrary)]
pub enum Edit {
    /// Copy point `from` over point `to` (indices modulo the length).
    Duplicate { from: u8, to: u8 },
    /// Put point `k` on the line through points `a` and `b`, at parameter `t`.
    Collinear { a: u8, b: u8, k: u8, t: Num },
    /// Scale every coordinate by `s`.
    ScaleAll(Num),
}

pub fn pt2(p: (Num, Num)) -> Point2<f32> {
    Point2::new(p.0.get(), p.1.get())
}

pub fn pt3(p: (Num, Num, Num)) -> Point3<f32> {
    Point3::new(p.0.get(), p.1.get(), p.2.get())
}

pub fn vec3(p: (Num, Num, Num)) -> Vector3<f32> {
    Vector3::new(p.0.get(), p.1.get(), p.2.get())
}

/// Applies `edits` to `points` (2-D or 3-D) in order; nothing for an empty set.
pub fn apply_edits<const D: usize>(points: &mut [Point<f32, D>], edits: &[Edit]) {
    let n = points.len();
    if n == 0 {
        return;
    }
    for e in edits {
        match *e {
            Edit::Duplicate { from, to } => {
                points[usize::from(to) % n] = points[usize::from(from) % n];
            }
            Edit::Collinear { a, b, k, t } => {
                let (pa, pb) = (points[usize::from(a) % n], points[usize::from(b) % n]);
                points[usize::from(k) % n] = pa + (pb - pa) * t.get();
            }
            Edit::ScaleAll(s) => {
                let s = s.get();
                for p in points.iter_mut() {
                    *p = Point::from(p.coords * s);
                }
            }
        }
    }
}

/// RANSAC parameters from the fuzzer, with the iteration cap bounded so a run stays short.
#[derive(Debug, Clone, Copy, Arbitrary)]
pub struct Ransac {
    pub threshold: Num,
    pub confidence: Num,
    pub max_iterations: u8,
    pub local_optimization: u8,
    pub lo_multiplier: Num,
    pub refine: bool,
    pub seed: u64,
}

impl Ransac {
    pub fn config(&self) -> camgeom::ransac::RansacConfig<f32> {
        camgeom::ransac::RansacConfig {
            threshold: self.threshold.get(),
            confidence: self.confidence.get(),
            max_iterations: u32::from(self.max_iterations % 64),
            local_optimization: self.local_optimization % 6,
            lo_threshold_multiplier: self.lo_multiplier.get(),
            refine: self.refine,
            seed: self.seed,
        }
    }

    /// [`Self::config`] checked (`None` when the check refuses it, as it does many fuzzer
    /// values: the estimators only take checked parameters).
    pub fn params(&self) -> Option<camgeom::ransac::RansacParams<f32>> {
        self.config().check().ok()
    }
}

pub fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Every entry of a pose (rotation and translation) is finite and the rotation is orthonormal.
pub fn check_pose(pose: &camgeom::transform::Pose<f32>, what: &str) {
    let r = pose.rotation();
    let t = pose.translation();
    assert!(finite(r.matrix().as_slice()), "{what}: rotation not finite");
    assert!(finite(t.as_slice()), "{what}: translation not finite");
    let e = (r.matrix().transpose() * r.matrix() - camgeom::nalgebra::Matrix3::identity())
        .abs()
        .max();
    assert!(e < 1e-3, "{what}: rotation not orthonormal ({e})");
}

/// A frame's geometry: usually a plausible one (so that the fuzzer reaches detection), or any
/// width, height and stride with a buffer of any length (zero, tiny, huge-claimed sizes,
/// strides below the width, buffers shorter or longer than the geometry needs).
#[derive(Debug, Clone, Copy, Arbitrary)]
pub enum Geometry {
    /// `16 + w` by `16 + h` pixels, rows padded by `pad`, an exact buffer.
    Plain { w: u8, h: u8, pad: u8 },
    /// Anything: the buffer's length is what the geometry needs plus `slack`.
    Any {
        width: u16,
        height: u16,
        stride: u16,
        slack: i16,
    },
}

impl Geometry {
    /// Width, height, stride and buffer length (at most `max_len` bytes, plus any slack).
    pub fn dims(self, max_len: usize) -> (usize, usize, usize, usize) {
        match self {
            Geometry::Plain { w, h, pad } => {
                let (w, h) = (16 + usize::from(w), 16 + usize::from(h));
                let s = w + usize::from(pad % 8);
                (w, h, s, camgeom::image::buffer_len(w, h, s))
            }
            Geometry::Any {
                width,
                height,
                stride,
                slack,
            } => {
                let (w, h, s) = (usize::from(width), usize::from(height), usize::from(stride));
                let need = camgeom::image::buffer_len(w, h, s).min(max_len) as i64;
                (w, h, s, (need + i64::from(slack)).max(0) as usize)
            }
        }
    }
}

/// A detection of tag `id` of `family` whose target corners (`Detection::target_corners`:
/// corners 3, 2, 1, 0) are `c`; the other fields plausible constants.
pub fn detection(family: &'static Family, id: u16, c: [Point2<f32>; 4]) -> Detection {
    Detection {
        family,
        id,
        hamming: 0,
        decision_margin: 10.0,
        corners: [c[3], c[2], c[1], c[0]],
        center: c[0],
        homography: Homography::identity(),
    }
}
