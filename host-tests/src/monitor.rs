//! A board's record stream read on the host (`camgeom monitor`, and the main job's check of the
//! emulated board's stream): [`camgeom_fw_app::link`] frames of [`camgeom_fw_app::report`]
//! records, decoded by the board's own receiver, printed a line a frame record (a table row or
//! one JSON object), then the summary and the link's counts. The board's answers to commands
//! ([`camgeom_fw_app::command::Ack`], `CACK` records on the same stream) are printed as they
//! come and returned ([`monitor_link`]) for the caller to check against the commands it sent
//! ([`command_bytes`], [`check_acks`]). A board streaming frames sends their pixels too
//! ([`crate::monitor_frames`]); one in calibrate mode its progress, its result and the
//! settings it runs with after it ([`camgeom_fw_app::calibrate_mode`]), a line each. A live board is read through [`Live`] ([`open_tcp`]), which
//! [`LiveLimits`] end even when the board stalls.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

use camgeom::target::TargetState;
use camgeom_fw_app::calibrate_mode::{PROGRESS_TAG, RESULT_TAG};
use camgeom_fw_app::command::{ACK_LEN, ACK_TAG, Ack, AckStatus, COMMAND_LEN, Command};
use camgeom_fw_app::costs::STAGES;
use camgeom_fw_app::frame_chunk::{CHUNK_LEN, CHUNK_TAG, FrameChunk};
use camgeom_fw_app::link::{Deframer, LinkStats, encode_frame, max_frame_len};
use camgeom_fw_app::report::{FrameRecord, RECORD_LEN, Record, SummaryRecord};
use camgeom_fw_app::settings::{SETTINGS_LEN, SETTINGS_TAG, Settings};
use serde::Serialize;

use crate::error::{Error, ErrorKind, Result};
use crate::monitor_frames::{FrameAssembler, save_frame};
use crate::points::to_json_line;

/// How long one read of a live source waits before it looks at the clock again.
pub const POLL: Duration = Duration::from_millis(100);

/// When to stop reading a live board besides the end of its stream.
#[derive(Debug, Clone, Copy, Default)]
pub struct LiveLimits {
    /// Stop at this time (`camgeom monitor --seconds`).
    pub deadline: Option<Instant>,
    /// Stop after this long without a byte: a board that stalled (`--idle`).
    pub idle: Option<Duration>,
}

/// A live source read with a short timeout, so that [`LiveLimits`] can end it: a read that
/// times out is tried again until a limit passes, then reads as the end of the stream.
pub struct Live<R> {
    inner: R,
    limits: LiveLimits,
    last_byte: Instant,
    timed_out: bool,
}

impl<R> Live<R> {
    /// `inner` (which must time out its reads, after [`POLL`] or so) read until `limits`.
    pub fn new(inner: R, limits: LiveLimits) -> Self {
        Self {
            inner,
            limits,
            last_byte: Instant::now(),
            timed_out: false,
        }
    }

    /// The stream ended by a limit, not by the board closing it.
    pub fn timed_out(&self) -> bool {
        self.timed_out
    }
}

impl<R: Read> Read for Live<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        loop {
            let now = Instant::now();
            let idle = self
                .limits
                .idle
                .is_some_and(|d| now.duration_since(self.last_byte) >= d);
            if idle || self.limits.deadline.is_some_and(|d| now >= d) {
                self.timed_out = true;
                return Ok(0);
            }
            match self.inner.read(buf) {
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) => {}
                Ok(n) => {
                    if n > 0 {
                        self.last_byte = Instant::now();
                    }
                    return Ok(n);
                }
                r => return r,
            }
        }
    }
}

