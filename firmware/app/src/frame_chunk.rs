//! A frame's pixels on the record stream, in chunks: what a board in mode
//! [`crate::command::Mode::StreamFrames`] sends before each frame's
//! [`crate::report::FrameRecord`], so that the host can show the frame with the overlay the
//! record describes.
//!
//! A frame of `width x height` 8-bit pixels, row-major without padding, is cut into chunks of
//! [`CHUNK_PIXELS`] pixels (the last one shorter); chunk `k` holds pixels
//! `k·CHUNK_PIXELS ..`. Each chunk is one record, one [`crate::link`] frame: a damaged chunk
//! costs its frame's picture, never another frame's. A chunk record is exactly as long as a
//! frame record ([`CHUNK_LEN`] = [`RECORD_LEN`]), so every receiver sized for the frame
//! records takes it.
//!
//! # `"CPIX"`, version 1, [`CHUNK_LEN`] bytes
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag `"CPIX"`, version (see [`crate::wire`]) |
//! | 8..12 | `u32` the frame's index (its frame record's) |
//! | 12..16 | `u16` width, `u16` height (pixels) |
//! | 16..20 | `u32` offset: the chunk's first pixel, a multiple of [`CHUNK_PIXELS`] |
//! | 20..24 | `u16` pixels in the chunk, `u16` 0 |
//! | 24.. | the pixels, zeros after them |

use camgeom::image::ImageView;

use crate::report::RECORD_LEN;
use crate::wire::{Reader, WireError, Writer, tag};

/// The chunk record's tag.
pub const CHUNK_TAG: u32 = tag(b"CPIX");
/// Its layout version.
pub const VERSION: u32 = 1;
/// Bytes of a chunk record: those of a frame record.
pub const CHUNK_LEN: usize = RECORD_LEN;
/// Bytes before the pixels.
const HEADER_LEN: usize = 24;
/// Pixels a chunk holds at most (128 with today's frame record).
pub const CHUNK_PIXELS: usize = CHUNK_LEN - HEADER_LEN;

/// One chunk of a frame's pixels, checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameChunk {
    /// The frame's index.
    pub index: u32,
    /// The frame's width.
    pub width: u16,
    /// The frame's height.
    pub height: u16,
    /// The chunk's first pixel in the frame (row-major).
    pub offset: u32,
    len: u16,
    pixels: [u8; CHUNK_PIXELS],
}

impl FrameChunk {
    /// Pixels of the frame.
    pub fn frame_len(&self) -> usize {
        usize::from(self.width) * usize::from(self.height)
    }

    /// Chunks of the frame.
    pub fn count(&self) -> usize {
        self.frame_len().div_ceil(CHUNK_PIXELS)
    }

    /// Which chunk of its frame this is.
    pub fn number(&self) -> usize {
        self.offset as usize / CHUNK_PIXELS
    }

    /// Its pixels.
    pub fn pixels(&self) -> &[u8] {
        self.pixels.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// The [`CHUNK_LEN`] bytes.
    pub fn encode(&self) -> [u8; CHUNK_LEN] {
        Writer::fill(CHUNK_TAG, VERSION, |w| {
            w.u32(self.index);
            w.u16(self.width);
            w.u16(self.height);
            w.u32(self.offset);
            w.u16(self.len);
            w.u16(0);
            w.bytes(self.pixels());
        })
    }

    /// Decodes and checks a chunk. Errors: [`WireError`] for the length, tag or version;
    /// `Field` for a `size` of no pixels, an `offset` that is not a chunk's start inside the
    /// frame, or a `count` of pixels other than that chunk's.
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("frame_chunk", bytes, CHUNK_LEN, &[CHUNK_TAG], VERSION)?;
        let index = r.u32();
        let (width, height) = (r.u16(), r.u16());
        let offset = r.u32();
        let len = r.u16();
        let _ = r.u16();
        let mut pixels = r.array::<CHUNK_PIXELS>();
        let total = usize::from(width) * usize::from(height);
        if total == 0 {
            return Err(r.invalid("size"));
        }
        let start = offset as usize;
        if !start.is_multiple_of(CHUNK_PIXELS) || start >= total {
            return Err(r.invalid("offset"));
        }
        if usize::from(len) != (total - start).min(CHUNK_PIXELS) {
            return Err(r.invalid("count"));
        }
        // Bytes after the pixels are not the chunk's (a chunk is equal to its bytes' decoding).
        if let Some(rest) = pixels.get_mut(usize::from(len)..) {
            rest.fill(0);
        }
        Ok(Self {
            index,
            width,
            height,
            offset,
            len,
            pixels,
        })
    }
}

