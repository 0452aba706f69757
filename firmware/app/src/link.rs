//! The board's record stream: [`crate::wire`] records framed for a byte link (a UART, USB
//! CDC-ACM, a socket), so that a receiver that starts late or loses bytes finds the next
//! record and says what it lost.
//!
//! A frame on the link is
//!
//! ```text
//! COBS( seq: u16 LE | record (a wire record: tag, version, fields) | CRC-32 LE ) 0x00
//! ```
//!
//! COBS (consistent overhead byte stuffing, the `cobs` crate) removes every zero byte from the
//! body at a cost of one byte in 254, so the single `0x00` after it marks the end of a frame
//! unambiguously; the CRC-32 (ISO-HDLC, the `crc` crate: Ethernet's and zlib's) over
//! `seq | record` rejects a damaged frame; `seq` counts frames modulo 2¹⁶, so the receiver
//! counts the frames lost between two good ones and drops a repeated one.
//!
//! The receiver ([`Deframer`]) holds at most `N` encoded bytes. It resynchronises at the next
//! `0x00` after anything (flipped, dropped or duplicated bytes, a frame longer than `N`, a
//! start in the middle of a frame), counts what it discarded ([`LinkStats`]), and never
//! waits for more than the next delimiter: a damaged frame costs that frame only.

use crc::{CRC_32_ISO_HDLC, Crc};

/// The frames' CRC: CRC-32/ISO-HDLC.
const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// Bytes a frame adds around its record before stuffing: the sequence number and the CRC.
pub const FRAME_OVERHEAD: usize = 2 + 4;

/// Bytes on the link, at most, of a frame carrying a record of `record` bytes: the stuffed
/// body ([`FRAME_OVERHEAD`] more bytes, plus one in 254, plus one) and the delimiter.
pub const fn max_frame_len(record: usize) -> usize {
    cobs::max_encoding_length(record + FRAME_OVERHEAD) + 1
}

/// Why a frame could not be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LinkError {
    /// The output buffer is shorter than [`max_frame_len`] of the record.
    BufferTooSmall,
}

/// Frames `record` as the `seq`-th frame into `out`; returns the bytes to send (the delimiter
/// included). `out` of [`max_frame_len`]`(record.len())` bytes always suffices.
pub fn encode_frame(seq: u16, record: &[u8], out: &mut [u8]) -> Result<usize, LinkError> {
    // The body leaves room for the delimiter.
    let body_len = out.len().checked_sub(1).ok_or(LinkError::BufferTooSmall)?;
    let mut digest = CRC.digest();
    digest.update(&seq.to_le_bytes());
    digest.update(record);
    let crc = digest.finalize().to_le_bytes();
    let mut enc = cobs::CobsEncoder::new(out.get_mut(..body_len).unwrap_or(&mut []));
    for part in [&seq.to_le_bytes()[..], record, &crc[..]] {
        enc.push(part).map_err(|_| LinkError::BufferTooSmall)?;
    }
    let n = enc.finalize();
    // The delimiter: `n` is within `body`, one shorter than `out`.
    let end = out.get_mut(n).ok_or(LinkError::BufferTooSmall)?;
    *end = 0;
    Ok(n + 1)
}

/// What a [`Deframer`] has seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStats {
    /// Frames delivered.
    pub frames: u32,
    /// Frames rejected: a stuffing error, a CRC mismatch, too short, or longer than the
    /// receiver's buffer.
    pub damaged: u32,
    /// Frames the sequence numbers say never arrived whole (damaged ones included), between
    /// two delivered frames.
    pub lost: u32,
    /// Frames dropped as repeats of the one before (the same sequence number).
    pub repeated: u32,
    /// Bytes discarded with the damaged frames.
    pub bytes_discarded: u32,
}

/// A frame delivered by [`Deframer::push`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Its sequence number.
    pub seq: u16,
    /// The record it carries (a [`crate::wire`] record).
    pub record: &'a [u8],
}