/// A board's stream at `addr` (`camgeom monitor --tcp`: an emulated board's UART behind a
/// socket), `commands` (framed, [`command_bytes`]) sent to it first, read until the board
/// closes it or `limits` end it. Errors: [`ErrorKind::Io`] (connecting, sending).
pub fn open_tcp(addr: &str, commands: &[u8], limits: LiveLimits) -> Result<Live<TcpStream>> {
    let io = |e| Error::new(addr, ErrorKind::Io(e));
    let mut s = TcpStream::connect(addr).map_err(io)?;
    if !commands.is_empty() {
        s.write_all(commands)
            .and_then(|()| s.flush())
            .map_err(|e| Error::new(addr, ErrorKind::Write(e)))?;
    }
    if limits.deadline.is_some() || limits.idle.is_some() {
        s.set_read_timeout(Some(POLL)).map_err(io)?;
    }
    Ok(Live::new(s, limits))
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
    /// The pose is from a partly seen target.
    partial: bool,
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

/// A board's answer as JSON: `{"ack":{"seq":0,"kind":"tag","status":"done"}}`.
#[derive(Serialize)]
struct JsonAck {
    ack: JsonAckBody,
}

#[derive(Serialize)]
struct JsonAckBody {
    seq: u16,
    kind: &'static str,
    status: &'static str,
}

/// A calibrate-mode progress record or verdict ([`camgeom_fw_app::calibrate_mode`]).
#[derive(Serialize)]
struct JsonCalibrate {
    calibrate: JsonCalibrateBody,
}

#[derive(Serialize)]
struct JsonCalibrateBody {
    frame: u32,
    found: bool,
    kept: bool,
    views: u32,
    needed: u32,
    status: &'static str,
    /// Why refused, by name.
    reasons: Vec<&'static str>,
    /// The solve's error, by name.
    error: Option<&'static str>,
}

/// A calibrate mode's result.
#[derive(Serialize)]
struct JsonCalibration {
    calibration: JsonCalibrationBody,
}

#[derive(Serialize)]
struct JsonCalibrationBody {
    views_used: u32,
    iterations: u32,
    intrinsics: [f32; 4],
    distortion: [f32; 5],
    rms_px: f32,
    initial_rms_px: f32,
    std: [f32; 9],
    warnings: Vec<&'static str>,
}

/// The settings a board sends after a calibration.
#[derive(Serialize)]
struct JsonSettings {
    settings: JsonSettingsBody,
}

#[derive(Serialize)]
struct JsonSettingsBody {
    mode: &'static str,
    intrinsics: [f32; 4],
    distortion: [f32; 5],
    tag_size: f32,
}

const WARNINGS: [&str; 3] = [
    "focal_length_unconstrained",
    "principal_point_unconstrained",
    "distortion_unconstrained",
];

/// The names of a verdict's reasons ([`camgeom_fw_app::calibrate_mode::reason`]).
fn reasons(bits: u32) -> Vec<&'static str> {
    use camgeom_fw_app::calibrate_mode::reason;
    let mut out: Vec<&'static str> = (0..3)
        .filter(|k| bits & (1 << k) != 0)
        .filter_map(|k| WARNINGS.get(k).copied())
        .collect();
    for (bit, name) in [
        (reason::RMS, "rms_above_bound"),
        (reason::SOLVE, "solve_failed"),
        (reason::ENDED, "frames_ended"),
        (reason::CAMERA, "camera_out_of_range"),
    ] {
        if bits & bit != 0 {
            out.push(name);
        }
    }
    out
}

