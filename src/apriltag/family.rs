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
//! **Border width** ([`Family::border_bits`]): the layouts are those of a border 1 cell wide
//! (as AprilTag 3 and OpenCV draw every family). A family drawn with a border `b` cells wide
//! (Kalibr's AprilGrid tags: tag36h11 with `b = 2`, the old AprilTags C++ library's drawing)
//! has the same codes, ids and layout with every payload cell moved inward by `b - 1` on both
//! axes ([`Family::bit_cell`]) and `2 (b - 1)` more cells across the border: the same
//! decoder reads it, the layout's cells shifted.
//!
//! The layouts are built so that turning the tag a quarter turn is a cyclic shift of the code
//! by `nbits / 4` ([`rotate90`], AprilTag's `rotate90`: the code of the tag turned a quarter
//! counter-clockwise on screen, `y` down; the centre cell fixed when `nbits` is odd). A read
//! code `r` decodes to id `k` in rotation `q` when `popcount(rotate90^q(r) ⊕ codes[k]) ≤
//! max_hamming`.
//!
//! **Lookup** (AprilTag 3's current scheme, generalised): the code is cut into `c` chunks of
//! `⌈nbits / c⌉` bits (`c = 4` for the AprilTag families); a word within `e` bits of a code
//! agrees with it exactly on at least one of any `e + 1` chunks (pigeonhole: `e` wrong bits
//! fall in at most `e` chunks), so only the codes sharing a chunk value with the read word in
//! the first `e + 1` chunks are compared, and a family corrects up to `c - 1` bits exactly
//! ([`Family::max_correctable`]). The index (per chunk, the codes by chunk value) is built at compile time into
//! flash: `4 (2^⌈nbits/4⌉ + 1) + 4 ncodes` `u16` — 8.8 KB for tag36h11, 1.3 KB for tag25h9,
//! 0.4 KB for tag16h5, 33 KB for tagStandard41h12. (AprilTag 3.1, what pupil-apriltags ships,
//! hashes every word within 2 bits of a code: 3 x 761,339 entries of 12 bytes, about 27 MB for
//! tag36h11, built at start-up; the current AprilTag uses this chunk index.) A lookup compares
//! about `4 (e + 1) ncodes / 2^chunk` codes (about 14 for tag36h11 at `e = 2`).
//!
//! **Which code** (OpenCV's `Dictionary::identify`): of the codes within `max_hamming` of the
//! word in some rotation, the smallest id, in the rotation that differs least. When
//! `2 max_hamming < min_distance` there is at most one.
//!
//! **ArUco dictionaries** ([`Kind::Aruco`], OpenCV's predefined dictionaries in
//! [`super::families`]) are families of the same shape: a 1-cell black border of
//! `markerSize + 2` cells, a white quiet zone outside it, the `markerSize²` payload cells
//! inside. Their bound on corrected bits comes from the detector's `error_correction_rate`
//! and their `max_correction_bits` (OpenCV's `maxCorrectionBits`), and their border cells are
//! read too (OpenCV's `maxErroneousBitsInBorderRate`): see
//! [`super::DetectorConfig::error_correction_rate`].

/// Chunks the code of an AprilTag family is cut into for the lookup (up to 3 corrected
/// bits); ArUco dictionaries have their own ([`Family::max_correctable`]).
pub const CHUNKS: usize = 4;

/// Largest number of bits the decoder corrects for an AprilTag family (the chunk lookup's
/// pigeonhole bound, `CHUNKS - 1`).
pub const MAX_CORRECTABLE: u8 = 3;

/// What a family is: an AprilTag family or an ArUco dictionary (how its bits are corrected
/// and its border checked, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Kind {
    /// AprilTag's: up to [`super::DetectorConfig::max_hamming`] bits corrected.
    AprilTag,
    /// OpenCV's ArUco dictionaries: `⌊max_correction_bits · errorCorrectionRate⌋` bits
    /// corrected, at most `⌊markerSize² · maxErroneousBitsInBorderRate⌋` border cells white.
    #[doc(alias = "Dictionary")]
    Aruco {
        /// OpenCV's `maxCorrectionBits` of the dictionary.
        max_correction_bits: u8,
    },
}

