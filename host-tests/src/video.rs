//! Video files in and out through the system's `ffmpeg` and `ffprobe` (child processes, raw
//! RGB frames through a pipe): a video is decoded one frame at a time, never held whole in
//! memory, and a video is written by piping frames into the encoder.
//!
//! - [`probe`]: size, frame rate, pixel format and every frame's presentation time
//!   (`ffprobe`, packets only: nothing is decoded);
//! - [`VideoReader`]: the frames, as `ffmpeg -i IN -f rawvideo -pix_fmt rgb24 -` prints them,
//!   each with its index and time;
//! - [`VideoWriter`]: frames into `ffmpeg -f rawvideo -pix_fmt rgb24 -i - OUT` (H.264 for
//!   `.mp4`/`.mov`/`.mkv`, MPEG-4 part 2 for `.avi`).
//!
//! Frames are decoded as the file stores them: a rotation tag (phone videos) is not applied
//! (`-noautorotate`), so frames keep the sensor's orientation, the one a calibration from the
//! same video has. Every decoded frame is kept (`-vsync passthrough`): none is dropped or
//! duplicated to make a constant rate.
//!
//! Without `ffmpeg`/`ffprobe` on the `PATH`, every function returns
//! [`ErrorKind::Unsupported`] with the install hint (`cargo xtask setup` installs them).

use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use image::RgbImage;

use crate::error::{Error, ErrorKind, Result};

/// The file name extensions read as videos (case-insensitive).
pub const VIDEO_EXTENSIONS: [&str; 7] = ["mp4", "m4v", "mov", "avi", "mkv", "webm", "mpg"];

/// Whether `path` names a video file by its extension ([`VIDEO_EXTENSIONS`]).
pub fn is_video(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| VIDEO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// What [`probe`] finds out about a video's first video stream.
#[derive(Debug, Clone, PartialEq)]
pub struct VideoInfo {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height in pixels.
    pub height: usize,
    /// Frames per second: the stream's average rate (`avg_frame_rate`), else its base rate
    /// (`r_frame_rate`); `None` when the file gives neither.
    pub fps: Option<f64>,
    /// The decoder's pixel format (`yuv420p`, `rgb24`, `gray`, ...).
    pub pix_fmt: String,
    /// The codec's name (`h264`, `mpeg4`, `png`, ...).
    pub codec: String,
    /// Each frame's presentation time in seconds, in display order (the packets' `pts_time`,
    /// sorted): as many as the stream has frames.
    pub times: Vec<f64>,
}

impl VideoInfo {
    /// Whether the frames are grey (`gray*` pixel formats): their overlays are drawn on grey.
    pub fn is_gray(&self) -> bool {
        self.pix_fmt.starts_with("gray") || self.pix_fmt.starts_with("ya")
    }
}

/// A tool that is not installed: its name and how to get it.
fn missing(tool: &str, path: &Path) -> Error {
    Error::new(
        path,
        ErrorKind::Unsupported(format!(
            "reading and writing videos needs `{tool}` (FFmpeg), which was not found on the \
             PATH: install it with `cargo xtask setup` (Debian/Ubuntu: `apt-get install \
             ffmpeg`)"
        )),
    )
}

/// Starts `tool` with `args`, a missing tool mapped to its install hint.
fn spawn(tool: &str, path: &Path, cmd: &mut Command) -> Result<Child> {
    cmd.spawn().map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            missing(tool, path)
        } else {
            Error::new(path, ErrorKind::Io(e))
        }
    })
}

/// Reads a child's stderr to the end on a thread (a tool that writes much there must not
/// block on a full pipe); the thread's answer is the text.
fn drain(child: &mut Child) -> Option<std::thread::JoinHandle<Vec<u8>>> {
    let mut stderr = child.stderr.take()?;
    Some(std::thread::spawn(move || {
        let mut text = Vec::new();
        let _ = stderr.read_to_end(&mut text);
        text
    }))
}

/// What [`drain`] collected (empty when there is nothing).
fn drained(handle: Option<std::thread::JoinHandle<Vec<u8>>>) -> Vec<u8> {
    handle.and_then(|h| h.join().ok()).unwrap_or_default()
}

