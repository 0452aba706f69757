//! The detector's working memory: [`Workspace`], fixed-size buffers a board owns (in a
//! `static`), and [`WorkspaceView`], the same buffers as slices, which is what the detector
//! takes (so that its functions carry no buffer sizes, and buffers sized at run time serve as
//! well).

use super::label::Label;
use super::quad::Cluster;
use super::segment::{Run, tile_count};

/// Per-frame counts of a detection: what each stage found and what a capacity cut off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// Width of the image the per-pixel stages ran on (after decimation).
    pub width: u16,
    /// Height of that image.
    pub height: u16,
    /// Provisional component labels used (capacity `LABELS`).
    pub labels: u32,
    /// Pixels left out of every component because the labels ran out (0 when they sufficed).
    pub label_overflow: u32,
    /// Boundary points between large black and white components (all clusters).
    pub boundary_points: u32,
    /// Clusters (black/white component pairs with a common boundary) in the table.
    pub clusters: u32,
    /// Boundary points of clusters that found no table slot (0 when `CLUSTERS` sufficed).
    pub cluster_overflow: u32,
    /// Clusters with a plausible point count, handed to the quad fit.
    pub clusters_kept: u32,
    /// Boundary points of the kept clusters (what `POINTS` would hold in one batch).
    pub cluster_points: u32,
    /// Kept clusters left unfitted: the point batches (`max_batches` of `POINTS`) ran out.
    pub clusters_skipped: u32,
    /// Boundary scans that stored points (one per batch).
    pub batches: u32,
    /// Boundary points stored over all batches.
    pub points: u32,
    /// Quads fitted.
    pub quads: u32,
    /// Quads not decoded because `max_quads` was reached.
    pub quads_skipped: u32,
    /// Quad decodes that gave a tag (before duplicate removal).
    pub decoded: u32,
    /// Detections removed as duplicates of a better overlapping one (same family and id).
    pub duplicates: u32,
    /// Detections lost because the output was full (the weakest are dropped first).
    pub dropped: u32,
}

/// Working memory for frames whose decimated width is at most `W`:
///
/// | buffer | elements | bytes |
/// |---|---|---|
/// | tile thresholds | `TILES ≥ ⌊w/4⌋ ⌊h/4⌋` | 1 each |
/// | tile min/max ring | `2 W` | 1 each |
/// | runs of two rows | `2 W` | 8 |
/// | union-find parents, sizes | `LABELS` (≤ 65533) | 2 + 1 |
/// | cluster table | `CLUSTERS` (3/4 usable) | 32 |
/// | boundary points (one batch) | `POINTS` | 4 |
/// | sort keys (largest cluster) | `SORT` (≤ 65534) | 2 |
///
/// [`Workspace::BYTES`] is the total (the table's sum plus a few bytes of counts and padding).
/// `W`, `TILES`, `LABELS` and `SORT` must hold the frame (checked per frame:
/// [`crate::Error::BufferTooSmall`]); `CLUSTERS` and `POINTS` only limit how many candidates a
/// frame gets (counted in [`Stats`]). [`tiles_len`] and [`sort_len`] give `TILES` and `SORT`
/// for a frame size; [`Workspace320x240`] and [`Workspace640x480`] are measured choices.
///
/// The detector takes the buffers as a [`WorkspaceView`] ([`Workspace::as_mut_view`]).
pub struct Workspace<
    const W: usize,
    const TILES: usize,
    const LABELS: usize,
    const CLUSTERS: usize,
    const POINTS: usize,
    const SORT: usize,
> {
    pub(crate) tiles: [u8; TILES],
    pub(crate) ring_min: [u8; W],
    pub(crate) ring_max: [u8; W],
    pub(crate) runs: [[Run; W]; 2],
    pub(crate) parent: [u16; LABELS],
    pub(crate) size: [u8; LABELS],
    pub(crate) clusters: [Cluster; CLUSTERS],
    pub(crate) points: [u32; POINTS],
    pub(crate) keys: [u16; SORT],
    pub(crate) stats: Stats,
}

