//! The commands job: the host sets the tag job's board over its link and the board keeps what
//! it was told in flash.
//!
//! Two boots of `camgeom-fw-tag` on the first [`FRAMES`] frames of the tag job's sequence, in
//! `target/camgeom-run/commands`:
//!
//! 1. The board boots with an erased flash and receives, framed as on the link
//!    ([`camgeom_fw_app::link`]), a new tag side (twice the true one), the same camera, the
//!    calibrate mode's chessboard, a damaged frame, a tag side no board takes, and a save. It
//!    must answer each readable command on its record stream (done, done, done, invalid,
//!    done), count the damaged frame, and leave in `flash.bin` exactly the settings record
//!    (erased bytes after it). (A mode a firmware does not have is answered unsupported: the
//!    box firmware has no calibrate mode; `settings`' unit tests check the answer.)
//! 2. The board boots again without commands: it must load the settings from the flash.
//!
//! Both boots must track with the commanded side: against the tag job's poses (the true side)
//! every translation twice as long (a target twice the size at the same image), the rotations
//! equal; and the two boots' records equal.
//!
//! 3. The board boots again, is switched to stream-frames, and streams its first few frames
//!    ([`stream_frames`]): their pixels, put back together, must be the frames it was fed.
//! 4. and 5. The board calibrates its camera in the calibrate mode and the next boot loads
//!    it ([`super::calibrate_boot`]).

use std::fs;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, ensure};
use camgeom_fw_app::command::{ACK_LEN, Ack, AckStatus, Command, Mode};
use camgeom_fw_app::frame_chunk::{CHUNK_TAG, FrameChunk};
use camgeom_fw_app::report::{FrameRecord, Record};
use camgeom_fw_app::run::{Acquisition, RunSpec};
use camgeom_fw_app::settings::{SETTINGS_LEN, SETTINGS_TAG, Settings};
use camgeom_host::monitor::monitor_link;
use camgeom_host::monitor_frames::FrameAssembler;

use super::calibrate_boot::BOARD;
use super::emulate::{self, read_report};
use super::stream::{decode, frame};
use super::tag::SIZE;
use crate::firmware::build_bin_for;
use crate::jobs::M7;
use crate::util::root;

/// Frames of each boot.
const FRAMES: u32 = 24;

/// An answer as the check compares it: the command's sequence number, kind, status.
type Answer = (u16, u32, AckStatus);

/// The commands of the first boot, and the answers they must get (sequence, kind, status).
fn commands(spec: &RunSpec) -> Result<(Vec<u8>, Vec<Answer>, Settings)> {
    let Acquisition::Tag { family, id } = spec.acquisition else {
        anyhow::bail!("the tag job's run does not acquire a tag");
    };
    let size = 2.0 * spec.target_size[0];
    let set_tag = Command::SetTag { family, id, size };
    let camera = Command::SetCamera {
        intrinsics: spec.intrinsics,
        distortion: spec.distortion,
    };
    let no_side = Command::SetTag {
        family,
        id,
        size: -1.0,
    };
    let mut bytes = Vec::new();
    bytes.extend(frame(0, &set_tag.encode())?);
    bytes.extend(frame(1, &camera.encode())?);
    let board = Command::SetChessboard(BOARD);
    bytes.extend(frame(2, &board.encode())?);
    let mut damaged = frame(3, &set_tag.encode())?;
    let mid = damaged.len() / 2;
    damaged[mid] ^= 0x10;
    bytes.extend(damaged);
    bytes.extend(frame(4, &no_side.encode())?);
    bytes.extend(frame(5, &Command::Save.encode())?);
    let want = vec![
        (0, set_tag.kind(), AckStatus::Done),
        (1, camera.kind(), AckStatus::Done),
        (2, board.kind(), AckStatus::Done),
        (4, 0, AckStatus::Invalid),
        (5, Command::Save.kind(), AckStatus::Done),
    ];
    let mut settings = spec.settings();
    settings.tag_size = size;
    settings.chessboard = BOARD;
    Ok((bytes, want, settings))
}

/// The answers at the head of a boot's record stream, and the number of damaged frames.
fn acks(dir: &Path) -> Result<(Vec<Answer>, usize)> {
    let serial = dir.join("serial.bin");
    let bytes = fs::read(&serial).with_context(|| format!("no {}", serial.display()))?;
    let (frames, stats) = decode(&bytes);
    ensure!(
        stats.damaged == 0 && stats.lost == 0,
        "{}: {stats:?}",
        serial.display()
    );
    let mut out = Vec::new();
    for (_, rec) in frames.iter().take_while(|(_, r)| r.len() == ACK_LEN) {
        let a = Ack::decode(rec).map_err(|e| anyhow::anyhow!("{}: {e}", serial.display()))?;
        out.push((a.seq, a.kind, a.status));
    }
    Ok((out, frames.len()))
}