/// The last non-empty line a tool wrote on stderr, for an error message.
fn last_line(stderr: &[u8]) -> String {
    String::from_utf8_lossy(stderr)
        .lines()
        .map(str::trim)
        .rfind(|l| !l.is_empty())
        .unwrap_or("no message")
        .to_string()
}

/// `a/b` as a rate; `None` for `0/0`, a zero or a non-number.
fn rate(s: &str) -> Option<f64> {
    let (a, b) = s.split_once('/').unwrap_or((s, "1"));
    let v = a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?;
    (v.is_finite() && v > 0.0).then_some(v)
}

/// Size, rate, pixel format and frame times of `path`'s first video stream, by `ffprobe`
/// (the packets are read, not decoded).
///
/// Errors: [`ErrorKind::Unsupported`] without ffprobe (the hint says how to install it) or for a
/// file without a video stream; [`ErrorKind::Syntax`] when ffprobe cannot read the file (its
/// message); [`ErrorKind::Io`] when the file is missing.
pub fn probe(path: &Path) -> Result<VideoInfo> {
    if !path.is_file() {
        return Err(Error::new(
            path,
            ErrorKind::Io(std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such video file",
            )),
        ));
    }
    let out = spawn(
        "ffprobe",
        path,
        Command::new("ffprobe")
            .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
            .arg("stream=width,height,avg_frame_rate,r_frame_rate,pix_fmt,codec_name")
            .args(["-show_entries", "packet=pts_time,dts_time", "-of", "json"])
            .arg(path)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    )?
    .wait_with_output()
    .map_err(|e| Error::new(path, ErrorKind::Io(e)))?;
    if !out.status.success() {
        return Err(Error::new(
            path,
            ErrorKind::Syntax(format!(
                "ffprobe cannot read it: {}",
                last_line(&out.stderr)
            )),
        ));
    }
    #[derive(serde::Deserialize)]
    struct Probe {
        #[serde(default)]
        streams: Vec<Stream>,
        #[serde(default)]
        packets: Vec<Packet>,
    }
    #[derive(serde::Deserialize)]
    struct Stream {
        width: Option<usize>,
        height: Option<usize>,
        avg_frame_rate: Option<String>,
        r_frame_rate: Option<String>,
        pix_fmt: Option<String>,
        codec_name: Option<String>,
    }
    #[derive(serde::Deserialize)]
    struct Packet {
        pts_time: Option<String>,
        dts_time: Option<String>,
    }
    let p: Probe = serde_json::from_slice(&out.stdout).map_err(|e| {
        Error::new(
            path,
            ErrorKind::Syntax(format!("ffprobe's answer is not understood: {e}")),
        )
    })?;
    let no_video = || Error::new(path, ErrorKind::Unsupported("no video stream".into()));
    let s = p.streams.first().ok_or_else(no_video)?;
    let (Some(width), Some(height)) = (s.width, s.height) else {
        return Err(no_video());
    };
    let fps = s
        .avg_frame_rate
        .as_deref()
        .and_then(rate)
        .or_else(|| s.r_frame_rate.as_deref().and_then(rate));
    let mut times: Vec<f64> = p
        .packets
        .iter()
        .enumerate()
        .map(|(k, pk)| {
            [&pk.pts_time, &pk.dts_time]
                .into_iter()
                .flatten()
                .find_map(|t| t.parse::<f64>().ok())
                .unwrap_or_else(|| fps.map_or(f64::NAN, |f| k as f64 / f))
        })
        .collect();
    times.sort_by(f64::total_cmp);
    Ok(VideoInfo {
        width,
        height,
        fps,
        pix_fmt: s.pix_fmt.clone().unwrap_or_default(),
        codec: s.codec_name.clone().unwrap_or_default(),
        times,
    })
}

/// One decoded frame of a [`VideoReader`].
#[derive(Debug, Clone)]
pub struct VideoFrame {
    /// 0-based index in display order.
    pub index: usize,
    /// Presentation time in seconds ([`VideoInfo::times`]); for a frame past the probed ones,
    /// the last time plus one frame period.
    pub t: f64,
    /// The pixels.
    pub rgb: RgbImage,
}