/// Tile count of a `width x height` frame at `decimate`: `⌊w/4⌋ ⌊h/4⌋` with
/// `w = ⌈width / decimate⌉` (the `TILES` a [`Workspace`] needs).
pub const fn tiles_len(width: usize, height: usize, decimate: usize) -> usize {
    let d = if decimate == 0 { 1 } else { decimate };
    tile_count(width.div_ceil(d), height.div_ceil(d))
}

/// Sort keys for a `width x height` frame at `decimate` (the `SORT` a [`Workspace`] needs to
/// fit the largest quads): the most points one cluster may have, twice the frame's perimeter,
/// `2 (2w + 2h)` (AprilTag's bound: a boundary point is counted about twice along an edge),
/// at most 65534 (clusters are counted in `u16`; the cap is reached only beyond
/// `w + h = 16383`, frames of [`super::segment::MAX_SIDE`] a side).
pub const fn sort_len(width: usize, height: usize, decimate: usize) -> usize {
    let d = if decimate == 0 { 1 } else { decimate };
    let n = 4 * (width.div_ceil(d) + height.div_ceil(d));
    if n > 65534 { 65534 } else { n }
}

impl<
    const W: usize,
    const TILES: usize,
    const LABELS: usize,
    const CLUSTERS: usize,
    const POINTS: usize,
    const SORT: usize,
> Workspace<W, TILES, LABELS, CLUSTERS, POINTS, SORT>
{
    /// Bytes of this workspace (`size_of`).
    pub const BYTES: usize = core::mem::size_of::<Self>();

    /// An empty workspace (`const`: it can initialise a `static`).
    pub const fn new() -> Self {
        Self {
            tiles: [0; TILES],
            ring_min: [0; W],
            ring_max: [0; W],
            runs: [[Run::EMPTY; W]; 2],
            parent: [0; LABELS],
            size: [0; LABELS],
            clusters: [Cluster::EMPTY; CLUSTERS],
            points: [0; POINTS],
            keys: [0; SORT],
            stats: Stats {
                width: 0,
                height: 0,
                labels: 0,
                label_overflow: 0,
                boundary_points: 0,
                clusters: 0,
                cluster_overflow: 0,
                clusters_kept: 0,
                cluster_points: 0,
                clusters_skipped: 0,
                batches: 0,
                points: 0,
                quads: 0,
                quads_skipped: 0,
                decoded: 0,
                duplicates: 0,
                dropped: 0,
            },
        }
    }

    /// The counts of the last detection.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Every buffer as a slice: what the detector takes.
    pub fn as_mut_view(&mut self) -> WorkspaceView<'_> {
        let [r0, r1] = &mut self.runs;
        WorkspaceView {
            tiles: &mut self.tiles,
            ring_min: &mut self.ring_min,
            ring_max: &mut self.ring_max,
            runs: [r0, r1],
            parent: &mut self.parent,
            size: &mut self.size,
            clusters: &mut self.clusters,
            points: &mut self.points,
            keys: &mut self.keys,
            stats: &mut self.stats,
        }
    }
}

impl<
    const W: usize,
    const TILES: usize,
    const LABELS: usize,
    const CLUSTERS: usize,
    const POINTS: usize,
    const SORT: usize,
> Default for Workspace<W, TILES, LABELS, CLUSTERS, POINTS, SORT>
{
    fn default() -> Self {
        Self::new()
    }
}

/// The detector's working memory as slices (the buffers of the [`Workspace`] table, of any
/// lengths): what [`super::Detector::detect`], [`super::Detector::detect_into`] and
/// [`super::Detector::find_target`] take. A board gets one from its `static` [`Workspace`]
/// ([`Workspace::as_mut_view`]); [`WorkspaceView::new`] makes one of buffers sized at run time
/// (a host's `Vec`s).
///
/// `L` is the label type ([`Label`]): `u16` (a [`Workspace`]'s: at most 65533 labels a frame)
/// or `u32` (2 more bytes a label, for frames whose noise and texture need more, such as a
/// host's 1920x1080 ones). Every buffer of label type takes it: `runs` (8 bytes a run with
/// `u16`, 12 with `u32`), `parent`, and `clusters` (keyed by a pair of labels).
pub struct WorkspaceView<'a, L: Label = u16> {
    pub(crate) tiles: &'a mut [u8],
    pub(crate) ring_min: &'a mut [u8],
    pub(crate) ring_max: &'a mut [u8],
    pub(crate) runs: [&'a mut [Run<L>]; 2],
    pub(crate) parent: &'a mut [L],
    pub(crate) size: &'a mut [u8],
    pub(crate) clusters: &'a mut [Cluster<L::Key>],
    pub(crate) points: &'a mut [u32],
    pub(crate) keys: &'a mut [u16],
    pub(crate) stats: &'a mut Stats,
}

