//! `camgeom monitor`: the host end of a board's record stream ([`camgeom_fw_app::link`]
//! frames of [`camgeom_fw_app::report`] records), from a saved stream file or a TCP socket (an
//! emulated board's UART: QEMU `-serial tcp:...`).
//!
//! Each frame record becomes one line: a table row, or with `--json` one JSON object; `--csv`
//! also logs the rows. The receiver's counts (frames, damaged, lost, repeated) end the output.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;

use camgeom::target::TargetState;
use camgeom_fw_app::costs::STAGES;
use camgeom_fw_app::link::{Deframer, LinkStats, max_frame_len};
use camgeom_fw_app::report::{FrameRecord, RECORD_LEN, Record, SummaryRecord};
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["replay", "tcp"])))]
pub struct MonitorArgs {
    /// A saved record stream (an emulated board's `serial.bin`, or bytes captured from a real
    /// board's port).
    #[arg(long, value_name = "FILE")]
    replay: Option<PathBuf>,
    /// Connect to a board's stream at HOST:PORT (an emulated board started with QEMU
    /// `-serial tcp:HOST:PORT,server`) and read until it closes.
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// One JSON object a frame record (and one for the summary, one for the link counts)
    /// instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write every frame record as a CSV row to this file.
    #[arg(long, value_name = "LOG.csv")]
    csv: Option<PathBuf>,
}

/// A pose as the JSON gives it.
#[derive(Serialize)]
struct JsonPose {
    t: [f32; 3],
    rvec: [f32; 3],
    rms_px: f32,
}

/// A frame record as JSON.
#[derive(Serialize)]
struct JsonFrame<'a> {
    seq: u16,
    frame: u32,
    state: &'static str,
    acquired: bool,
    error: Option<&'static str>,
    tracked: u16,
    inliers: u16,
    added: u16,
    features: u16,
    pose: Option<JsonPose>,
    alternative: Option<JsonPose>,
    outline: Option<[[f32; 2]; 4]>,
    /// Instructions (or cycles) a stage, by [`STAGES`] name.
    costs: std::collections::BTreeMap<&'a str, u32>,
}

#[derive(Serialize)]
struct JsonSummary {
    summary: JsonSummaryBody,
}

#[derive(Serialize)]
struct JsonSummaryBody {
    frames: u32,
    tracking: u32,
    pipeline_ram: u32,
    stack_used: u32,
    stack_size: u32,
    overlays: u32,
}

#[derive(Serialize)]
struct JsonLink {
    link: JsonLinkBody,
}

#[derive(Serialize)]
struct JsonLinkBody {
    frames: u32,
    damaged: u32,
    lost: u32,
    repeated: u32,
    bytes_discarded: u32,
    /// Frames whose record did not decode (another layout version, say).
    unreadable: u32,
}

fn state(s: TargetState) -> &'static str {
    match s {
        TargetState::Uninitialised => "uninitialised",
        TargetState::Tracking => "tracking",
        TargetState::Lost => "lost",
    }
}

fn pose(p: &camgeom_fw_app::report::PoseRecord) -> JsonPose {
    JsonPose {
        t: p.t,
        rvec: p.r,
        rms_px: p.rms_px,
    }
}

fn json_frame(seq: u16, f: &FrameRecord) -> JsonFrame<'static> {
    JsonFrame {
        seq,
        frame: f.index,
        state: state(f.state),
        acquired: f.acquired,
        error: f.error.map(|e| e.name()),
        tracked: f.tracked,
        inliers: f.inliers,
        added: f.added,
        features: f.features,
        pose: f.pose.map(|p| pose(&p.0)),
        alternative: f.pose.map(|p| pose(&p.1)),
        outline: f.outline,
        costs: STAGES.iter().copied().zip(f.costs.to_array()).collect(),
    }
}

/// A frame record as a table row (and CSV row): frame, state, counts, `t` (m), rotation
/// vector, RMS and the total cost.
fn row(seq: u16, f: &FrameRecord) -> Vec<String> {
    let num = |v: Option<f32>| v.map_or_else(|| "nan".to_string(), |v| format!("{v:.4}"));
    let best = f.pose.map(|p| p.0);
    let mut r = vec![
        seq.to_string(),
        f.index.to_string(),
        state(f.state).to_string(),
        f.error.map_or("", |e| e.name()).to_string(),
        f.tracked.to_string(),
        f.inliers.to_string(),
    ];
    r.extend((0..3).map(|k| num(best.map(|p| p.t[k]))));
    r.extend((0..3).map(|k| num(best.map(|p| p.r[k]))));
    r.push(num(best.map(|p| p.rms_px)));
    r.push(f.costs.to_array().last().copied().unwrap_or(0).to_string());
    r
}

