//! The calibration job: the emulated Cortex-M7 calibrates its camera from the bundled
//! chessboard views (`host-tests/data/chessboard/left*.jpg`, 13 views of a 9x6 board with
//! 25 mm squares), downscaled to 320x240 with camgeom's `pyrDown` (bit-exact with OpenCV's),
//! and the host runs the same code on the same frames; K, distortion, RMS and every corner
//! must agree within [`TOLERANCE`].

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail, ensure};
use camgeom::image::{ImageMut, ImageView};
use camgeom::pyramid::pyr_down;
use camgeom_fw_app::calibration::{
    BoardCalibrator, BoardDetector, CalibError, CalibRecord, CalibSpec, RECORD_LEN, Record,
    ViewRecord, calibrate, scratch_len,
};
use camgeom_fw_app::pipeline::NoClock;
use camgeom_fw_app::recorded::{FaultPlan, RecordedCamera, SliceFrames};
use camgeom_host::images::load_gray;

use crate::firmware::{build_bin_for, run_on_qemu_in, size_of};
use crate::jobs::M7;
use crate::util::root;

/// Board and host run the same f32 code; the main job sees them differ by at most a few ulp
/// (3e-7 relative) where the code generators order independent operations differently. A
/// 13-view Levenberg-Marquardt solve can carry such a difference into the result at about
/// the solver's own tolerance, far below 1e-4; a different corner or view (a real
/// divergence) moves K by 1e-3 or more. So: relative 1e-4 on K, RMS and each corner's
/// coordinates, absolute 1e-4 on the lens coefficients.
pub const TOLERANCE: f32 = 1e-4;

pub const BIN: &str = "camgeom-fw-calib";

/// The 13 bundled views at 320x240 in `dir` (`frames.raw`), and the run description (`calib.bin`).
pub(super) fn prepare(dir: &Path) -> Result<CalibSpec> {
    fs::create_dir_all(dir)?;
    let src = camgeom_host::data_dir().join("chessboard");
    let mut names: Vec<PathBuf> = fs::read_dir(&src)
        .with_context(|| format!("cannot read {}", src.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("left"))
                && p.extension().is_some_and(|e| e == "jpg")
        })
        .collect();
    names.sort();
    ensure!(
        names.len() == 13,
        "expected the 13 bundled views, found {}",
        names.len()
    );
    let mut raw = Vec::new();
    for n in &names {
        let img = load_gray(n)?;
        ensure!(
            (img.width, img.height) == (640, 480),
            "{}: not 640x480",
            n.display()
        );
        let v = ImageView::packed(&img.data, 640, 480)?;
        let mut out = vec![0u8; 320 * 240];
        pyr_down(&v, &mut ImageMut::packed(&mut out, 320, 240)?)?;
        raw.extend_from_slice(&out);
    }
    fs::write(dir.join("frames.raw"), &raw)?;
    let spec = CalibSpec {
        width: 320,
        height: 240,
        frames: names.len() as u32,
        cols: 9,
        rows: 6,
        square: 0.025,
    };
    fs::write(dir.join("calib.bin"), spec.to_bytes())?;
    let _ = fs::remove_file(dir.join("calib-report.bin"));
    Ok(spec)
}

/// The host's run of the same code: every view record and the result.
fn replay(spec: &CalibSpec, raw: &[u8]) -> Result<(Vec<ViewRecord>, CalibRecord)> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut camera = RecordedCamera::new(
        SliceFrames::new(raw, w, h),
        1,
        spec.frames as usize,
        FaultPlan::none(),
    );
    let mut frame = vec![0u8; w * h];
    let mut detector: Box<BoardDetector> = Box::default();
    let mut scratch = vec![0i32; scratch_len(w)];
    let board = camgeom::chessboard::BoardSize::new(spec.cols as usize, spec.rows as usize)?;
    let mut calibrator = Box::new(BoardCalibrator::new(board, spec.square, w, h)?);
    let mut views = Vec::new();
    let result = calibrate(
        spec,
        &mut camera,
        &mut frame,
        &mut detector,
        &mut scratch,
        &mut calibrator,
        &mut NoClock,
        &mut |v| views.push(v.clone()),
    )
    .map_err(|e| match e {
        CalibError::Source(s) => anyhow!("host calibration: frame source: {s:?}"),
        CalibError::Core(c) => anyhow!("host calibration: {c}"),
    })?;
    Ok((views, result))
}

fn read_report(path: &Path) -> Result<(Vec<ViewRecord>, CalibRecord)> {
    let bytes = fs::read(path).with_context(|| format!("the board wrote no {}", path.display()))?;
    ensure!(
        bytes.len().is_multiple_of(RECORD_LEN),
        "{}: truncated",
        path.display()
    );
    let (mut views, mut result) = (Vec::new(), None);
    for c in bytes.chunks_exact(RECORD_LEN) {
        match Record::decode(c).map_err(|e| anyhow!("{}: {e}", path.display()))? {
            Record::View(v) if result.is_none() => views.push(v),
            Record::Result(r) if result.is_none() => result = Some(r),
            _ => bail!("{}: a record after the result", path.display()),
        }
    }
    Ok((
        views,
        result.context("the board wrote no calibration result")?,
    ))
}

