//! camgeom's integration tests, one module a subject, in one test binary: one link and one
//! set of monomorphised solvers instead of one per file (run one subject with a filter:
//! `cargo test --test it twoview_opencv::`).

mod calib;
mod common;
mod essential_f32;
mod fixtures;
mod fuzz_regressions;
mod homography_dlt;
mod homography_ransac;
mod linalg_conditioning;
mod pnp;
mod properties;
mod sfm;
mod twoview;
mod twoview_opencv;
