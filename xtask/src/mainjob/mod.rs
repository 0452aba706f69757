//! `cargo xtask run`: the main job on every emulated board, and the host-vs-board check.
//!
//! 1. The projection checks (`camgeom-fw-projection`) run first on the reference board (the
//!    Cortex-M7): small and quick.
//! 2. For each frame size (320x240 and 160x120), [`prepare`] turns the bundled sequence
//!    `host-tests/data/sequences/box/*.png` into raw grayscale frames (`frames.raw`; 160x120 is
//!    the `pyrDown` of each frame) and a run description (`run.bin`: the camera from
//!    `box-camera.yml`, the lid corners from `box-top.csv`, both scaled to the frame size) in
//!    `target/camgeom-run/<size>/`, and [`replay`] runs the same `camgeom-fw-app` pipeline,
//!    compiled for the host, on the same bytes.
//! 3. [`emulate`]: on each board (`crate::jobs::BOARDS`) the firmware built for its target runs
//!    on QEMU in that directory, reads both over semihosting and writes its binary report
//!    (`report.bin`, one record a frame and a summary) and overlay frames back; the reference
//!    board's overlays become PNGs and a contact sheet `overlays.png` here.
//! 4. [`compare`]: every board must agree with the host replay on every frame: state, counts
//!    and error exactly, the checksum of the Q16.16 track positions bit for bit, the overlays
//!    byte for byte, and both f32 poses within [`compare::POSE_TOLERANCE`].
//! 5. [`table`]: the per-stage cost table of every board in Markdown (BENCHMARKS.md takes it
//!    verbatim), each board's ratio to the reference.
//! 6. On the reference board also: the fault job, the forward-backward job (the check on, its
//!    templates computed and kept, both against the host replay), the tag job and the
//!    calibration job.

mod calibrate_boot;
mod calibration;
mod commands;
mod compare;
mod emulate;
mod faults;
mod live;
mod prepare;
mod replay;
mod stream;
mod table;
mod tag;

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, ensure};
use camgeom_fw_app::recorded::FaultPlan;
use camgeom_host::contact_sheet::contact_sheet;
use camgeom_host::images::{GrayImage, save_gray};
use camgeom_host::rgb::{Overlay, RgbImage};

use crate::firmware::{
    PROJECTION_BIN, build_and_run_projection, build_bin_for, build_bins_for, build_bins_for_all,
    size_of,
};
use crate::jobs::{BOARDS, Board, FULL, HALF, M7, Size, snapshot_key};
use crate::util::root;

/// What `cargo xtask run` (or CI) runs.
pub struct Options {
    pub boards: Vec<Board>,
    pub sizes: Vec<Size>,
    /// Every `stride`-th recorded frame.
    pub stride: u32,
}

impl Options {
    /// `cargo xtask run`: every board, both sizes, every frame.
    pub fn full() -> Self {
        Self::boards(BOARDS.to_vec())
    }

