//! The commands job's calibrate boots: the tag job's board, switched to the calibrate mode
//! over its link, calibrates its camera from the calibration job's frames (the 13 bundled
//! chessboard views at 320x240, [`super::calibration`]) and keeps it in flash; the next boot
//! loads it.
//!
//! 1. The board boots with the flash the commands boots left (a tag side twice the true one)
//!    and receives `chessboard 9x6, 25 mm, 12 views` and `mode calibrate`. It must answer both
//!    done; report one progress record a frame, the result and the verdict (calibrated), then
//!    the settings it runs with; and each must equal the host's run of the same code on the
//!    same frames (the progress, the verdict, K, distortion and RMS within the calibration
//!    job's [`TOLERANCE`]). `flash.bin` must then hold those settings: the board's calibrated
//!    camera bit for bit, the tag unchanged, the mode back to track-tag.
//! 2. The board boots again and is switched to stream-frames for one frame: the settings it
//!    streams (loaded from the flash) must hold that camera bit for bit.

use std::fs;
use std::mem::MaybeUninit;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail, ensure};
use camgeom::image::ImageMut;
use camgeom_fw_app::calibrate_mode::{
    Buffers, PROGRESS_TAG, ProgressRecord, RESULT_TAG, Status, calibrate_mode, decode_result,
};
use camgeom_fw_app::calibration::{BoardCalibrator, BoardDetector, CalibRecord, scratch_len};
use camgeom_fw_app::command::{ACK_TAG, Ack, AckStatus, ChessboardSettings, Command, Mode};
use camgeom_fw_app::pipeline::NoClock;
use camgeom_fw_app::recorded::{FaultPlan, RecordedCamera, SliceFrames};
use camgeom_fw_app::run::RunSpec;
use camgeom_fw_app::settings::{SETTINGS_LEN, SETTINGS_TAG, Settings};

use super::calibration::{TOLERANCE, close, prepare};
use super::emulate;
use super::stream::{decode, frame};
use super::tag::SIZE;
use crate::firmware::run_on_qemu_with;
use crate::jobs::M7;

/// The calibrate mode's chessboard the first boot is told: the bundled one (9x6, 25 mm), 12
/// views (of its 13).
pub(super) const BOARD: ChessboardSettings = ChessboardSettings {
    cols: 9,
    rows: 6,
    square: 0.025,
    views: 12,
};

/// What a calibrate mode sent: its progress records, its result, its verdict, and the
/// settings sent after it (the board's only).
struct Calibration {
    progress: Vec<ProgressRecord>,
    result: Option<CalibRecord>,
    verdict: ProgressRecord,
    settings: Option<Settings>,
}

/// Sorts a calibrate mode's records (after the answers to commands).
fn records<'a>(records: impl IntoIterator<Item = &'a [u8]>) -> Result<Calibration> {
    let (mut progress, mut result, mut settings) = (Vec::new(), None, None);
    for rec in records {
        let tag = rec
            .get(..4)
            .map(|t| u32::from_le_bytes([t[0], t[1], t[2], t[3]]));
        match tag {
            Some(PROGRESS_TAG) => {
                progress.push(ProgressRecord::decode(rec).map_err(|e| anyhow!("{e}"))?)
            }
            Some(RESULT_TAG) => result = Some(decode_result(rec).map_err(|e| anyhow!("{e}"))?),
            Some(SETTINGS_TAG) => {
                settings = Some(Settings::decode(rec).map_err(|e| anyhow!("{e}"))?)
            }
            _ => bail!("an unexpected record of {} bytes", rec.len()),
        }
    }
    let verdict = progress.pop().context("no progress record")?;
    ensure!(
        verdict.status != Status::Collecting
            && progress.iter().all(|p| p.status == Status::Collecting),
        "the verdict is not the last progress record"
    );
    Ok(Calibration {
        progress,
        result,
        verdict,
        settings,
    })
}

