//! Where frames come from.

use camgeom::image::ImageMut;

/// Anything that delivers grayscale `u8` frames of one fixed size: a camera driver, or a
/// recorded sequence (the emulator's "virtual camera").
///
/// The caller owns the frame buffer; a source writes into it and never keeps a reference,
/// so the application decides where frames live (a static, a DMA-capable region, ...).
pub trait FrameSource {
    /// What can go wrong while reading a frame (a bus error, a missing file, ...).
    type Error: core::fmt::Debug;

    /// The `(width, height)` of every frame this source delivers.
    fn size(&self) -> (usize, usize);

    /// Writes the next frame into `frame`, whose width and height must equal
    /// [`Self::size`]. Returns `Ok(false)`, leaving `frame` untouched, once a finite
    /// sequence has ended; a live camera never ends.
    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, Self::Error>;
}
