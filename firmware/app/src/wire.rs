//! The board's binary records, written and read one way: a [`Writer`], a [`Reader`] and their
//! [`WireError`].
//!
//! Every record a board and its host exchange (the run description [`crate::run::RunSpec`],
//! the fault plan [`crate::recorded::FaultPlan`], the calibration job's
//! [`crate::calibration::CalibSpec`] and records, the frame and summary records of
//! [`crate::report`]) has a fixed length and the same frame:
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | tag: four ASCII bytes naming the record (`"CRUN"`, `"CFRM"`, ...), [`tag`] |
//! | 4..8 | `u32` layout version of that record |
//! | 8.. | the record's fields, little-endian, in the order its table gives |
//!
//! Each record's module holds its field table and is the only place that writes or reads those
//! bytes, on the board and on the host alike. A [`Reader`] is made by [`Reader::new_checked`],
//! which checks the length, the tag and the version once; after that no read can fail (a read
//! past the end, which the length check rules out, gives zeros), and a field whose value is
//! out of range is reported by name ([`Reader::invalid`]).

use core::fmt;

/// The tag word of a record: four ASCII bytes as a little-endian `u32`.
pub const fn tag(name: &[u8; 4]) -> u32 {
    u32::from_le_bytes(*name)
}

/// Bytes that are not the record they were read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum WireError {
    /// Not the record's length.
    Length {
        /// The record read.
        record: &'static str,
        /// Its length.
        expected: u32,
        /// The bytes given.
        got: u32,
    },
    /// A tag this record is not.
    Tag {
        /// The record read.
        record: &'static str,
        /// The tag found.
        got: u32,
    },
    /// Another layout version than this build's.
    Version {
        /// The record read.
        record: &'static str,
        /// This build's version.
        expected: u32,
        /// The version found.
        got: u32,
    },
    /// A field whose value no record of this layout has.
    Field {
        /// The record read.
        record: &'static str,
        /// The field.
        field: &'static str,
    },
}

impl fmt::Display for WireError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Length {
                record,
                expected,
                got,
            } => write!(f, "{record}: {got} bytes, the record has {expected}"),
            Self::Tag { record, got } => {
                let b = got.to_le_bytes().map(|c| {
                    if c.is_ascii_graphic() {
                        char::from(c)
                    } else {
                        '?'
                    }
                });
                write!(
                    f,
                    "{record}: tag \"{}{}{}{}\" is not this record's",
                    b[0], b[1], b[2], b[3]
                )
            }
            Self::Version {
                record,
                expected,
                got,
            } => write!(
                f,
                "{record}: layout version {got}, this build reads {expected}"
            ),
            Self::Field { record, field } => write!(f, "{record}: invalid {field}"),
        }
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for WireError {
    fn format(&self, f: defmt::Formatter<'_>) {
        match *self {
            Self::Length {
                record,
                expected,
                got,
            } => defmt::write!(
                f,
                "{=str}: {=u32} bytes, the record has {=u32}",
                record,
                got,
                expected
            ),
            Self::Tag { record, got } => {
                defmt::write!(f, "{=str}: tag {=u32:#x} is not this record's", record, got)
            }
            Self::Version {
                record,
                expected,
                got,
            } => defmt::write!(
                f,
                "{=str}: layout version {=u32}, this build reads {=u32}",
                record,
                got,
                expected
            ),
            Self::Field { record, field } => {
                defmt::write!(f, "{=str}: invalid {=str}", record, field)
            }
        }
    }
}

/// Writes a record's fields in order into a caller buffer, little-endian. Bytes past the end
/// of the buffer are dropped and counted ([`Writer::len`] then exceeds the buffer): a record of
/// fixed length is sized so that this never happens, which its round-trip test checks.
#[derive(Debug)]
pub struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl<'a> Writer<'a> {
    /// A writer of the record `tag`, layout `version`, into `out` (the tag and version
    /// written).
    pub fn record(out: &'a mut [u8], tag: u32, version: u32) -> Self {
        let mut w = Self { out, at: 0 };
        w.u32(tag);
        w.u32(version);
        w
    }

    /// The record of `N` bytes that `fields` writes after the tag and the version.
    pub fn fill<const N: usize>(
        tag: u32,
        version: u32,
        fields: impl FnOnce(&mut Writer),
    ) -> [u8; N] {
        let mut out = [0u8; N];
        fields(&mut Writer::record(&mut out, tag, version));
        out
    }

    /// Raw bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        if let Some(d) = self.out.get_mut(self.at..self.at.saturating_add(b.len())) {
            d.copy_from_slice(b);
        }
        self.at = self.at.saturating_add(b.len());
    }

    /// A byte.
    pub fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }

    /// A little-endian `u16`.
    pub fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }

    /// A little-endian `u32`.
    pub fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }

    /// An `f32` as its little-endian bits.
    pub fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }

    /// Each `f32` of `v`.
    pub fn f32s(&mut self, v: impl IntoIterator<Item = f32>) {
        for x in v {
            self.f32(x);
        }
    }

    /// Each `u32` of `v`.
    pub fn u32s(&mut self, v: impl IntoIterator<Item = u32>) {
        for x in v {
            self.u32(x);
        }
    }

    /// Bytes written so far, the tag and version included (more than the buffer when it
    /// overflowed).
    pub fn len(&self) -> usize {
        self.at
    }

    /// Nothing written (never: the tag and version are).
    pub fn is_empty(&self) -> bool {
        self.at == 0
    }
}

