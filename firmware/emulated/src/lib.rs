//! The emulated board (QEMU `mps2-an500`, Cortex-M7): what its binaries share.
//!
//! - [`board`]: exit codes through semihosting, the panic and fault handlers, stack use;
//! - [`cost`]: SysTick as an instruction counter under QEMU `-icount`, and a cost table;
//! - [`semihost`]: host files over semihosting and the recorded sequence as a camera;
//! - [`job`]: the main job, the `camgeom-fw-app` pipeline over a recorded sequence;
//! - [`chessboard`]: the bundled chessboard camera and OpenCV's projections, for the checks.
//!
//! Binaries: `camgeom-fw-emulated` (the main job at 320x240, `src/main.rs`) and the others in
//! `src/bin/`. Every static buffer is a [`static_cell::ConstStaticCell`], placed by the
//! linker from its `const` value (in `.bss` when all zeros) and handed out once.
#![no_std]

pub mod board;
pub mod chessboard;
pub mod cost;
pub mod job;
pub mod semihost;

// The defmt global logger: every binary of this crate logs over semihosting.
use defmt_semihosting as _;
