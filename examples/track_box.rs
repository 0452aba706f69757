//! The AR loop over the bundled box sequence: the board's per-frame policy
//! (`PlanarTarget::step`: KLT in Q16.16, RANSAC homography, IPPE + LM pose, re-detection,
//! relocation after a loss), from the box lid's corners picked by hand in frame 0.
//!
//! `cargo run --release --example track_box [FRAMES]`
//!
//! The configuration is the board's main job's at 320x240 (`TargetConfig::default()` without
//! the forward-backward check, 3 pyramid levels, 32 tracks), so this is also the host twin of
//! the board loop for instruction-level profiling:
//! `valgrind --tool=callgrind target/release/examples/track_box`.

#[path = "common.rs"]
mod common;

use std::hint::black_box;

use camgeom::camera::{Camera, Intrinsics};
use camgeom::image::ImageView;
use camgeom::klt::Fixed;
use camgeom::nalgebra::Point2;
use camgeom::pyramid::{PyramidPair, buffer_len};
use camgeom::target::{
    GivenCorners, PlanarTarget, TargetConfig, TargetParams, TargetState, corner_scratch_len,
    flow_scratch_len,
};

const W: usize = 320;
const H: usize = 240;
const LEVELS: usize = 3;
/// 32 tracks, 15x15 windows, 512 corner candidates: the board's main job.
type Target = PlanarTarget<Fixed, 32, { flow_scratch_len(15) }, { corner_scratch_len(W) }, 512>;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let frames: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(150);
    let seq = common::data_dir().join("sequences");
    // box-camera.yml: the nominal camera of the recording; box-top.csv: the lid's corners in
    // frame 0 (a 0.258 x 0.189 m lid).
    let camera = Camera::pinhole(
        Intrinsics::new(789.237_668_161_435_f64, 885.906_040_268_456_4, 160.0, 120.0)?.cast(),
    );
    let lid = [(186.0, 8.0), (296.5, 35.0), (280.0, 88.0), (149.0, 50.0)];
    let mut cfg = TargetConfig::default();
    cfg.lk.fb_threshold = None;
    let params = black_box(TargetParams::new(&cfg, camera, [0.258, 0.189])?);
    let mut acquire = GivenCorners::new(lid.map(|(x, y)| Point2::new(x, y)));
    let mut target = Box::new(Target::new());
    let mut pair = PyramidPair::new(
        [vec![0u8; W * H], vec![0u8; W * H]],
        [
            vec![0u8; buffer_len(W, H, LEVELS)],
            vec![0u8; buffer_len(W, H, LEVELS)],
        ],
    );
    pair.set_geometry(W, H, LEVELS)?;
    let mut count = 0;
    let mut tracking = 0;
    for k in 0..frames {
        let path = seq.join(format!("box/{k:04}.png"));
        if !path.exists() {
            break;
        }
        let (w, h, px) = common::read_gray_png(&path)?;
        if (w, h) != (W, H) {
            return Err(format!("{}: not {W}x{H}", path.display()).into());
        }
        count += 1;
        pair.capture()?.copy_from(&ImageView::packed(&px, W, H)?)?;
        let pyramids = pair.advance()?;
        let r = target.step(
            &params,
            pyramids.previous.as_ref(),
            &pyramids.next,
            &mut acquire,
            &mut (),
        )?;
        tracking += usize::from(r.state == TargetState::Tracking);
        if k % 15 == 0 {
            let pose = r.pose.map(|p| p.best.pose.translation());
            println!(
                "frame {k:3}: {:<8} {:2} tracked {:2} inliers {:2} added; t = {}",
                r.state.name(),
                r.tracked,
                r.inliers,
                r.added,
                pose.map_or("-".into(), |t| format!(
                    "({:.3}, {:.3}, {:.3}) m",
                    t.x, t.y, t.z
                ))
            );
        }
    }
    println!("tracking in {tracking} of {count} frames");
    Ok(())
}
