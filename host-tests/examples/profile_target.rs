//! The planar-target loop on the first frames of the bundled box sequence, for
//! instruction-level profiling on the host:
//!
//! `cargo build --release -p camgeom-host --example profile_target &&
//!  valgrind --tool=callgrind target/release/examples/profile_target [FRAMES]`
//!
//! Same inputs as the board's main job (box lid corners of frame 0, the nominal camera,
//! `TargetConfig::default()`, `PlanarTarget<Fixed, 32>`, 4 pyramid levels), so the profile's
//! proportions carry over to the board. Prints each frame's outcome.

use std::hint::black_box;
use std::path::Path;

use camgeom::camera::{Camera, Intrinsics};
use camgeom::corners::{self, Corner};
use camgeom::klt::{Fixed, scratch_len};
use camgeom::nalgebra::Point2;
use camgeom::pyramid::{Pyramid, buffer_len};
use camgeom::target::{PlanarTarget, TargetConfig};
use camgeom_host::images::load_gray;

const LEVELS: usize = 4;
const LID: [(f32, f32); 4] = [(186.0, 8.0), (296.5, 35.0), (280.0, 88.0), (149.0, 50.0)];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let frames: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(10);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/sequences/box");
    let imgs = (0..frames)
        .map(|k| load_gray(dir.join(format!("{k:04}.png"))))
        .collect::<Result<Vec<_>, _>>()?;
    let (w, h) = (imgs[0].width, imgs[0].height);
    let cfg = black_box(TargetConfig::default());
    let camera = Camera::pinhole(Intrinsics::new(789.237_7_f32, 885.906, 160.0, 120.0)?);
    let mut cand = vec![Corner::default(); 512];
    let mut cscr = vec![0u32; corners::scratch_len(w)];
    let mut fscr = vec![0i16; scratch_len(cfg.lk.win)];
    let mut bufs = [
        vec![0u8; buffer_len(w, h, LEVELS)],
        vec![0u8; buffer_len(w, h, LEVELS)],
    ];
    let mut target = PlanarTarget::<Fixed, 32>::new(0.258, 0.189)?;
    let v0 = imgs[0].view().ok_or("frame 0")?;
    let found = target.init(
        &v0,
        &LID.map(|(x, y)| Point2::new(x, y)),
        &cfg,
        &mut cand,
        &mut cscr,
    )?;
    println!("init: {found} features");
    for k in 1..frames {
        let (a, b) = bufs.split_at_mut(1);
        let prev = Pyramid::build(imgs[k - 1].view().ok_or("frame")?, &mut a[0], LEVELS)?;
        let next = Pyramid::build(imgs[k].view().ok_or("frame")?, &mut b[0], LEVELS)?;
        let out = target.step(&prev, &next, &camera, &cfg, &mut fscr, &mut cand, &mut cscr)?;
        println!(
            "frame {k}: {:?}, {} tracked, {} inliers, {} added",
            out.state, out.tracked, out.inliers, out.added
        );
    }
    Ok(())
}
