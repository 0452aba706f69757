//! KLT on the host bench's case (basketball1 -> basketball2, 640x480, 21x21, 4 levels, the
//! 1000 bench points, fixed point, per-window derivatives) for instruction counts
//! (BENCHMARKS.md, "KLT / Host speed per tracked feature"); prints a checksum of the tracks
//! so that two builds can be compared:
//!
//! ```sh
//! cargo build --release -p camgeom-host --example klt_count
//! valgrind --tool=callgrind --toggle-collect='*flow_pyramids*' target/release/examples/klt_count
//! target/release/examples/klt_count 1 auto 278         # Gradients::Auto, the first 278 points
//! target/release/examples/klt_count 1 auto 278 known   # the peer table's KLT case
//! target/release/examples/klt_count 1 auto 278 known once  # its buffers made once
//! ```

use camgeom::klt::LkConfig;
use camgeom_host::bench::load_rows;
use camgeom_host::data_dir;
use camgeom_host::images::load_gray;
use camgeom_host::klt::{
    Derivatives, FlowScratch, Path, flow_pyramids, flow_pyramids_in, levels, pyramid,
};

fn main() {
    let mb = data_dir().join("middlebury");
    let a = load_gray(mb.join("basketball1.png")).unwrap();
    let b = load_gray(mb.join("basketball2.png")).unwrap();
    // `known` as the fourth argument: the peer table's case (basketball1 and its warp by the
    // test homography, the 278 Shi-Tomasi corners).
    let known = std::env::args().nth(4).as_deref() == Some("known");
    let file = if known {
        "basketball_corners.csv"
    } else {
        "basketball_bench_pts.csv"
    };
    let pts: Vec<[f64; 2]> = load_rows(&data_dir().join("fixtures/klt").join(file), &["x", "y"])
        .iter()
        .map(|r| [r[0], r[1]])
        .collect();
    let b = if known {
        let (_, h) = camgeom_host::known_motion::warps(a.width, a.height)
            .into_iter()
            .find(|(name, _)| *name == "homography")
            .expect("the homography warp");
        camgeom_host::known_motion::warp(&a, &h)
    } else {
        b
    };
    let cfg = LkConfig::default();
    let l = levels(&cfg);
    let (mut ba, mut bb) = (Vec::new(), Vec::new());
    let pa = pyramid(&a, &mut ba, l);
    let pb = pyramid(&b, &mut bb, l);
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    // `auto` as the second argument: derivatives per level where cheaper; a third: only the
    // first that many points (278, the peer table's count).
    let derivs = match std::env::args().nth(2).as_deref() {
        Some("auto") => Derivatives::Auto,
        _ => Derivatives::Window,
    };
    let pts = match std::env::args()
        .nth(3)
        .and_then(|s| s.parse::<usize>().ok())
    {
        Some(k) => &pts[..k.min(pts.len())],
        None => &pts[..],
    };
    // `once` as the fifth argument: the buffers made once and reused, as the benches do (by
    // default each call makes its own, as the count's history was measured).
    let mut once = (std::env::args().nth(5).as_deref() == Some("once"))
        .then(|| FlowScratch::new(&pa, &cfg, derivs));
    let mut sum = 0u64;
    let mut tracked = 0;
    for _ in 0..n {
        let flows = match once.as_mut() {
            Some(s) => flow_pyramids_in(s, &pa, &pb, pts, &cfg, Path::Fixed),
            None => flow_pyramids(&pa, &pb, pts, &cfg, Path::Fixed, derivs),
        }
        .unwrap();
        tracked = 0;
        for f in &flows {
            let ok = f.status == camgeom::klt::FlowStatus::Tracked;
            tracked += usize::from(ok);
            sum = sum.wrapping_mul(31).wrapping_add(
                f.x.to_bits() ^ (f.y.to_bits() << 1) ^ (f.err.to_bits() << 2) ^ u64::from(ok),
            );
        }
    }
    println!("{} points, {tracked} tracked, checksum {sum}", pts.len());
}
