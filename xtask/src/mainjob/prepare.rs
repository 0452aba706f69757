//! Turns the bundled box sequence into what a board reads: raw frames and a run description.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, ensure};
use camgeom::camera::Lens;
use camgeom::image::{ImageMut, ImageView};
use camgeom::pyramid::{down_size, pyr_down};
use camgeom_fw_app::run::{Acquisition, RunSpec};
use camgeom_host::images::load_gray;
use camgeom_host::load_camera;
use camgeom_host::points::read_points2;

use crate::jobs::Size;

/// The lid of the box (OpenCV's real-time pose tutorial mesh, `host-tests/data/README.md`).
const LID_M: [f32; 2] = [0.258, 0.189];
/// Every this many frames an overlay is written back (plus the last).
pub const OVERLAY_EVERY: u32 = 15;
/// The size the sequence is recorded at.
const RECORDED: (usize, usize) = (320, 240);

fn sequence_dir() -> PathBuf {
    camgeom_host::data_dir().join("sequences")
}

/// `fx fy cx cy` and the distortion of `box-camera.yml`, read by the host's loader.
fn box_camera() -> Result<([f32; 4], [f32; 5])> {
    let spec = load_camera(sequence_dir().join("box-camera.yml"))?;
    let c = spec.camera_f32();
    let k = &c.intrinsics;
    let Lens::BrownConrady(d) = c.lens else {
        return Err(anyhow!(
            "box-camera.yml: the board takes a Brown-Conrady camera"
        ));
    };
    Ok(([k.fx(), k.fy(), k.cx(), k.cy()], d.to_opencv()))
}

/// The lid corners of `box-top.csv`.
fn box_corners() -> Result<[[f32; 2]; 4]> {
    let pts = read_points2(sequence_dir().join("box-top.csv"))?;
    let rows: Vec<[f32; 2]> = pts.iter().map(|p| [p.x as f32, p.y as f32]).collect();
    rows.try_into()
        .map_err(|_| anyhow!("box-top.csv: expected the lid's 4 corners"))
}

/// The sequence's frames at `size`: as recorded, or their `pyrDown` (camgeom's, bit-exact with
/// OpenCV's) for the half size.
fn frames(size: Size) -> Result<Vec<u8>> {
    let seq = sequence_dir().join("box");
    let mut names: Vec<PathBuf> = fs::read_dir(&seq)
        .with_context(|| format!("cannot read {}", seq.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    ensure!(!names.is_empty(), "no frames in {}", seq.display());
    let (w, h) = (size.width as usize, size.height as usize);
    let mut raw = Vec::with_capacity(names.len() * w * h);
    for name in &names {
        let img = load_gray(name)?;
        ensure!(
            (img.width, img.height) == RECORDED,
            "{}: expected 320x240, got {}x{}",
            name.display(),
            img.width,
            img.height
        );
        if (w, h) == RECORDED {
            raw.extend_from_slice(&img.data);
        } else {
            ensure!(
                down_size(RECORDED.0, RECORDED.1) == (w, h),
                "only 320x240 and its pyrDown are prepared"
            );
            let src = ImageView::packed(&img.data, RECORDED.0, RECORDED.1)?;
            let mut out = vec![0u8; w * h];
            pyr_down(&src, &mut ImageMut::packed(&mut out, w, h)?)?;
            raw.extend_from_slice(&out);
        }
    }
    Ok(raw)
}

/// Writes `frames.raw` and `run.bin` for `size` into `dir` (all recorded frames; the stride is
/// in `run.bin`). Returns the run description.
pub fn prepare(size: Size, stride: u32, dir: &Path) -> Result<RunSpec> {
    fs::create_dir_all(dir)?;
    let raw = frames(size)?;
    let count = raw.len() / (size.width * size.height) as usize;
    fs::write(dir.join("frames.raw"), &raw)?;
    // pyrDown's output pixel x samples input 2x: positions and intrinsics halve.
    let scale = size.width as f32 / RECORDED.0 as f32;
    let ([fx, fy, cx, cy], distortion) = box_camera()?;
    let spec = RunSpec {
        width: size.width,
        height: size.height,
        frames: count as u32,
        stride,
        overlay_every: OVERLAY_EVERY,
        intrinsics: [fx * scale, fy * scale, cx * scale, cy * scale],
        distortion,
        target_size: LID_M,
        corners: box_corners()?.map(|[x, y]| [x * scale, y * scale]),
        acquisition: Acquisition::Corners,
        reacquire_every: 0,
        forward_backward: false,
    };
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    Ok(spec)
}
