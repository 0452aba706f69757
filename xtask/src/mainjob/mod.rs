//! `cargo xtask run`: the emulated board's main job, and the host-vs-board check.
//!
//! 1. The projection checks (`camgeom-fw-projection`) run first: small and quick.
//! 2. For each frame size (320x240 and 160x120), [`prepare`] turns the bundled sequence
//!    `host-tests/data/sequences/box/*.png` into raw grayscale frames (`frames.raw`; 160x120 is
//!    the `pyrDown` of each frame) and a run description (`run.bin`: the camera from
//!    `box-camera.yml`, the lid corners from `box-top.csv`, both scaled to the frame size) in
//!    `target/camgeom-run/<size>/`.
//! 3. [`emulate`]: the firmware runs on QEMU in that directory, reads both over semihosting and
//!    writes its binary report (`report.bin`, one record a frame and a summary) and overlay
//!    frames back; the overlays become PNGs and a contact sheet `overlays.png` here.
//! 4. [`replay`]: the same `camgeom-fw-app` pipeline, compiled for the host, replays the same
//!    bytes. [`compare`]: every frame must agree: state, counts and error exactly, the checksum
//!    of the Q16.16 track positions bit for bit, the overlays byte for byte, and both f32 poses
//!    within [`compare::POSE_TOLERANCE`].
//! 5. [`table`]: the per-stage cost table in Markdown (BENCHMARKS.md takes it verbatim).

mod compare;
mod emulate;
mod prepare;
mod replay;
mod table;

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, ensure};
use camgeom_host::ar::{RgbImage, contact_sheet};
use camgeom_host::images::{GrayImage, save_gray};

use crate::firmware::{build_and_run_projection, build_bin, size_report};
use crate::jobs::{FULL, HALF, Size};
use crate::util::root;

/// What `cargo xtask run` (or CI) runs.
pub struct Options {
    pub sizes: Vec<Size>,
    /// Every `stride`-th recorded frame.
    pub stride: u32,
}

impl Options {
    /// `cargo xtask run`: every frame, both sizes.
    pub fn full() -> Self {
        Self {
            sizes: vec![FULL, HALF],
            stride: 1,
        }
    }
}

/// The run directory of a size.
pub fn run_dir(size: Size) -> PathBuf {
    root().join("target/camgeom-run").join(size.name())
}

fn shown(p: &Path) -> String {
    p.strip_prefix(root()).unwrap_or(p).display().to_string()
}

/// Writes the overlays as PNGs and a contact sheet (5 columns, labelled with the frame
/// number); returns the sheet's path.
fn write_overlays(dir: &Path, size: Size, overlays: &emulate::Overlays) -> Result<PathBuf> {
    let (w, h) = (size.width as usize, size.height as usize);
    let mut tiles = Vec::new();
    for (i, data) in overlays {
        let img = GrayImage {
            data: data.clone(),
            width: w,
            height: h,
        };
        save_gray(&img, dir.join(format!("overlay-{i:04}.png")))?;
        tiles.push((*i as usize, RgbImage::from_gray(&img)));
    }
    let sheet = dir.join("overlays.png");
    contact_sheet(&tiles, 5, 1).save(&sheet)?;
    Ok(sheet)
}

fn run_size(size: Size, opts: &Options) -> Result<table::Row> {
    let dir = run_dir(size);
    let name = size.name();
    let t = Instant::now();
    let spec = prepare::prepare(size, opts.stride, &dir)?;
    println!(
        "main job {name}: input prepared in {} ({:.1} s)",
        shown(&dir),
        t.elapsed().as_secs_f64()
    );
    let elf = build_bin(size.bin, &[])?;
    let (flash, ram) = size_report(&elf)?;
    let t = Instant::now();
    let board = emulate::run_board(&elf, &dir, size, spec.stride)?;
    let qemu_secs = t.elapsed().as_secs_f64();
    let sheet = write_overlays(&dir, size, &board.overlays)?;

    let t = Instant::now();
    let raw = fs::read(dir.join("frames.raw"))?;
    let (host, host_overlays) = replay::replay_size(size, &spec, &raw)?;
    let host_secs = t.elapsed().as_secs_f64();
    let verdict = compare::compare(&board.frames, &host, &board.overlays, &host_overlays)?;
    println!("main job {name}: {verdict}");
    println!(
        "main job {name}: QEMU {qemu_secs:.1} s, host replay {host_secs:.1} s; overlays: {}",
        shown(&sheet)
    );
    Ok(table::Row::new(
        size,
        &board.frames,
        &board.summary,
        flash,
        ram,
    ))
}

/// `cargo xtask run`.
pub fn run(opts: &Options) -> Result<()> {
    let summary = build_and_run_projection()?;
    println!("projection checks: {summary}");
    let mut rows = Vec::new();
    for &size in &opts.sizes {
        let row = run_size(size, opts)?;
        ensure!(
            row.ram >= row.pipeline_ram,
            "static RAM {} B is less than the pipeline's {} B: the buffers are not in statics",
            row.ram,
            row.pipeline_ram
        );
        rows.push(row);
    }
    println!(
        "\n---- main job cost table (Markdown; fps = 480e6 / mean total, assuming about one \
         instruction per cycle: an estimate) ----\n{}",
        table::table(&rows, opts.stride)
    );
    let measured: Vec<(&str, u64, u64)> =
        rows.iter().map(|r| (r.size.bin, r.flash, r.ram)).collect();
    crate::size::compare(&measured)?;
    Ok(())
}
