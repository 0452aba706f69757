//! Sequences of frames (`track`, `ar`, `apriltag --frames`, `warp --frames`): a folder of
//! PNG/JPEG files or a video file, read one frame at a time ([`FrameSource`]); and the
//! progress bar of the subcommands that go through many files (`track`, `ar`, `calibrate`).

use std::path::{Path, PathBuf};

use crate::error::{Error, ErrorKind, Result};
use crate::images::{GrayImage, gray_of_rgb, load_gray, load_gray_and_rgb};
use crate::rgb::RgbImage;
use crate::video::{VideoReader, is_video};

/// One frame of a [`FrameSource`].
#[derive(Debug, Clone)]
pub struct Frame {
    /// 0-based index in the sequence.
    pub index: usize,
    /// The name of its outputs: the file's stem (`0007` for `0007.png`), or for a video the
    /// index on six digits (`000007`).
    pub name: String,
    /// The frame's file (folders only).
    pub file: Option<PathBuf>,
    /// Presentation time in seconds (videos only).
    pub t: Option<f64>,
    /// The frame in grey (what the detectors and trackers see).
    pub gray: GrayImage,
    /// The frame in colour, when [`FrameSource::open`] was asked for colour and the input is
    /// in colour (the overlays are drawn on it).
    pub rgb: Option<RgbImage>,
}

/// Where the frames come from.
#[derive(Debug)]
enum Source {
    /// The files of a folder and the index of the next one.
    Files(Vec<PathBuf>, usize),
    /// A video being decoded.
    Video(Box<VideoReader>),
}

/// The frames of a folder of PNG/JPEG files ([`frame_files`], file-name order) or of a video
/// file ([`crate::video`], decoded by ffmpeg), one at a time: never more than one frame is in
/// memory. Every frame must have the first one's size (unless [`FrameSource::any_size`]).
#[derive(Debug)]
pub struct FrameSource {
    path: PathBuf,
    source: Source,
    colour: bool,
    len: usize,
    fps: Option<f64>,
    size: Option<(usize, usize)>,
    any_size: bool,
}

impl FrameSource {
    /// The frames of `path`: a folder, or a video file (by its extension,
    /// [`crate::video::VIDEO_EXTENSIONS`]). With `colour`, each [`Frame`] carries its colour
    /// pixels too when the input is in colour.
    ///
    /// Errors: a folder without frames ([`frame_files`]); a file that is not a video;
    /// [`crate::video::probe`]'s errors (no ffmpeg, an unreadable video).
    pub fn open(path: &Path, colour: bool) -> Result<Self> {
        let (source, len, fps) = if path.is_dir() {
            let files = frame_files(path)?;
            let n = files.len();
            (Source::Files(files, 0), n, None)
        } else if is_video(path) {
            let reader = VideoReader::open(path)?;
            let (n, fps) = (reader.info().times.len(), reader.info().fps);
            let colour = colour && !reader.info().is_gray();
            return Ok(Self {
                path: path.to_path_buf(),
                source: Source::Video(Box::new(reader)),
                colour,
                len: n,
                fps,
                size: None,
                any_size: false,
            });
        } else if path.exists() {
            return Err(Error::new(
                path,
                ErrorKind::Unsupported(format!(
                    "frames are a folder of PNG/JPEG files or a video ({})",
                    crate::video::VIDEO_EXTENSIONS.join(", ")
                )),
            ));
        } else {
            return Err(Error::new(
                path,
                ErrorKind::Io(std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no such folder or video file",
                )),
            ));
        };
        Ok(Self {
            path: path.to_path_buf(),
            source,
            colour,
            len,
            fps,
            size: None,
            any_size: false,
        })
    }

    /// Frames of any size (a folder of photos for a detector): the check that every frame
    /// has the first one's size is off.
    pub fn any_size(mut self) -> Self {
        self.any_size = true;
        self
    }

    /// The folder or video.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Number of frames: the files, or the video stream's frames as ffprobe counts them.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are no frames.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the frames come from a video.
    pub fn is_video(&self) -> bool {
        matches!(self.source, Source::Video(_))
    }

    /// The video's frame rate (`None` for a folder, or a video that gives none).
    pub fn fps(&self) -> Option<f64> {
        self.fps
    }

    /// The next frame, `None` after the last.
    ///
    /// Errors: an unreadable file or video frame; a frame of another size than the first.
    pub fn next_frame(&mut self) -> Result<Option<Frame>> {
        let (frame, at) = match &mut self.source {
            Source::Files(files, next) => {
                let Some(f) = files.get(*next) else {
                    return Ok(None);
                };
                let (gray, rgb) = if self.colour {
                    load_gray_and_rgb(f)?
                } else {
                    (load_gray(f)?, None)
                };
                let name = f
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| next.to_string());
                let frame = Frame {
                    index: *next,
                    name,
                    file: Some(f.clone()),
                    t: None,
                    gray,
                    rgb,
                };
                *next += 1;
                (frame, f.clone())
            }
            Source::Video(reader) => {
                let Some(v) = reader.next_frame()? else {
                    return Ok(None);
                };
                let frame = Frame {
                    index: v.index,
                    name: format!("{:06}", v.index),
                    file: None,
                    t: Some(v.t),
                    gray: gray_of_rgb(&v.rgb),
                    rgb: self.colour.then_some(v.rgb),
                };
                (frame, self.path.clone())
            }
        };
        let size = (frame.gray.width, frame.gray.height);
        match self.size {
            None => self.size = Some(size),
            Some(first) if first != size && !self.any_size => {
                return Err(Error::new(
                    at,
                    ErrorKind::Shape("frame size differs from the first frame".into()),
                ));
            }
            Some(_) => {}
        }
        Ok(Some(frame))
    }
}

impl Iterator for FrameSource {
    type Item = Result<Frame>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

/// The PNG and JPEG files of `dir`, in file-name order.
pub fn frame_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::new(dir, ErrorKind::Io(e)))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::new(
            dir,
            ErrorKind::Shape("no PNG or JPEG frames".into()),
        ));
    }
    Ok(files)
}

/// The progress bar of the sequence subcommands (on stderr; hidden when it is not a terminal).
pub fn progress_bar(len: u64) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>8} [{bar:40}] {pos}/{len} {eta}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}