/// A video decoded one frame at a time: `ffmpeg` prints raw RGB frames on a pipe and
/// [`VideoReader::next_frame`] reads one (`width * height * 3` bytes) a call.
#[derive(Debug)]
pub struct VideoReader {
    path: PathBuf,
    info: VideoInfo,
    child: Child,
    stdout: BufReader<ChildStdout>,
    stderr: Option<std::thread::JoinHandle<Vec<u8>>>,
    index: usize,
    done: bool,
}

impl VideoReader {
    /// Probes `path` ([`probe`]) and starts decoding it.
    pub fn open(path: &Path) -> Result<Self> {
        let info = probe(path)?;
        let mut child = spawn(
            "ffmpeg",
            path,
            Command::new("ffmpeg")
                .args(["-v", "error", "-nostdin", "-noautorotate", "-i"])
                .arg(path)
                .args(["-map", "0:v:0", "-vsync", "passthrough", "-f", "rawvideo"])
                .args(["-pix_fmt", "rgb24", "-"])
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped()),
        )?;
        let stdout = child.stdout.take().ok_or_else(|| {
            Error::new(
                path,
                ErrorKind::Io(std::io::Error::other("ffmpeg's output pipe")),
            )
        })?;
        let stderr = drain(&mut child);
        Ok(Self {
            path: path.to_path_buf(),
            info,
            child,
            stdout: BufReader::with_capacity(1 << 20, stdout),
            stderr,
            index: 0,
            done: false,
        })
    }

    /// What [`probe`] found.
    pub fn info(&self) -> &VideoInfo {
        &self.info
    }

    /// The next frame, `None` after the last one.
    ///
    /// Errors: [`ErrorKind::Syntax`] when ffmpeg stops with an error or a frame is cut short
    /// (ffmpeg's message).
    pub fn next_frame(&mut self) -> Result<Option<VideoFrame>> {
        if self.done {
            return Ok(None);
        }
        let (w, h) = (self.info.width, self.info.height);
        let mut buf = vec![0u8; w * h * 3];
        let mut filled = 0;
        while filled < buf.len() {
            match self.stdout.read(&mut buf[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::new(&self.path, ErrorKind::Io(e))),
            }
        }
        if filled < buf.len() {
            self.done = true;
            let stderr = drained(self.stderr.take());
            let status = self
                .child
                .wait()
                .map_err(|e| Error::new(&self.path, ErrorKind::Io(e)))?;
            if !status.success() || filled > 0 {
                return Err(Error::new(
                    &self.path,
                    ErrorKind::Syntax(format!(
                        "ffmpeg could not decode frame {}: {}",
                        self.index,
                        last_line(&stderr)
                    )),
                ));
            }
            return Ok(None);
        }
        let k = self.index;
        let t = match self.info.times.get(k) {
            Some(t) => *t,
            None => {
                let last = self.info.times.last().copied().unwrap_or(0.0);
                let extra = (k + 1).saturating_sub(self.info.times.len()) as f64;
                last + extra / self.info.fps.unwrap_or(1.0)
            }
        };
        self.index += 1;
        let rgb = RgbImage::from_raw(w as u32, h as u32, buf).ok_or_else(|| {
            Error::new(
                &self.path,
                ErrorKind::Shape("frame buffer does not match the size".into()),
            )
        })?;
        Ok(Some(VideoFrame { index: k, t, rgb }))
    }
}

