//! The features bench's warp (the 128x128 checker logo into a 320x240 frame through its
//! quadrilateral) for instruction counts (BENCHMARKS.md, "Features, matching, warp"); prints a
//! checksum of the frame so that two builds can be compared:
//!
//! ```sh
//! cargo build --release -p camgeom-host --example warp_count
//! valgrind --tool=callgrind --toggle-collect='*warp_perspective_into*' \
//!     target/release/examples/warp_count 20 f32     # or `fixed`
//! ```

use camgeom::warp::{Arithmetic, WarpConfig, warp_into_quad};
use camgeom_host::images::GrayImage;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(20, |a| a.parse().expect("a count"));
    let arithmetic = match args.next().as_deref() {
        Some("fixed") => Arithmetic::Fixed,
        _ => Arithmetic::Float,
    };
    // The features bench's logo and quadrilateral.
    let (logo, quad) = camgeom_host::bench::warp_case();
    let cfg = WarpConfig {
        alpha: 255,
        arithmetic,
    };
    let mut frame = GrayImage::filled(320, 240, 100);
    let mut written = 0;
    for _ in 0..n {
        let r = warp_into_quad(
            &logo.view().unwrap(),
            &mut frame.view_mut().unwrap(),
            &quad,
            &cfg,
        )
        .unwrap();
        written = r.written;
    }
    // FNV-1a of the frame.
    let sum = frame.data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    println!("{arithmetic:?}: {written} pixels written, frame checksum {sum}");
}
