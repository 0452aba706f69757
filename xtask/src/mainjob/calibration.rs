//! The calibration job: the emulated Cortex-M7 calibrates its camera from the bundled
//! chessboard views (`host-tests/data/chessboard/left*.jpg`, 13 views of a 9x6 board with
//! 25 mm squares), downscaled to 320x240 with camgeom's `pyrDown` (bit-exact with OpenCV's),
//! and the host runs the same code on the same frames; K, distortion, RMS and every corner
//! must agree within [`TOLERANCE`].
//!
//! Then the ChArUco run ([`run_charuco`]): the same firmware calibrates from ChArUco views
//! that never show the whole board (`host-tests/data/charuco/brown-320x240`, OpenCV renders
//! reduced to 320x240, with their exact camera), checked against the host's run in the same
//! way and against the rendered truth.

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail, ensure};
use camgeom::image::{ImageMut, ImageView};
use camgeom::pyramid::pyr_down;
use camgeom_fw_app::calibration::{
    BoardCalibrator, BoardDetector, CalibError, CalibRecord, CalibSpec, RECORD_LEN, Record,
    SpecBoard, ViewRecord, calibrate, scratch_len,
};
use camgeom_fw_app::charuco_calibration::{
    CHARUCO_RECORD_LEN, CharucoDetection, CharucoRecord, CharucoViewRecord, board_of,
    calibrate_charuco, charuco_calibrator,
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
        board: SpecBoard::Chessboard,
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
    compare_results(&board.1, &host.1, &mut problems);
    if !problems.is_empty() {
        bail!(
            "board and host calibrations disagree:\n  {}",
            problems.join("\n  ")
        );
    }
    Ok(())
}

/// The differences between the board's result `b` and the host's `h` beyond [`TOLERANCE`].
fn compare_results(b: &CalibRecord, h: &CalibRecord, problems: &mut Vec<String>) {
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
    let charuco = run_charuco(&elf, ram, flash)?;
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
        "Chessboard (13 views of 9x6):\n\n\
         | views found (used) | fx fy cx cy (px, 320x240) | k1 k2 p1 p2 k3 | RMS (px) | detection, mean / worst | solve | static RAM | flash | stack |\n\
         |---|---|---|---|---|---|---|---|---|\n\
         | {found} of {} ({}) | {fx:.2} {fy:.2} {cx:.2} {cy:.2} | {k1:.4} {k2:.4} {p1:.5} {p2:.5} {k3:.4} | {:.4} | {:.2}M / {:.2}M | {:.1}M | {ram} B | {flash} B | {} B |\n",
        v.len(),
        r.views_used,
        r.rms_px,
        mean as f64 / 1e6,
        f64::from(worst) / 1e6,
        f64::from(r.cost) / 1e6,
        r.stack
    ) + &charuco)
}

/// The ChArUco set: 10 views of an 11x8 ChArUco board (30 mm squares, 22 mm DICT_4X4_50
/// markers) rendered by OpenCV at 640x480 through a known Brown-Conrady camera, no view
/// showing the whole board, reduced to 320x240 by `cv2.resize(INTER_AREA)`
/// (`charuco_render.py qvga`), with the truth camera scaled to match (`truth.yaml`).
const CHARUCO_SET: &str = "charuco/brown-320x240";

/// The rendered truth: `fx fy cx cy` and `k1 k2 p1 p2 k3`.
struct Truth {
    intrinsics: [f32; 4],
    distortion: [f32; 5],
}

/// The numbers of `key: [a, b, ...]` in the truth file's `text`.
fn yaml_list(text: &str, key: &str) -> Result<Vec<f32>> {
    let line = text
        .lines()
        .find(|l| l.starts_with(key))
        .with_context(|| format!("truth.yaml: no {key}"))?;
    let inner = line
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .with_context(|| format!("truth.yaml: {key} is not a list"))?
        .0;
    inner
        .split(',')
        .map(|x| {
            x.trim()
                .parse()
                .with_context(|| format!("truth.yaml: {key}: `{x}`"))
        })
        .collect()
}

