//! camgeom on an emulated Cortex-M7 (QEMU `mps2-an500`): the main job at 320x240.
//!
//! The `camgeom-fw-app` pipeline (pyramid, planar-target tracking in Q16.16, pose, AR overlay)
//! over the bundled recorded sequence, read from the host over semihosting; see [`job`].
//! `cargo xtask run` prepares the input, runs this on QEMU and checks its log against the same
//! pipeline on the host.
#![no_std]
#![no_main]

use camgeom_fw_emulated::job;

use camgeom_fw_emulated::entry;

use camgeom_fw_app::sizes::Qvga;
use static_cell::ConstStaticCell;

const W: usize = 320;
const H: usize = 240;

/// Every buffer of the pipeline, in `.bss`: the linker checks it against `memory.x`.
static APP: ConstStaticCell<Qvga> = ConstStaticCell::new(Qvga::new());

#[entry]
fn main() -> ! {
    job::run(APP.take(), W, H, job::Stream::Off, (), job::given_corners)
}
