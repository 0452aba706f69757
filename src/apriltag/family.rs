//! Tag families: code tables, bit layouts and the error-correcting decoder.
//!
//! A tag of a family is a square of `total_width x total_width` cells. The detection border is
//! the square of `width_at_border` cells whose outer edge the detector finds (black on a white
//! quiet zone, or white inside black for a reversed border); tag coordinates `(-1, -1)` and
//! `(1, 1)` are two opposite corners of that edge. The payload is `nbits` cells: bit `i` of the
//! layout is cell `(x, y)` = `layout[i]` (columns and rows counted from the border's outer
//! corner, so cells may lie outside the border: tagStandard41h12 has bits at -2), white when
//! bit `nbits - 1 - i` of the code is set (AprilTag 3's order: `apriltag_to_image`).
//!
//! The layouts are built so that turning the tag a quarter turn is a cyclic shift of the code
//! by `nbits / 4` ([`rotate90`], AprilTag's `rotate90`: the code of the tag turned a quarter
//! counter-clockwise on screen, `y` down; the centre cell fixed when `nbits` is odd). A read
//! code `r` decodes to id `k` in rotation `q` when `popcount(rotate90^q(r) ⊕ codes[k]) ≤
//! max_hamming`.
//!
//! **Lookup** (AprilTag 3's current scheme): the code is cut into 4 chunks of
//! `⌈nbits / 4⌉` bits; a word within 3 bits of a code agrees with it exactly on at least one
//! chunk (pigeonhole), so only the codes sharing a chunk value with the read word are
//! compared. The index (per chunk, the codes by chunk value) is built at compile time into
//! flash: `4 (2^⌈nbits/4⌉ + 1) + 4 ncodes` `u16` — 8.8 KB for tag36h11, 1.3 KB for tag25h9,
//! 0.4 KB for tag16h5, 33 KB for tagStandard41h12. (AprilTag 3.1, what pupil-apriltags ships,
//! hashes every word within 2 bits of a code: 3 x 761,339 entries of 12 bytes, about 27 MB for
//! tag36h11, built at start-up; the current AprilTag uses this chunk index.) A lookup compares
//! about `4 · 4 · ncodes / 2^chunk` codes (about 18 for tag36h11).

/// Chunks the code is cut into for the lookup (up to 3 corrected bits).
pub const CHUNKS: usize = 4;

/// Largest number of bits the decoder corrects (the chunk lookup's pigeonhole bound).
pub const MAX_CORRECTABLE: u8 = 3;

/// A payload cell: column `x` and row `y`, counted from the detection border's outer corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LayoutBit {
    /// Column.
    pub x: i8,
    /// Row.
    pub y: i8,
}

/// A tag family: its geometry, code table and (compile-time) lookup index.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Family {
    pub(crate) name: &'static str,
    pub(crate) min_distance: u8,
    pub(crate) width_at_border: u8,
    pub(crate) total_width: u8,
    pub(crate) reversed_border: bool,
    pub(crate) layout: &'static [LayoutBit],
    pub(crate) codes: &'static [u64],
    pub(crate) index: IndexRef,
}

/// The chunk index of a family (see the module docs), as slices into its `static`.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct IndexRef {
    /// Chunk width in bits.
    pub(crate) chunk_bits: u8,
    /// `CHUNKS` tables of `2^chunk_bits + 1` offsets into `ids`.
    pub(crate) offsets: &'static [u16],
    /// `CHUNKS` tables of `ncodes` code indices, grouped by chunk value.
    pub(crate) ids: &'static [u16],
}

/// The chunk index of `N` codes: `OFF = CHUNKS (2^chunk + 1)`, `IDS = CHUNKS N`.
pub(crate) struct ChunkIndex<const OFF: usize, const IDS: usize> {
    pub(crate) offsets: [u16; OFF],
    pub(crate) ids: [u16; IDS],
}

