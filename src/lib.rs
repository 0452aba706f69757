//! camgeom: camera geometry and tracking for microcontroller camera boards.
//!
//! `#![no_std]`, no allocator, no panics on any input. Every buffer is fixed-size or provided by
//! the caller. Floating-point code is generic over [`nalgebra::RealField`] with `f32` as the
//! default; [`fixed`] holds integer-only paths for cores without an FPU.
//!
//! | module | what |
//! |---|---|
//! | [`homogeneous`] | points and lines of the projective plane, join, meet, vanishing points |
//! | [`vanishing`] | vanishing points of line segments (sequential RANSAC, least squares) and the horizon |
//! | [`transform`] | rigid transforms `[R t; 0 1]` between typed frames |
//! | [`camera`] | pinhole intrinsics, Brown-Conrady distortion, projection, back-projection |
//! | [`calib`] | camera calibration from chessboard views: Zhang's closed form, joint LM over the camera and every pose (Schur structure by QR), Brown-Conrady or fisheye, standard deviations |
//! | [`chessboard`] | chessboard detection (saddle response, grid growing, OpenCV's corner order), saddle-fit or `cornerSubPix` refinement |
//! | [`image`] | borrowed grayscale views with a stride, validated once |
//! | [`pyramid`] | Gaussian pyramids (OpenCV's `pyrDown`, bit-exact) into caller buffers |
//! | [`gradient`] | Scharr derivatives in `i16`, per level or per window |
//! | [`corners`] | Shi-Tomasi corners (good features to track), integer, streaming, replenishment |
//! | [`klt`] | pyramidal Lucas-Kanade flow (fixed-point and `f32`), multi-frame tracker |
//! | [`fixed`] | Q16.16 projective transfer (homography, projection) without floating point |
//! | [`linalg`] | one-sided Jacobi SVD and streaming (row-by-row) QR of small static matrices |
//! | [`homography`] | plane homographies: 4-point solver, normalised DLT, LM refinement, RANSAC |
//! | [`twoview`] | epipolar geometry: 7/8-point `F`, 5-point `E`, RANSAC, Sampson LM, relative pose, triangulation |
//! | [`sfm`] | three-view structure from motion (E, triangulation, PnP) and a small Schur-complement bundle adjustment |
//! | [`pose`] | pose from a homography, IPPE (both planar solutions), LM refinement on reprojection |
//! | [`draw`] | clipped integer line drawing and projected wireframes (AR cube) |
//! | [`target`] | tracking a planar target: KLT, RANSAC homography and pose each frame, re-detection |
//! | [`probe`] | stage probes: a pipeline reports each stage's end (a board's cycle counter) |
//! | [`ransac`] | generic RANSAC loop: MSAC scoring, adaptive stopping, local optimisation |
//! | [`remap`] | frame undistortion: new camera matrix (alpha / balance), per-pixel maps (Q10.5 for the board's frames up to 1023 px, [`remap::WideEntry`] as OpenCV's `CV_16SC2` up to 32767 px) or a compact grid map, integer bilinear remap of grey or RGB |
//! | [`rng`] | PCG32, a small deterministic generator for sampling |
//! | [`resize`] | bilinear resizing with aligned pixel centres, in integers |
//! | [`warp`] | perspective warp of a logo into a quadrilateral: inverse mapping, bilinear, f32 or fixed point, clipped |
//! | [`features`] | FAST corners, ORB (oriented FAST + steered BRIEF) descriptors, Hamming matching |
//! | [`apriltag`] | AprilTag detection (tag36h11, tag25h9, tag16h5, tagStandard41h12) in fixed memory, tag pose |
//!
//! Cargo features (none by default):
//!
//! - `std`: CPU features found at run time. On x86-64 the KLT's window kernel then samples with
//!   AVX2 where the CPU has it (the same integers as its SSE2 form; without `std`, only when
//!   the build itself enables AVX2). Nothing allocates either way.
//! - `defmt`: `defmt::Format` on the public types, for logging on the boards.
#![no_std]
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]
// No panic path may be reachable from the public API: these lints keep it so in library code.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]
#![forbid(unsafe_code)]

#[cfg(any(feature = "std", test))]
extern crate std;

/// Whether this target has 128-bit SIMD (SSE2, NEON, wasm `simd128`): `wide`'s vectors are
/// registers there, arrays elsewhere. Kernels with a vector form and a scalar form (KLT
/// windows, Shi-Tomasi rows, the warp) choose by this constant; the other form is compiled
/// out of every optimised build.
pub(crate) const SIMD: bool = cfg!(any(
    target_arch = "x86_64",
    all(target_arch = "x86", target_feature = "sse2"),
    target_arch = "aarch64",
    all(target_arch = "arm", target_feature = "neon"),
    all(target_arch = "wasm32", target_feature = "simd128"),
));

pub mod aprilgrid;
pub mod apriltag;
pub mod arith;
pub mod calib;
pub mod camera;
pub mod charuco;
pub mod chessboard;
pub mod corners;
pub mod draw;
mod error;
pub mod features;
pub mod fixed;
pub mod gradient;
pub mod homogeneous;
pub mod homography;
pub mod image;
pub mod klt;
pub mod linalg;
pub mod pose;
pub mod probe;
pub mod pyramid;
pub mod ransac;
pub mod remap;
pub mod resize;
pub mod rng;
mod scalar;
pub mod sfm;
mod simd;
pub mod target;
pub mod transform;
pub mod twoview;
pub mod vanishing;
pub mod warp;

pub use error::{Error, Result};
pub use heapless;
pub use nalgebra;
pub use scalar::Real;
