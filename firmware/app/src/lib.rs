//! camgeom's on-board application, shared by every board crate.
//!
//! A board supplies frames through [`FrameSource`] (a camera, or a recorded sequence read
//! from the host on the emulator) and a [`Clock`]; everything downstream of the frame is the
//! same code on every board: [`pipeline::Pipeline`] (pyramid, planar-target tracking, pose, AR
//! overlay, per-stage cost). It has no board dependency, so it also builds for the host (the
//! replay that checks a board's log) and for any Cortex-M target.
#![no_std]

pub mod pipeline;
pub mod qvga;
pub mod run;
pub mod slot;
pub mod source;

pub use pipeline::{AppConfig, AppError, Clock, CubeConfig, FrameReport, Pipeline, StageCosts};
pub use run::RunSpec;
pub use source::FrameSource;
