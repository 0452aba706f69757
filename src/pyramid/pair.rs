//! The frame loop's two frames and their two pyramids, owned once.
//!
//! Tracking from frame `k - 1` to frame `k` needs both pyramids at once; frame `k + 1` then
//! needs frame `k`'s pyramid and a free buffer. [`PyramidPair`] holds two frame buffers and two
//! pyramid buffers and alternates them: the next frame is captured into the free buffer
//! ([`PyramidPair::capture`]), [`PyramidPair::advance`] builds its pyramid and hands out both
//! pyramids (the previous one re-wrapped, never rebuilt), and the previous frame, no longer a
//! template, is lent out mutably ([`PyramidPair::previous_mut`]) for an overlay. No frame is
//! copied.
//!
//! Storage is the caller's choice (`[u8; N]` in a board's `static`, `Vec<u8>` on a host): any
//! `F, P: AsRef<[u8]> + AsMut<[u8]>`, sized by [`crate::image`]'s `width * height` and
//! [`super::buffer_len`].
//!
//! ```
//! use camgeom::pyramid::{PyramidPair, buffer_len};
//!
//! const W: usize = 64;
//! const H: usize = 48;
//! let mut pair = PyramidPair::new([[0u8; W * H]; 2], [[0u8; buffer_len(W, H, 3)]; 2]);
//! pair.set_geometry(W, H, 3)?;
//! for k in 0..3u8 {
//!     pair.capture()?.fill(k); // a camera writes here
//!     let p = pair.advance()?;
//!     assert_eq!(p.previous.is_some(), k > 0);
//!     let l0 = p.next.level(0).ok_or(camgeom::Error::Degenerate)?;
//!     assert_eq!(l0.get(0, 0), Some(k));
//! }
//! // Frame 1 is free to draw on now that frame 2 has been tracked from it.
//! assert_eq!(pair.previous_mut()?.map(|f| f.as_view().get(0, 0)), Some(Some(1)));
//! # Ok::<(), camgeom::Error>(())
//! ```

use super::{Pyramid, buffer_len};
use crate::image::{ImageMut, ImageView};
use crate::{Error, Result};

/// Two frame buffers (`F`) and two pyramid buffers (`P`) that swap roles each frame: see the
/// module documentation of [`crate::pyramid`].
#[derive(Debug, Clone)]
pub struct PyramidPair<F, P> {
    frames: [F; 2],
    pyramids: [P; 2],
    // The geometry in the smallest types that hold it ([`crate::image::MAX_DIM`],
    // [`super::MAX_LEVELS`]): a board's pipeline static keeps its size to the byte.
    width: u16,
    height: u16,
    levels: u8,
    /// Bit 0: the buffer holding the latest frame; bits 1-2: frames held (0, 1 or 2: the
    /// latest and, with 2, the one before it); bit 3: the last [`PyramidPair::advance`] can
    /// be undone ([`PyramidPair::rewind`]).
    state: u8,
}

/// `PyramidPair::state` of the latest buffer, the frames held and whether the last advance
/// can be undone.
const fn pack(latest: usize, held: usize, undo: bool) -> u8 {
    (latest as u8 & LATEST)
        | ((if held > 2 { 2 } else { held as u8 }) << HELD_SHIFT)
        | if undo { UNDO } else { 0 }
}

/// `PyramidPair::state`'s fields.
const LATEST: u8 = 1;
const HELD_SHIFT: u8 = 1;
const HELD: u8 = 0b110;
const UNDO: u8 = 0b1000;

/// What [`PyramidPair::advance`] hands out: the new frame's pyramid and the previous frame's.
#[derive(Debug, Clone)]
pub struct Pyramids<'a> {
    /// The previous frame's pyramid (`None` on the first frame).
    pub previous: Option<Pyramid<'a>>,
    /// The new frame's pyramid.
    pub next: Pyramid<'a>,
}

impl<F, P> PyramidPair<F, P> {
    /// A pair over `frames` and `pyramids`, holding no frame and no geometry yet
    /// ([`Self::set_geometry`]). `const`: a board's `static` of zeroed arrays stays in `.bss`.
    pub const fn new(frames: [F; 2], pyramids: [P; 2]) -> Self {
        Self {
            frames,
            pyramids,
            width: 0,
            height: 0,
            levels: 0,
            state: 0,
        }
    }

    /// `(width, height, levels)` set by [`Self::set_geometry`] (zeros before).
    pub const fn geometry(&self) -> (usize, usize, usize) {
        (
            self.width as usize,
            self.height as usize,
            self.levels as usize,
        )
    }

    /// Frames held: 0 before the first [`Self::advance`] (and after [`Self::clear`]), then
    /// 1, then 2.
    pub const fn held(&self) -> usize {
        ((self.state & HELD) >> HELD_SHIFT) as usize
    }

    /// The buffer (0 or 1) holding the latest frame.
    const fn latest(&self) -> usize {
        (self.state & LATEST) as usize
    }