/// Reads a record's fields in order, after [`Reader::new_checked`] has checked its frame.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    record: &'static str,
    tag: u32,
}

impl<'a> Reader<'a> {
    /// A reader of `bytes` as the record `record` (its name in errors): exactly `len` bytes,
    /// tag one of `tags`, layout `version`. Errors: [`WireError::Length`], [`WireError::Tag`],
    /// [`WireError::Version`].
    pub fn new_checked(
        record: &'static str,
        bytes: &'a [u8],
        len: usize,
        tags: &[u32],
        version: u32,
    ) -> Result<Self, WireError> {
        if bytes.len() != len {
            return Err(WireError::Length {
                record,
                expected: u32::try_from(len).unwrap_or(u32::MAX),
                got: u32::try_from(bytes.len()).unwrap_or(u32::MAX),
            });
        }
        let mut r = Self {
            bytes,
            at: 0,
            record,
            tag: 0,
        };
        r.tag = r.u32();
        if !tags.contains(&r.tag) {
            return Err(WireError::Tag { record, got: r.tag });
        }
        let got = r.u32();
        if got != version {
            return Err(WireError::Version {
                record,
                expected: version,
                got,
            });
        }
        Ok(r)
    }

    /// The record's tag.
    pub fn tag(&self) -> u32 {
        self.tag
    }

    /// The error for the field `field` holding a value no record has.
    pub fn invalid(&self, field: &'static str) -> WireError {
        WireError::Field {
            record: self.record,
            field,
        }
    }

    /// The next `M` bytes.
    pub fn array<const M: usize>(&mut self) -> [u8; M] {
        let mut a = [0u8; M];
        if let Some(s) = self.bytes.get(self.at..self.at.saturating_add(M)) {
            a.copy_from_slice(s);
        }
        self.at = self.at.saturating_add(M);
        a
    }

    /// A byte.
    pub fn u8(&mut self) -> u8 {
        let [b] = self.array::<1>();
        b
    }

    /// A little-endian `u16`.
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.array())
    }

    /// A little-endian `u32`.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.array())
    }

    /// An `f32` from its little-endian bits.
    pub fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    /// `M` `f32`s.
    pub fn f32s<const M: usize>(&mut self) -> [f32; M] {
        core::array::from_fn(|_| self.f32())
    }

    /// `M` `u32`s.
    pub fn u32s<const M: usize>(&mut self) -> [u32; M] {
        core::array::from_fn(|_| self.u32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u32 = tag(b"TEST");

    #[test]
    fn fields_round_trip_and_the_frame_is_checked() {
        let rec: [u8; 19] = Writer::fill(T, 2, |w| {
            w.u8(7);
            w.u16(0xbeef);
            w.f32(-1.5);
            w.u32(42);
        });
        let mut r = Reader::new_checked("test", &rec, 19, &[T], 2).unwrap();
        assert_eq!(
            (r.tag(), r.u8(), r.u16(), r.f32(), r.u32()),
            (T, 7, 0xbeef, -1.5, 42)
        );
        assert_eq!(
            Reader::new_checked("test", &rec[..18], 19, &[T], 2).unwrap_err(),
            WireError::Length {
                record: "test",
                expected: 19,
                got: 18
            }
        );
        assert_eq!(
            Reader::new_checked("test", &rec, 19, &[tag(b"ELSE")], 2).unwrap_err(),
            WireError::Tag {
                record: "test",
                got: T
            }
        );
        assert_eq!(
            Reader::new_checked("test", &rec, 19, &[T], 3).unwrap_err(),
            WireError::Version {
                record: "test",
                expected: 3,
                got: 2
            }
        );
    }

    #[test]
    fn overflow_is_dropped_and_counted_and_reads_past_the_end_are_zero() {
        let mut out = [0u8; 10];
        let mut w = Writer::record(&mut out, T, 1);
        w.u32(5);
        assert_eq!(w.len(), 12);
        assert_eq!(out[8..], [0, 0]);
        let rec: [u8; 8] = Writer::fill(T, 1, |_| {});
        let mut r = Reader::new_checked("test", &rec, 8, &[T], 1).unwrap();
        assert_eq!(r.u32(), 0);
    }
}