impl<'a> WorkspaceView<'a> {
    /// A view of caller buffers with `u16` labels, one per row of the [`Workspace`] table:
    /// `tiles` (`TILES`), `ring_min` and `ring_max` (`W` each), the two rows of `runs` (`W`
    /// each), `parent` and `size` (`LABELS`: the shorter, at most 65533, is the label
    /// capacity), `clusters`, `points`, `keys` (`SORT`), and the counts `stats`. The lengths
    /// are checked against each frame ([`crate::Error::BufferTooSmall`]), as a
    /// [`Workspace`]'s are. [`WorkspaceView::with_labels`] takes any label type.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        tiles: &'a mut [u8],
        ring_min: &'a mut [u8],
        ring_max: &'a mut [u8],
        runs: [&'a mut [Run]; 2],
        parent: &'a mut [u16],
        size: &'a mut [u8],
        clusters: &'a mut [Cluster],
        points: &'a mut [u32],
        keys: &'a mut [u16],
        stats: &'a mut Stats,
    ) -> Self {
        Self::with_labels(
            tiles, ring_min, ring_max, runs, parent, size, clusters, points, keys, stats,
        )
    }
}

impl<'a, L: Label> WorkspaceView<'a, L> {
    /// [`WorkspaceView::new`] with labels of type `L` ([`Label`]): `parent` and `size` hold
    /// at most [`Label::MAX_LABELS`] labels, `runs` and `clusters` are of the same type. A host
    /// sizes the buffers for each frame ([`tiles_len`], [`sort_len`], `W` = the decimated
    /// width) and picks `u32` when a frame may need more than 65533 labels.
    #[allow(clippy::too_many_arguments)]
    pub fn with_labels(
        tiles: &'a mut [u8],
        ring_min: &'a mut [u8],
        ring_max: &'a mut [u8],
        runs: [&'a mut [Run<L>]; 2],
        parent: &'a mut [L],
        size: &'a mut [u8],
        clusters: &'a mut [Cluster<L::Key>],
        points: &'a mut [u32],
        keys: &'a mut [u16],
        stats: &'a mut Stats,
    ) -> Self {
        Self {
            tiles,
            ring_min,
            ring_max,
            runs,
            parent,
            size,
            clusters,
            points,
            keys,
            stats,
        }
    }

    /// The counts of the last detection.
    pub fn stats(&self) -> &Stats {
        self.stats
    }

    /// Provisional labels a frame may use: `min(parent, size, L::MAX_LABELS)`.
    pub(crate) fn labels_len(&self) -> usize {
        self.parent.len().min(self.size.len()).min(L::MAX_LABELS)
    }
}

/// For 320x240 frames at decimation 1 (and 640x480 at 2): 4800 tiles, 8192 labels, 512
/// cluster slots, 16384 points a batch, clusters of up to 2240 points. Sized on the bundled
/// 320x240 recordings and the rendered stills (at most 4230 labels, 151 clusters and 17300
/// kept points a frame, textured and noisy ones included).
pub type Workspace320x240 =
    Workspace<320, { tiles_len(320, 240, 1) }, 8192, 512, 16384, { sort_len(320, 240, 1) }>;

/// For 640x480 frames at decimation 1: 19200 tiles, 24576 labels, 1024 cluster slots,
/// 32768 points a batch, clusters of up to 4480 points.
pub type Workspace640x480 =
    Workspace<640, { tiles_len(640, 480, 1) }, 24576, 1024, 32768, { sort_len(640, 480, 1) }>;
