//! A recorded sequence as a camera, with faults injected on purpose.
//!
//! [`RecordedFrames`] is random access to the frames of a recording (a host file over
//! semihosting on the emulated board, a byte slice on the host). [`RecordedCamera`] turns it
//! into a [`FrameSource`]: every `stride`-th frame, up to a count, and a [`FaultPlan`] of what
//! goes wrong on which delivered frame, so that the board and its host replay see the same
//! faulty camera and must still agree bit for bit:
//!
//! | [`Fault`] | the frame delivered |
//! |---|---|
//! | `Black`, `White` | all 0 or all 255 (lens covered, sensor saturated); the scene moves on |
//! | `Noise` | saturated noise (each pixel 0 or 255, from a seeded generator) |
//! | `Repeat` | the previous recorded frame again (a camera delivering a stale buffer) |
//! | `Drop` | `n` recorded frames skipped, then the next one (frames lost on the bus) |
//! | `Torn` | the top half of one frame and the bottom half of the next (a DMA race) |
//! | `WrongSize` | none: the source reports a frame of another size, a typed error |
//! | `ReadError` | none: the read itself fails (on the emulated board a real failed host call) |
//!
//! A plan is stored as [`FAULT_PLAN_LEN`] bytes (`faults.bin` beside `run.bin`): magic
//! `"CFLT"`, version, count, then up to [`MAX_FAULTS`] `(first frame, frames, fault, parameter)`
//! `u32` quadruples, little-endian.

use camgeom::Error;
use camgeom::image::ImageMut;
use camgeom::rng::Pcg32;

use crate::source::FrameSource;
use crate::wire::{Reader, WireError, Writer, tag};

/// Random access to the frames of a recording, all `width x height` grayscale.
pub trait RecordedFrames {
    /// What can go wrong while reading.
    type Error: core::fmt::Debug;

    /// `(width, height)` of every frame.
    fn size(&self) -> (usize, usize);

    /// Frames recorded.
    fn len(&self) -> usize;

    /// `true` without frames.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes rows `rows` of recorded frame `index` into the same rows of `frame`.
    fn read_rows(
        &mut self,
        index: usize,
        rows: core::ops::Range<usize>,
        frame: &mut ImageMut<'_, u8>,
    ) -> Result<(), Self::Error>;

    /// Makes a read that fails the way this recording's reads fail (a host call that the host
    /// refuses): what [`Fault::ReadError`] delivers.
    fn failing_read(&mut self) -> Self::Error;
}

/// What goes wrong with one delivered frame (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// All zeros.
    Black,
    /// All 255.
    White,
    /// Each pixel 0 or 255 at random (the parameter seeds the generator).
    Noise,
    /// The previous recorded frame again.
    Repeat,
    /// The parameter's number of recorded frames skipped first.
    Drop,
    /// The top half of one recorded frame, the bottom half of the next.
    Torn,
    /// A frame of another size: an error.
    WrongSize,
    /// A failed read: an error.
    ReadError,
}

impl Fault {
    const ALL: [Fault; 8] = [
        Fault::Black,
        Fault::White,
        Fault::Noise,
        Fault::Repeat,
        Fault::Drop,
        Fault::Torn,
        Fault::WrongSize,
        Fault::ReadError,
    ];

    /// The fault in snake case.
    pub const fn name(self) -> &'static str {
        match self {
            Fault::Black => "black",
            Fault::White => "white",
            Fault::Noise => "noise",
            Fault::Repeat => "repeat",
            Fault::Drop => "drop",
            Fault::Torn => "torn",
            Fault::WrongSize => "wrong_size",
            Fault::ReadError => "read_error",
        }
    }

    const fn code(self) -> u32 {
        self as u32 + 1
    }

    fn from_code(c: u32) -> Option<Self> {
        Self::ALL.get((c as usize).checked_sub(1)?).copied()
    }
}

/// Faults a plan holds at most.
pub const MAX_FAULTS: usize = 16;
/// Bytes of a stored plan.
pub const FAULT_PLAN_LEN: usize = 12 + 16 * MAX_FAULTS;
/// `"CFLT"`.
pub const FAULT_MAGIC: u32 = tag(b"CFLT");
/// Layout version of a stored plan.
pub const FAULT_VERSION: u32 = 1;