    /// The buffer the next frame goes into.
    const fn free(&self) -> usize {
        if self.held() == 0 {
            0
        } else {
            1 - self.latest()
        }
    }

    /// Forgets the frames held: the next [`Self::advance`] is a first frame again.
    pub fn clear(&mut self) {
        self.state = 0;
    }

    /// Undoes the last [`Self::advance`] (the frame it took in is dropped; the frame before is
    /// the latest again, its buffers untouched): for a frame that failed downstream, so that
    /// the next frame is tracked from the last good one. The frame before that one may have
    /// been overwritten by the dropped frame's capture, so no previous frame is lent out until
    /// the next advance. Once only; nothing otherwise.
    pub fn rewind(&mut self) {
        if self.state & UNDO != 0 {
            // One frame held: it was the first, nothing is left. Two: the one before is the
            // latest again.
            match self.held() {
                2 => self.state = pack(1 - self.latest(), 1, false),
                _ => self.state = pack(0, 0, false),
            }
        }
    }
}

impl<F: AsRef<[u8]> + AsMut<[u8]>, P: AsRef<[u8]> + AsMut<[u8]>> PyramidPair<F, P> {
    /// Sets the frame geometry and pyramid level count, and forgets the frames held.
    ///
    /// Errors: [`Error::InvalidParameter`] (`levels`) for a level count outside
    /// `1..=`[`super::MAX_LEVELS`] and ([`Error::InvalidImage`]) for an empty frame;
    /// [`Error::BufferTooSmall`] (`frames`, `pyramids`) when a buffer holds less than
    /// `width * height` or [`buffer_len`] bytes.
    pub fn set_geometry(&mut self, width: usize, height: usize, levels: usize) -> Result<()> {
        if levels == 0 || levels > super::MAX_LEVELS {
            return Err(Error::InvalidParameter("levels"));
        }
        let frame = width.checked_mul(height).ok_or(Error::InvalidImage)?;
        if frame == 0 {
            return Err(Error::InvalidImage);
        }
        if self.frames.iter().any(|f| f.as_ref().len() < frame) {
            return Err(Error::BufferTooSmall("frames"));
        }
        let pyr = buffer_len(width, height, levels);
        if self.pyramids.iter().any(|p| p.as_ref().len() < pyr) {
            return Err(Error::BufferTooSmall("pyramids"));
        }
        let (Ok(w), Ok(h), Ok(l)) = (
            u16::try_from(width),
            u16::try_from(height),
            u8::try_from(levels),
        ) else {
            return Err(Error::InvalidImage);
        };
        (self.width, self.height, self.levels) = (w, h, l);
        self.clear();
        Ok(())
    }

    /// The buffer the next frame goes into: the free one (never the latest frame's). Errors:
    /// as [`ImageMut::packed`] before [`Self::set_geometry`].
    pub fn capture(&mut self) -> Result<ImageMut<'_, u8>> {
        let free = self.free();
        let (w, h, _) = self.geometry();
        let buf = self
            .frames
            .get_mut(free)
            .ok_or(Error::InvalidImage)?
            .as_mut();
        ImageMut::packed(buf.get_mut(..w * h).ok_or(Error::InvalidImage)?, w, h)
    }

    /// Takes the frame written through [`Self::capture`] as the latest: builds its pyramid into
    /// the free pyramid buffer and returns it with the previous frame's (re-wrapped from its
    /// buffer). Errors: as [`Pyramid::build`] (before [`Self::set_geometry`]).
    ///
    /// Never inlined, for the same reason as [`Pyramid::build`]: what it needs on the stack
    /// is not held under the later stages of the caller's frame.
    #[inline(never)]
    pub fn advance(&mut self) -> Result<Pyramids<'_>> {
        let next_index = self.free();
        let held = self.held();
        let (w, h, levels) = self.geometry();
        let [f0, f1] = &self.frames;
        let [p0, p1] = &mut self.pyramids;
        let (next_frame, prev_frame, next_pyr, prev_pyr) = if next_index == 0 {
            (f0, f1, p0, p1)
        } else {
            (f1, f0, p1, p0)
        };
        let prev_pyr: &P = prev_pyr;
        let next = Pyramid::build(view(next_frame, w, h)?, next_pyr.as_mut(), levels)?;
        let previous = if held > 0 {
            Some(Pyramid::from_buffer(
                view(prev_frame, w, h)?,
                prev_pyr.as_ref(),
                levels,
            )?)
        } else {
            None
        };
        self.state = pack(next_index, held + 1, true);
        Ok(Pyramids { previous, next })
    }

    /// The frame before the latest, writable (it is no template any more once the latest
    /// frame has been tracked from it): `None` with fewer than two frames held.
    pub fn previous_mut(&mut self) -> Result<Option<ImageMut<'_, u8>>> {
        if self.held() < 2 {
            return Ok(None);
        }
        self.frame_mut(1 - self.latest()).map(Some)
    }

    /// The latest frame, writable (for a last overlay: the next [`Self::advance`] then tracks
    /// from what was drawn): `None` before the first frame.
    pub fn latest_mut(&mut self) -> Result<Option<ImageMut<'_, u8>>> {
        if self.held() == 0 {
            return Ok(None);
        }
        self.frame_mut(self.latest()).map(Some)
    }

    fn frame_mut(&mut self, i: usize) -> Result<ImageMut<'_, u8>> {
        let (w, h, _) = self.geometry();
        let buf = self.frames.get_mut(i).ok_or(Error::InvalidImage)?.as_mut();
        ImageMut::packed(buf.get_mut(..w * h).ok_or(Error::InvalidImage)?, w, h)
    }
}