/// Chunk width for `nbits`: `⌈nbits / CHUNKS⌉`.
pub(crate) const fn chunk_bits(nbits: usize) -> usize {
    nbits.div_ceil(CHUNKS)
}

impl<const OFF: usize, const IDS: usize> ChunkIndex<OFF, IDS> {
    /// Builds the index at compile time (a counting sort of the codes by each chunk's value).
    /// A size mismatch or more than `u16::MAX` codes fails the build.
    #[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
    pub(crate) const fn build(codes: &[u64], nbits: usize) -> Self {
        let bits = chunk_bits(nbits);
        let cap = 1usize << bits;
        assert!(OFF == CHUNKS * (cap + 1) && IDS == CHUNKS * codes.len());
        assert!(codes.len() < u16::MAX as usize);
        let mask = (cap - 1) as u64;
        let mut offsets = [0u16; OFF];
        let mut ids = [0u16; IDS];
        let mut c = 0;
        while c < CHUNKS {
            let base = c * (cap + 1);
            let mut i = 0;
            while i < codes.len() {
                let v = ((codes[i] >> (c * bits)) & mask) as usize;
                offsets[base + v + 1] += 1;
                i += 1;
            }
            let mut v = 0;
            while v < cap {
                offsets[base + v + 1] += offsets[base + v];
                v += 1;
            }
            // Fill through a cursor per value, started at its offset.
            let mut cursor = offsets;
            let mut i = 0;
            while i < codes.len() {
                let v = ((codes[i] >> (c * bits)) & mask) as usize;
                ids[c * codes.len() + cursor[base + v] as usize] = i as u16;
                cursor[base + v] += 1;
                i += 1;
            }
            c += 1;
        }
        Self { offsets, ids }
    }
}

/// A decoded code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Decoded {
    /// Tag id: index into the family's codes.
    pub id: u16,
    /// Bits that differed from the code (corrected).
    pub hamming: u8,
    /// Quarter turns `q` with `rotate90^q(read) = code` (module docs).
    pub rotation: u8,
}

/// AprilTag's `rotate90`: the code of the same tag turned a quarter counter-clockwise (on
/// screen, `y` down; cell `(x, y)` moves to `(y, w - 1 - x)`, `w` the border width), for the
/// layouts of the module docs (a cyclic shift of the four quadrants, the centre bit fixed when
/// `nbits` is odd). `nbits` must be in `1..=64`; other values give 0.
pub const fn rotate90(w: u64, nbits: u32) -> u64 {
    if nbits == 0 || nbits > 64 {
        return 0;
    }
    let (p, l) = if nbits % 4 == 1 {
        (nbits - 1, 1)
    } else {
        (nbits, 0)
    };
    let mask = if nbits == 64 {
        u64::MAX
    } else {
        (1u64 << nbits) - 1
    };
    let quarter = p / 4;
    // (w >> l) << (p/4 + l): every quadrant moves up one; the top one wraps to the bottom.
    let up = (w >> l).wrapping_shl(quarter + l);
    let wrapped = (w >> (3 * p / 4 + l)) << l;
    (up | wrapped | (w & l as u64)) & mask
}