    /// `cargo xtask run --board NAME`: those boards, both sizes, every frame.
    pub fn boards(boards: Vec<Board>) -> Self {
        Self {
            boards,
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
    contact_sheet(&tiles, 5, 1).save_png(&sheet)?;
    Ok(sheet)
}

/// One board and size: build, run, compare with the host replay; returns its table row.
fn run_board(
    board: Board,
    size: Size,
    dir: &Path,
    stride: u32,
    host: &replay::Replay,
) -> Result<table::Row> {
    let elf = build_bin_for(board, size.bin, &[])?;
    let (flash, ram, _) = size_of(board, &elf)?;
    let t = Instant::now();
    let run = emulate::run_board(board, &elf, dir, size, stride)?;
    let qemu_secs = t.elapsed().as_secs_f64();
    let verdict = compare::compare(&run.frames, &host.0, &run.overlays, &host.1)?;
    let row = table::Row::new(board, size, &run.frames, &run.summary, flash, ram);
    ensure!(
        row.ram >= row.pipeline_ram,
        "{} {}: static RAM {} B is less than the pipeline's {} B: the buffers are not in statics",
        board.name,
        size.name(),
        row.ram,
        row.pipeline_ram
    );
    let sheet = if board == M7 {
        format!(
            ", overlays {}",
            shown(&write_overlays(dir, size, &run.overlays)?)
        )
    } else {
        String::new()
    };
    println!(
        "main job {} {} ({}): {verdict}; {:.2}M instructions a frame, QEMU {qemu_secs:.1} s{sheet}",
        board.name,
        size.name(),
        board.core,
        row.mean_total() as f64 / 1e6
    );
    Ok(row)
}

/// The fault job on the reference board (see [`faults`]): prints its table.
fn fault_job(stride: u32) -> Result<()> {
    let size = FULL;
    let dir = root().join("target/camgeom-run/faults");
    let t = Instant::now();
    let spec = prepare::prepare(size, stride, &dir)?;
    let plan = faults::plan()?;
    fs::write(dir.join("faults.bin"), plan.to_bytes())?;
    let raw = fs::read(dir.join("frames.raw"))?;
    let host = replay::replay_size(size, &spec, &plan, &raw)?;
    let elf = build_bin_for(M7, size.bin, &[])?;
    let run = emulate::run_board(M7, &elf, &dir, size, stride)?;
    let verdict = compare::compare(&run.frames, &host.0, &run.overlays, &host.1)?;
    let rows = faults::check(&plan, &run.frames, host.0.len())?;
    println!(
        "fault job {} {} ({} fault spans): {verdict}; every frame reported, the target found again \
         after every fault ({:.1} s)\n\n{}",
        M7.name,
        size.name(),
        plan.spans().count(),
        t.elapsed().as_secs_f64(),
        faults::table(&rows)
    );
    Ok(())
}

/// The firmware of the forward-backward job that keeps the check's templates.
const KEPT_BIN: &str = "camgeom-fw-kept";

/// The forward-backward job on the reference board: the main job at 320x240 with the
/// forward-backward check on, run by the main firmware (every template computed) and by
/// [`KEPT_BIN`] (the backward pass's templates kept for the next frame's forward pass), each
/// checked against the host replay (which computes every template); returns its table.
fn forward_backward_job(stride: u32) -> Result<String> {
    let size = FULL;
    let dir = root().join("target/camgeom-run/forward-backward");
    let mut spec = prepare::prepare(size, stride, &dir)?;
    spec.forward_backward = true;
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    let raw = fs::read(dir.join("frames.raw"))?;
    let host = replay::replay_size(size, &spec, &FaultPlan::none(), &raw)?;
    let mut out = String::from(
        "| firmware | templates | flow (mean / worst) | total (mean / worst) | static RAM |\n\
         |---|---|---|---|---|\n",
    );
    for (bin, what) in [(size.bin, "computed"), (KEPT_BIN, "kept")] {
        let elf = build_bin_for(M7, bin, &[])?;
        let (flash, ram, _) = size_of(M7, &elf)?;
        let t = Instant::now();
        let run = emulate::run_board(M7, &elf, &dir, size, stride)?;
        let verdict = compare::compare(&run.frames, &host.0, &run.overlays, &host.1)?;
        let row = table::Row::new(M7, size, &run.frames, &run.summary, flash, ram);
        let ((fm, fw), (tm, tw)) = (row.stage("flow"), row.stage("total"));
        println!(
            "forward-backward job {} {} ({bin}, templates {what}): {verdict}; {} instructions a \
             frame, QEMU {:.1} s",
            M7.name,
            size.name(),
            table::m(tm),
            t.elapsed().as_secs_f64()
        );
        out += &format!(
            "| `{bin}` | {what} | {} / {} | {} / {} | {ram} B |\n",
            table::m(fm),
            table::m(u64::from(fw)),
            table::m(tm),
            table::m(u64::from(tw))
        );
    }
    Ok(out)
}

/// Every binary the run needs, built up front: the sizes' binaries for every board of an
/// architecture in one cargo call (the targets compile side by side), then the reference board's own binaries
/// (their links run in parallel; see [`build_bins_for`]).
fn prebuild(opts: &Options) -> Result<()> {
    let mut bins: Vec<&str> = opts.sizes.iter().map(|s| s.bin).collect();
    bins.sort_unstable();
    bins.dedup();
    // One call per architecture: a call for Arm and RISC-V targets together would unify their
    // dependencies' features (critical-section's restore state is `u32` on Cortex-M, `bool` on
    // riscv-rt) and fail.
    let (arm, other): (Vec<Board>, Vec<Board>) = opts
        .boards
        .iter()
        .partition(|b| b.target.starts_with("thumb"));
    for group in [arm, other] {
        if !group.is_empty() {
            build_bins_for_all(&group, &bins)?;
        }
    }
    if opts.boards.contains(&M7) {
        build_bins_for(
            M7,
            &[PROJECTION_BIN, KEPT_BIN, tag::SIZE.bin, calibration::BIN],
        )?;
    }
    Ok(())
}

/// `cargo xtask run`.
pub fn run(opts: &Options) -> Result<()> {
    let t = Instant::now();
    prebuild(opts)?;
    println!(
        "main job: firmware built for {} board(s) ({:.1} s)",
        opts.boards.len(),
        t.elapsed().as_secs_f64()
    );
    if opts.boards.contains(&M7) {
        let summary = build_and_run_projection()?;
        println!("projection checks: {summary}");
    }
    let mut rows = Vec::new();
    for &size in &opts.sizes {
        let dir = run_dir(size);
        let t = Instant::now();
        let spec = prepare::prepare(size, opts.stride, &dir)?;
        let raw = fs::read(dir.join("frames.raw"))?;
        let host = replay::replay_size(size, &spec, &FaultPlan::none(), &raw)?;
        if let Some((k, r)) = host.0.iter().find(|(_, r)| r.error.is_some()) {
            anyhow::bail!(
                "main job {}: frame {k} failed with {} on the host",
                size.name(),
                r.error.map_or("?", |e| e.name())
            );
        }
        println!(
            "main job {}: input prepared in {} and replayed on the host ({:.1} s)",
            size.name(),
            shown(&dir),
            t.elapsed().as_secs_f64()
        );
        for &board in &opts.boards {
            rows.push(run_board(board, size, &dir, spec.stride, &host)?);
        }
    }
    let extra = if opts.boards.contains(&M7) {
        fault_job(opts.stride)?;
        let fb = forward_backward_job(opts.stride)?;
        let t = tag::run(opts.stride)?;
        println!("{}", commands::run()?);
        Some((fb, t, calibration::run()?))
    } else {
        None
    };
    println!(
        "\n---- main job cost table (Markdown; fps = 480e6 / mean total on the Cortex-M7, assuming \
         about one instruction per cycle: an estimate) ----\n{}",
        table::table(&rows, opts.stride)
    );
    if let Some((fb, t, c)) = extra {
        println!("---- forward-backward job (instructions on the Cortex-M7, 320x240) ----\n{fb}");
        println!("---- tag job (instructions on the Cortex-M7) ----\n{t}");
        println!("---- calibration job (instructions on the Cortex-M7) ----\n{c}");
    }
    let measured: Vec<crate::size::Measured> = rows
        .iter()
        .map(|r| crate::size::Measured {
            bin: snapshot_key(r.board, r.size.bin),
            flash: r.flash,
            ram: r.ram,
            stack: Some(r.stack),
        })
        .collect();
    crate::size::compare(&measured)?;
    Ok(())
}