/// Translations twice the tag job's, rotations equal: the worst relative error of the length
/// ratio and the worst rotation-vector difference, over the frames both have a pose for.
fn scaled(
    got: &[FrameRecord],
    truth: &std::collections::BTreeMap<u32, FrameRecord>,
) -> (usize, f64, f64) {
    let (mut n, mut ratio, mut rot) = (0, 0f64, 0f64);
    for g in got {
        let (Some((p, _)), Some((q, _))) = (g.pose, truth.get(&g.index).and_then(|t| t.pose))
        else {
            continue;
        };
        let norm = |v: [f32; 3]| v.iter().map(|x| f64::from(*x).powi(2)).sum::<f64>().sqrt();
        ratio = ratio.max((norm(p.t) / norm(q.t) / 2.0 - 1.0).abs());
        rot = rot.max(
            p.r.iter()
                .zip(q.r)
                .map(|(a, b)| f64::from(a - b).abs())
                .fold(0.0, f64::max),
        );
        n += 1;
    }
    (n, ratio, rot)
}

/// `cargo xtask run`'s commands job (after the tag job, whose run it reuses); returns its line.
pub fn run() -> Result<String> {
    let tag_dir = root().join("target/camgeom-run/tag");
    let dir = root().join("target/camgeom-run/commands");
    fs::create_dir_all(&dir)?;
    for name in [
        "report.bin",
        "serial.bin",
        "mavlink.bin",
        "flash.bin",
        "commands.bin",
        "run.bin",
    ] {
        let _ = fs::remove_file(dir.join(name));
    }
    let tag_spec =
        RunSpec::parse(&fs::read(tag_dir.join("run.bin"))?).map_err(|e| anyhow::anyhow!("{e}"))?;
    let spec = RunSpec {
        frames: FRAMES,
        overlay_every: 0,
        ..tag_spec
    };
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    let frames = dir.join("frames.raw");
    if !frames.exists() {
        fs::hard_link(tag_dir.join("frames.raw"), &frames)
            .or_else(|_| fs::copy(tag_dir.join("frames.raw"), &frames).map(|_| ()))?;
    }
    let (truth, _) = read_report(&tag_dir.join("report.bin"))?;
    let (bytes, want, settings) = commands(&spec)?;
    fs::write(dir.join("commands.bin"), &bytes)?;
    let elf = build_bin_for(M7, SIZE.bin, &[])?;

    // Boot 1: the commands, then the run.
    let first = emulate::run_board(M7, &elf, &dir, SIZE, 1)?;
    let (got, _) = acks(&dir)?;
    ensure!(got == want, "the board answered {got:?}, not {want:?}");
    ensure!(
        first
            .log
            .iter()
            .any(|l| l.starts_with("commands: 5 frames, 1 damaged")),
        "the board did not count the damaged command frame: {:?}",
        first.log.iter().find(|l| l.starts_with("commands: "))
    );
    let flash = fs::read(dir.join("flash.bin")).context("the board saved no flash.bin")?;
    ensure!(
        flash.len() == 4096 && flash[SETTINGS_LEN..].iter().all(|&b| b == 0xFF),
        "flash.bin: {} bytes, not the settings record and erased bytes",
        flash.len()
    );
    let stored = Settings::decode(&flash[..SETTINGS_LEN]).map_err(|e| anyhow::anyhow!("{e}"))?;
    ensure!(
        stored == settings,
        "flash holds {stored:?}, not {settings:?}"
    );

    // Boot 2: no commands; the settings come from the flash.
    fs::remove_file(dir.join("commands.bin"))?;
    let second = emulate::run_board(M7, &elf, &dir, SIZE, 1)?;
    ensure!(
        second
            .log
            .iter()
            .any(|l| l.starts_with("settings: loaded from flash")),
        "the second boot did not load the settings from the flash"
    );
    let (_, n_second) = acks(&dir)?;
    ensure!(
        n_second == second.frames.len() + 1,
        "the second boot answered commands it was not sent"
    );
    let a: Vec<FrameRecord> = first.frames.values().copied().collect();
    let b: Vec<FrameRecord> = second.frames.values().copied().collect();
    let same = |r: &FrameRecord| (r.index, r.state, r.tracked, r.inliers, r.checksum, r.pose);
    ensure!(
        a.iter().map(same).eq(b.iter().map(same)),
        "the two boots tracked differently"
    );
    let (n, ratio, rot) = scaled(&a, &truth);
    ensure!(
        n >= (FRAMES as usize) / 2 && ratio < 1e-3 && rot < 1e-3,
        "with the tag side doubled, {n} poses: |t| ratio off by {ratio:.2e}, rotation by {rot:.2e}"
    );
    let streamed = stream_frames(&dir, &elf, &tag_spec, &settings, &a)?;
    let calibrated = super::calibrate_boot::run(&dir, &elf, &tag_spec, &settings)?;
    Ok(format!(
        "commands job: {} command frames (1 damaged, counted), answered done/done/done/invalid/done; flash.bin holds the settings record, erased after it; the second boot loaded them; {n} poses with the tag side doubled: |t| x2 within {ratio:.1e}, rotations within {rot:.1e} rad of the tag job's\n{streamed}\n{calibrated}",
        want.len() + 1
    ))
}