/// One entry of a plan: `fault` on the delivered frames `first .. first + frames`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultSpan {
    /// First delivered frame (0-based) the fault hits.
    pub first: u32,
    /// Delivered frames it hits, one after the other.
    pub frames: u32,
    /// What goes wrong.
    pub fault: Fault,
    /// Its parameter: frames dropped for [`Fault::Drop`], the seed for [`Fault::Noise`].
    pub param: u32,
}

/// Which delivered frames go wrong, and how: at most [`MAX_FAULTS`] spans.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultPlan {
    spans: [Option<FaultSpan>; MAX_FAULTS],
}

impl FaultPlan {
    /// No faults.
    pub const fn none() -> Self {
        Self {
            spans: [None; MAX_FAULTS],
        }
    }

    /// The plan of `spans` (those past [`MAX_FAULTS`] are an error). Errors:
    /// [`Error::InvalidParameter`] (`faults`).
    pub fn new(spans: &[FaultSpan]) -> Result<Self, Error> {
        let mut p = Self::none();
        if spans.len() > MAX_FAULTS {
            return Err(Error::InvalidParameter("faults"));
        }
        for (slot, s) in p.spans.iter_mut().zip(spans) {
            *slot = Some(*s);
        }
        Ok(p)
    }

    /// The spans, in order.
    pub fn spans(&self) -> impl Iterator<Item = &FaultSpan> {
        self.spans.iter().flatten()
    }

    /// The fault on delivered frame `k`, if any (the first span that covers it).
    pub fn at(&self, k: u32) -> Option<FaultSpan> {
        self.spans()
            .find(|s| k >= s.first && k - s.first < s.frames)
            .copied()
    }

    /// The [`FAULT_PLAN_LEN`] bytes of the plan: tag and version ([`crate::wire`]), `u32`
    /// count, then `first, frames, fault code, param` of each span (`u32` each), zeros after.
    pub fn to_bytes(&self) -> [u8; FAULT_PLAN_LEN] {
        Writer::fill(FAULT_MAGIC, FAULT_VERSION, |w| {
            w.u32(self.spans().count() as u32);
            for s in self.spans() {
                w.u32s([s.first, s.frames, s.fault.code(), s.param]);
            }
        })
    }

    /// Decodes [`FAULT_PLAN_LEN`] bytes. Errors: [`WireError`] for a wrong length, magic or
    /// version, a count above [`MAX_FAULTS`] or an unknown fault code.
    pub fn parse(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked(
            "fault_plan",
            bytes,
            FAULT_PLAN_LEN,
            &[FAULT_MAGIC],
            FAULT_VERSION,
        )?;
        let n = r.u32() as usize;
        if n > MAX_FAULTS {
            return Err(r.invalid("count"));
        }
        let mut p = Self::none();
        for slot in p.spans.iter_mut().take(n) {
            let [first, frames, code, param] = r.u32s();
            let fault = Fault::from_code(code).ok_or(r.invalid("fault"))?;
            *slot = Some(FaultSpan {
                first,
                frames,
                fault,
                param,
            });
        }
        Ok(p)
    }
}

/// Why a [`RecordedCamera`] delivered no frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraError<E> {
    /// The recording could not be read (a [`Fault::ReadError`], or a real failure).
    Read(E),
    /// The frame is not the size the source promised ([`Fault::WrongSize`]), or the caller's
    /// buffer is not.
    WrongSize,
}

/// A recording as a camera: every `stride`-th recorded frame, at most `count` of them, with the
/// faults of a [`FaultPlan`].
#[derive(Debug)]
pub struct RecordedCamera<R> {
    frames: R,
    plan: FaultPlan,
    stride: usize,
    count: usize,
    /// Frames delivered (or failed) so far.
    delivered: u32,
    /// The next recorded frame.
    next: usize,
}