/// A calibrate-mode record as its line (a table line or JSON).
fn calibrate_line(rec: &[u8], json: bool, calibrated: &mut bool) -> Option<String> {
    use camgeom_fw_app::calibrate_mode::{ProgressRecord, decode_result};
    let tag = rec.get(..4)?;
    if tag == PROGRESS_TAG.to_le_bytes() {
        let p = ProgressRecord::decode(rec).ok()?;
        let body = JsonCalibrateBody {
            frame: p.frame,
            found: p.found,
            kept: p.kept,
            views: p.views,
            needed: p.needed,
            status: p.status.name(),
            reasons: reasons(p.reason),
            error: (p.error != 0)
                .then(|| camgeom_fw_app::report::ErrorCode(p.error.min(255) as u8).name()),
        };
        *calibrated |= p.status != camgeom_fw_app::calibrate_mode::Status::Collecting;
        return Some(if json {
            to_json_line(&JsonCalibrate { calibrate: body })
        } else if p.status == camgeom_fw_app::calibrate_mode::Status::Collecting {
            format!(
                "calibrate: frame {} {}, {} of {} views",
                body.frame,
                match (p.found, p.kept) {
                    (true, true) => "board found, kept",
                    (true, false) => "board found, not new",
                    _ => "no board",
                },
                body.views,
                body.needed
            )
        } else {
            let why = if body.reasons.is_empty() {
                String::new()
            } else {
                format!(" ({})", body.reasons.join(", "))
            };
            let err = body.error.map_or(String::new(), |e| format!(" error {e}"));
            format!(
                "calibrate: {} after {} frames, {} of {} views{why}{err}",
                body.status, body.frame, body.views, body.needed
            )
        });
    }
    if tag == RESULT_TAG.to_le_bytes() {
        let r = decode_result(rec).ok()?;
        let body = JsonCalibrationBody {
            views_used: r.views_used,
            iterations: r.iterations,
            intrinsics: r.intrinsics,
            distortion: r.distortion,
            rms_px: r.rms_px,
            initial_rms_px: r.initial_rms_px,
            std: r.std,
            warnings: reasons(r.warnings & 7),
        };
        return Some(if json {
            to_json_line(&JsonCalibration { calibration: body })
        } else {
            let [fx, fy, cx, cy] = r.intrinsics;
            let [k1, k2, p1, p2, k3] = r.distortion;
            format!(
                "calibration: {} views, fx {fx:.2} fy {fy:.2} cx {cx:.2} cy {cy:.2}, k1 {k1:.4} k2 {k2:.4} p1 {p1:.5} p2 {p2:.5} k3 {k3:.4}, RMS {:.4} px, warnings [{}]",
                r.views_used,
                r.rms_px,
                body.warnings.join(", ")
            )
        });
    }
    None
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

/// The name of a command kind ([`Command::kind`]; `"unknown"` for 0, the kind of a command the
/// board could not decode, or any other).
pub fn kind_name(kind: u32) -> &'static str {
    camgeom_fw_app::command::Command::kind_name(kind)
}

/// The commands as the board reads them: each a [`Command`] record in a link frame, numbered
/// from 0 in order (an emulated board's `commands.bin`, or the bytes sent to a live board).
pub fn command_bytes(commands: &[Command]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut buf = [0u8; max_frame_len(COMMAND_LEN)];
    for (seq, c) in (0u16..).zip(commands) {
        // The buffer is `max_frame_len` of the record: encoding cannot fail.
        if let Ok(n) = encode_frame(seq, &c.encode(), &mut buf) {
            out.extend_from_slice(buf.get(..n).unwrap_or(&[]));
        }
    }
    out
}

/// A command that was not carried out: its number and kind, and the board's answer
/// (`None`: no answer came).
#[derive(Debug, Serialize)]
pub struct NotDone {
    /// The command frame's number.
    pub seq: u16,
    /// Its kind ([`kind_name`]).
    pub kind: &'static str,
    /// The board's answer ([`AckStatus::name`]), `None` when none came.
    pub status: Option<&'static str>,
}

/// What came of the commands sent to a board ([`check_acks`]).
#[derive(Debug, Serialize)]
pub struct CommandsReport {
    /// Commands sent.
    pub sent: usize,
    /// Answered `done`.
    pub done: usize,
    /// Answered with anything else, or not answered.
    pub not_done: Vec<NotDone>,
}

#[derive(Serialize)]
struct JsonCommands<'a> {
    commands: &'a CommandsReport,
}

impl CommandsReport {
    /// Every command was answered `done`.
    pub fn all_done(&self) -> bool {
        self.done == self.sent
    }

    /// The report as a line: `{"commands":{...}}` with `json`, else `commands: N sent, N done`
    /// and each command not done (`0 tag invalid`, `3 save unanswered`).
    pub fn line(&self, json: bool) -> String {
        if json {
            return to_json_line(&JsonCommands { commands: self });
        }
        let mut line = format!("commands: {} sent, {} done", self.sent, self.done);
        for n in &self.not_done {
            line += &format!(
                ", {} {} {}",
                n.seq,
                n.kind,
                n.status.unwrap_or("unanswered")
            );
        }
        line
    }
}

