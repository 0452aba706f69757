//! AprilTag detection speed per frame on the host, camgeom against AprilTag 3
//! (`scripts/bench_apriltag.py` runs this bench and pupil-apriltags on the same files in one
//! run and prints the ratio): a 320x240 frame of the rendered tag sequence (frame 20, the tag
//! at about 70 px) and a 640x480 photo (the chessboard view `left01.jpg`, textured, no tag),
//! at decimation 1 and 2, tag36h11, camgeom's defaults otherwise (2 bits corrected, edge
//! refinement, sharpening 0.25). Workspaces: the board's `Workspace320x240` (320x240, and
//! 640x480 at decimation 2) and `Workspace640x480`.
//!
//! The `aruco` group (`scripts/bench_aruco.py` times OpenCV's `ArucoDetector` on the same
//! files): the DICT_6X6_250 frame of the rendered ArUco frames (`aruco/0002.png`, 320x240,
//! six markers of 10 to 48 px) and `left01.jpg` with DICT_4X4_50, decimation 1, OpenCV's
//! decoding defaults.
//!
//! `cargo bench -p camgeom-host --bench apriltag` (`-- aruco` for that group alone)

use std::hint::black_box;

use camgeom::apriltag::{
    Detection, Detector, DetectorConfig, Workspace320x240, Workspace640x480, families,
};
use camgeom_host::data_dir;
use camgeom_host::images::load_gray;
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

/// The bench's frames: `(id, path under host-tests/data/, tags expected)`.
const FRAMES: [(&str, &str, usize); 2] = [
    ("320x240_tag", "sequences/tag/0020.png", 1),
    ("640x480_left01", "chessboard/left01.jpg", 0),
];

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("apriltag");
    g.sample_size(30);
    let mut small = Box::new(Workspace320x240::new());
    let mut large = Box::new(Workspace640x480::new());
    for (id, file, tags) in FRAMES {
        let img = load_gray(data_dir().join(file)).unwrap();
        let view = img.view().unwrap();
        for d in [1u8, 2] {
            let cfg = DetectorConfig {
                decimate: d,
                ..DetectorConfig::default()
            };
            let det = Detector::new(cfg, &[&families::TAG36H11]).unwrap();
            let big = img.width.div_ceil(usize::from(d)) > 320;
            let mut run = || -> camgeom::heapless::Vec<Detection, 16> {
                if big {
                    det.detect(&view, &mut large.as_mut_view()).unwrap()
                } else {
                    det.detect(&view, &mut small.as_mut_view()).unwrap()
                }
            };
            // The bench times what it should: the frame's tags are found.
            assert_eq!(run().len(), tags, "{file} at decimation {d}");
            g.bench_function(BenchmarkId::new(id, format!("d{d}")), |b| {
                b.iter(|| black_box(run()))
            });
        }
    }
    g.finish();
}

/// The ArUco frames: `(id, path under host-tests/data/, dictionary, markers expected)`.
const ARUCO_FRAMES: [(&str, &str, &str, usize); 2] = [
    ("320x240_6x6_250", "aruco/0002.png", "DICT_6X6_250", 6),
    (
        "640x480_left01_4x4_50",
        "chessboard/left01.jpg",
        "DICT_4X4_50",
        0,
    ),
];

fn bench_aruco(c: &mut Criterion) {
    let mut g = c.benchmark_group("aruco");
    g.sample_size(30);
    let mut small = Box::new(Workspace320x240::new());
    let mut large = Box::new(Workspace640x480::new());
    for (id, file, dict, markers) in ARUCO_FRAMES {
        let img = load_gray(data_dir().join(file)).unwrap();
        let view = img.view().unwrap();
        let family = families::by_name(dict).unwrap();
        let det = Detector::new(DetectorConfig::default(), &[family]).unwrap();
        let big = img.width > 320;
        let mut run = || -> camgeom::heapless::Vec<Detection, 16> {
            if big {
                det.detect(&view, &mut large.as_mut_view()).unwrap()
            } else {
                det.detect(&view, &mut small.as_mut_view()).unwrap()
            }
        };
        assert_eq!(run().len(), markers, "{file} {dict}");
        g.bench_function(BenchmarkId::new(id, "d1"), |b| b.iter(|| black_box(run())));
    }
    g.finish();
}

criterion_group!(benches, bench, bench_aruco);
criterion_main!(benches);
