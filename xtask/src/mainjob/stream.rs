//! The tag job's record stream: what the board sent over UART0 (`serial.bin`, QEMU's
//! `-serial file:`), read with the receiver a real board's monitor uses
//! ([`camgeom_fw_app::link::Deframer`]), against what it wrote over semihosting (`report.bin`);
//! then the same bytes through a damaged link.
//!
//! The link faults are applied to the recorded stream between the board and the receiver, as a
//! flaky cable or a UART overrun would: bits flipped, bytes dropped, bytes repeated, and bursts
//! of garbage, at seeded random places. Every record that comes through must be the board's
//! record of that sequence number; the damaged ones are counted, never delivered.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, ensure};
use camgeom::rng::Pcg32;
use camgeom_fw_app::link::{Deframer, LinkStats, max_frame_len};
use camgeom_fw_app::report::{RECORD_LEN, Record};

use crate::util::{in_ci, root};

/// The receiver of the stream: room for one frame of the longest record.
type Receiver = Deframer<{ max_frame_len(RECORD_LEN) }>;

/// Frames of `bytes` in arrival order (sequence number, record), with the receiver's counts.
pub fn decode(bytes: &[u8]) -> (Vec<(u16, Vec<u8>)>, LinkStats) {
    let mut rx = Receiver::new();
    let mut input = bytes;
    let mut out = Vec::new();
    while let Some(f) = rx.push(&mut input) {
        out.push((f.seq, f.record.to_vec()));
    }
    (out, rx.stats())
}

/// One way a link damages a stream.
#[derive(Clone, Copy)]
enum Fault {
    /// One bit flipped in this many bytes.
    Flip(u32),
    /// One byte dropped in this many.
    Drop(u32),
    /// One byte sent twice in this many.
    Repeat(u32),
    /// A burst of 16 random bytes in this many.
    Burst(u32),
}

impl Fault {
    fn name(self) -> String {
        match self {
            Fault::Flip(n) => format!("bit flipped, 1 byte in {n}"),
            Fault::Drop(n) => format!("byte dropped, 1 in {n}"),
            Fault::Repeat(n) => format!("byte repeated, 1 in {n}"),
            Fault::Burst(n) => format!("16-byte burst of noise, 1 in {n} bytes"),
        }
    }

    /// `bytes` through the faulty link, and the bytes it touched.
    fn apply(self, bytes: &[u8], rng: &mut Pcg32) -> (Vec<u8>, usize) {
        let mut out = Vec::with_capacity(bytes.len() + bytes.len() / 8);
        let mut touched = 0;
        for &b in bytes {
            match self {
                Fault::Flip(n) if rng.below(n) == 0 => {
                    out.push(b ^ (1 << rng.below(8)));
                    touched += 1;
                }
                Fault::Drop(n) if rng.below(n) == 0 => touched += 1,
                Fault::Repeat(n) if rng.below(n) == 0 => {
                    out.extend([b, b]);
                    touched += 1;
                }
                Fault::Burst(n) if rng.below(n) == 0 => {
                    out.push(b);
                    out.extend((0..16).map(|_| rng.below(256) as u8));
                    touched += 16;
                }
                _ => out.push(b),
            }
        }
        (out, touched)
    }
}

/// Checks `serial.bin` against `report.bin` (the same records in the same order, none damaged),
/// `mavlink.bin` with pymavlink (a target of `size`, metres), runs the damaged-link cases, and
/// returns the lines to print and the BENCHMARKS table.
pub fn check(dir: &Path, log: &[String], size: [f32; 2]) -> Result<String> {
    let serial = dir.join("serial.bin");
    let bytes =
        fs::read(&serial).with_context(|| format!("the board streamed no {}", serial.display()))?;
    let report = fs::read(dir.join("report.bin"))?;
    let records: Vec<&[u8]> = report.chunks_exact(RECORD_LEN).collect();
    let (frames, stats) = decode(&bytes);
    ensure!(
        stats
            == LinkStats {
                frames: records.len() as u32,
                ..LinkStats::default()
            },
        "{}: {stats:?} for {} records",
        serial.display(),
        records.len()
    );
    for (k, ((seq, rec), want)) in frames.iter().zip(&records).enumerate() {
        ensure!(
            usize::from(*seq) == k && rec.as_slice() == *want,
            "{}: frame {k} (seq {seq}) differs from report.bin's record {k}",
            serial.display()
        );
    }
    let monitored = monitor(&serial, &records)?;
    let mavlink = mavlink(dir, log, size)?;
    let per_frame = bytes.len() as f64 / records.len() as f64;
    // The board's own count: "record stream: F frames, B bytes over UART0, I instructions a
    // frame to frame and send".
    let cost = log
        .iter()
        .find_map(|m| m.strip_prefix("record stream: "))
        .and_then(|m| m.split(", ").nth(2))
        .and_then(|m| m.split(' ').next())
        .context("the board's log has no record stream line")?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "record stream over UART0: {} frames, {} bytes ({per_frame:.1} a frame for a {RECORD_LEN}-byte record), each equal to report.bin's; {cost} instructions a frame on the board to frame and send it; at 8N1 a link needs {:.0} baud at 30 fps and {:.0} at 100 fps",
        frames.len(),
        bytes.len(),
        per_frame * 10.0 * 30.0,
        per_frame * 10.0 * 100.0
    );
    let _ = writeln!(s, "{monitored}");
    let _ = writeln!(s, "{mavlink}");
    let _ = writeln!(
        s,
        "\n| link fault (seeded, over the {} bytes) | bytes affected | frames delivered | damaged | lost | repeated | delivered wrong |\n|---|---|---|---|---|---|---|",
        bytes.len()
    );
    let faults = [
        Fault::Flip(1000),
        Fault::Flip(100),
        Fault::Drop(1000),
        Fault::Drop(100),
        Fault::Repeat(1000),
        Fault::Repeat(100),
        Fault::Burst(2000),
    ];
    for (i, fault) in faults.into_iter().enumerate() {
        let mut rng = Pcg32::new(0x5eed + i as u64);
        let (damaged, touched) = fault.apply(&bytes, &mut rng);
        let (got, st) = decode(&damaged);
        let wrong = got
            .iter()
            .filter(|(seq, rec)| records.get(usize::from(*seq)) != Some(&rec.as_slice()))
            .count();
        ensure!(
            wrong == 0,
            "{}: {wrong} damaged records delivered as good",
            fault.name()
        );
        ensure!(
            st.frames as usize == got.len() && got.len() <= records.len(),
            "{}: {st:?}",
            fault.name()
        );
        let _ = writeln!(
            s,
            "| {} | {touched} | {} of {} | {} | {} | {} | {wrong} |",
            fault.name(),
            st.frames,
            records.len(),
            st.damaged,
            st.lost,
            st.repeated
        );
    }
    Ok(s)
}