impl Family {
    /// AprilTag's name of the family (`"tag36h11"`, ...).
    pub fn name(&self) -> &'static str {
        self.name
    }
    /// Payload bits.
    pub fn nbits(&self) -> u32 {
        self.layout.len() as u32
    }
    /// Number of codes (ids `0..ncodes`).
    pub fn ncodes(&self) -> usize {
        self.codes.len()
    }
    /// Minimum Hamming distance between any two codes in any rotation (and between a code and
    /// its own rotations): `max_hamming < min_distance / 2` keeps the correction unique.
    pub fn min_distance(&self) -> u8 {
        self.min_distance
    }
    /// Cells across the detection border's outer edge (the metric tag size spans these).
    pub fn width_at_border(&self) -> u8 {
        self.width_at_border
    }
    /// Cells across the whole printed tag, quiet zone included.
    pub fn total_width(&self) -> u8 {
        self.total_width
    }
    /// `true` when the detection border is white inside black (tagStandard41h12).
    pub fn reversed_border(&self) -> bool {
        self.reversed_border
    }
    /// The payload layout (module docs).
    pub fn layout(&self) -> &'static [LayoutBit] {
        self.layout
    }
    /// The code of tag `id`, `None` past the table.
    pub fn code(&self, id: u16) -> Option<u64> {
        self.codes.get(usize::from(id)).copied()
    }

    /// The colour of cell `(x, y)` of tag `id` (`true` white), cells counted as the layout's
    /// (from the border's outer corner; the quiet zone and a reversed family's outer ring are
    /// at negative and `>= width_at_border` indices): AprilTag's `apriltag_to_image`. `None`
    /// for an unknown id or a cell outside the `total_width` square.
    pub fn cell(&self, id: u16, x: i32, y: i32) -> Option<bool> {
        let code = self.code(id)?;
        let wab = i32::from(self.width_at_border);
        let lo = (wab - i32::from(self.total_width)) / 2;
        let hi = lo + i32::from(self.total_width);
        if x < lo || y < lo || x >= hi || y >= hi {
            return None;
        }
        let n = self.layout.len();
        if let Some(i) = self
            .layout
            .iter()
            .position(|b| i32::from(b.x) == x && i32::from(b.y) == y)
        {
            return Some((code >> (n - 1 - i)) & 1 == 1);
        }
        // Not a payload cell: the border square (black; white when reversed), a ring outside it
        // (white; black when reversed, where the reversed family's outer ring is) or, for
        // normal families, cells inside the border that the layout leaves out (none here).
        let on_border = (x == 0 || y == 0 || x == wab - 1 || y == wab - 1)
            && (0..wab).contains(&x)
            && (0..wab).contains(&y);
        let inside = (1..wab - 1).contains(&x) && (1..wab - 1).contains(&y);
        // Reversed (tagStandard41h12): only the detection ring is white. Normal: the quiet
        // zone around the border is white, the border and unused inner cells black.
        Some(if self.reversed_border {
            on_border
        } else {
            !(on_border || inside)
        })
    }

    /// Decodes a read word (module docs): the code within `max_hamming` bits of `rcode` in
    /// some rotation, if any (`max_hamming ≤` [`MAX_CORRECTABLE`]; larger values are treated
    /// as [`MAX_CORRECTABLE`]). With `2 max_hamming < min_distance` the answer is unique.
    pub fn decode(&self, rcode: u64, max_hamming: u8) -> Option<Decoded> {
        let maxh = max_hamming.min(MAX_CORRECTABLE) as u32;
        let nbits = self.nbits();
        let bits = u32::from(self.index.chunk_bits);
        let cap = 1usize << bits;
        let mask = (cap - 1) as u64;
        let n = self.codes.len();
        let mut r = rcode;
        for rotation in 0..4u8 {
            for c in 0..CHUNKS {
                let v = ((r >> (c as u32 * bits)) & mask) as usize;
                let base = c * (cap + 1) + v;
                let (Some(&start), Some(&end)) = (
                    self.index.offsets.get(base),
                    self.index.offsets.get(base + 1),
                ) else {
                    continue;
                };
                let ids = self
                    .index
                    .ids
                    .get(c * n + usize::from(start)..c * n + usize::from(end))
                    .unwrap_or(&[]);
                for &id in ids {
                    let Some(code) = self.codes.get(usize::from(id)) else {
                        continue;
                    };
                    let hamming = (code ^ r).count_ones();
                    if hamming <= maxh {
                        return Some(Decoded {
                            id,
                            hamming: hamming as u8,
                            rotation,
                        });
                    }
                }
            }
            r = rotate90(r, nbits);
        }
        None
    }
}

impl PartialEq for Family {
    /// Families are the `static`s of [`super::families`]: the same family is the same name.
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Eq for Family {}