/// The ChArUco views at 320x240 in `dir` (`frames.raw`), the run description (`calib.bin`)
/// and the truth.
fn prepare_charuco(dir: &Path) -> Result<(CalibSpec, Truth)> {
    fs::create_dir_all(dir)?;
    let src = camgeom_host::data_dir().join(CHARUCO_SET);
    let mut names: Vec<PathBuf> = fs::read_dir(&src)
        .with_context(|| format!("cannot read {}", src.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    ensure!(
        names.len() == 10,
        "expected the 10 ChArUco views, found {}",
        names.len()
    );
    let mut raw = Vec::new();
    for n in &names {
        let img = load_gray(n)?;
        ensure!(
            (img.width, img.height) == (320, 240),
            "{}: not 320x240",
            n.display()
        );
        raw.extend_from_slice(&img.data);
    }
    fs::write(dir.join("frames.raw"), &raw)?;
    let spec = CalibSpec {
        width: 320,
        height: 240,
        frames: names.len() as u32,
        cols: 11,
        rows: 8,
        square: 0.030,
        board: SpecBoard::Charuco {
            marker: 0.022,
            // OpenCV's DICT_4X4_50.
            dictionary: 0,
        },
    };
    fs::write(dir.join("calib.bin"), spec.to_bytes())?;
    let _ = fs::remove_file(dir.join("calib-report.bin"));
    let text = fs::read_to_string(src.join("truth.yaml"))?;
    let k = yaml_list(&text, "camera_matrix")?;
    let d = yaml_list(&text, "distortion")?;
    ensure!(
        k.len() == 9 && d.len() == 5,
        "truth.yaml: not a 3x3 K and 5 coefficients"
    );
    Ok((
        spec,
        Truth {
            intrinsics: [k[0], k[4], k[2], k[5]],
            distortion: [d[0], d[1], d[2], d[3], d[4]],
        },
    ))
}

/// The host's run of the ChArUco job: every view record and the result.
fn replay_charuco(spec: &CalibSpec, raw: &[u8]) -> Result<(Vec<CharucoViewRecord>, CalibRecord)> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut camera = RecordedCamera::new(
        SliceFrames::new(raw, w, h),
        1,
        spec.frames as usize,
        FaultPlan::none(),
    );
    let mut frame = vec![0u8; w * h];
    let board = board_of(spec)?;
    let detector = camgeom::apriltag::Detector::new(
        camgeom::apriltag::DetectorConfig::default(),
        &[board.dictionary()],
    )?;
    let mut ws: Box<camgeom::apriltag::Workspace320x240> = Box::default();
    let mut view = ws.as_mut_view();
    let params = camgeom::charuco::CharucoParams::default();
    let mut detection = CharucoDetection {
        board: &board,
        detector: &detector,
        workspace: &mut view,
        params: &params,
    };
    let mut calibrator = Box::new(charuco_calibrator(&board, w, h)?);
    let mut views = Vec::new();
    let result = calibrate_charuco(
        spec,
        &mut camera,
        &mut frame,
        &mut detection,
        &mut calibrator,
        &mut NoClock,
        &mut |v| views.push(v.clone()),
    )
    .map_err(|e| match e {
        CalibError::Source(s) => anyhow!("host ChArUco calibration: frame source: {s:?}"),
        CalibError::Core(c) => anyhow!("host ChArUco calibration: {c}"),
    })?;
    Ok((views, result))
}

fn read_charuco_report(path: &Path) -> Result<(Vec<CharucoViewRecord>, CalibRecord)> {
    let bytes = fs::read(path).with_context(|| format!("the board wrote no {}", path.display()))?;
    ensure!(
        bytes.len().is_multiple_of(CHARUCO_RECORD_LEN),
        "{}: truncated",
        path.display()
    );
    let (mut views, mut result) = (Vec::new(), None);
    for c in bytes.chunks_exact(CHARUCO_RECORD_LEN) {
        match CharucoRecord::decode(c).map_err(|e| anyhow!("{}: {e}", path.display()))? {
            CharucoRecord::View(v) if result.is_none() => views.push(v),
            CharucoRecord::Result(r) if result.is_none() => result = Some(r),
            _ => bail!("{}: a record after the result", path.display()),
        }
    }
    Ok((
        views,
        result.context("the board wrote no ChArUco calibration result")?,
    ))
}

/// Board against host: the same corners (ids, and positions within [`TOLERANCE`] of the
/// width) in every view and the same result ([`compare_results`]).
fn compare_charuco(
    board: &(Vec<CharucoViewRecord>, CalibRecord),
    host: &(Vec<CharucoViewRecord>, CalibRecord),
) -> Result<()> {
    let mut problems = Vec::new();
    ensure!(
        board.0.len() == host.0.len(),
        "board {} views, host {}",
        board.0.len(),
        host.0.len()
    );
    for (b, h) in board.0.iter().zip(&host.0) {
        let ids = |v: &CharucoViewRecord| v.corners.iter().map(|c| c.id).collect::<Vec<_>>();
        if (b.markers, ids(b)) != (h.markers, ids(h)) {
            problems.push(format!(
                "frame {}: markers {} / {}, corner ids {:?} / {:?}",
                b.frame,
                b.markers,
                h.markers,
                ids(b),
                ids(h)
            ));
            continue;
        }
        let worst = b
            .corners
            .iter()
            .zip(&h.corners)
            .map(|(p, q)| (p.point - q.point).abs().max())
            .fold(0.0f32, f32::max);
        if worst > TOLERANCE * 320.0 {
            problems.push(format!("frame {}: corners differ by {worst} px", b.frame));
        }
    }
    compare_results(&board.1, &host.1, &mut problems);
    if !problems.is_empty() {
        bail!(
            "board and host ChArUco calibrations disagree:\n  {}",
            problems.join("\n  ")
        );
    }
    Ok(())
}

/// The result against the rendered truth: each of `fx fy cx cy` and the five coefficients
/// within three of the standard deviations the calibration reports for it (a calibration that
/// is wrong beyond its own stated uncertainty is a failure); returns the errors.
fn against_truth(r: &CalibRecord, truth: &Truth) -> Result<([f32; 4], [f32; 5])> {
    let dk: [f32; 4] = std::array::from_fn(|i| r.intrinsics[i] - truth.intrinsics[i]);
    let dd: [f32; 5] = std::array::from_fn(|i| r.distortion[i] - truth.distortion[i]);
    let names = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];
    let bad: Vec<String> = dk
        .iter()
        .chain(&dd)
        .zip(&r.std)
        .zip(names)
        // NaN (an error or a deviation) fails too.
        .filter(|((e, s), _)| {
            !matches!(
                e.abs().partial_cmp(&(3.0 * **s)),
                Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
            )
        })
        .map(|((e, s), n)| format!("{n} off by {e} (std {s})"))
        .collect();
    ensure!(
        bad.is_empty(),
        "the ChArUco calibration is off the rendered truth by more than 3 standard deviations: {}",
        bad.join(", ")
    );
    Ok((dk, dd))
}