/// The receiving end of the stream: feed it bytes as they come, take frames out. Holds at
/// most `N` encoded bytes of one frame (the longest record it accepts is about `N` −
/// [`FRAME_OVERHEAD`] − `N / 254` − 2 bytes; [`max_frame_len`] of the longest record is enough).
#[derive(Debug)]
pub struct Deframer<const N: usize> {
    /// The current frame, unstuffed as its bytes arrive.
    buf: [u8; N],
    /// Its decoded bytes (beyond `N` when it outgrew the buffer).
    len: usize,
    /// Its bytes on the link (for [`LinkStats::bytes_discarded`]).
    raw: usize,
    /// The stuffing's state (the `cobs` crate's byte-at-a-time decoder).
    cobs: cobs::DecoderState,
    /// At least one delimiter was seen (bytes before the first may be a partial frame).
    synced: bool,
    last_seq: Option<u16>,
    stats: LinkStats,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    /// An empty receiver.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            raw: 0,
            cobs: cobs::DecoderState::Idle,
            synced: false,
            last_seq: None,
            stats: LinkStats {
                frames: 0,
                damaged: 0,
                lost: 0,
                repeated: 0,
                bytes_discarded: 0,
            },
        }
    }

    /// What it has seen so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Takes bytes from the front of `input` up to and including the end of the next good
    /// frame, and returns that frame; `None` once `input` is used up (a partial frame is kept
    /// for the next call). The bytes before the first delimiter ever seen are a whole frame
    /// when the stream was read from its start, else the tail of one begun before the receiver
    /// listened: delivered if they check, discarded without counting a damaged frame if not.
    pub fn push<'s>(&'s mut self, input: &mut &[u8]) -> Option<Frame<'s>> {
        use cobs::DecodeResult;
        while let Some((&b, rest)) = input.split_first() {
            *input = rest;
            if b != 0 {
                self.raw = self.raw.saturating_add(1);
            }
            // The decoder ends a frame only at a delimiter: complete, or (an error) cut short.
            let complete = match self.cobs.feed(b) {
                Ok(DecodeResult::DataContinue(x)) => {
                    if let Some(slot) = self.buf.get_mut(self.len) {
                        *slot = x;
                    }
                    self.len = self.len.saturating_add(1);
                    continue;
                }
                Ok(DecodeResult::DataStart | DecodeResult::NoData) => {
                    if b == 0 {
                        // A delimiter between frames.
                        self.synced = true;
                    }
                    continue;
                }
                Ok(DecodeResult::DataComplete) => true,
                Err(_) => false,
            };
            let (len, raw, synced) = (self.len, self.raw, self.synced);
            self.len = 0;
            self.raw = 0;
            self.synced = true;
            if let Some((seq, n)) = self.check(len, complete, synced, raw) {
                return Some(Frame {
                    seq,
                    record: self.buf.get(2..n).unwrap_or(&[]),
                });
            }
        }
        None
    }

    /// Checks the frame of `len` decoded bytes (`raw` on the link) that just ended, `complete`
    /// if its stuffing was whole: its sequence number and the end of its record, or `None`
    /// (counted) for a damaged or repeated frame. Before the first delimiter (`synced` false)
    /// a frame that does not check is the tail of one sent before the receiver listened: its
    /// bytes are discarded without counting a damaged frame.
    fn check(
        &mut self,
        len: usize,
        complete: bool,
        synced: bool,
        raw: usize,
    ) -> Option<(u16, usize)> {
        let body = if complete { self.buf.get(..len) } else { None };
        let end = body.filter(|b| b.len() >= FRAME_OVERHEAD).and_then(|b| {
            let (data, crc) = b.split_at_checked(b.len() - 4)?;
            let crc = u32::from_le_bytes(crc.try_into().ok()?);
            (CRC.checksum(data) == crc).then_some(data.len())
        });
        let Some(end) = end else {
            if synced {
                self.stats.damaged = self.stats.damaged.saturating_add(1);
            }
            self.stats.bytes_discarded = self
                .stats
                .bytes_discarded
                .saturating_add(u32::try_from(raw).unwrap_or(u32::MAX));
            return None;
        };
        let seq = u16::from_le_bytes([
            self.buf.first().copied().unwrap_or(0),
            self.buf.get(1).copied().unwrap_or(0),
        ]);
        if let Some(last) = self.last_seq {
            let gap = seq.wrapping_sub(last.wrapping_add(1));
            if gap == u16::MAX {
                self.stats.repeated = self.stats.repeated.saturating_add(1);
                return None;
            }
            // A jump backwards by less than half the range is a restart of the sender, not
            // 60000 lost frames.
            if gap < 0x8000 {
                self.stats.lost = self.stats.lost.saturating_add(u32::from(gap));
            }
        }
        self.last_seq = Some(seq);
        self.stats.frames = self.stats.frames.saturating_add(1);
        Some((seq, end))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A stream of `n` frames of records of varied lengths and contents (zeros included).
    fn stream(n: u16) -> (Vec<Vec<u8>>, Vec<u8>) {
        let mut records = Vec::new();
        let mut bytes = Vec::new();
        for seq in 0..n {
            let len = 1 + usize::from(seq) * 37 % 300;
            let rec: Vec<u8> = (0..len)
                .map(|k| (k * 7 + usize::from(seq)) as u8 % 5)
                .collect();
            let mut out = [0u8; max_frame_len(300)];
            let m = encode_frame(seq, &rec, &mut out).unwrap();
            assert_eq!(out[..m].iter().filter(|&&b| b == 0).count(), 1);
            bytes.extend_from_slice(&out[..m]);
            records.push(rec);
        }
        (records, bytes)
    }

    fn receive<const N: usize>(d: &mut Deframer<N>, bytes: &[u8]) -> Vec<(u16, Vec<u8>)> {
        let mut input = bytes;
        let mut got = Vec::new();
        while let Some(f) = d.push(&mut input) {
            got.push((f.seq, f.record.to_vec()));
        }
        got
    }

    #[test]
    fn a_clean_stream_decodes_whole_in_any_chunking() {
        let (records, bytes) = stream(40);
        for chunk in [1, 3, 64, bytes.len()] {
            let mut d = Deframer::<{ max_frame_len(300) }>::new();
            let mut got = Vec::new();
            for c in bytes.chunks(chunk) {
                got.extend(receive(&mut d, c));
            }
            assert_eq!(got.len(), 40, "chunk {chunk}");
            for (k, (seq, rec)) in got.iter().enumerate() {
                assert_eq!((usize::from(*seq), rec), (k, &records[k]));
            }
            assert_eq!(
                d.stats(),
                LinkStats {
                    frames: 40,
                    ..LinkStats::default()
                }
            );
        }
    }

    #[test]
    fn damage_costs_only_the_frames_it_touches() {
        let (records, bytes) = stream(30);
        let mut rng = camgeom::rng::Pcg32::new(7);
        for trial in 0..200 {
            let mut b = bytes.clone();
            let at = rng.below(b.len() as u32) as usize;
            match trial % 3 {
                0 => b[at] ^= 1 << rng.below(8),
                1 => {
                    b.remove(at);
                }
                _ => {
                    let v = b[at];
                    b.insert(at, v);
                }
            }
            let mut d = Deframer::<{ max_frame_len(300) }>::new();
            let mut got = receive(&mut d, &[0]);
            got.extend(receive(&mut d, &b));
            let s = d.stats();
            // One or two frames touched (a delimiter hit joins or splits two), never a wrong
            // record delivered.
            assert!(got.len() >= 28 && got.len() <= 30, "{trial}: {}", got.len());
            for (seq, rec) in &got {
                assert_eq!(rec, &records[usize::from(*seq)], "{trial}");
            }
            assert_eq!(s.frames as usize, got.len());
            // Lost: between delivered frames; the rest went before the first or after the last.
            let before = got.first().map_or(0, |g| u32::from(g.0));
            let after = got.last().map_or(0, |g| 29 - u32::from(g.0));
            assert_eq!(s.lost + before + after, 30 - s.frames, "{trial}: {s:?}");
        }
    }

    #[test]
    fn repeats_late_starts_and_oversize_frames_are_counted_not_delivered() {
        let (_, bytes) = stream(5);
        let ends: Vec<usize> = bytes
            .iter()
            .enumerate()
            .filter(|(_, b)| **b == 0)
            .map(|(i, _)| i + 1)
            .collect();
        // Frame 2 sent twice; the receiver starts in the middle of frame 0.
        let mut b = bytes[3..ends[2]].to_vec();
        b.extend_from_slice(&bytes[ends[1]..]);
        let mut d = Deframer::<{ max_frame_len(300) }>::new();
        let seqs: Vec<u16> = receive(&mut d, &b).iter().map(|g| g.0).collect();
        assert_eq!(seqs, [1, 2, 3, 4]);
        let s = d.stats();
        assert_eq!((s.frames, s.repeated, s.damaged, s.lost), (4, 1, 0, 0));
        assert_eq!(s.bytes_discarded as usize, ends[0] - 3 - 1);
        // A receiver too small for frame 3 (the longest) drops it and keeps the others.
        let mut small = Deframer::<64>::new();
        let got: Vec<u16> = receive(&mut small, &[0]).into_iter().map(|g| g.0).collect();
        assert!(got.is_empty());
        let got: Vec<u16> = receive(&mut small, &bytes).iter().map(|g| g.0).collect();
        assert_eq!(got, [0, 1]);
        assert_eq!(small.stats().damaged, 3);
        // Garbage without a delimiter never delivers and never stalls the next frame.
        let mut d = Deframer::<{ max_frame_len(300) }>::new();
        let mut noise: Vec<u8> = (0..5000u32).map(|k| (k * 13 % 255 + 1) as u8).collect();
        noise.push(0);
        noise.extend_from_slice(&bytes[..ends[0]]);
        let got = receive(&mut d, &noise);
        assert_eq!(got.len(), 1);
    }

    #[test]
    fn a_short_buffer_is_an_error() {
        let mut out = [0u8; 8];
        assert_eq!(
            encode_frame(0, &[1; 10], &mut out),
            Err(LinkError::BufferTooSmall)
        );
        assert_eq!(
            encode_frame(0, &[], &mut []),
            Err(LinkError::BufferTooSmall)
        );
    }
}