/// Cuts frame `index`, `img`, into its chunks and hands each record to `send`, in order;
/// returns how many. Errors: [`WireError::Field`] `size` for a frame without pixels or wider
/// or taller than 65535.
pub fn send_frame(
    index: u32,
    img: &ImageView<'_, u8>,
    mut send: impl FnMut(&[u8; CHUNK_LEN]),
) -> Result<u32, WireError> {
    let size = WireError::Field {
        record: "frame_chunk",
        field: "size",
    };
    let w = img.width();
    let width = u16::try_from(w).map_err(|_| size)?;
    let height = u16::try_from(img.height()).map_err(|_| size)?;
    if width == 0 || height == 0 {
        return Err(size);
    }
    let mut chunk = FrameChunk {
        index,
        width,
        height,
        offset: 0,
        len: 0,
        pixels: [0; CHUNK_PIXELS],
    };
    let mut sent = 0u32;
    let mut flush = |c: &mut FrameChunk| {
        send(&c.encode());
        c.offset = c.offset.saturating_add(u32::from(c.len));
        c.len = 0;
        sent = sent.saturating_add(1);
    };
    for row in img.rows() {
        let mut row = row.get(..w).unwrap_or(row);
        while !row.is_empty() {
            let fill = usize::from(chunk.len);
            let take = (CHUNK_PIXELS - fill).min(row.len());
            let (head, rest) = row.split_at(take);
            if let Some(d) = chunk.pixels.get_mut(fill..fill + take) {
                d.copy_from_slice(head);
            }
            // `fill + take` is at most CHUNK_PIXELS.
            chunk.len = u16::try_from(fill + take).unwrap_or(u16::MAX);
            row = rest;
            if usize::from(chunk.len) == CHUNK_PIXELS {
                flush(&mut chunk);
            }
        }
    }
    if chunk.len > 0 {
        flush(&mut chunk);
    }
    Ok(sent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn frame(w: usize, h: usize) -> Vec<u8> {
        (0..w * h).map(|k| (k * 31 % 251) as u8).collect()
    }

    #[test]
    fn a_frame_goes_out_in_chunks_that_put_it_back_together() {
        // 13 x 21 = 273 pixels: two full chunks and a short one, rows across chunk ends.
        for (w, h) in [(13, 21), (320, 240), (1, 1)] {
            let px = frame(w, h);
            let img = ImageView::packed(&px, w, h).unwrap();
            let mut back = std::vec![0u8; w * h];
            let mut seen = Vec::new();
            let n = send_frame(7, &img, |rec| {
                let c = FrameChunk::decode(rec).unwrap();
                assert_eq!((c.index, c.width, c.height), (7, w as u16, h as u16));
                back[c.offset as usize..][..c.pixels().len()].copy_from_slice(c.pixels());
                seen.push(c.number());
            })
            .unwrap();
            assert_eq!(n as usize, (w * h).div_ceil(CHUNK_PIXELS));
            assert_eq!(seen, (0..n as usize).collect::<Vec<_>>());
            assert_eq!(back, px);
        }
    }

    #[test]
    fn a_strided_view_sends_only_its_pixels() {
        // A 4 x 3 view of a 6-wide buffer.
        let buf: Vec<u8> = (0..18).collect();
        let img = ImageView::new(&buf, 4, 3, 6).unwrap();
        let mut got = Vec::new();
        send_frame(0, &img, |rec| {
            got.extend_from_slice(FrameChunk::decode(rec).unwrap().pixels())
        })
        .unwrap();
        assert_eq!(got, [0, 1, 2, 3, 6, 7, 8, 9, 12, 13, 14, 15]);
    }

    #[test]
    fn chunks_that_are_not_a_frame_s_are_errors() {
        let px = frame(20, 10);
        let img = ImageView::packed(&px, 20, 10).unwrap();
        let mut recs = Vec::new();
        send_frame(1, &img, |r| recs.push(*r)).unwrap();
        let field = |f| {
            Err(WireError::Field {
                record: "frame_chunk",
                field: f,
            })
        };
        let with = |k: usize, at: usize, v: &[u8]| {
            let mut b = recs[k];
            b[at..at + v.len()].copy_from_slice(v);
            FrameChunk::decode(&b)
        };
        assert_eq!(with(0, 12, &[0, 0]), field("size"));
        assert_eq!(with(0, 16, &5u32.to_le_bytes()), field("offset"));
        assert_eq!(with(0, 16, &256u32.to_le_bytes()), field("offset"));
        // The last chunk holds 200 - 128 = 72 pixels, no other count.
        assert_eq!(with(1, 20, &128u16.to_le_bytes()), field("count"));
        assert_eq!(with(0, 20, &0u16.to_le_bytes()), field("count"));
        assert!(matches!(
            FrameChunk::decode(&recs[0][..100]),
            Err(WireError::Length { .. })
        ));
        assert!(matches!(
            FrameChunk::decode(&crate::report::SummaryRecord::default().encode()),
            Err(WireError::Tag { .. })
        ));
        if let Ok(e) = ImageView::packed(&[], 0, 0) {
            assert_eq!(
                send_frame(0, &e, |_| {}),
                Err(WireError::Field {
                    record: "frame_chunk",
                    field: "size"
                })
            );
        }
    }
}
