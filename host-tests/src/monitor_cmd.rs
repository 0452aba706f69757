//! `camgeom monitor`: the host end of a board's record stream, from a saved stream file, a TCP
//! socket (an emulated board's UART: QEMU `-serial tcp:...`) or a serial port (a board's USB
//! CDC-ACM or UART); with commands from the command line sent to the board first (or written
//! to a file for the emulated board). The decoding and printing are
//! [`camgeom_host::monitor`].

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use camgeom::camera::Lens;
use camgeom_fw_app::command::{ChessboardSettings, Command, Mode};
use camgeom_fw_app::options::TAG_FAMILIES;
use camgeom_host::monitor::{
    Live, LiveLimits, POLL, check_acks, command_bytes, monitor_link, open_tcp,
};
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::Args;

/// The tag family a `--set tag-id`/`tag-size` without `tag-family` sends.
const DEFAULT_FAMILY: &str = "tag36h11";
/// The serial port's speed unless `--baud` says otherwise (a USB CDC-ACM port ignores it).
const DEFAULT_BAUD: u32 = 115_200;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("source").args(["replay", "tcp", "serial"])))]
pub struct MonitorArgs {
    /// A saved record stream (an emulated board's `serial.bin`, or bytes captured from a real
    /// board's port). Nothing is sent to it.
    #[arg(long, value_name = "FILE")]
    replay: Option<PathBuf>,
    /// Connect to a board's stream at HOST:PORT (an emulated board started with QEMU
    /// `-serial tcp:HOST:PORT,server`) and read until it closes.
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// Read a board's serial port (`/dev/ttyACM0`, `COM3`: the OpenMV Cam's USB, or a UART
    /// adapter) until it closes or `--seconds` pass.
    #[arg(long, value_name = "PORT")]
    serial: Option<String>,
    /// The serial port's speed, bits a second (default 115200; a USB CDC-ACM port ignores it).
    #[arg(long, value_name = "N", requires = "serial")]
    baud: Option<u32>,
    /// Stop reading a live board (`--tcp`, `--serial`) after this many seconds.
    #[arg(long, value_name = "S")]
    seconds: Option<f64>,
    /// Stop reading a live board (`--tcp`, `--serial`) after this many seconds without a byte
    /// from it (a board that stalled or was unplugged without closing the port).
    #[arg(long, value_name = "S")]
    idle: Option<f64>,
    /// Write each frame the board streams (`--mode stream-frames`) as DIR/frame-NNNNNN.png,
    /// the frame with the overlay its record describes (the tag's outline, the cube on it);
    /// frames that came incomplete are counted, not written.
    #[arg(long, value_name = "DIR")]
    frames_dir: Option<PathBuf>,
    /// A setting to send to the board, repeatable: `tag-size=METRES` (the side of the tag's
    /// black square), `tag-family=NAME` (tag36h11, tag25h9, tag16h5, tagStandard41h12;
    /// default tag36h11), `tag-id=N` (default 0), `camera=FILE` (intrinsics and distortion from
    /// a camgeom or OpenCV camera file), and for `--mode calibrate`: `chessboard=COLSxROWS`
    /// (inner corners, default 9x6), `square=METRES` (default 0.025), `views=N` (views kept
    /// before it solves, 3 to 16, default 10). The tag's keys travel as one command, which
    /// needs `tag-size`; the chessboard's as another.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Switch the board to this mode.
    #[arg(long, value_name = "MODE", value_parser = clap::builder::PossibleValuesParser::new(Mode::ALL.map(Mode::name)))]
    mode: Option<String>,
    /// Have the board store its settings in flash (sent after the other commands), where it
    /// loads them at boot.
    #[arg(long)]
    save: bool,
    /// Write the framed commands to this file instead of sending them (an emulated board's
    /// `commands.bin`).
    #[arg(long, value_name = "FILE")]
    commands_out: Option<PathBuf>,
    /// One JSON object a frame record (and one for each answer to a command, the summary, the
    /// link counts and the commands' outcome) instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write every frame record as a CSV row to this file.
    #[arg(long, value_name = "LOG.csv")]
    csv: Option<PathBuf>,
}

