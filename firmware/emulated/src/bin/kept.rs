//! The main job at 320x240 with the forward-backward check's templates kept for the next
//! frame (`pipeline_type!(.., kept)`): the forward-backward job of `cargo xtask run`, which
//! runs it and the main firmware on the same run with the check on and compares both with the
//! host replay (the same results to the bit, fewer instructions, more RAM).
#![no_std]
#![no_main]

use camgeom_fw_emulated::entry;
use camgeom_fw_emulated::job;
use camgeom_fw_emulated::job::{CANDIDATES, LEVELS, TRACKS, WIN};
use static_cell::ConstStaticCell;

const W: usize = 320;
const H: usize = 240;

/// Every buffer of the pipeline, the kept templates included, in `.bss`.
static APP: ConstStaticCell<
    camgeom_fw_app::pipeline_type!(W, H, LEVELS, WIN, CANDIDATES, TRACKS, kept),
> = ConstStaticCell::new(camgeom_fw_app::Pipeline::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H, job::given_corners)
}