impl<R: RecordedFrames> RecordedCamera<R> {
    /// The camera over `frames`; `count` is capped to the frames the recording holds at
    /// `stride`.
    pub fn new(frames: R, stride: usize, count: usize, plan: FaultPlan) -> Self {
        let stride = stride.max(1);
        let count = count.min(frames.len().div_ceil(stride));
        Self {
            frames,
            plan,
            stride,
            count,
            delivered: 0,
            next: 0,
        }
    }

    /// Frames this camera delivers in all (faulty ones included).
    pub fn count(&self) -> usize {
        self.count
    }

    /// Frames delivered (or failed) so far: the number of the next one.
    pub fn delivered(&self) -> u32 {
        self.delivered
    }

    /// The recorded frame the next delivery starts from.
    pub fn recorded_next(&self) -> usize {
        self.next
    }

    fn read(
        &mut self,
        index: usize,
        rows: core::ops::Range<usize>,
        frame: &mut ImageMut<'_, u8>,
    ) -> Result<(), CameraError<R::Error>> {
        let last = self.frames.len().saturating_sub(1);
        self.frames
            .read_rows(index.min(last), rows, frame)
            .map_err(CameraError::Read)
    }
}

fn fill(frame: &mut ImageMut<'_, u8>, mut value: impl FnMut() -> u8) {
    for y in 0..frame.height() {
        let w = frame.width();
        if let Some(row) = frame.row_mut(y).and_then(|r| r.get_mut(..w)) {
            row.iter_mut().for_each(|p| *p = value());
        }
    }
}

impl<R: RecordedFrames> FrameSource for RecordedCamera<R> {
    type Error = CameraError<R::Error>;

    fn size(&self) -> (usize, usize) {
        self.frames.size()
    }

    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, Self::Error> {
        if self.delivered as usize >= self.count {
            return Ok(false);
        }
        let (w, h) = self.frames.size();
        if (frame.width(), frame.height()) != (w, h) {
            return Err(CameraError::WrongSize);
        }
        let k = self.delivered;
        self.delivered += 1;
        let here = self.next;
        // Every frame, faulty or not, moves the recording on by the stride (the scene goes on
        // while the camera misbehaves), except a repeat, which delivers a stale frame.
        self.next += self.stride;
        match self.plan.at(k) {
            None => self.read(here, 0..h, frame)?,
            Some(s) => match s.fault {
                Fault::Black => fill(frame, || 0),
                Fault::White => fill(frame, || 255),
                Fault::Noise => {
                    let mut g = Pcg32::new(u64::from(s.param) ^ u64::from(k));
                    fill(frame, || if g.next_u32() & 1 == 0 { 0 } else { 255 });
                }
                Fault::Repeat => {
                    self.next = here;
                    self.read(here.saturating_sub(self.stride), 0..h, frame)?;
                }
                Fault::Drop => {
                    let skipped = here + self.stride * s.param as usize;
                    self.next = skipped + self.stride;
                    self.read(skipped, 0..h, frame)?;
                }
                Fault::Torn => {
                    self.read(here, 0..h / 2, frame)?;
                    self.read(here + self.stride, h / 2..h, frame)?;
                }
                Fault::WrongSize => return Err(CameraError::WrongSize),
                Fault::ReadError => return Err(CameraError::Read(self.frames.failing_read())),
            },
        }
        Ok(true)
    }
}

/// A recording held in memory: `len` packed `width x height` frames one after the other (the
/// host replay's camera, and this module's tests).
#[derive(Debug, Clone, Copy)]
pub struct SliceFrames<'a> {
    bytes: &'a [u8],
    width: usize,
    height: usize,
}

impl<'a> SliceFrames<'a> {
    /// The frames of `bytes` (a partial frame at the end is ignored).
    pub fn new(bytes: &'a [u8], width: usize, height: usize) -> Self {
        Self {
            bytes,
            width,
            height,
        }
    }
}

/// A [`SliceFrames`] read past its end (or a [`Fault::ReadError`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutOfRange;

