//! The main job at 160x120 (the second row of the cost table): the same pipeline as the
//! 320x240 firmware, on the sequence downscaled by `cargo xtask run`.
#![no_std]
#![no_main]

use camgeom_fw_emulated::job;

use camgeom_fw_emulated::entry;

use camgeom_fw_app::sizes::Qqvga;
use static_cell::ConstStaticCell;

const W: usize = 160;
const H: usize = 120;

/// Every buffer of the pipeline, in `.bss`: the linker checks it against `memory.x`.
static APP: ConstStaticCell<Qqvga> = ConstStaticCell::new(Qqvga::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H, job::Stream::Off, (), job::given_corners)
}
