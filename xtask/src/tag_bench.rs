//! The rendered tag sequence the bench firmware detects at decimation 1 (`cargo xtask
//! bench-fw`, `tag_sequence_bench` in `firmware/emulated/src/bin/bench.rs`), and what it must
//! find there.
//!
//! The frames are the tag job's (`host-tests/data/sequences/tag/`, 160 at 320x240). The
//! expectation is the host's run of the same detector on the same bytes (camgeom's default
//! configuration, tag36h11, the board's `Workspace320x240`): the board must find as many tags
//! in every frame.

use std::fs;
use std::path::PathBuf;

use anyhow::{Context, Result, ensure};
use camgeom::apriltag::{Detection, Detector, DetectorConfig, Workspace320x240, families};
use camgeom::heapless::Vec as HVec;
use camgeom::image::ImageView;
use camgeom_host::images::load_gray;

/// Writes `tag-frames.raw` (the frames, one byte a pixel, in name order) and `tag-expect.bin`
/// (a byte a frame: the tags the host's detector finds) into [`crate::charuco_bench::dir`].
pub fn prepare() -> Result<()> {
    let seq = camgeom_host::data_dir().join("sequences/tag");
    let mut names: Vec<PathBuf> = fs::read_dir(&seq)
        .with_context(|| format!("cannot read {}", seq.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    ensure!(
        (1..=256).contains(&names.len()),
        "{}: not 1 to 256 frames",
        seq.display()
    );
    let det = Detector::new(DetectorConfig::default(), &[&families::TAG36H11])?;
    let mut ws = Box::new(Workspace320x240::new());
    let (mut raw, mut expect) = (Vec::new(), Vec::new());
    for n in &names {
        let img = load_gray(n)?;
        ensure!(
            (img.width, img.height) == (320, 240),
            "{}: not 320x240",
            n.display()
        );
        let view = ImageView::packed(&img.data, 320, 240)?;
        let found: HVec<Detection, 8> = det.detect(&view, &mut ws.as_mut_view())?;
        expect.push(found.len() as u8);
        raw.extend_from_slice(&img.data);
    }
    let d = crate::charuco_bench::dir();
    fs::create_dir_all(&d)?;
    fs::write(d.join("tag-frames.raw"), &raw)?;
    fs::write(d.join("tag-expect.bin"), expect)?;
    Ok(())
}
