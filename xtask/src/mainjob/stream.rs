//! The tag job's record stream: what the board sent over UART0 (QEMU's `-serial tcp:` to the
//! link harness, [`super::live`], which saves it as `serial.bin`), read with the receiver a
//! real board's monitor uses ([`camgeom_fw_app::link::Deframer`]), against what it wrote over
//! semihosting (`report.bin`); then what `camgeom monitor`'s code printed live, on the clean
//! link and on each damaged one.
//!
//! The link faults are applied by the harness between the board and the monitors, as a flaky
//! cable or a UART overrun would: bits flipped, bytes dropped, bytes repeated, and bursts of
//! garbage, at seeded random places. Every record a monitor prints must be the board's record
//! of that sequence number; the damaged ones are counted, never delivered.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, ensure};
use camgeom_fw_app::link::{Deframer, LinkStats, encode_frame, max_frame_len};
use camgeom_fw_app::report::{RECORD_LEN, Record};

use super::live::LiveRun;
use crate::util::{in_ci, root};

/// The receiver of the stream: room for one frame of the longest record.
type Receiver = Deframer<{ max_frame_len(RECORD_LEN) }>;

/// `record` framed as on the link, sequence number `seq`.
pub fn frame(seq: u16, record: &[u8]) -> Result<Vec<u8>> {
    let mut out = vec![0u8; max_frame_len(record.len())];
    let n = encode_frame(seq, record, &mut out).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    out.truncate(n);
    Ok(out)
}

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

/// Checks `serial.bin` against `report.bin` (the same records in the same order, none damaged),
/// what the monitor printed live against what it prints replaying `serial.bin`,
/// `mavlink.bin` with pymavlink (a target of `size`, metres), the live damaged-link monitors
/// ([`live`]), and returns the lines to print and the BENCHMARKS table.
pub fn check(dir: &Path, log: &[String], size: [f32; 2], live: &LiveRun) -> Result<String> {
    let serial = dir.join("serial.bin");
    let bytes =
        fs::read(&serial).with_context(|| format!("the board streamed no {}", serial.display()))?;
    ensure!(
        bytes == live.bytes,
        "{} is not what came over the link",
        serial.display()
    );
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
    for m in &live.monitors {
        ensure!(
            !m.timed_out,
            "the live monitor of {} stopped at a time limit, not at the end of the stream",
            m.fault.map_or("the clean link".into(), |f| f.name())
        );
    }
    let [clean, damaged @ ..] = &live.monitors[..] else {
        anyhow::bail!("the harness ran no monitor");
    };
    let (monitored, replayed) = monitor(&serial, &records)?;
    ensure!(
        clean.output == replayed,
        "camgeom monitor --tcp (live) printed otherwise than camgeom monitor --replay serial.bin"
    );
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
    let _ = writeln!(
        s,
        "camgeom monitor --tcp (its code, live over localhost from QEMU's UART0): the clean link printed what the replay prints; {} damaged links ran beside it, each ended by the board closing its stream",
        damaged.len()
    );
    let _ = writeln!(s, "{mavlink}");
    let _ = writeln!(
        s,
        "\n| link fault (seeded, live over the {} bytes) | bytes affected | frames delivered | damaged | lost | repeated | delivered wrong |\n|---|---|---|---|---|---|---|",
        bytes.len()
    );
    let lines = |text: &str| -> Result<Vec<serde_json::Value>> {
        text.lines()
            .map(|l| serde_json::from_str(l).context("the monitor printed a line that is not JSON"))
            .collect()
    };
    let clean_lines = lines(&clean.output)?;
    // The clean link's frame and summary lines (each checked against the board's records), by
    // sequence number: a damaged link's line must be the very same.
    let good: std::collections::BTreeMap<u64, &serde_json::Value> = clean_lines
        .iter()
        .filter_map(|v| v.get("seq").and_then(|q| q.as_u64()).map(|q| (q, v)))
        .collect();
    let clean_summary = clean_lines.iter().find(|v| v.get("summary").is_some());
    for m in damaged {
        let name = m.fault.map_or(String::new(), |f| f.name());
        let got = lines(&m.output)?;
        let link = got
            .last()
            .and_then(|v| v.get("link"))
            .with_context(|| format!("{name}: no link counts"))?;
        let count = |k: &str| link[k].as_u64().unwrap_or(u64::MAX);
        let frame_lines: Vec<&serde_json::Value> =
            got.iter().filter(|v| v.get("frame").is_some()).collect();
        let wrong = frame_lines
            .iter()
            .filter(|v| v["seq"].as_u64().and_then(|q| good.get(&q)) != Some(*v))
            .count()
            + got
                .iter()
                .filter(|v| v.get("summary").is_some() && Some(*v) != clean_summary)
                .count();
        ensure!(
            wrong == 0,
            "{name}: {wrong} damaged records delivered as good"
        );
        let summaries = got.iter().filter(|v| v.get("summary").is_some()).count() as u64;
        ensure!(
            count("frames") == frame_lines.len() as u64 + summaries + count("unreadable")
                && count("unreadable") == 0
                && count("frames") <= records.len() as u64,
            "{name}: {link}"
        );
        let _ = writeln!(
            s,
            "| {name} | {} | {} of {} | {} | {} | {} | {wrong} |",
            m.touched,
            count("frames"),
            records.len(),
            count("damaged"),
            count("lost"),
            count("repeated")
        );
    }
    Ok(s)
}

/// `camgeom monitor --replay serial.bin --json`'s code ([`camgeom_host::monitor`], which the
/// command only wraps): one JSON object a frame record, each the board's record of
/// `report.bin` (frame, counts, poses to the bit), then the summary and the link's counts.
/// Returns the line to print and what the monitor printed.
fn monitor(serial: &Path, records: &[&[u8]]) -> Result<(String, String)> {
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
    Ok((
        format!(
            "camgeom monitor --replay {} --json (its code): {} JSON lines, {} frames equal to the board's records (poses to the bit), then the summary and the link's counts",
            serial.strip_prefix(root()).unwrap_or(serial).display(),
            lines.len(),
            frames.len()
        ),
        text + "\n",
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
