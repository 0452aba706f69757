//! One frame of the planar-target loop on the firmware bench's synthetic 320x240 frames, for
//! instruction-level profiling on the host:
//!
//! `cargo build --release -p camgeom-host --example profile_target &&
//!  valgrind --tool=callgrind target/release/examples/profile_target`
//!
//! The same inputs and configuration as `camgeom-fw-bench`'s `target_frame_32`, so the
//! profile's proportions carry over to the board.

use std::hint::black_box;

use camgeom::camera::{Camera, Intrinsics};
use camgeom::corners::{self, Corner};
use camgeom::image::{ImageMut, ImageView};
use camgeom::klt::synthetic::textured_frame;
use camgeom::klt::{Fixed, scratch_len};
use camgeom::nalgebra::Point2;
use camgeom::pyramid::{Pyramid, buffer_len};
use camgeom::target::{PlanarTarget, TargetConfig};

const W: usize = 320;
const H: usize = 240;
const LEVELS: usize = 4;
const SHIFT: (i32, i32) = (300, -170);
const RECT: [(f32, f32); 4] = [(70.0, 50.0), (250.0, 50.0), (250.0, 185.0), (70.0, 185.0)];

fn main() -> Result<(), camgeom::Error> {
    let repeats: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1);
    let mut a = vec![0u8; W * H];
    let mut b = vec![0u8; W * H];
    textured_frame(&mut ImageMut::packed(&mut a, W, H)?, 0, 0);
    textured_frame(&mut ImageMut::packed(&mut b, W, H)?, SHIFT.0, SHIFT.1);
    let cfg = black_box(TargetConfig::default());
    let camera = Camera::pinhole(Intrinsics::new(300.0f32, 300.0, 159.5, 119.5)?);
    let mut cand = vec![Corner::default(); 512];
    let mut cscr = vec![0u32; corners::scratch_len(W)];
    let mut fscr = vec![0i16; scratch_len(cfg.lk.win)];
    let mut pa = vec![0u8; buffer_len(W, H, LEVELS)];
    let mut pb = vec![0u8; buffer_len(W, H, LEVELS)];
    let va = ImageView::packed(&a, W, H)?;
    let vb = ImageView::packed(&b, W, H)?;
    let rect = RECT.map(|(x, y)| Point2::new(x, y));
    for _ in 0..repeats {
        let mut target = PlanarTarget::<Fixed, 32>::new(0.2, 0.15)?;
        let found = target.init(&va, &rect, &cfg, &mut cand, &mut cscr)?;
        let prev = Pyramid::build(va, &mut pa, LEVELS)?;
        let next = Pyramid::build(vb, &mut pb, LEVELS)?;
        let out = target.step(&prev, &next, &camera, &cfg, &mut fscr, &mut cand, &mut cscr)?;
        println!(
            "init {found} features; {:?}, {} tracked, {} inliers, {} added",
            out.state, out.tracked, out.inliers, out.added
        );
    }
    Ok(())
}