/// Frames of the boot that streams them.
const STREAMED: u32 = 4;

/// Boot 3: the board, its settings loaded from the flash, is switched to stream-frames and
/// runs [`STREAMED`] frames. Its stream must hold, for each frame, the settings, the frame's
/// pixels (put back together by the monitor's code, equal to the frames it was fed) and the
/// frame's record (equal to `report.bin`'s and to the first boot's: streaming does not change
/// the tracking); the monitor's code draws each frame with its overlay into `frames/`.
fn stream_frames(
    dir: &Path,
    elf: &Path,
    tag_spec: &RunSpec,
    stored: &Settings,
    first: &[FrameRecord],
) -> Result<String> {
    let started = Instant::now();
    let spec = RunSpec {
        frames: STREAMED,
        overlay_every: 0,
        ..*tag_spec
    };
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    let mode = Command::SetMode(Mode::StreamFrames);
    fs::write(dir.join("commands.bin"), frame(0, &mode.encode())?)?;
    let run = emulate::run_board(M7, elf, dir, SIZE, 1)?;
    let seconds = started.elapsed().as_secs_f64();
    fs::remove_file(dir.join("commands.bin"))?;
    let serial = dir.join("serial.bin");
    let bytes = fs::read(&serial).with_context(|| format!("no {}", serial.display()))?;
    let (records, stats) = decode(&bytes);
    ensure!(
        stats.damaged == 0 && stats.lost == 0,
        "{}: {stats:?}",
        serial.display()
    );
    let answer = records
        .first()
        .and_then(|(_, r)| Ack::decode(r).ok())
        .map(|a| (a.seq, a.kind, a.status));
    ensure!(
        answer == Some((0, mode.kind(), AckStatus::Done)),
        "the board answered {answer:?} to stream-frames"
    );
    // The frames as the monitor puts them back together.
    let raw = fs::read(dir.join("frames.raw"))?;
    let len = (SIZE.width * SIZE.height) as usize;
    let want_settings = Settings {
        mode: Mode::StreamFrames,
        ..*stored
    };
    let mut frames = FrameAssembler::new();
    let mut got = Vec::new();
    for (_, rec) in &records[1..] {
        let tag = rec.get(..4);
        if tag == Some(&CHUNK_TAG.to_le_bytes()[..]) {
            frames.chunk(&FrameChunk::decode(rec).map_err(|e| anyhow::anyhow!("{e}"))?);
        } else if tag == Some(&SETTINGS_TAG.to_le_bytes()[..]) {
            let s = Settings::decode(rec).map_err(|e| anyhow::anyhow!("{e}"))?;
            ensure!(s == want_settings, "the board streamed the settings {s:?}");
            frames.settings(s);
        } else if let Ok(Record::Frame(f)) = Record::decode(rec) {
            let (img, settings) = frames
                .record(f.index)
                .with_context(|| format!("frame {} came without its pixels", f.index))?;
            let k = f.index as usize;
            ensure!(
                settings == Some(want_settings)
                    && (img.width, img.height) == (SIZE.width as usize, SIZE.height as usize)
                    && raw.get(k * len..(k + 1) * len) == Some(&img.data[..]),
                "frame {k}: the streamed pixels are not the frame the board was fed"
            );
            got.push(f);
        }
    }
    let reported: Vec<FrameRecord> = run.frames.values().copied().collect();
    let same = |r: &FrameRecord| (r.index, r.state, r.tracked, r.inliers, r.checksum, r.pose);
    ensure!(
        got == reported
            && got.len() == STREAMED as usize
            && got
                .iter()
                .map(same)
                .eq(first.iter().take(got.len()).map(same)),
        "the streamed frame records differ from report.bin's or from the first boot's"
    );
    // `camgeom monitor --replay serial.bin --frames-dir frames`'s code.
    let pictures = dir.join("frames");
    let _ = fs::remove_dir_all(&pictures);
    fs::create_dir_all(&pictures)?;
    let seen = monitor_link(
        &mut fs::File::open(&serial)?,
        &serial.display().to_string(),
        true,
        &mut Vec::new(),
        None,
        Some(&pictures),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    ensure!(
        seen.pictures == STREAMED && seen.incomplete == 0,
        "camgeom monitor --frames-dir wrote {} pictures, {} frames incomplete",
        seen.pictures,
        seen.incomplete
    );
    let picture = pictures.join(format!("frame-{:06}.png", STREAMED - 1));
    ensure!(picture.is_file(), "no {}", picture.display());
    let chunks = run
        .log
        .iter()
        .find_map(|l| l.strip_prefix("frames streamed: "))
        .unwrap_or("?");
    Ok(format!(
        "stream-frames boot: {STREAMED} frames, each its settings, its pixels (equal to the frames fed) and its record (equal to report.bin's and the first boot's); {chunks}; camgeom monitor --frames-dir wrote {} pictures ({}); {seconds:.1} s",
        seen.pictures,
        picture.strip_prefix(root()).unwrap_or(&picture).display()
    ))
}
