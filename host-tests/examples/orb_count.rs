//! ORB on graf1 (800x640, 500 features, the bench's configuration) for instruction counts
//! (BENCHMARKS.md, "Features, matching, warp"); prints a checksum of the features so that two
//! builds can be compared:
//!
//! ```sh
//! cargo build --release -p camgeom-host --example orb_count
//! valgrind --tool=callgrind --toggle-collect='*orb_detect*' target/release/examples/orb_count
//! ```

use camgeom::features::orb::{self, Feature, OrbParams};
use camgeom::heapless::Vec as HVec;
fn main() {
    let img =
        camgeom_host::images::load_gray(camgeom_host::data_dir().join("oxford-graf/graf1.png"))
            .unwrap();
    let view = img.view().unwrap();
    let params = OrbParams::default();
    let scale_q8 = params.config().scale_q8;
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, scale_q8)];
    let mut out: Box<HVec<Feature, 500>> = Box::default();
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let mut sum = 0u64;
    for _ in 0..n {
        orb::orb_detect(&view, &params, &mut scratch, &mut out).unwrap();
        for f in out.iter() {
            sum = sum.wrapping_mul(31).wrapping_add(
                f.descriptor.0[0] as u64
                    ^ f.keypoint.response as u64
                    ^ (f.keypoint.x.to_bits() as u64),
            );
        }
    }
    println!("{} features, checksum {sum}", out.len());
}
