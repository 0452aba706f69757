//! The integer type of the component labels: `u16` (a board's [`super::Workspace`], at most
//! 65533 labels a frame, 2 bytes each) or `u32` (a host's frames of millions of pixels, where
//! noise and texture need more), and the cluster key of a pair of them.
//!
//! The detector is generic over [`Label`] and compiles once per type: the `u16` path is the
//! board's, unchanged by the `u32` one.

/// What a label type gives the detector: the two marker values, the capacity they leave, and
/// the cluster key of a (black, white) pair of labels. Implemented by `u16` and `u32` only.
pub trait Label: Copy + Eq + Ord + core::fmt::Debug + sealed::Sealed {
    /// A label value for "no component": a skipped pixel (the type's largest value).
    const NONE: Self;
    /// A label value for a component below [`super::segment::MIN_COMPONENT`] pixels (boundary
    /// scans only): `NONE - 1`.
    const SMALL: Self;
    /// Most labels a frame can use: every value below [`Label::SMALL`].
    const MAX_LABELS: usize;
    /// The cluster key of a (black root, white root) pair: twice the label's bits.
    type Key: ClusterKey;
    /// Label number `i` (`i < MAX_LABELS`; larger values are truncated).
    fn from_index(i: usize) -> Self;
    /// The label as an index.
    fn index(self) -> usize;
    /// The key of the pair: `black << bits | white`.
    fn key(black: Self, white: Self) -> Self::Key;
    /// The two labels of a key, as indices: `(black, white)`.
    fn halves(key: Self::Key) -> (usize, usize);
}

/// A cluster key (`u32` for `u16` labels, `u64` for `u32` ones).
pub trait ClusterKey: Copy + Eq + core::fmt::Debug + sealed::Sealed {
    /// The key of an empty table slot: both halves [`Label::NONE`], never a pair of roots.
    const EMPTY: Self;
    /// The key widened to 64 bits (the table's Fibonacci hash multiplies it).
    fn wide(self) -> u64;
    /// The key with its two halves exchanged: `key(a, b)` becomes `key(b, a)`.
    fn swapped(self) -> Self;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for u16 {}
    impl Sealed for u32 {}
    impl Sealed for u64 {}
}

impl Label for u16 {
    const NONE: Self = u16::MAX;
    const SMALL: Self = u16::MAX - 1;
    const MAX_LABELS: usize = (u16::MAX - 1) as usize;
    type Key = u32;
    #[inline(always)]
    fn from_index(i: usize) -> Self {
        i as u16
    }
    #[inline(always)]
    fn index(self) -> usize {
        usize::from(self)
    }
    #[inline(always)]
    fn key(black: Self, white: Self) -> u32 {
        u32::from(black) << 16 | u32::from(white)
    }
    #[inline(always)]
    fn halves(key: u32) -> (usize, usize) {
        ((key >> 16) as usize, (key & 0xffff) as usize)
    }
}

impl Label for u32 {
    const NONE: Self = u32::MAX;
    const SMALL: Self = u32::MAX - 1;
    const MAX_LABELS: usize = (u32::MAX - 1) as usize;
    type Key = u64;
    #[inline(always)]
    fn from_index(i: usize) -> Self {
        i as u32
    }
    #[inline(always)]
    fn index(self) -> usize {
        self as usize
    }
    #[inline(always)]
    fn key(black: Self, white: Self) -> u64 {
        u64::from(black) << 32 | u64::from(white)
    }
    #[inline(always)]
    fn halves(key: u64) -> (usize, usize) {
        ((key >> 32) as usize, (key & 0xffff_ffff) as usize)
    }
}

impl ClusterKey for u32 {
    const EMPTY: Self = u32::MAX;
    #[inline(always)]
    fn wide(self) -> u64 {
        u64::from(self)
    }
    #[inline(always)]
    fn swapped(self) -> Self {
        self.rotate_left(16)
    }
}

impl ClusterKey for u64 {
    const EMPTY: Self = u64::MAX;
    #[inline(always)]
    fn wide(self) -> u64 {
        self
    }
    #[inline(always)]
    fn swapped(self) -> Self {
        self.rotate_left(32)
    }
}
