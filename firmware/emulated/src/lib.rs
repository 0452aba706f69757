//! The emulated boards (QEMU `mps2-an500` Cortex-M7, `mps2-an385` Cortex-M3, `mps2-an505`
//! Cortex-M33, `virt` RV32IMAC): what their binaries share. The target a binary is built for
//! picks the board (`build.rs`); the code is the same on each.
//!
//! - [`board`]: exit codes through semihosting, the panic and fault handlers, stack use;
//! - [`cost`]: SysTick as an instruction counter under QEMU `-icount`, and a cost table;
//! - [`semihost`]: host files over semihosting and the recorded sequence as a camera;
//! - [`job`]: the main job, the `camgeom-fw-app` pipeline over a recorded sequence;
//! - [`flash`]: the settings flash, a NOR sector kept between boots in a host file;
//! - `uart` (Arm): UART0, the transport of the record stream;
//! - [`chessboard`]: the bundled chessboard camera and OpenCV's projections, for the checks.
//!
//! Binaries: `camgeom-fw-emulated` (the main job at 320x240, `src/main.rs`) and the others in
//! `src/bin/`. Every static buffer is a [`static_cell::ConstStaticCell`], placed by the
//! linker from its `const` value (in `.bss` when all zeros) and handed out once.
#![no_std]

pub mod board;
pub mod chessboard;
pub mod cost;
pub mod flash;
pub mod job;
pub mod semihost;
#[cfg(target_arch = "arm")]
pub mod uart;

// The defmt global logger: every binary of this crate logs over semihosting.
use defmt_semihosting as _;

/// The runtime's entry-point attribute (cortex-m-rt's on Arm, riscv-rt's on RISC-V), so that a
/// binary's `main` is the same on every board.
#[cfg(target_arch = "arm")]
pub use cortex_m_rt::entry;
#[cfg(target_arch = "riscv32")]
pub use riscv_rt::entry;