/// The codes of a family, stored in the narrowest word that holds `nbits`.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) enum Codes {
    U16(&'static [u16]),
    U32(&'static [u32]),
    U64(&'static [u64]),
}

impl Codes {
    pub(crate) fn len(&self) -> usize {
        match self {
            Codes::U16(c) => c.len(),
            Codes::U32(c) => c.len(),
            Codes::U64(c) => c.len(),
        }
    }

    pub(crate) fn get(&self, i: usize) -> Option<u64> {
        match self {
            Codes::U16(c) => c.get(i).map(|&v| u64::from(v)),
            Codes::U32(c) => c.get(i).map(|&v| u64::from(v)),
            Codes::U64(c) => c.get(i).copied(),
        }
    }
}

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
    /// Cells across the black border (1 for the families as AprilTag 3 and OpenCV draw them).
    pub(crate) border_bits: u8,
    pub(crate) kind: Kind,
    pub(crate) layout: &'static [LayoutBit],
    pub(crate) codes: Codes,
    pub(crate) index: IndexRef,
}

/// The chunk index of a family (see the module docs), as slices into its `static`.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct IndexRef {
    /// Chunks (`max_correctable + 1`).
    pub(crate) chunks: u8,
    /// Chunk width in bits.
    pub(crate) chunk_bits: u8,
    /// Codes indexed: a dictionary that is a prefix of a larger one shares its index, and
    /// skips the ids past its own.
    pub(crate) stride: u16,
    /// `chunks` tables of `2^chunk_bits + 1` offsets into `ids`.
    pub(crate) offsets: &'static [u16],
    /// `chunks` tables of `stride` code indices, grouped by chunk value, ascending within a
    /// value.
    pub(crate) ids: &'static [u16],
}

/// The chunk index of `N` codes in `C` chunks: `OFF = C (2^chunk + 1)`, `IDS = C N`.
pub(crate) struct ChunkIndex<const OFF: usize, const IDS: usize> {
    pub(crate) offsets: [u16; OFF],
    pub(crate) ids: [u16; IDS],
}

/// Chunk width for `nbits` in `chunks`: `⌈nbits / chunks⌉`.
pub(crate) const fn chunk_bits(nbits: usize, chunks: usize) -> usize {
    nbits.div_ceil(chunks)
}