impl Drop for VideoReader {
    /// A reader dropped before the end stops its ffmpeg.
    fn drop(&mut self) {
        if !self.done {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// A video written one frame at a time: raw RGB frames piped into `ffmpeg`, which encodes them
/// at a constant rate. `.mp4`, `.mov` and `.mkv` get H.264 (`libx264`, `yuv420p`, preset
/// `ultrafast`, CRF 20; odd sizes are padded by one pixel), `.avi` MPEG-4 part 2 (`mpeg4`,
/// `-q:v 3`).
#[derive(Debug)]
pub struct VideoWriter {
    path: PathBuf,
    child: Child,
    stdin: Option<ChildStdin>,
    stderr: Option<std::thread::JoinHandle<Vec<u8>>>,
    size: (u32, u32),
    frames: usize,
}

impl VideoWriter {
    /// Starts the encoder for frames of `width x height` at `fps` frames per second.
    ///
    /// Errors: [`ErrorKind::Unsupported`] without ffmpeg, or for an extension that is not
    /// `.mp4`, `.mov`, `.mkv` or `.avi`; [`ErrorKind::Usage`] for a rate that is not positive.
    pub fn create(path: &Path, width: u32, height: u32, fps: f64) -> Result<Self> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(Error::usage(format!(
                "{}: the frame rate must be positive, got {fps}",
                path.display()
            )));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let codec: &[&str] = match ext.as_str() {
            "mp4" | "mov" | "mkv" => &[
                "-c:v",
                "libx264",
                "-preset",
                "ultrafast",
                "-crf",
                "20",
                "-pix_fmt",
                "yuv420p",
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            ],
            "avi" => &["-c:v", "mpeg4", "-q:v", "3"],
            _ => {
                return Err(Error::new(
                    path,
                    ErrorKind::Unsupported(
                        "video output is written as .mp4, .mov, .mkv or .avi".into(),
                    ),
                ));
            }
        };
        let mut child = spawn(
            "ffmpeg",
            path,
            Command::new("ffmpeg")
                .args(["-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24"])
                .args(["-s", &format!("{width}x{height}")])
                .args(["-framerate", &format!("{fps}"), "-i", "-"])
                .args(codec)
                .arg(path)
                .stdin(Stdio::piped())
                .stdout(Stdio::null())
                .stderr(Stdio::piped()),
        )?;
        let stdin = child.stdin.take();
        let stderr = drain(&mut child);
        Ok(Self {
            path: path.to_path_buf(),
            child,
            stdin,
            stderr,
            size: (width, height),
            frames: 0,
        })
    }

    /// Appends `frame`, which must have the writer's size.
    pub fn write(&mut self, frame: &RgbImage) -> Result<()> {
        if frame.dimensions() != self.size {
            return Err(Error::new(
                &self.path,
                ErrorKind::Shape(format!(
                    "frame {} is {}x{}, the video {}x{}",
                    self.frames,
                    frame.width(),
                    frame.height(),
                    self.size.0,
                    self.size.1
                )),
            ));
        }
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(self.failed());
        };
        if stdin.write_all(frame.as_raw()).is_err() {
            // ffmpeg has stopped: its message says why.
            return Err(self.failed());
        }
        self.frames += 1;
        Ok(())
    }

    /// Closes the pipe and waits for the encoder; the number of frames written.
    pub fn finish(mut self) -> Result<usize> {
        drop(self.stdin.take());
        let status = self
            .child
            .wait()
            .map_err(|e| Error::new(&self.path, ErrorKind::Write(e)))?;
        if !status.success() {
            return Err(self.failed());
        }
        Ok(self.frames)
    }

    /// The encoder's error, after it has stopped.
    fn failed(&mut self) -> Error {
        drop(self.stdin.take());
        let _ = self.child.wait();
        let stderr = drained(self.stderr.take());
        Error::new(
            &self.path,
            ErrorKind::Write(std::io::Error::other(format!(
                "ffmpeg could not encode: {}",
                last_line(&stderr)
            ))),
        )
    }
}

impl Drop for VideoWriter {
    fn drop(&mut self) {
        if self.stdin.is_some() {
            drop(self.stdin.take());
            let _ = self.child.wait();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_and_extensions() {
        assert_eq!(rate("30000/1001"), Some(30000.0 / 1001.0));
        assert_eq!(rate("25"), Some(25.0));
        assert_eq!(rate("0/0"), None);
        assert_eq!(rate("x"), None);
        assert!(is_video(Path::new("a/b.MP4")));
        assert!(is_video(Path::new("b.avi")));
        assert!(!is_video(Path::new("frames")));
        assert!(!is_video(Path::new("f.png")));
        assert_eq!(last_line(b"one\ntwo\n\n"), "two");
    }
}