/// The host's run of the board's code on the same frames and settings; what it would store.
fn host_run(raw: &[u8], spec: &RunSpec, settings: &Settings) -> Result<(Calibration, Settings)> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut camera = RecordedCamera::new(
        SliceFrames::new(raw, w, h),
        1,
        spec.frames as usize,
        FaultPlan::none(),
    );
    let mut pixels = vec![0u8; w * h];
    let mut frame = ImageMut::packed(&mut pixels, w, h)?;
    let mut detector: Box<BoardDetector> = Box::default();
    let mut scratch = vec![0i32; scratch_len(w)];
    let mut calibrator: Box<MaybeUninit<BoardCalibrator>> = Box::new(MaybeUninit::uninit());
    let mut sent: Vec<Vec<u8>> = Vec::new();
    let mut saved = None;
    let outcome = calibrate_mode(
        settings,
        Mode::TrackTag,
        &mut camera,
        &mut frame,
        Buffers {
            detector: &mut detector,
            scratch: &mut scratch,
            calibrator: &mut calibrator,
        },
        &mut NoClock,
        &mut |r| sent.push(r.to_vec()),
        |s| {
            saved = Some(*s);
            Ok(())
        },
    )
    .map_err(|e| anyhow!("host calibrate mode: {e:?}"))?;
    let cal = records(sent.iter().map(|r| &r[..]))?;
    ensure!(
        saved == Some(outcome.settings),
        "the host run saved {saved:?}, not {:?}",
        outcome.settings
    );
    Ok((cal, outcome.settings))
}

/// Board and host results within the calibration job's tolerance.
fn agree(b: &CalibRecord, h: &CalibRecord) -> Result<()> {
    let k = b
        .intrinsics
        .iter()
        .zip(&h.intrinsics)
        .all(|(x, y)| close(*x, *y, y.abs()));
    let d = b
        .distortion
        .iter()
        .zip(&h.distortion)
        .all(|(x, y)| close(*x, *y, 1.0));
    ensure!(
        k && d
            && close(b.rms_px, h.rms_px, h.rms_px)
            && (b.views_used, b.warnings) == (h.views_used, h.warnings),
        "board and host calibrations disagree: K {:?} / {:?}, distortion {:?} / {:?}, RMS {} / {}, views {} / {}",
        b.intrinsics,
        h.intrinsics,
        b.distortion,
        h.distortion,
        b.rms_px,
        h.rms_px,
        b.views_used,
        h.views_used
    );
    Ok(())
}

fn bits(s: &Settings) -> ([u32; 4], [u32; 5]) {
    (
        s.intrinsics.map(f32::to_bits),
        s.distortion.map(f32::to_bits),
    )
}