/// The ChArUco run of the calibration job on the firmware `elf` (static RAM `ram`, flash
/// `flash`); returns its Markdown table.
fn run_charuco(elf: &Path, ram: u64, flash: u64) -> Result<String> {
    let dir = root().join("target/camgeom-run/calib-charuco");
    let t = Instant::now();
    let (spec, truth) = prepare_charuco(&dir)?;
    let raw = fs::read(dir.join("frames.raw"))?;
    let host = replay_charuco(&spec, &raw)?;
    let (line, _) = run_on_qemu_in(
        M7,
        elf,
        Some(&dir),
        "charuco calibration: ",
        " views used",
        None,
    )?;
    let board = read_charuco_report(&dir.join("calib-report.bin"))?;
    compare_charuco(&board, &host)?;
    let (v, r) = &board;
    let (dk, dd) = against_truth(r, &truth)?;
    let found = v.iter().filter(|v| !v.corners.is_empty()).count();
    let corners: usize = v.iter().map(|v| v.corners.len()).sum();
    let costs: Vec<u32> = v.iter().map(|v| v.cost).collect();
    let total: u64 = costs.iter().map(|&c| u64::from(c)).sum();
    let mean = total / costs.len().max(1) as u64;
    let worst = costs.iter().copied().max().unwrap_or(0);
    let [fx, fy, cx, cy] = r.intrinsics;
    let [tfx, tfy, tcx, tcy] = truth.intrinsics;
    let dmax = dd.iter().fold(0.0f32, |m, e| m.max(e.abs()));
    println!(
        "calibration job {} 320x240 ChArUco: the board calibrates from {} views that never show \
         the whole board and agrees with the host run within {TOLERANCE:e}; K off the rendered \
         truth by {:.2} {:.2} {:.2} {:.2} px (within 3 std) ({found} of {} views with corners, \
         {corners} corners, {} used; {:.1} s)",
        M7.name,
        v.len(),
        dk[0].abs(),
        dk[1].abs(),
        dk[2].abs(),
        dk[3].abs(),
        v.len(),
        r.views_used,
        t.elapsed().as_secs_f64()
    );
    Ok(format!(
        "\nChArUco (10 views of an 11x8 board, none whole; truth fx fy cx cy {tfx} {tfy} {tcx} {tcy}):\n\n\
         | views with corners (used) | corners | fx fy cx cy (px, 320x240) | \\|dfx\\| \\|dfy\\| \\|dcx\\| \\|dcy\\| px | max \\|d dist\\| | RMS (px) | detection, mean / worst / all views | solve | static RAM | flash | stack |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n\
         | {found} of {} ({}) | {corners} | {fx:.2} {fy:.2} {cx:.2} {cy:.2} | {:.3} {:.3} {:.3} {:.3} | {dmax:.4} | {:.4} | {:.2}M / {:.2}M / {:.1}M | {:.1}M | {ram} B | {flash} B | {} B |\n\n\
         The board: `{line}`\n",
        v.len(),
        r.views_used,
        dk[0].abs(),
        dk[1].abs(),
        dk[2].abs(),
        dk[3].abs(),
        r.rms_px,
        mean as f64 / 1e6,
        f64::from(worst) / 1e6,
        total as f64 / 1e6,
        f64::from(r.cost) / 1e6,
        r.stack
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(intrinsics: [f32; 4], std: f32) -> CalibRecord {
        CalibRecord {
            views_used: 10,
            iterations: 5,
            cost: 0,
            warnings: 0,
            intrinsics,
            distortion: [-0.3, 0.1, 0.001, -0.0008, -0.015],
            rms_px: 0.1,
            initial_rms_px: 0.5,
            std: [std; 9],
            per_view_rms_px: [0.1; camgeom_fw_app::calibration::VIEWS],
            stack: 0,
        }
    }

    #[test]
    fn the_truth_check_refuses_a_result_off_its_own_uncertainty() {
        let truth = Truth {
            intrinsics: [260.0, 258.0, 161.0, 118.75],
            distortion: [-0.3, 0.1, 0.001, -0.0008, -0.015],
        };
        let near = record([260.2, 257.9, 161.1, 118.7], 0.1);
        let (dk, _) = against_truth(&near, &truth).unwrap();
        assert!((dk[0] - 0.2).abs() < 1e-3);
        // fx off by 0.4 with a stated deviation of 0.1: refused.
        assert!(against_truth(&record([260.4, 258.0, 161.0, 118.75], 0.1), &truth).is_err());
        // A NaN deviation or result is refused, not passed.
        assert!(against_truth(&record([260.0, 258.0, 161.0, 118.75], f32::NAN), &truth).is_err());
        assert!(against_truth(&record([f32::NAN, 258.0, 161.0, 118.75], 0.1), &truth).is_err());
    }
}
