//! Folders of frames (`track`, `ar`, `apriltag --frames`) and the progress bar of the
//! subcommands that go through many files (`track`, `ar`, `calibrate`).

use std::path::{Path, PathBuf};

use crate::error::{Error, ErrorKind, Result};
use crate::images::{GrayImage, load_gray};

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

/// Loads `files` as grey frames of one size, advancing `bar` by one per frame.
pub fn load_frames(files: &[PathBuf], bar: &indicatif::ProgressBar) -> Result<Vec<GrayImage>> {
    bar.set_message("loading");
    let mut frames: Vec<GrayImage> = Vec::with_capacity(files.len());
    for f in files {
        let img = load_gray(f)?;
        if let Some(first) = frames.first()
            && (first.width, first.height) != (img.width, img.height)
        {
            return Err(Error::new(
                f,
                ErrorKind::Shape("frame size differs from the first frame".into()),
            ));
        }
        frames.push(img);
        bar.inc(1);
    }
    Ok(frames)
}