/// The calibrate boots in `dir/calibrate`, the flash of `dir` (the commands boots') first;
/// `tag_spec` is the tag job's run, `stored` the settings in that flash. Returns the job's
/// line.
pub fn run(dir: &Path, elf: &Path, tag_spec: &RunSpec, stored: &Settings) -> Result<String> {
    let started = Instant::now();
    let sub = dir.join("calibrate");
    for name in ["serial.bin", "report.bin", "flash.bin", "commands.bin"] {
        let _ = fs::remove_file(sub.join(name));
    }
    let views = prepare(&sub)?;
    let raw = fs::read(sub.join("frames.raw"))?;
    fs::copy(dir.join("flash.bin"), sub.join("flash.bin"))?;
    let spec = RunSpec {
        frames: views.frames,
        overlay_every: 0,
        ..*tag_spec
    };
    fs::write(sub.join("run.bin"), spec.to_bytes())?;
    let board = Command::SetChessboard(BOARD);
    let mode = Command::SetMode(Mode::Calibrate);
    let mut bytes = frame(0, &board.encode())?;
    bytes.extend(frame(1, &mode.encode())?);
    fs::write(sub.join("commands.bin"), &bytes)?;
    let told = Settings {
        mode: Mode::Calibrate,
        chessboard: BOARD,
        ..*stored
    };
    let (host, host_settings) = host_run(&raw, &spec, &told)?;
    ensure!(
        host.verdict.status == Status::Calibrated,
        "the host's calibrate mode did not calibrate: {:?}",
        host.verdict
    );

    // Boot 1: the commands, then the calibrate mode.
    let t = Instant::now();
    run_on_qemu_with(
        M7,
        elf,
        Some(&sub),
        None,
        "calibrate mode: ",
        " views",
        None,
    )?;
    let boot_seconds = t.elapsed().as_secs_f64();
    let serial = sub.join("serial.bin");
    let bytes = fs::read(&serial).with_context(|| format!("no {}", serial.display()))?;
    let (frames, stats) = decode(&bytes);
    ensure!(
        stats.damaged == 0 && stats.lost == 0,
        "{}: {stats:?}",
        serial.display()
    );
    let acks: Vec<_> = frames
        .iter()
        .take_while(|(_, r)| r.get(..4) == Some(&ACK_TAG.to_le_bytes()[..]))
        .map(|(_, r)| Ack::decode(r).map(|a| (a.seq, a.kind, a.status)))
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow!("{e}"))?;
    let want = vec![
        (0, board.kind(), AckStatus::Done),
        (1, mode.kind(), AckStatus::Done),
    ];
    ensure!(acks == want, "the board answered {acks:?}, not {want:?}");
    let got = records(frames[acks.len()..].iter().map(|(_, r)| &r[..]))?;
    let shape = |p: &ProgressRecord| {
        (
            p.frame, p.found, p.kept, p.views, p.needed, p.status, p.reason,
        )
    };
    ensure!(
        got.progress
            .iter()
            .map(shape)
            .eq(host.progress.iter().map(shape))
            && shape(&got.verdict) == shape(&host.verdict),
        "the board's progress differs from the host's: {:?} / {:?}",
        got.progress.iter().map(shape).collect::<Vec<_>>(),
        host.progress.iter().map(shape).collect::<Vec<_>>()
    );
    let (b, h) = (
        got.result.context("the board sent no result")?,
        host.result.context("the host run has no result")?,
    );
    agree(&b, &h)?;
    let now = got
        .settings
        .context("the board sent no settings after calibrating")?;
    ensure!(
        now.intrinsics == b.intrinsics
            && now.distortion == b.distortion
            && now
                == Settings {
                    intrinsics: now.intrinsics,
                    distortion: now.distortion,
                    ..host_settings
                },
        "the board runs with {now:?} after calibrating to {b:?}"
    );
    let flash = fs::read(sub.join("flash.bin")).context("no flash.bin")?;
    let kept = Settings::decode(flash.get(..SETTINGS_LEN).unwrap_or(&[]))
        .map_err(|e| anyhow!("flash.bin: {e}"))?;
    ensure!(
        bits(&kept) == bits(&now)
            && kept == now
            && flash[SETTINGS_LEN..].iter().all(|&x| x == 0xFF),
        "flash.bin holds {kept:?}, not {now:?}"
    );

    // Boot 2: the settings from the flash, streamed with one frame.
    let t = Instant::now();
    fs::write(
        sub.join("run.bin"),
        RunSpec { frames: 1, ..spec }.to_bytes(),
    )?;
    fs::write(
        sub.join("commands.bin"),
        frame(0, &Command::SetMode(Mode::StreamFrames).encode())?,
    )?;
    let second = emulate::run_board(M7, elf, &sub, SIZE, 1)?;
    let load_seconds = t.elapsed().as_secs_f64();
    ensure!(
        second
            .log
            .iter()
            .any(|l| l.starts_with("settings: loaded from flash")),
        "the second boot did not load the settings from the flash"
    );
    let (streamed, _) = decode(&fs::read(&serial)?);
    let loaded = streamed
        .iter()
        .find(|(_, r)| r.get(..4) == Some(&SETTINGS_TAG.to_le_bytes()[..]))
        .map(|(_, r)| Settings::decode(r))
        .context("the second boot streamed no settings")?
        .map_err(|e| anyhow!("{e}"))?;
    ensure!(
        bits(&loaded) == bits(&now)
            && loaded
                == Settings {
                    mode: Mode::StreamFrames,
                    ..now
                },
        "the second boot runs with {loaded:?}, not the calibrated {now:?}"
    );
    let kept_views = got.progress.iter().filter(|p| p.kept).count();
    let found = got.progress.iter().filter(|p| p.found).count();
    // Found but like a view kept before (frame numbers from 1).
    let alike: Vec<u32> = got
        .progress
        .iter()
        .filter(|p| p.found && !p.kept)
        .map(|p| p.frame)
        .collect();
    let [fx, fy, cx, cy] = b.intrinsics;
    Ok(format!(
        "calibrate boot: chessboard and mode calibrate answered done; {} frames, board found in {found}, {kept_views} views kept of {} needed (frames {alike:?} found like a kept view); calibrated fx {fx:.2} fy {fy:.2} cx {cx:.2} cy {cy:.2}, RMS {:.4} px (host within {TOLERANCE:e}); flash.bin holds the camera bit for bit, the next boot loaded it; {boot_seconds:.1} s + {load_seconds:.1} s ({:.1} s with the host run)",
        got.progress.len(),
        BOARD.views,
        b.rms_px,
        started.elapsed().as_secs_f64()
    ))
}