/// Checks `acks` against the commands `sent` (numbered from 0 as [`command_bytes`] numbers
/// them): the last answer to a number counts.
pub fn check_acks(sent: &[Command], acks: &[Ack]) -> CommandsReport {
    let mut done = 0;
    let mut not_done = Vec::new();
    for (seq, c) in (0u16..).zip(sent) {
        match acks.iter().rev().find(|a| a.seq == seq) {
            Some(a) if a.status == AckStatus::Done => done += 1,
            answer => not_done.push(NotDone {
                seq,
                kind: kind_name(c.kind()),
                status: answer.map(|a| a.status.name()),
            }),
        }
    }
    CommandsReport {
        sent: sent.len(),
        done,
        not_done,
    }
}

/// What [`monitor_link`] saw.
#[derive(Debug)]
pub struct Monitored {
    /// The last line (the link's counts), for the caller to print.
    pub last: String,
    /// The board's answers to commands, in the order they came.
    pub acks: Vec<Ack>,
    /// Streamed frames written as pictures (`frames_dir`).
    pub pictures: u32,
    /// Streamed frames that came incomplete ([`FrameAssembler::incomplete`]).
    pub incomplete: u32,
}

#[derive(Serialize)]
struct JsonPictures<'a> {
    pictures: JsonPicturesBody<'a>,
}

#[derive(Serialize)]
struct JsonPicturesBody<'a> {
    dir: &'a str,
    written: u32,
    incomplete: u32,
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
        partial: f.partial,
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

/// The columns of the table and the CSV log.
pub const COLUMNS: [&str; 14] = [
    "seq", "frame", "state", "error", "tracked", "inliers", "tx", "ty", "tz", "rx", "ry", "rz",
    "rms_px", "total",
];

/// Reads `input` (named `name` in errors) to its end, writing a line a frame record to `out` (a
/// table row with a header first, or with `json` one JSON object a line) and each row as CSV to
/// `csv`; then the summary record's line, if the stream had one. Returns the last line, the
/// link's counts (the caller prints it). A closed `out` (a pipe to `head`) is not an error.
/// The board's answers to commands are printed too ([`monitor_link`] also returns them).
pub fn monitor(
    input: &mut dyn Read,
    name: &str,
    json: bool,
    out: &mut dyn Write,
    csv: Option<(&std::path::Path, &mut dyn Write)>,
) -> Result<String> {
    monitor_link(input, name, json, out, csv, None).map(|m| m.last)
}

