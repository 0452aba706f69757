//! The features bench's warp (the 128x128 checker logo into a 320x240 frame through its
//! quadrilateral) for instruction counts (BENCHMARKS.md, "Features, matching, warp"); prints a
//! checksum of the frame so that two builds can be compared:
//!
//! ```sh
//! cargo build --release -p camgeom-host --example warp_count
//! valgrind --tool=callgrind --toggle-collect='*warp_perspective_into*' \
//!     target/release/examples/warp_count 20 f32     # or `fixed`
//! ```

use camgeom::arith::{Arithmetic, Fixed};
use camgeom::warp::WarpConfig;
use camgeom_host::images::GrayImage;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(20, |a| a.parse().expect("a count"));
    match args.next().as_deref() {
        Some("fixed") => run::<Fixed>(n),
        _ => run::<f32>(n),
    }
}

fn run<A: Arithmetic>(n: usize) {
    // The features bench's logo and quadrilateral.
    let (logo, quad) = camgeom_host::bench::warp_case();
    let cfg = WarpConfig { alpha: 255 };
    let mut frame = GrayImage::filled(320, 240, 100);
    let mut written = 0;
    for _ in 0..n {
        written = camgeom_host::bench::warp_once::<A>(&logo, &mut frame, &quad, &cfg);
    }
    let sum = camgeom_host::bench::fnv1a(frame.data.iter().map(|&b| u64::from(b)));
    println!(
        "{}: {written} pixels written, frame checksum {sum}",
        A::NAME
    );
}
