//! The main job's 320x240 pipeline as one concrete, non-generic function.
//!
//! A generic pipeline is only compiled where it is instantiated; [`step_qvga`] instantiates
//! it, so building this crate for a target (CI does for `thumbv6m-none-eabi`, RP2040 class
//! with no FPU, and `thumbv8m.main-none-eabihf`, RP2350 class) compiles and optimises the whole
//! per-frame path for that target.

use camgeom::image::{ImageMut, ImageView};
use camgeom::target::Acquire;

use crate::pipeline::{AppConfig, AppError, FrameLoop, FrameReport, NoClock};
use crate::source::FrameSource;

pub use crate::sizes::Qvga;

/// Frames read one after the other from a slice of packed `width x height` frames.
#[derive(Debug, Clone)]
pub struct SliceSource<'a> {
    frames: &'a [u8],
    width: usize,
    height: usize,
    next: usize,
}

impl<'a> SliceSource<'a> {
    /// Frames `frames` (packed, `width * height` bytes each; a partial frame at the end is
    /// ignored).
    pub fn new(frames: &'a [u8], width: usize, height: usize) -> Self {
        Self {
            frames,
            width,
            height,
            next: 0,
        }
    }
}

/// A [`SliceSource`] frame did not fit the caller's frame buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameMismatch;

impl FrameSource for SliceSource<'_> {
    type Error = FrameMismatch;

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, FrameMismatch> {
        let len = self.width * self.height;
        let Some(src) = self.frames.get(self.next * len..(self.next + 1) * len) else {
            return Ok(false);
        };
        for (y, row) in src.chunks_exact(self.width.max(1)).enumerate() {
            let dst = frame.row_mut(y).ok_or(FrameMismatch)?;
            dst.get_mut(..self.width)
                .ok_or(FrameMismatch)?
                .copy_from_slice(row);
        }
        self.next += 1;
        Ok(true)
    }
}

/// One frame of the 320x240 pipeline from `source`, no clock, overlays passed to `overlay`.
#[inline(never)]
pub fn step_qvga(
    pipeline: &mut Qvga,
    cfg: &AppConfig,
    source: &mut SliceSource<'_>,
    acquire: &mut dyn Acquire,
    overlay: &mut dyn FnMut(u32, &ImageView<'_, u8>),
) -> Result<Option<FrameReport>, AppError<FrameMismatch>> {
    pipeline.step(cfg, source, acquire, &mut NoClock, &mut |i, img| {
        overlay(i, img)
    })
}