impl RecordedFrames for SliceFrames<'_> {
    type Error = OutOfRange;

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn len(&self) -> usize {
        self.bytes.len() / (self.width * self.height).max(1)
    }

    fn read_rows(
        &mut self,
        index: usize,
        rows: core::ops::Range<usize>,
        frame: &mut ImageMut<'_, u8>,
    ) -> Result<(), OutOfRange> {
        let w = self.width;
        let start = index * w * self.height;
        for y in rows {
            let src = self
                .bytes
                .get(start + y * w..start + (y + 1) * w)
                .ok_or(OutOfRange)?;
            frame
                .row_mut(y)
                .and_then(|r| r.get_mut(..w))
                .ok_or(OutOfRange)?
                .copy_from_slice(src);
        }
        Ok(())
    }

    fn failing_read(&mut self) -> OutOfRange {
        OutOfRange
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// 6 recorded 4x2 frames, frame `i` all `10 i + row`.
    fn recording() -> Vec<u8> {
        (0..6u8)
            .flat_map(|i| (0..2u8).flat_map(move |y| [10 * i + y; 4]))
            .collect()
    }

    fn deliver(plan: FaultPlan, stride: usize) -> Vec<Result<[u8; 2], CameraError<OutOfRange>>> {
        let bytes = recording();
        let mut cam = RecordedCamera::new(SliceFrames::new(&bytes, 4, 2), stride, 6, plan);
        let mut buf = [0u8; 8];
        let mut out = Vec::new();
        loop {
            let mut img = ImageMut::packed(&mut buf, 4, 2).unwrap();
            match cam.next_frame(&mut img) {
                Ok(true) => out.push(Ok([buf[0], buf[4]])),
                Ok(false) => break,
                Err(e) => out.push(Err(e)),
            }
        }
        out
    }

    #[test]
    fn faults_do_what_the_plan_says() {
        assert_eq!(
            deliver(FaultPlan::none(), 1),
            (0..6u8)
                .map(|i| Ok([10 * i, 10 * i + 1]))
                .collect::<Vec<_>>()
        );
        let span = |first, frames, fault, param| FaultSpan {
            first,
            frames,
            fault,
            param,
        };
        let plan = FaultPlan::new(&[
            span(0, 1, Fault::Black, 0),
            span(1, 1, Fault::Repeat, 0),
            span(2, 1, Fault::Torn, 0),
            span(3, 1, Fault::Drop, 1),
            span(4, 1, Fault::ReadError, 0),
            span(5, 1, Fault::WrongSize, 0),
        ])
        .unwrap();
        assert_eq!(
            deliver(plan, 1),
            [
                Ok([0, 0]),
                // Frame 0 again: the black frame replaced it, the repeat delivers it late.
                Ok([0, 1]),
                // Top of frame 1, bottom of frame 2.
                Ok([10, 21]),
                // The torn frame took frame 1 (and frame 2's bottom); frame 2 dropped: frame 3.
                Ok([30, 31]),
                Err(CameraError::Read(OutOfRange)),
                Err(CameraError::WrongSize),
            ]
        );
        // The stride applies to the recording, faults to deliveries.
        let white = FaultPlan::new(&[span(1, 1, Fault::White, 0)]).unwrap();
        assert_eq!(
            deliver(white, 2),
            [Ok([0, 1]), Ok([255, 255]), Ok([40, 41])]
        );
    }

    #[test]
    fn plans_round_trip_and_bad_bytes_are_errors() {
        let plan = FaultPlan::new(&[
            FaultSpan {
                first: 20,
                frames: 3,
                fault: Fault::Noise,
                param: 7,
            },
            FaultSpan {
                first: 90,
                frames: 1,
                fault: Fault::WrongSize,
                param: 0,
            },
        ])
        .unwrap();
        assert_eq!(FaultPlan::parse(&plan.to_bytes()), Ok(plan));
        assert_eq!(
            FaultPlan::parse(&FaultPlan::none().to_bytes()),
            Ok(FaultPlan::none())
        );
        let mut bad = plan.to_bytes();
        bad[12 + 8] = 99;
        assert!(FaultPlan::parse(&bad).is_err());
        assert!(FaultPlan::parse(&bad[..10]).is_err());
        assert!(FaultPlan::new(&[plan.at(20).unwrap(); MAX_FAULTS + 1]).is_err());
        assert_eq!(plan.at(22).map(|s| s.fault), Some(Fault::Noise));
        assert_eq!(plan.at(23), None);
    }
}
