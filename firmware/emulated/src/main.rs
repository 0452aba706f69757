//! camgeom on an emulated Cortex-M7 (QEMU `mps2-an500`): the main job at 320x240.
//!
//! The `camgeom-fw-app` pipeline (pyramid, planar-target tracking in Q16.16, pose, AR overlay)
//! over the bundled recorded sequence, read from the host over semihosting; see [`job`].
//! `cargo xtask run` prepares the input, runs this on QEMU and checks its log against the same
//! pipeline on the host.
#![no_std]
#![no_main]

mod board;
// The main job times its stages with the clock, not with the bench's cost table.
#[allow(dead_code)]
mod cost;
mod job;
mod once;
mod semihost;

use cortex_m_rt::entry;
use defmt_semihosting as _;

use crate::job::{CANDIDATES, LEVELS, TRACKS, WIN};
use crate::once::Once;

const W: usize = 320;
const H: usize = 240;

/// Every buffer of the pipeline, in `.bss`: the linker checks it against `memory.x`.
static APP: Once<camgeom_fw_app::pipeline_type!(W, H, LEVELS, WIN, CANDIDATES, TRACKS)> =
    Once::new(camgeom_fw_app::Pipeline::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H)
}