/// The first `w * h` bytes of `f` as a packed image.
fn view<F: AsRef<[u8]>>(f: &F, w: usize, h: usize) -> Result<ImageView<'_, u8>> {
    ImageView::packed(f.as_ref().get(..w * h).ok_or(Error::InvalidImage)?, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 20;
    const H: usize = 10;
    type Pair = PyramidPair<[u8; W * H], [u8; buffer_len(W, H, 2)]>;

    fn pair() -> Pair {
        let mut p = Pair::new([[0; W * H]; 2], [[0; buffer_len(W, H, 2)]; 2]);
        p.set_geometry(W, H, 2).unwrap();
        p
    }

    fn base(p: &Pyramid<'_>) -> u8 {
        p.level(0).unwrap().get(3, 3).unwrap()
    }

    /// The previous pyramid is the one built a frame earlier, bit for bit, and the frame
    /// before the latest is the one lent for drawing.
    #[test]
    fn frames_alternate_and_the_previous_pyramid_is_kept() {
        let mut p = pair();
        let mut kept: Option<std::vec::Vec<u8>> = None;
        for k in 1..=5u8 {
            p.capture().unwrap().fill(k * 10);
            let ps = p.advance().unwrap();
            assert_eq!(base(&ps.next), k * 10);
            match (&ps.previous, &kept) {
                (Some(prev), Some(level1)) => {
                    assert_eq!(base(prev), (k - 1) * 10);
                    let l = prev.level(1).unwrap();
                    let now: std::vec::Vec<u8> = l.rows().flatten().copied().collect();
                    assert_eq!(&now, level1);
                }
                (None, None) => assert_eq!(k, 1),
                _ => panic!("frame {k}: previous pyramid {:?}", ps.previous.is_some()),
            }
            kept = Some(
                ps.next
                    .level(1)
                    .unwrap()
                    .rows()
                    .flatten()
                    .copied()
                    .collect(),
            );
            drop(ps);
            let prev = p.previous_mut().unwrap().map(|f| f.as_view().get(0, 0));
            assert_eq!(prev, (k > 1).then_some(Some((k - 1) * 10)));
            assert_eq!(
                p.latest_mut().unwrap().unwrap().as_view().get(0, 0),
                Some(k * 10)
            );
        }
    }

    /// A rewound frame is dropped: the next one is tracked from the frame before it.
    #[test]
    fn rewind_drops_the_last_frame() {
        let mut p = pair();
        p.capture().unwrap().fill(1);
        p.advance().unwrap();
        p.capture().unwrap().fill(2);
        p.advance().unwrap();
        p.rewind();
        p.rewind(); // once only
        assert_eq!(p.held(), 1);
        p.capture().unwrap().fill(3);
        let ps = p.advance().unwrap();
        assert_eq!(base(ps.previous.as_ref().unwrap()), 1);
        assert_eq!(base(&ps.next), 3);
        // A rewound first frame leaves nothing held.
        let mut q = pair();
        q.capture().unwrap().fill(7);
        q.advance().unwrap();
        q.rewind();
        assert_eq!(q.held(), 0);
        assert!(q.advance().unwrap().previous.is_none());
    }

    #[test]
    fn geometry_the_buffers_cannot_hold_is_an_error() {
        let mut p = pair();
        assert_eq!(
            p.set_geometry(W + 1, H, 2),
            Err(Error::BufferTooSmall("frames"))
        );
        assert_eq!(
            p.set_geometry(W, H, 3),
            Err(Error::BufferTooSmall("pyramids"))
        );
        assert_eq!(
            p.set_geometry(W, H, 0),
            Err(Error::InvalidParameter("levels"))
        );
        assert_eq!(p.set_geometry(0, H, 1), Err(Error::InvalidImage));
        // Nothing set yet: an error, not a panic.
        let mut fresh = Pair::new([[0; W * H]; 2], [[0; buffer_len(W, H, 2)]; 2]);
        assert!(fresh.capture().is_err());
        assert!(fresh.advance().is_err());
        assert!(matches!(fresh.previous_mut(), Ok(None)));
    }
}