pub(super) fn close(a: f32, b: f32, scale: f32) -> bool {
    (a - b).abs() <= TOLERANCE * scale.max(1e-12)
}

fn compare(
    board: &(Vec<ViewRecord>, CalibRecord),
    host: &(Vec<ViewRecord>, CalibRecord),
) -> Result<()> {
    let mut problems = Vec::new();
    ensure!(
        board.0.len() == host.0.len(),
        "board {} views, host {}",
        board.0.len(),
        host.0.len()
    );
    for (b, h) in board.0.iter().zip(&host.0) {
        match (&b.corners, &h.corners) {
            (Some(p), Some(q)) => {
                let worst = p
                    .iter()
                    .zip(q.iter())
                    .map(|(a, c)| (a[0] - c[0]).abs().max((a[1] - c[1]).abs()))
                    .fold(0.0f32, f32::max);
                if p.len() != q.len() || worst > TOLERANCE * 320.0 {
                    problems.push(format!("frame {}: corners differ by {worst} px", b.frame));
                }
            }
            (None, None) => {}
            _ => problems.push(format!(
                "frame {}: the board found on one side only",
                b.frame
            )),
        }
    }
    let (b, h) = (&board.1, &host.1);
    if (b.views_used, b.warnings) != (h.views_used, h.warnings) {
        problems.push(format!(
            "views used {} / {}, warnings {:#x} / {:#x}",
            b.views_used, h.views_used, b.warnings, h.warnings
        ));
    }
    for (x, y) in b.intrinsics.iter().zip(&h.intrinsics) {
        if !close(*x, *y, y.abs()) {
            problems.push(format!(
                "K board {:?}, host {:?}",
                b.intrinsics, h.intrinsics
            ));
            break;
        }
    }
    for (x, y) in b.distortion.iter().zip(&h.distortion) {
        if !close(*x, *y, 1.0) {
            problems.push(format!(
                "distortion board {:?}, host {:?}",
                b.distortion, h.distortion
            ));
            break;
        }
    }
    if !close(b.rms_px, h.rms_px, h.rms_px) {
        problems.push(format!("RMS board {}, host {}", b.rms_px, h.rms_px));
    }
    if !problems.is_empty() {
        bail!(
            "board and host calibrations disagree:\n  {}",
            problems.join("\n  ")
        );
    }
    Ok(())
}

/// `cargo xtask run`'s calibration job on the reference board; returns its Markdown summary.
pub fn run() -> Result<String> {
    let dir = root().join("target/camgeom-run/calib");
    let t = Instant::now();
    let spec = prepare(&dir)?;
    let raw = fs::read(dir.join("frames.raw"))?;
    let host = replay(&spec, &raw)?;
    let elf = build_bin_for(M7, BIN, &[])?;
    let (flash, ram, _) = size_of(M7, &elf)?;
    run_on_qemu_in(M7, &elf, Some(&dir), "calibration: ", " views used", None)?;
    let board = read_report(&dir.join("calib-report.bin"))?;
    compare(&board, &host)?;
    let (v, r) = &board;
    let found = v.iter().filter(|v| v.corners.is_some()).count();
    let costs: Vec<u32> = v.iter().map(|v| v.cost).collect();
    let mean = costs.iter().map(|&c| u64::from(c)).sum::<u64>() / costs.len().max(1) as u64;
    let worst = costs.iter().copied().max().unwrap_or(0);
    let [fx, fy, cx, cy] = r.intrinsics;
    let [k1, k2, p1, p2, k3] = r.distortion;
    println!(
        "calibration job {} 320x240: the board calibrates on QEMU and agrees with the host run \
         within {TOLERANCE:e} ({found} of {} views found, {} used; {:.1} s)",
        M7.name,
        v.len(),
        r.views_used,
        t.elapsed().as_secs_f64()
    );
    Ok(format!(
        "| views found (used) | fx fy cx cy (px, 320x240) | k1 k2 p1 p2 k3 | RMS (px) | detection, mean / worst | solve | static RAM | flash | stack |\n\
         |---|---|---|---|---|---|---|---|---|\n\
         | {found} of {} ({}) | {fx:.2} {fy:.2} {cx:.2} {cy:.2} | {k1:.4} {k2:.4} {p1:.5} {p2:.5} {k3:.4} | {:.4} | {:.2}M / {:.2}M | {:.1}M | {ram} B | {flash} B | {} B |\n",
        v.len(),
        r.views_used,
        r.rms_px,
        mean as f64 / 1e6,
        f64::from(worst) / 1e6,
        f64::from(r.cost) / 1e6,
        r.stack
    ))
}