/// The commands the arguments ask for, in the order the board applies them: camera, tag,
/// mode, save.
fn commands(a: &MonitorArgs) -> Result<Vec<Command>> {
    let (mut size, mut family, mut id, mut camera) = (None, None, None, None);
    let (mut board, mut square, mut views) = (None, None, None);
    for s in &a.set {
        let (key, value) = s
            .split_once('=')
            .ok_or_else(|| Error::usage(format!("--set {s}: expected KEY=VALUE")))?;
        let bad = |what: &str| Error::usage(format!("--set {s}: {what}"));
        let twice = || Error::usage(format!("--set {key} given twice"));
        match key {
            "tag-size" => {
                let v: f32 = value
                    .parse()
                    .ok()
                    .filter(|v: &f32| v.is_finite() && *v > 0.0)
                    .ok_or_else(|| bad("the size must be a positive number of metres"))?;
                size.replace(v).map_or(Ok(()), |_| Err(twice()))?;
            }
            "tag-family" => {
                let names: Vec<&str> = TAG_FAMILIES.iter().map(|f| f.name()).collect();
                let k = names
                    .iter()
                    .position(|n| *n == value)
                    .ok_or_else(|| bad(&format!("the family is one of {}", names.join(", "))))?;
                let k = u8::try_from(k).map_err(|_| bad("family index"))?;
                family.replace(k).map_or(Ok(()), |_| Err(twice()))?;
            }
            "tag-id" => {
                let v: u16 = value
                    .parse()
                    .map_err(|_| bad("the id is a number from 0 to 65535"))?;
                id.replace(v).map_or(Ok(()), |_| Err(twice()))?;
            }
            "camera" => {
                let spec = load_camera(value)?;
                let k = spec.camera.intrinsics;
                let distortion = match spec.camera.lens {
                    Lens::BrownConrady(d) => d.to_opencv().map(|v| v as f32),
                    Lens::KannalaBrandt(_) => {
                        return Err(Error::new(
                            value,
                            ErrorKind::Unsupported(
                                "a fisheye camera: the board models k1 k2 p1 p2 k3".into(),
                            ),
                        ));
                    }
                };
                let c = Command::SetCamera {
                    intrinsics: [k.fx(), k.fy(), k.cx(), k.cy()].map(|v| v as f32),
                    distortion,
                };
                camera.replace(c).map_or(Ok(()), |_| Err(twice()))?;
            }
            "chessboard" => {
                let v = value
                    .split_once('x')
                    .and_then(|(c, r)| Some((c.parse::<u8>().ok()?, r.parse::<u8>().ok()?)))
                    .ok_or_else(|| bad("the board is COLSxROWS inner corners, e.g. 9x6"))?;
                board.replace(v).map_or(Ok(()), |_| Err(twice()))?;
            }
            "square" => {
                let v: f32 = value
                    .parse()
                    .ok()
                    .filter(|v: &f32| v.is_finite() && *v > 0.0)
                    .ok_or_else(|| bad("the square must be a positive number of metres"))?;
                square.replace(v).map_or(Ok(()), |_| Err(twice()))?;
            }
            "views" => {
                let v: u8 = value
                    .parse()
                    .map_err(|_| bad("views is a number, 3 to 16"))?;
                views.replace(v).map_or(Ok(()), |_| Err(twice()))?;
            }
            _ => {
                return Err(bad(
                    "the keys are tag-size, tag-family, tag-id, camera, chessboard, square and views",
                ));
            }
        }
    }
    let mut out: Vec<Command> = camera.into_iter().collect();
    if family.is_some() || id.is_some() || size.is_some() {
        let size = size.ok_or_else(|| {
            Error::usage("--set tag-family/tag-id: the tag also needs --set tag-size=METRES")
        })?;
        let family = match family {
            Some(f) => f,
            None => TAG_FAMILIES
                .iter()
                .position(|f| f.name() == DEFAULT_FAMILY)
                .and_then(|k| u8::try_from(k).ok())
                .unwrap_or(0),
        };
        out.push(Command::SetTag {
            family,
            id: id.unwrap_or(0),
            size,
        });
    }
    if board.is_some() || square.is_some() || views.is_some() {
        let d = ChessboardSettings::DEFAULT;
        let (cols, rows) = board.unwrap_or((d.cols, d.rows));
        let b = ChessboardSettings {
            cols,
            rows,
            square: square.unwrap_or(d.square),
            views: views.unwrap_or(d.views),
        };
        b.check().map_err(|field| {
            Error::usage(format!(
                "--set chessboard/square/views: a {field} no board takes (3 to 64 corners each way, at most 64 in all; 3 to 16 views)"
            ))
        })?;
        out.push(Command::SetChessboard(b));
    }
    if let Some(m) = &a.mode {
        let mode = Mode::ALL
            .into_iter()
            .find(|x| x.name() == m)
            .ok_or_else(|| Error::usage(format!("--mode {m}")))?;
        out.push(Command::SetMode(mode));
    }
    if a.save {
        out.push(Command::Save);
    }
    Ok(out)
}