const COLUMNS: [&str; 14] = [
    "seq", "frame", "state", "error", "tracked", "inliers", "tx", "ty", "tz", "rx", "ry", "rz",
    "rms_px", "total",
];

/// `camgeom monitor`: decodes the stream, printing as it goes.
pub fn run(a: &MonitorArgs) -> Result<String> {
    let (name, mut input): (String, Box<dyn Read>) = match (&a.replay, &a.tcp) {
        (Some(p), _) => (
            p.display().to_string(),
            Box::new(File::open(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?),
        ),
        (None, Some(addr)) => (
            addr.clone(),
            Box::new(
                TcpStream::connect(addr)
                    .map_err(|e| Error::new(addr.as_str(), ErrorKind::Io(e)))?,
            ),
        ),
        (None, None) => return Err(Error::usage("give --replay FILE or --tcp HOST:PORT")),
    };
    let mut csv = match &a.csv {
        Some(p) => {
            let mut w =
                BufWriter::new(File::create(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?);
            writeln!(w, "{}", COLUMNS.join(",")).map_err(|e| Error::new(p, ErrorKind::Io(e)))?;
            Some((p, w))
        }
        None => None,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let print = |out: &mut std::io::StdoutLock, line: String| {
        // A closed pipe (`| head`) ends the output, not the program with a panic.
        let _ = writeln!(out, "{line}");
    };
    if !a.json {
        print(&mut out, COLUMNS.join("\t"));
    }
    let mut rx = Deframer::<{ max_frame_len(RECORD_LEN) }>::new();
    let mut buf = vec![0u8; 4096];
    let mut unreadable = 0u32;
    let mut summary: Option<SummaryRecord> = None;
    loop {
        let n = input
            .read(&mut buf)
            .map_err(|e| Error::new(name.as_str(), ErrorKind::Io(e)))?;
        if n == 0 {
            break;
        }
        let mut bytes = &buf[..n];
        while let Some(frame) = rx.push(&mut bytes) {
            let seq = frame.seq;
            match Record::decode(frame.record) {
                Ok(Record::Frame(f)) => {
                    if a.json {
                        print(
                            &mut out,
                            camgeom_host::points::to_json_line(&json_frame(seq, &f)),
                        );
                    } else {
                        print(&mut out, row(seq, &f).join("\t"));
                    }
                    if let Some((p, w)) = &mut csv {
                        writeln!(w, "{}", row(seq, &f).join(","))
                            .map_err(|e| Error::new(p.as_path(), ErrorKind::Io(e)))?;
                    }
                }
                Ok(Record::Summary(s)) => summary = Some(s),
                Err(_) => unreadable += 1,
            }
        }
    }
    if let Some((p, mut w)) = csv {
        w.flush()
            .map_err(|e| Error::new(p.as_path(), ErrorKind::Io(e)))?;
    }
    let LinkStats {
        frames,
        damaged,
        lost,
        repeated,
        bytes_discarded,
    } = rx.stats();
    if let Some(s) = summary {
        let body = JsonSummaryBody {
            frames: s.frames,
            tracking: s.tracking,
            pipeline_ram: s.pipeline_ram,
            stack_used: s.stack_used,
            stack_size: s.stack_size,
            overlays: s.overlays,
        };
        if a.json {
            print(
                &mut out,
                camgeom_host::points::to_json_line(&JsonSummary { summary: body }),
            );
        } else {
            print(
                &mut out,
                format!(
                    "summary: {} frames, {} tracking, pipeline RAM {} B, stack {} of {} B",
                    body.frames, body.tracking, body.pipeline_ram, body.stack_used, body.stack_size
                ),
            );
        }
    }
    let link = JsonLinkBody {
        frames,
        damaged,
        lost,
        repeated,
        bytes_discarded,
        unreadable,
    };
    Ok(if a.json {
        camgeom_host::points::to_json_line(&JsonLink { link }) + "\n"
    } else {
        format!(
            "link: {frames} frames, {damaged} damaged, {lost} lost, {repeated} repeated, {bytes_discarded} bytes discarded, {unreadable} unreadable\n"
        )
    })
}