impl<const OFF: usize, const IDS: usize> ChunkIndex<OFF, IDS> {
    /// Builds the index at compile time (a counting sort of the codes by each chunk's value,
    /// stable: ids ascend within a value). A size mismatch or more than `u16::MAX` codes fails
    /// the build.
    #[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
    pub(crate) const fn build(codes: &[u64], nbits: usize, chunks: usize) -> Self {
        let bits = chunk_bits(nbits, chunks);
        let cap = 1usize << bits;
        assert!(OFF == chunks * (cap + 1) && IDS == chunks * codes.len());
        assert!(codes.len() < u16::MAX as usize);
        let mask = (cap - 1) as u64;
        let mut offsets = [0u16; OFF];
        let mut ids = [0u16; IDS];
        let mut c = 0;
        while c < chunks {
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
    /// Cells across the black border between the detection edge and the payload (module
    /// docs): 1 for the families as AprilTag 3 and OpenCV draw them, 2 for
    /// [`super::families::TAG36H11_B2`] (Kalibr's AprilGrid tags).
    pub fn border_bits(&self) -> u8 {
        self.border_bits
    }
    /// The payload layout for a 1-cell border (module docs): a family with a wider border has
    /// its cells at [`Self::bit_cell`].
    pub fn layout(&self) -> &'static [LayoutBit] {
        self.layout
    }
    /// The cell `(x, y)` of payload bit `i` (columns and rows from the border's outer corner):
    /// `layout[i]` moved inward by `border_bits - 1`. `None` past the layout.
    pub fn bit_cell(&self, i: usize) -> Option<(i32, i32)> {
        let b = self.layout.get(i)?;
        let shift = i32::from(self.border_bits) - 1;
        Some((i32::from(b.x) + shift, i32::from(b.y) + shift))
    }
    /// The code of tag `id`, `None` past the table.
    pub fn code(&self, id: u16) -> Option<u64> {
        self.codes.get(usize::from(id))
    }
    /// AprilTag family or ArUco dictionary.
    pub fn kind(&self) -> Kind {
        self.kind
    }
    /// `true` for an ArUco dictionary.
    pub fn is_aruco(&self) -> bool {
        matches!(self.kind, Kind::Aruco { .. })
    }
    /// Most bits [`Self::decode`] corrects: chunks of the lookup less one (3 for the AprilTag
    /// families; for an ArUco dictionary at least OpenCV's `maxCorrectionBits`).
    pub fn max_correctable(&self) -> u8 {
        self.index.chunks.saturating_sub(1)
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
        if let Some(i) = (0..n).position(|i| self.bit_cell(i) == Some((x, y))) {
            return Some((code >> (n - 1 - i)) & 1 == 1);
        }
        // Not a payload cell: the border square `border_bits` wide (black; white when
        // reversed), a ring outside it (white; black when reversed, where the reversed
        // family's outer ring is) or, for normal families, cells inside the border that the
        // layout leaves out (none here).
        let depth = x.min(y).min(wab - 1 - x).min(wab - 1 - y);
        let on_border = (0..i32::from(self.border_bits)).contains(&depth);
        let inside = depth >= i32::from(self.border_bits);
        // Reversed (tagStandard41h12): only the detection ring is white. Normal: the quiet
        // zone around the border is white, the border and unused inner cells black.
        Some(if self.reversed_border {
            on_border
        } else {
            !(on_border || inside)
        })
    }

    /// Decodes a read word (module docs): of the codes within `max_hamming` bits of `rcode`
    /// in some rotation, the smallest id (OpenCV's `Dictionary::identify`), in its rotation of
    /// fewest differing bits. `max_hamming` above [`Self::max_correctable`] is treated as it.
    /// With `2 max_hamming < min_distance` the answer is unique.
    ///
    /// Work: for each of 4 rotations, the codes sharing one of the first `max_hamming + 1`
    /// chunk values with the word (about `4 (max_hamming + 1) stride / 2^chunk_bits` codes).
    #[doc(alias = "identify")]
    pub fn decode(&self, rcode: u64, max_hamming: u8) -> Option<Decoded> {
        let maxh = max_hamming.min(self.max_correctable());
        let probe = usize::from(maxh) + 1;
        let maxh = u32::from(maxh);
        let nbits = self.nbits();
        let bits = u32::from(self.index.chunk_bits);
        let cap = 1usize << bits.min(16);
        let mask = (cap - 1) as u64;
        let stride = usize::from(self.index.stride);
        let n = self.codes.len();
        let mut best: Option<Decoded> = None;
        let mut r = rcode;
        for rotation in 0..4u8 {
            for c in 0..probe {
                let v = ((r >> (c as u32 * bits).min(63)) & mask) as usize;
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
                    .get(c * stride + usize::from(start)..c * stride + usize::from(end))
                    .unwrap_or(&[]);
                for &id in ids {
                    // Ids ascend: past this family's codes, or past the best id, nothing
                    // better follows in this bucket.
                    if usize::from(id) >= n || best.is_some_and(|b| id > b.id) {
                        break;
                    }
                    let Some(code) = self.codes.get(usize::from(id)) else {
                        continue;
                    };
                    let hamming = (code ^ r).count_ones();
                    if hamming > maxh {
                        continue;
                    }
                    let better = match best {
                        None => true,
                        Some(b) => id < b.id || (id == b.id && hamming < u32::from(b.hamming)),
                    };
                    if better {
                        best = Some(Decoded {
                            id,
                            hamming: hamming as u8,
                            rotation,
                        });
                    }
                }
            }
            r = rotate90(r, nbits);
        }
        best
    }
}

impl PartialEq for Family {
    /// Families are the `static`s of [`super::families`]: the same family is the same name.
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Eq for Family {}
