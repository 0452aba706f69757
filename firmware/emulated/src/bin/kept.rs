//! The main job at 320x240 with the forward-backward check's templates kept for the next
//! frame ([`camgeom_fw_app::sizes::QvgaKept`]): the forward-backward job of `cargo xtask run`, which
//! runs it and the main firmware on the same run with the check on and compares both with the
//! host replay (the same results to the bit, fewer instructions, more RAM).
#![no_std]
#![no_main]

use camgeom_fw_app::sizes::QvgaKept;
use camgeom_fw_emulated::entry;
use camgeom_fw_emulated::job;
use static_cell::ConstStaticCell;

const W: usize = 320;
const H: usize = 240;

/// Every buffer of the pipeline, the kept templates included, in `.bss`.
static APP: ConstStaticCell<QvgaKept> = ConstStaticCell::new(QvgaKept::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H, job::Stream::Off, (), job::given_corners)
}
