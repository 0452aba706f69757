//! The main job at 160x120 (the second row of the cost table): the same pipeline as the
//! 320x240 firmware, on the sequence downscaled by `cargo xtask run`.
#![no_std]
#![no_main]

#[path = "../board.rs"]
mod board;
// The main job times its stages with the clock, not with the bench's cost table.
#[allow(dead_code)]
#[path = "../cost.rs"]
mod cost;
#[path = "../job.rs"]
mod job;
#[path = "../once.rs"]
mod once;
#[path = "../semihost.rs"]
mod semihost;

use cortex_m_rt::entry;
use defmt_semihosting as _;

use crate::job::{CANDIDATES, LEVELS, TRACKS, WIN};
use crate::once::Once;

const W: usize = 160;
const H: usize = 120;

/// Every buffer of the pipeline, in `.bss`: the linker checks it against `memory.x`.
static APP: Once<camgeom_fw_app::pipeline_type!(W, H, LEVELS, WIN, CANDIDATES, TRACKS)> =
    Once::new(camgeom_fw_app::Pipeline::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H)
}