/// [`monitor`], also returning the board's answers to commands: each printed as it comes, a
/// line `ack: command SEQ KIND STATUS` in the table, `{"ack":{"seq":..,"kind":..,"status":..}}`
/// with `json`. With `frames_dir`, each frame the board streams whole (mode `stream-frames`,
/// [`crate::monitor_frames`]) is written there as `frame-NNNNNN.png` with its overlay, and a
/// line before the last says how many were written and how many came incomplete.
pub fn monitor_link(
    input: &mut dyn Read,
    name: &str,
    json: bool,
    out: &mut dyn Write,
    mut csv: Option<(&std::path::Path, &mut dyn Write)>,
    frames_dir: Option<&Path>,
) -> Result<Monitored> {
    let print = |out: &mut dyn Write, line: String| {
        let _ = writeln!(out, "{line}");
    };
    if !json {
        print(out, COLUMNS.join("\t"));
    }
    if let Some((p, w)) = &mut csv {
        writeln!(w, "{}", COLUMNS.join(",")).map_err(|e| Error::new(*p, ErrorKind::Io(e)))?;
    }
    // Frame records are the longest on the stream.
    const _: () = assert!(ACK_LEN <= RECORD_LEN && CHUNK_LEN <= RECORD_LEN);
    const _: () = assert!(SETTINGS_LEN <= RECORD_LEN);
    let mut rx = Deframer::<{ max_frame_len(RECORD_LEN) }>::new();
    let mut frames = FrameAssembler::new();
    let mut pictures = 0u32;
    let mut buf = vec![0u8; 4096];
    let mut unreadable = 0u32;
    let mut summary: Option<SummaryRecord> = None;
    let mut acks = Vec::new();
    // A calibration's verdict came: the settings record after it is printed.
    let mut calibrated = false;
    loop {
        let n = input
            .read(&mut buf)
            .map_err(|e| Error::new(name, ErrorKind::Io(e)))?;
        if n == 0 {
            break;
        }
        let mut bytes = buf.get(..n).unwrap_or(&[]);
        while let Some(frame) = rx.push(&mut bytes) {
            let seq = frame.seq;
            if frame.record.get(..4) == Some(&ACK_TAG.to_le_bytes()[..]) {
                match Ack::decode(frame.record) {
                    Ok(a) => {
                        let body = JsonAckBody {
                            seq: a.seq,
                            kind: kind_name(a.kind),
                            status: a.status.name(),
                        };
                        if json {
                            print(out, to_json_line(&JsonAck { ack: body }));
                        } else {
                            print(
                                out,
                                format!("ack: command {} {} {}", body.seq, body.kind, body.status),
                            );
                        }
                        acks.push(a);
                    }
                    Err(_) => unreadable += 1,
                }
                continue;
            }
            let tag = frame.record.get(..4);
            if tag == Some(&CHUNK_TAG.to_le_bytes()[..]) {
                match FrameChunk::decode(frame.record) {
                    Ok(c) => frames.chunk(&c),
                    Err(_) => unreadable += 1,
                }
                continue;
            }
            if tag == Some(&SETTINGS_TAG.to_le_bytes()[..]) {
                match Settings::decode(frame.record) {
                    // After a calibration: the settings the board runs with now.
                    Ok(st) if calibrated => {
                        calibrated = false;
                        let body = JsonSettingsBody {
                            mode: st.mode.name(),
                            intrinsics: st.intrinsics,
                            distortion: st.distortion,
                            tag_size: st.tag_size,
                        };
                        print(
                            out,
                            if json {
                                to_json_line(&JsonSettings { settings: body })
                            } else {
                                let [fx, fy, cx, cy] = body.intrinsics;
                                format!(
                                    "settings: mode {}, camera fx {fx:.2} fy {fy:.2} cx {cx:.2} cy {cy:.2}, distortion {:?}",
                                    body.mode, body.distortion
                                )
                            },
                        );
                    }
                    Ok(st) => frames.settings(st),
                    Err(_) => unreadable += 1,
                }
                continue;
            }
            if tag.is_some_and(|t| t == PROGRESS_TAG.to_le_bytes() || t == RESULT_TAG.to_le_bytes())
            {
                match calibrate_line(frame.record, json, &mut calibrated) {
                    Some(line) => print(out, line),
                    None => unreadable += 1,
                }
                continue;
            }
            match Record::decode(frame.record) {
                Ok(Record::Frame(f)) => {
                    if json {
                        print(out, to_json_line(&json_frame(seq, &f)));
                    } else {
                        print(out, row(seq, &f).join("\t"));
                    }
                    if let Some((p, w)) = &mut csv {
                        writeln!(w, "{}", row(seq, &f).join(","))
                            .map_err(|e| Error::new(*p, ErrorKind::Io(e)))?;
                    }
                    if let Some((img, settings)) = frames.record(f.index)
                        && let Some(dir) = frames_dir
                    {
                        save_frame(dir, &img, &f, settings.as_ref())?;
                        pictures += 1;
                    }
                }
                Ok(Record::Summary(s)) => summary = Some(s),
                Err(_) => unreadable += 1,
            }
        }
    }
    frames.finish();
    let incomplete = frames.incomplete();
    if let Some(dir) = frames_dir {
        let dir = dir.display().to_string();
        if json {
            print(
                out,
                to_json_line(&JsonPictures {
                    pictures: JsonPicturesBody {
                        dir: &dir,
                        written: pictures,
                        incomplete,
                    },
                }),
            );
        } else {
            print(
                out,
                format!(
                    "frames: {pictures} pictures written to {dir}, {incomplete} frames incomplete"
                ),
            );
        }
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
        if json {
            print(out, to_json_line(&JsonSummary { summary: body }));
        } else {
            print(
                out,
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
    let last = if json {
        to_json_line(&JsonLink { link })
    } else {
        format!(
            "link: {frames} frames, {damaged} damaged, {lost} lost, {repeated} repeated, {bytes_discarded} bytes discarded, {unreadable} unreadable"
        )
    };
    Ok(Monitored {
        last,
        acks,
        pictures,
        incomplete,
    })
}
