//! Shi-Tomasi on the peer table's case (basketball1, 640x480, at most 400 corners, quality
//! 0.01, minimum distance 10) for instruction counts; prints the corners' count and a checksum
//! so that two builds can be compared:
//!
//! ```sh
//! cargo build --release -p camgeom-host --example corners_count
//! valgrind --tool=callgrind --toggle-collect='*good_features*' \
//!     target/release/examples/corners_count 5
//! ```

use camgeom::corners::CornerConfig;
use camgeom_host::data_dir;
use camgeom_host::images::load_gray;
use camgeom_host::klt::corners;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map_or(5, |a| a.parse().expect("a count"));
    let a = load_gray(data_dir().join("middlebury/basketball1.png")).unwrap();
    let cfg = CornerConfig {
        quality: 0.01,
        min_distance: 10,
        max_corners: 0,
    };
    let mut found = Vec::new();
    for _ in 0..n {
        found = corners(&a, &cfg, 400).unwrap();
    }
    let coords = found
        .iter()
        .flat_map(|c| [u64::from(c[0]), u64::from(c[1])]);
    let sum = camgeom_host::bench::fnv1a(coords);
    println!("{} corners, checksum {sum}", found.len());
}