/// Sends `bytes` (the framed commands) to a live board.
fn send(w: &mut dyn Write, bytes: &[u8], name: &str) -> Result<()> {
    w.write_all(bytes)
        .and_then(|()| w.flush())
        .map_err(|e| Error::new(name, ErrorKind::Write(e)))
}

/// `camgeom monitor`: sends the commands (or writes them to `--commands-out`), then decodes
/// the stream, printing as it goes; returns the link's counts and, when commands were sent,
/// what came of them. A command the board refused or did not answer is an error (exit 1),
/// after the link's counts are printed.
pub fn run(a: &MonitorArgs) -> Result<String> {
    let commands = commands(a)?;
    let bytes = command_bytes(&commands);
    if let Some(p) = &a.commands_out {
        std::fs::write(p, &bytes).map_err(|e| Error::new(p, ErrorKind::Write(e)))?;
    } else if !commands.is_empty() && a.replay.is_some() {
        return Err(Error::usage(
            "--set/--mode/--save go to a live board (--tcp, --serial) or to --commands-out; \
             nothing is sent to a --replay",
        ));
    }
    // Commands go on the link unless they went to a file.
    let live_commands = a.commands_out.is_none() && !commands.is_empty();
    let duration = |flag: &str, s: f64| {
        Duration::try_from_secs_f64(s)
            .map_err(|_| Error::usage(format!("--{flag} {s}: not a duration")))
    };
    let limits = LiveLimits {
        deadline: a
            .seconds
            .map(|s| duration("seconds", s).map(|d| Instant::now() + d))
            .transpose()?,
        idle: a.idle.map(|s| duration("idle", s)).transpose()?,
    };
    if let Some(dir) = &a.frames_dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::new(dir, ErrorKind::Write(e)))?;
    }
    let (name, mut input): (String, Box<dyn Read>) = match (&a.replay, &a.tcp, &a.serial) {
        (Some(p), _, _) => (
            p.display().to_string(),
            Box::new(File::open(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?),
        ),
        (None, Some(addr), _) => {
            let commands = if live_commands { &bytes[..] } else { &[] };
            (addr.clone(), Box::new(open_tcp(addr, commands, limits)?))
        }
        (None, None, Some(port)) => {
            let mut s = serialport::new(port, a.baud.unwrap_or(DEFAULT_BAUD))
                .timeout(POLL)
                .open()
                .map_err(|e| Error::new(port.as_str(), ErrorKind::Io(e.into())))?;
            if live_commands {
                send(&mut s, &bytes, port)?;
            }
            (port.clone(), Box::new(Live::new(s, limits)))
        }
        (None, None, None) if a.commands_out.is_some() => return Ok(String::new()),
        (None, None, None) => {
            return Err(Error::usage(
                "give --replay FILE, --tcp HOST:PORT or --serial PORT (or --commands-out FILE)",
            ));
        }
    };
    let mut csv = match &a.csv {
        Some(p) => Some((
            p.as_path(),
            BufWriter::new(File::create(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?),
        )),
        None => None,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let seen = monitor_link(
        &mut input,
        &name,
        a.json,
        &mut out,
        csv.as_mut().map(|(p, w)| (*p, w as &mut dyn Write)),
        a.frames_dir.as_deref(),
    )?;
    if let Some((p, mut w)) = csv {
        w.flush().map_err(|e| Error::new(p, ErrorKind::Write(e)))?;
    }
    if !live_commands {
        return Ok(seen.last + "\n");
    }
    let report = check_acks(&commands, &seen.acks);
    let text = format!("{}\n{}\n", seen.last, report.line(a.json));
    if report.all_done() {
        return Ok(text);
    }
    // The counts still reach standard output; the error says which commands failed.
    let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
    Err(Error::new(
        name,
        ErrorKind::Undetermined(format!(
            "{} of {} commands not done",
            report.sent - report.done,
            report.sent
        )),
    ))
}