/// `camgeom monitor --replay serial.bin --json`'s code ([`camgeom_host::monitor`], which the
/// command only wraps): one JSON object a frame record, each the board's record of
/// `report.bin` (frame, counts, poses to the bit), then the summary and the link's counts.
fn monitor(serial: &Path, records: &[&[u8]]) -> Result<String> {
    let mut file = fs::File::open(serial)?;
    let mut out = Vec::new();
    let last = camgeom_host::monitor::monitor(
        &mut file,
        &serial.display().to_string(),
        true,
        &mut out,
        None,
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let text = String::from_utf8(out)? + &last;
    // What `camgeom monitor --replay serial.bin --json` prints, kept beside the stream (the
    // MAVLink check reads the poses from it).
    let jsonl = serial.with_file_name("monitor.jsonl");
    fs::write(&jsonl, &text).with_context(|| format!("cannot write {}", jsonl.display()))?;
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<_, _>>()
        .context("camgeom monitor --json printed a line that is not JSON")?;
    let frames: Vec<&serde_json::Value> =
        lines.iter().filter(|v| v.get("frame").is_some()).collect();
    let want: Vec<_> = records
        .iter()
        .filter_map(|r| match Record::decode(r) {
            Ok(Record::Frame(f)) => Some(f),
            _ => None,
        })
        .collect();
    ensure!(
        frames.len() == want.len(),
        "camgeom monitor printed {} frames, the board reported {}",
        frames.len(),
        want.len()
    );
    let f32_of = |v: &serde_json::Value| v.as_f64().map(|x| x as f32);
    for (got, f) in frames.iter().zip(&want) {
        let t: Option<Vec<Option<f32>>> = got["pose"]["t"]
            .as_array()
            .map(|a| a.iter().map(f32_of).collect());
        let want_t = f.pose.map(|p| p.0.t.map(Some).to_vec());
        ensure!(
            got["frame"].as_u64() == Some(u64::from(f.index))
                && got["tracked"].as_u64() == Some(u64::from(f.tracked))
                && got["inliers"].as_u64() == Some(u64::from(f.inliers))
                && t == want_t,
            "camgeom monitor's frame {} differs from the board's record: {got}",
            f.index
        );
    }
    let link = lines
        .last()
        .and_then(|v| v.get("link"))
        .context("no link counts")?;
    ensure!(
        link["damaged"].as_u64() == Some(0) && link["lost"].as_u64() == Some(0),
        "camgeom monitor: {link}"
    );
    Ok(format!(
        "camgeom monitor --replay {} --json (its code): {} JSON lines, {} frames equal to the board's records (poses to the bit), then the summary and the link's counts",
        serial.strip_prefix(root()).unwrap_or(serial).display(),
        lines.len(),
        frames.len()
    ))
}

/// `mavlink.bin` (UART1) read by pymavlink, the autopilot side's parser
/// (`host-tests/scripts/check_mavlink.py`): every byte parses, a HEARTBEAT, one LANDING_TARGET
/// a frame with a pose whose distance and position are the pose's to 1 mm. Without pymavlink
/// it says so and skips, except in CI (`CI=true`), where it is a failure.
fn mavlink(dir: &Path, log: &[String], [w, h]: [f32; 2]) -> Result<String> {
    let bin = dir.join("mavlink.bin");
    ensure!(
        fs::metadata(&bin).is_ok_and(|m| m.len() > 0),
        "the board sent no MAVLink ({} is empty)",
        bin.display()
    );
    let board = log
        .iter()
        .find_map(|m| m.strip_prefix("mavlink: "))
        .context("the board's log has no mavlink line")?;
    let has_pymavlink = Command::new("python3")
        .args(["-c", "import pymavlink, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_pymavlink {
        ensure!(
            !in_ci(),
            "pymavlink is missing (`cargo xtask setup` installs it)"
        );
        return Ok(format!(
            "mavlink over UART1: {board}; pymavlink not installed, its check skipped (`cargo xtask setup`)"
        ));
    }
    let rel = |p: &Path| p.strip_prefix(root()).unwrap_or(p).to_path_buf();
    let out = Command::new("python3")
        .current_dir(root())
        .arg("host-tests/scripts/check_mavlink.py")
        .arg(rel(&bin))
        .arg(rel(&dir.join("monitor.jsonl")))
        .args([w.to_string(), h.to_string()])
        .output()
        .context("cannot run python3")?;
    let said = String::from_utf8_lossy(&out.stdout).trim().to_string();
    ensure!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(format!("mavlink over UART1: {board}\n{said}"))
}
