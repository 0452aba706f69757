//! camgeom's AprilTag detector over image files, one CSV row per detection (for the peer study
//! `host-tests/scripts/apriltag_study.py` and for counting instructions under callgrind).
//!
//! ```sh
//! cargo run -p camgeom-host --example apriltag_detect -- [--decimate N] [--no-refine]
//!     [--family tag36h11]... [--pose SIZE --camera FILE] [--repeat N] [--stats] [--time]
//!     IMAGE...
//! ```
//!
//! Rows: `image,family,id,hamming,margin,x0,y0,x1,y1,x2,y2,x3,y3` (AprilTag's corner order,
//! camgeom's pixel convention), with `--pose` also `r11..r33,tx,ty,tz,ambiguous` (the best
//! pose of `camgeom::apriltag::tag_pose`, AprilTag's tag frame). Frames up to 320x240 after
//! decimation use the board workspace [`Workspace320x240`], larger ones the CLI's
//! `camgeom_host::apriltag::HostWorkspace` (sized for the frame, `u32` labels).
//! `--repeat N` runs each detection N times (the output once): callgrind's per-call counts;
//! `--stats` prints each frame's [`camgeom::apriltag::Stats`] to stderr; `--time` the median
//! time of the N detections of each frame and the host workspace's bytes
//! (`time,IMAGE,NS,BYTES`, the first run, which sizes the workspace, included).

use camgeom::apriltag::{
    Detection, Detector, DetectorConfig, Family, Workspace320x240, families, tag_pose,
};
use camgeom::heapless::Vec as HVec;
use camgeom::pose::PlanarConfig;
use camgeom_host::apriltag::HostWorkspace as Large;

fn family(name: &str) -> &'static Family {
    camgeom_host::apriltag::family(name).unwrap_or_else(|e| panic!("{e}"))
}

fn main() {
    let mut cfg = DetectorConfig::default();
    let mut fams: Vec<&'static Family> = Vec::new();
    let mut pose: Option<(f32, camgeom::camera::Camera<f32>)> = None;
    let mut size = None;
    let mut camera = None;
    let mut repeat = 1usize;
    let mut stats = false;
    let mut time = false;
    let mut images = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--decimate" => cfg.decimate = args.next().unwrap().parse().unwrap(),
            "--no-refine" => cfg.refine_edges = false,
            "--family" => fams.push(family(&args.next().unwrap())),
            "--max-hamming" => cfg.max_hamming = args.next().unwrap().parse().unwrap(),
            "--pose" => size = Some(args.next().unwrap().parse::<f32>().unwrap()),
            "--camera" => camera = Some(args.next().unwrap()),
            "--repeat" => repeat = args.next().unwrap().parse().unwrap(),
            "--stats" => stats = true,
            "--time" => time = true,
            _ => images.push(a),
        }
    }
    if fams.is_empty() {
        fams.push(&families::TAG36H11);
    }
    if let (Some(s), Some(c)) = (size, camera) {
        let spec = camgeom_host::load_camera(&c).expect("camera file");
        pose = Some((s, spec.camera_f32()));
    }
    let det = Detector::new(cfg, &fams).expect("configuration");
    let mut small = Box::new(Workspace320x240::new());
    let mut large = Large::new();
    println!(
        "image,family,id,hamming,margin,x0,y0,x1,y1,x2,y2,x3,y3{}",
        if pose.is_some() {
            ",r11,r12,r13,r21,r22,r23,r31,r32,r33,tx,ty,tz,ambiguous"
        } else {
            ""
        }
    );
    for path in &images {
        let img = camgeom_host::images::load_gray(path).expect("image");
        let view = img.view().expect("image size");
        let d = usize::from(cfg.decimate);
        let fits = img.width.div_ceil(d) <= 320 && img.height.div_ceil(d) <= 240;
        let mut found: HVec<Detection, 64> = HVec::new();
        let mut times = Vec::with_capacity(repeat);
        for _ in 0..repeat {
            let t = std::time::Instant::now();
            found = if fits {
                det.detect(&view, &mut small.as_mut_view()).expect("detect")
            } else {
                large.detect(&det, &view).expect("detect")
            };
            times.push(t.elapsed().as_nanos());
        }
        if time {
            times.sort_unstable();
            let median = times.get(times.len() / 2).copied().unwrap_or(0);
            let ws = if fits { 0 } else { large.bytes() };
            eprintln!("time,{path},{median},{ws}");
        }
        if stats {
            let s = if fits { small.stats() } else { large.stats() };
            eprintln!("{path}: {s:?}");
        }
        for t in &found {
            let c = &t.corners;
            let mut row = format!(
                "{path},{},{},{},{:.4},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
                t.family.name(),
                t.id,
                t.hamming,
                t.decision_margin,
                c[0].x,
                c[0].y,
                c[1].x,
                c[1].y,
                c[2].x,
                c[2].y,
                c[3].x,
                c[3].y
            );
            if let Some((s, cam)) = &pose {
                match tag_pose(t, *s, cam, &PlanarConfig::default()) {
                    Ok(p) => {
                        let r = p.best.pose.rotation();
                        let tr = p.best.pose.translation();
                        let m = r.matrix();
                        for i in 0..3 {
                            for j in 0..3 {
                                row.push_str(&format!(",{:.9}", m[(i, j)]));
                            }
                        }
                        row.push_str(&format!(
                            ",{:.9},{:.9},{:.9},{}",
                            tr.x,
                            tr.y,
                            tr.z,
                            u8::from(p.is_ambiguous(1.5))
                        ));
                    }
                    Err(e) => row.push_str(&format!(",,,,,,,,,,,,,{}", e.name())),
                }
            }
            println!("{row}");
        }
    }
}
