//! camgeom's on-board application, shared by every board crate.
//!
//! A board supplies frames through [`FrameSource`] (a camera, or a recorded sequence read
//! from the host on the emulator) and a [`Clock`]; everything downstream of the frame is the
//! same code on every board: [`pipeline::Pipeline`] (pyramid, the core's per-frame loop
//! [`camgeom::target::PlanarTarget::step`], AR overlay, per-stage cost) and the binary
//! [`report`] records a board sends back, all written and read by [`wire`]. It has no board dependency, so it also builds for
//! the host (the replay that checks a board's run, and this crate's tests) and for any
//! Cortex-M or RISC-V target.
#![no_std]

#[cfg(test)]
extern crate std;

pub mod calibrate_mode;
pub mod calibration;
pub mod charuco_calibration;
pub mod command;
pub mod costs;
pub mod frame_chunk;
pub mod link;
#[cfg(feature = "mavlink")]
pub mod mavlink;
pub mod options;
pub mod pipeline;
pub mod qvga;
pub mod recorded;
pub mod report;
pub mod run;
pub mod settings;
pub mod sizes;
pub mod slot;
pub mod source;
pub mod texture;
pub mod wire;

pub use costs::{Cost, StageCosts};
pub use options::{Acquisition, AppOptions};
pub use pipeline::{AppConfig, AppError, Clock, CubePlacement, FrameLoop, FrameReport, Pipeline};
pub use run::{RunSpec, drive};
pub use source::FrameSource;
