//! Runs a main-job binary on the emulated board and reads back what it wrote: the binary
//! report (`report.bin`, [`camgeom_fw_app::report`]) and the overlay frames.

use std::collections::BTreeMap;
use std::fs;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use camgeom_fw_app::report::{FrameRecord, RECORD_LEN, Record, SummaryRecord};

use crate::firmware::run_on_qemu_with;
use crate::jobs::{Board, Size};

/// Overlay frames by delivered frame number.
pub type Overlays = BTreeMap<u32, Vec<u8>>;

/// What the board reported.
pub struct BoardRun {
    /// Every frame's record, by frame number.
    pub frames: BTreeMap<u32, FrameRecord>,
    /// The summary record.
    pub summary: SummaryRecord,
    /// The overlays it wrote back.
    pub overlays: Overlays,
    /// Its defmt log, one message a line.
    pub log: Vec<String>,
}

/// The records of `report.bin`: frames in order, then exactly one summary.
pub fn read_report(path: &Path) -> Result<(BTreeMap<u32, FrameRecord>, SummaryRecord)> {
    let bytes = fs::read(path).with_context(|| format!("the board wrote no {}", path.display()))?;
    ensure!(
        bytes.len().is_multiple_of(RECORD_LEN),
        "{}: {} bytes is not a whole number of {RECORD_LEN}-byte records",
        path.display(),
        bytes.len()
    );
    let mut frames = BTreeMap::new();
    let mut summary = None;
    for (k, chunk) in bytes.chunks_exact(RECORD_LEN).enumerate() {
        let rec = Record::decode(chunk)
            .map_err(|e| anyhow::anyhow!("{}: record {k}: {e}", path.display()))?;
        match (rec, summary) {
            (_, Some(_)) => bail!("{}: record {k} after the summary", path.display()),
            (Record::Frame(f), None) => {
                if frames.insert(f.index, f).is_some() {
                    bail!("{}: frame {} reported twice", path.display(), f.index);
                }
            }
            (Record::Summary(s), None) => summary = Some(s),
        }
    }
    let summary = summary.with_context(|| format!("{}: no summary record", path.display()))?;
    Ok((frames, summary))
}

/// The `overlay-NNNN.raw` frames of `dir` (by delivered frame number = recorded / `stride`).
pub fn read_overlays(dir: &Path, size: Size, stride: u32) -> Result<Overlays> {
    let len = (size.width * size.height) as usize;
    let mut out = BTreeMap::new();
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("overlay-"))
                && p.extension().is_some_and(|e| e == "raw")
        })
        .collect();
    entries.sort();
    for p in entries {
        let data = fs::read(&p)?;
        ensure!(data.len() == len, "{}: {} bytes", p.display(), data.len());
        let stem = p.file_stem().unwrap_or_default().to_string_lossy();
        let recorded: u32 = stem.trim_start_matches("overlay-").parse()?;
        out.insert(recorded / stride.max(1), data);
    }
    Ok(out)
}

/// Runs `elf` on `board`'s QEMU in `dir` (prepared by [`super::prepare::prepare`]) and reads
/// its report and overlays. Only the firmware's warnings and errors are printed; the figures
/// come from the records.
pub fn run_board(
    board: Board,
    elf: &Path,
    dir: &Path,
    size: Size,
    stride: u32,
) -> Result<BoardRun> {
    run_board_with(board, elf, dir, None, size, stride)
}

/// [`run_board`] with UART0 (the record stream) going to the TCP server at `uart0` (a
/// [`super::live::Harness`]) instead of `serial.bin`.
pub fn run_board_with(
    board: Board,
    elf: &Path,
    dir: &Path,
    uart0: Option<SocketAddr>,
    size: Size,
    stride: u32,
) -> Result<BoardRun> {
    // Outputs of an earlier run must not be mistaken for this one's.
    for e in fs::read_dir(dir)?.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with("overlay-") || n == "report.bin" || n == "serial.bin" || n == "mavlink.bin"
        {
            fs::remove_file(e.path())?;
        }
    }
    let (_, log) = run_on_qemu_with(
        board,
        elf,
        Some(dir),
        uart0,
        "main job: ",
        " frames, ",
        None,
    )?;
    let (frames, summary) = read_report(&dir.join("report.bin"))?;
    let overlays = read_overlays(dir, size, stride)?;
    ensure!(
        summary.frames as usize == frames.len(),
        "the board's summary counts {} frames, its report holds {}",
        summary.frames,
        frames.len()
    );
    ensure!(
        summary.overlays as usize == overlays.len(),
        "the board says it wrote {} overlays, {} are there",
        summary.overlays,
        overlays.len()
    );
    Ok(BoardRun {
        frames,
        summary,
        overlays,
        log,
    })
}
