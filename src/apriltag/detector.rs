//! The detector: configuration validated once, the per-frame pipeline, the detections.

use heapless::Vec;
use nalgebra::{Matrix3, Point2};

use super::decode::{read_code, refine_edges};
use super::family::{Family, Kind, MAX_CORRECTABLE};
use super::geom::{at4, project};
use super::label::{ClusterKey, Label};
use super::quad::Cluster;
use super::quad::{MAX_NMAXIMA, NOT_IN_BATCH, Quad, QuadParams, Table, fit_quad};
use super::segment::{
    PairPoints, Rows, Sampled, Sink, boundary_scan, boundary_scan_cached, build_tiles,
    cache_rows_end, label_pass, mark_small, pack, tile_count,
};
use super::workspace::{Stats, WorkspaceView};
use crate::homography::Homography;
use crate::image::ImageView;
use crate::probe::StageProbe;
use crate::{Error, Result};

/// Most families one detector decodes.
pub const MAX_FAMILIES: usize = 4;

/// Parameters of a [`Detector`] (AprilTag's `apriltag_detector_t` fields where they exist;
/// its defaults unless said).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectorConfig {
    /// Quads are searched on the frame point-sampled every `decimate` pixels (1..=8; AprilTag's
    /// integer `quad_decimate`); decoding and edge refinement use the full frame. Default 1
    /// (AprilTag's is 2): boards run small frames where tags are a few dozen pixels.
    pub decimate: u8,
    /// Snap the quad's edges to the strongest nearby gradient in the full frame (default on).
    pub refine_edges: bool,
    /// Sharpening of the payload readings (`v + s ∇²v`, default 0.25).
    pub decode_sharpening: f32,
    /// Bits corrected (default 2, at most 3 and below half the smallest family distance).
    /// tag16h5's 30 codes of 16 bits at distance 5 leave a random quad within 2 bits of a
    /// code too often: on 231 tag-free frames (BENCHMARKS, "False positives") it finds 32
    /// "tags" at 2 bits (AprilTag 3: 114) and none at 0; use 0 with tag16h5. The other
    /// families find none at 2.
    pub max_hamming: u8,
    /// Tiles whose dilated `max - min` is below this are skipped (default 5, at least 1).
    pub min_white_black_diff: u8,
    /// Where a pixel turns black between its tile neighbourhood's min and max: black when
    /// `v ≤ min + ⌊(max - min) f⌋` (default `1/2`, AprilTag's). In `[1/8, 7/8]`, read in
    /// 1/256 steps. Below `1/2` a mid-grey pixel reads white: black areas that touch only at
    /// a corner (Kalibr's AprilGrid, a tag's corner meeting a square's, where a pixel on the
    /// junction reads about half way) stay apart, as OpenCV's adaptive threshold keeps them
    /// (black only `C = 7` grey levels below the local mean); at `1/2` such a pixel joins
    /// the two in about half the junctions and the tag's outline is lost. The quad's edges
    /// are refined on the image, not on the threshold: the corners do not move with it.
    pub threshold_fraction: f32,
    /// Clusters with fewer boundary points are ignored (default 24).
    pub min_cluster_pixels: u16,
    /// Corner candidates kept per cluster (default 10, 4..=12).
    pub max_nmaxima: u8,
    /// Quads with a corner closer than this to straight (or to a fold), in degrees, are
    /// rejected (default 10; AprilTag's `cos_critical_rad = cos(10°)`), in `(0, 45)`.
    pub critical_angle_deg: f32,
    /// Largest mean squared distance of a side's boundary points to its line, pixels²
    /// (default 10).
    pub max_line_fit_mse: f32,
    /// Decodes with a smaller decision margin are dropped (default 0: AprilTag keeps every
    /// margin `≥ 0` and leaves filtering to the caller).
    pub min_decision_margin: f32,
    /// Clusters whose boundary has a mean gradient `|∇I| + 1` (3-tap central differences, grey
    /// levels) below this are not fitted (default 15; 0: AprilTag, which fits every cluster).
    /// Over the bundled photos, stills and sequence every decoded tag had a mean above 66,
    /// while half of all clusters (texture and noise) are below 13: the fit's work halves.
    pub min_edge_gradient: u8,
    /// Drop a tag whose quiet zone (the ring of cells just outside the detection border) is not
    /// entirely inside the frame (default on). Such a tag is cut by the frame edge or touches
    /// it; its outermost edge may not be seen, and a corner fitted to what is seen can be
    /// pixels off. AprilTag keeps them (off: the same).
    pub reject_clipped: bool,
    /// Point batches per frame (default 2; each is one more scan of the frame).
    pub max_batches: u8,
    /// Quads decoded per frame at most (default 256; each costs an edge refinement and a
    /// decode per family).
    pub max_quads: u16,
    /// ArUco dictionaries: a marker is dropped when more than
    /// `⌊markerSize² · rate⌋` of its border cells read white (OpenCV's
    /// `maxErroneousBitsInBorderRate`, default 0.35: 5 of the 20 border cells of a 4x4
    /// marker, 12 of the 28 of a 6x6). In `[0, 1]`. AprilTag families do not use it.
    #[doc(alias = "maxErroneousBitsInBorderRate")]
    pub max_erroneous_bits_in_border_rate: f64,
    /// ArUco dictionaries: bits corrected, `⌊maxCorrectionBits · rate⌋` (OpenCV's
    /// `errorCorrectionRate`, default 0.6: 3 bits for DICT_6X6_250, 0 for DICT_4X4_50 and
    /// DICT_ARUCO_ORIGINAL). In `[0, 1]`; of the codes within the bound, the smallest id is
    /// taken (OpenCV's `Dictionary::identify`). AprilTag families use
    /// [`Self::max_hamming`] instead.
    #[doc(alias = "errorCorrectionRate")]
    pub error_correction_rate: f64,
    /// ArUco dictionaries: a marker whose white quiet zone is less than this many grey
    /// levels brighter than its black border (the two intensity models at its centre) is
    /// dropped (default 32, an eighth of the 8-bit range; 0 keeps every one). A printed
    /// marker's border and quiet zone are ink and paper, far apart in any usable exposure
    /// (the rendered bench's detections: 47 and more); low-contrast texture is not, and
    /// DICT_4X4's codes (a random 16-bit word matches one of DICT_4X4_1000's in some
    /// rotation with chance 6 %) would otherwise find "markers" in it: on the 231 tag-free
    /// real frames, 5 at 0, all below 24 (OpenCV's adaptive threshold, 7 grey levels below
    /// the local mean, does not propose such candidates). AprilTag families do not use it.
    pub min_marker_contrast: u8,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            decimate: 1,
            refine_edges: true,
            decode_sharpening: 0.25,
            max_hamming: 2,
            min_white_black_diff: 5,
            threshold_fraction: 0.5,
            min_cluster_pixels: 24,
            max_nmaxima: 10,
            critical_angle_deg: 10.0,
            max_line_fit_mse: 10.0,
            min_decision_margin: 0.0,
            min_edge_gradient: 15,
            reject_clipped: true,
            max_batches: 2,
            max_quads: 256,
            max_erroneous_bits_in_border_rate: 0.35,
            error_correction_rate: 0.6,
            min_marker_contrast: 32,
        }
    }
}

/// One detected tag.
///
/// Coordinates are camgeom's (pixel `(i, j)` centred at `(i, j)`, as OpenCV's): AprilTag
/// reports the same points plus [`APRILTAG_PIXEL_OFFSET`] in x and y.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Detection {
    /// The family decoded.
    pub family: &'static Family,
    /// Tag id in the family.
    pub id: u16,
    /// Bits corrected.
    pub hamming: u8,
    /// Mean distance of the payload readings from their threshold (intensity units): how
    /// clearly the bits were read.
    pub decision_margin: f32,
    /// The border's outer corners in AprilTag's order: tag coordinates `(-1, 1)`, `(1, 1)`,
    /// `(1, -1)`, `(-1, -1)`, i.e. bottom-left, bottom-right, top-right, top-left of the
    /// upright tag image (counter-clockwise on screen).
    pub corners: [Point2<f32>; 4],
    /// The tag centre, `H (0, 0)`.
    pub center: Point2<f32>,
    /// `H`: tag coordinates (`(-1, -1)` top-left .. `(1, 1)` bottom-right of the border,
    /// `y` down the upright tag) to pixels (AprilTag's `H`, up to scale and the half-pixel).
    pub homography: Homography<f32>,
}

/// What AprilTag's coordinates add to camgeom's: its pixel centres are at `i + 0.5`.
pub const APRILTAG_PIXEL_OFFSET: f32 = 0.5;

/// The corner order of [`Detection::corners`] in tag coordinates.
pub const CORNER_TAG_COORDS: [(f32, f32); 4] = [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)];

impl Detection {
    /// The corners in a planar target's order `(0, 0), (w, 0), (w, h), (0, h)`: the tag's
    /// top-left, top-right, bottom-right, bottom-left (AprilTag corners 3, 2, 1, 0). The
    /// target's frame then has AprilTag's tag axes (`x` right, `y` down the upright tag, `z`
    /// into it) with its origin at the top-left corner: for a tag of side `s`,
    /// `t_target = t_tag - R (s/2, s/2, 0)` and the same `R`.
    pub fn target_corners(&self) -> [Point2<f32>; 4] {
        let c = self.corners;
        [c[3], c[2], c[1], c[0]]
    }

    /// The corners in OpenCV's `detectMarkers` order for an ArUco dictionary: the marker's
    /// top-left (as `generateImageMarker` draws it), top-right, bottom-right, bottom-left,
    /// clockwise on screen; tag coordinates `(-1, -1)`, `(1, -1)`, `(1, 1)`, `(-1, 1)`. The
    /// pixel convention is already OpenCV's. (The same points as [`Self::target_corners`].)
    #[doc(alias = "detectMarkers")]
    pub fn aruco_corners(&self) -> [Point2<f32>; 4] {
        self.target_corners()
    }
}

/// The stages of a detection, in the order they first run: what a
/// [`StageProbe`]`<Stage>` given to [`Detector::detect_into`] is told (the per-quad stages
/// repeat, interleaved).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// Tile min/max, dilation, thresholds (one pass over the frame).
    Threshold,
    /// Connected components (one pass).
    Components,
    /// Boundary clusters counted (one pass).
    Clusters,
    /// Boundary points stored (one pass a batch).
    Points,
    /// One cluster's quad fit.
    QuadFit,
    /// One quad's edge refinement.
    Refine,
    /// One quad's decoding (all families).
    Decode,
    /// Ordering the detections.
    Reconcile,
}

/// A validated detector: configuration and families. Keeps no per-frame state (that is the
/// [`WorkspaceView`]'s), so one detector serves any number of workspaces.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[doc(alias = "ArucoDetector")]
pub struct Detector {
    cfg: DetectorConfig,
    families: Vec<&'static Family, MAX_FAMILIES>,
    /// Per family (same order): the bits corrected and the border cells that may read white.
    limits: Vec<Limits, MAX_FAMILIES>,
    cos_critical: f32,
}

/// What a detector accepts from one family's reading.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct Limits {
    /// Bits corrected.
    pub(crate) max_hamming: u8,
    /// Border cells read white (ArUco), at most.
    pub(crate) max_border_errors: u16,
    /// Quiet zone over border, grey levels (ArUco), at least.
    pub(crate) min_contrast: f32,
}

impl Detector {
    /// Checks `cfg` against `families` (1..=[`MAX_FAMILIES`], decoded in this order; AprilTag
    /// families and ArUco dictionaries may be mixed).
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field (`"families"`, `"decimate"`,
    /// `"max_hamming"` (above [`MAX_CORRECTABLE`] or not below half an AprilTag family's
    /// distance), `"error_correction_rate"` and `"max_erroneous_bits_in_border_rate"` (not in
    /// `[0, 1]`), `"min_white_black_diff"`, `"max_nmaxima"`, `"critical_angle_deg"`,
    /// `"max_line_fit_mse"`, `"decode_sharpening"`, `"min_decision_margin"`, `"max_batches"`,
    /// `"threshold_fraction"`).
    #[doc(alias = "ArucoDetector")]
    pub fn new(cfg: DetectorConfig, families: &[&'static Family]) -> Result<Self> {
        if families.is_empty() || families.len() > MAX_FAMILIES {
            return Err(Error::InvalidParameter("families"));
        }
        if !(0.0..=1.0).contains(&cfg.error_correction_rate) {
            return Err(Error::InvalidParameter("error_correction_rate"));
        }
        if !(0.0..=1.0).contains(&cfg.max_erroneous_bits_in_border_rate) {
            return Err(Error::InvalidParameter("max_erroneous_bits_in_border_rate"));
        }
        let mut fams = Vec::new();
        let mut limits = Vec::new();
        for &f in families {
            if f.total_width as usize > super::decode::MAX_TOTAL_WIDTH || f.width_at_border < 3 {
                return Err(Error::InvalidParameter("families"));
            }
            let lim = match f.kind {
                Kind::AprilTag => {
                    if 2 * u32::from(cfg.max_hamming) >= u32::from(f.min_distance) {
                        return Err(Error::InvalidParameter("max_hamming"));
                    }
                    Limits {
                        max_hamming: cfg.max_hamming,
                        max_border_errors: u16::MAX,
                        min_contrast: f32::NEG_INFINITY,
                    }
                }
                // OpenCV's int(double(maxCorrectionBits) * rate) and
                // int(markerSize * markerSize * rate), both rates in [0, 1].
                Kind::Aruco {
                    max_correction_bits,
                } => {
                    let n = f64::from(f.width_at_border.saturating_sub(2));
                    Limits {
                        max_hamming: (f64::from(max_correction_bits) * cfg.error_correction_rate)
                            as u8,
                        max_border_errors: (n * n * cfg.max_erroneous_bits_in_border_rate) as u16,
                        min_contrast: f32::from(cfg.min_marker_contrast),
                    }
                }
            };
            fams.push(f)
                .map_err(|_| Error::InvalidParameter("families"))?;
            limits
                .push(lim)
                .map_err(|_| Error::InvalidParameter("families"))?;
        }
        if !(1..=8).contains(&cfg.decimate) {
            return Err(Error::InvalidParameter("decimate"));
        }
        if cfg.max_hamming > MAX_CORRECTABLE {
            return Err(Error::InvalidParameter("max_hamming"));
        }
        if cfg.min_white_black_diff == 0 {
            return Err(Error::InvalidParameter("min_white_black_diff"));
        }
        if !(0.125..=0.875).contains(&cfg.threshold_fraction) {
            return Err(Error::InvalidParameter("threshold_fraction"));
        }
        if !(4..=MAX_NMAXIMA as u8).contains(&cfg.max_nmaxima) {
            return Err(Error::InvalidParameter("max_nmaxima"));
        }
        if !(cfg.critical_angle_deg > 0.0 && cfg.critical_angle_deg < 45.0) {
            return Err(Error::InvalidParameter("critical_angle_deg"));
        }
        if !(cfg.max_line_fit_mse > 0.0 && cfg.max_line_fit_mse.is_finite()) {
            return Err(Error::InvalidParameter("max_line_fit_mse"));
        }
        if !(cfg.decode_sharpening >= 0.0 && cfg.decode_sharpening <= 4.0) {
            return Err(Error::InvalidParameter("decode_sharpening"));
        }
        if !cfg.min_decision_margin.is_finite() {
            return Err(Error::InvalidParameter("min_decision_margin"));
        }
        if cfg.max_batches == 0 {
            return Err(Error::InvalidParameter("max_batches"));
        }
        let cos_critical = libm::cosf(cfg.critical_angle_deg.to_radians());
        Ok(Self {
            cfg,
            families: fams,
            limits,
            cos_critical,
        })
    }

    /// Bits corrected for `family`: [`DetectorConfig::max_hamming`] for an AprilTag family,
    /// `⌊max_correction_bits · error_correction_rate⌋` (OpenCV's) for an ArUco dictionary of
    /// the detector (for one it does not decode, `max_hamming`).
    pub fn max_hamming_for(&self, family: &Family) -> u8 {
        self.limits(family).max_hamming
    }

    /// The bits corrected and border errors allowed for `family` (one of the detector's; the
    /// configuration's AprilTag bound otherwise).
    pub(crate) fn limits(&self, family: &Family) -> Limits {
        self.families
            .iter()
            .zip(self.limits.iter())
            .find(|(f, _)| **f == family)
            .map(|(_, l)| *l)
            .unwrap_or(Limits {
                max_hamming: self.cfg.max_hamming,
                max_border_errors: u16::MAX,
                min_contrast: f32::NEG_INFINITY,
            })
    }

    /// The configuration.
    pub fn config(&self) -> &DetectorConfig {
        &self.cfg
    }

    /// The families decoded.
    pub fn families(&self) -> &[&'static Family] {
        &self.families
    }

    /// Detects the tags of the detector's families in `frame`, sorted by id; at most `N`
    /// (when more are found, those with the largest Hamming distance and then the smallest
    /// margin are dropped, counted in [`Stats::dropped`]).
    ///
    /// The workspace's label type ([`Label`]: `u16` or `u32`) is the caller's choice; the
    /// detections are the same when neither runs out of labels ([`Stats::label_overflow`]).
    ///
    /// Any [`ImageView`] (at most [`crate::image::MAX_DIM`] = 8192 pixels a side) is taken:
    /// the boundary points' 14-bit coordinates ([`super::MAX_SIDE`]) hold it.
    ///
    /// Errors: [`Error::BufferTooSmall`] naming the workspace buffer that cannot hold this frame
    /// (`"workspace.width"`, `"workspace.tiles"`, `"workspace.labels"`: at least one,
    /// `"workspace.sort"`). Frames smaller than 8x8 after decimation give no detection.
    #[doc(alias = "detectMarkers")]
    pub fn detect<const N: usize>(
        &self,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, impl Label>,
    ) -> Result<Vec<Detection, N>> {
        let mut out = Vec::new();
        self.detect_into(frame, ws, &mut (), |_, _| true, &mut out)?;
        Ok(out)
    }

    /// [`Self::detect`] into `out` (cleared first), keeping only tags for which
    /// `keep(family, id)` holds (the others are decoded but never compete for `out`), with
    /// `probe` told as each stage ends.
    pub fn detect_into<const N: usize>(
        &self,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, impl Label>,
        probe: &mut impl StageProbe<Stage>,
        keep: impl Fn(&Family, u16) -> bool,
        out: &mut Vec<Detection, N>,
    ) -> Result<()> {
        out.clear();
        self.run(frame, ws, probe, &keep, &mut |det, stats| {
            merge(out, det, stats)
        })?;
        probe.stage_done(Stage::Reconcile);
        crate::corners::heapsort_by(out, |a, b| {
            (a.id, a.family.name)
                .cmp(&(b.id, b.family.name))
                .then(order_corners(a, b))
        });
        Ok(())
    }

    /// The four corners of tag `id` of `family` in a planar target's order (see
    /// [`Detection::target_corners`]): the acquisition of a target from a frame. `None` when
    /// the tag is not found (the best of several copies is taken).
    pub fn find_target(
        &self,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, impl Label>,
        family: &Family,
        id: u16,
    ) -> Result<Option<[Point2<f32>; 4]>> {
        let mut out: Vec<Detection, 1> = Vec::new();
        self.detect_into(frame, ws, &mut (), |f, i| f == family && i == id, &mut out)?;
        Ok(out.first().map(Detection::target_corners))
    }

    fn run<L: Label>(
        &self,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, L>,
        probe: &mut impl StageProbe<Stage>,
        keep: &impl Fn(&Family, u16) -> bool,
        sink: &mut impl FnMut(Detection, &mut Stats),
    ) -> Result<()> {
        let d = usize::from(self.cfg.decimate);
        let src = Sampled::new(*frame, d);
        *ws.stats = Stats {
            width: src.w as u16,
            height: src.h as u16,
            ..Stats::default()
        };
        if src.w < 8 || src.h < 8 {
            return Ok(());
        }
        if ws.runs.iter().any(|r| r.len() < src.w)
            || ws.ring_min.len() < src.w
            || ws.ring_max.len() < src.w
        {
            return Err(Error::BufferTooSmall("workspace.width"));
        }
        if ws.tiles.len() < tile_count(src.w, src.h) {
            return Err(Error::BufferTooSmall("workspace.tiles"));
        }
        let labels = ws.labels_len();
        if labels == 0 {
            return Err(Error::BufferTooSmall("workspace.labels"));
        }
        if ws.keys.len() < usize::from(self.cfg.min_cluster_pixels).max(24) {
            return Err(Error::BufferTooSmall("workspace.sort"));
        }
        let tiles = build_tiles(
            &src,
            self.cfg.min_white_black_diff,
            (self.cfg.threshold_fraction * 256.0) as u8,
            ws.tiles,
            ws.ring_min,
            ws.ring_max,
        );
        probe.stage_done(Stage::Threshold);
        let [r0, r1] = &mut ws.runs;
        let mut rows = Rows {
            runs: [&mut **r0, &mut **r1],
        };
        let parent = ws.parent.get_mut(..labels).unwrap_or(&mut []);
        let size = ws.size.get_mut(..labels).unwrap_or(&mut []);
        // The run cache goes at the end of the point buffer (segment docs).
        let lab = label_pass(&src, &tiles, &mut rows, parent, size, ws.points);
        ws.stats.labels = lab.labels as u32;
        ws.stats.label_overflow = lab.exhausted;
        probe.stage_done(Stage::Components);

        // Small components marked once: the counting scan then reads one label a run.
        mark_small(parent.get_mut(..lab.labels).unwrap_or(&mut []), size);

        let mut table = Table::new(ws.clusters);
        let mut counter = Counter {
            table: &mut table,
            emitted: 0,
        };
        let mut cache_at = lab.cached;
        match cache_at {
            Some(at) => boundary_scan_cached::<_, true>(
                ws.points,
                at,
                (src.w, src.h),
                (0, src.h),
                &mut rows,
                parent,
                size,
                &mut counter,
            ),
            None => boundary_scan(
                &src,
                &tiles,
                &mut rows,
                parent,
                size,
                lab.labels,
                ws.points,
                &mut counter,
            ),
        }
        // The batches' points fill the point buffer from its start; one that reaches the run
        // cache at its end ends the cache.
        let emitted = counter.emitted;
        ws.stats.boundary_points = emitted;
        ws.stats.clusters = table.used as u32;
        ws.stats.cluster_overflow = table.dropped;
        probe.stage_done(Stage::Clusters);

        // Clusters worth a fit (point count, closed, of a wanted border kind); the others are
        // marked done (n = 0).
        let max_pts = (4 * (src.w + src.h))
            .min(ws.keys.len())
            .min(ws.points.len())
            .min(65534);
        let min_pts = usize::from(self.cfg.min_cluster_pixels);
        let (normal, reversed) = (
            self.families.iter().any(|f| !f.reversed_border),
            self.families.iter().any(|f| f.reversed_border),
        );
        for c in table.slots.iter_mut() {
            let n = usize::from(c.n);
            let wanted = c.key != L::Key::EMPTY
                && match c.shape() {
                    Some(rev) => (rev && reversed) || (!rev && normal),
                    None => false,
                };
            if c.key == L::Key::EMPTY || n < min_pts || n > max_pts || !wanted {
                c.n = 0;
            } else {
                ws.stats.clusters_kept += 1;
                ws.stats.cluster_points += n as u32;
            }
        }

        let min_width = self
            .families
            .iter()
            .map(|f| u32::from(f.width_at_border))
            .min()
            .unwrap_or(3);
        let prm = QuadParams {
            max_nmaxima: usize::from(self.cfg.max_nmaxima),
            max_line_fit_mse: self.cfg.max_line_fit_mse,
            cos_critical: self.cos_critical,
            min_tag_width: (min_width / (d as u32).max(1)).max(3),
            normal_border: normal,
            reversed_border: reversed,
            min_edge_gradient: u32::from(self.cfg.min_edge_gradient),
        };
        let mut cursor = 0usize;
        let mut quads = 0u32;
        for _ in 0..self.cfg.max_batches {
            // Assign point ranges to the next clusters that fit.
            let mut offset = 0usize;
            let mut any = false;
            while let Some(c) = table.slots.get_mut(cursor) {
                let n = usize::from(c.n);
                if n > 0 {
                    if offset + n > ws.points.len() {
                        break;
                    }
                    c.start = offset as u32;
                    c.fill = 0;
                    offset += n;
                    any = true;
                }
                cursor += 1;
            }
            if !any {
                break;
            }
            ws.stats.batches += 1;
            // Only the components of this batch's clusters make points now: their `size` (no
            // longer needed as a count) becomes the flag the scan tests.
            size.iter_mut().for_each(|s| *s = 0);
            for c in table.slots.iter() {
                if c.start != NOT_IN_BATCH {
                    let (b, w) = L::halves(c.key);
                    for r in [b, w] {
                        if let Some(s) = size.get_mut(r) {
                            *s = u8::MAX;
                        }
                    }
                }
            }
            // The rows of the batch's points (bounding boxes in doubled coordinates).
            let (ylo, yhi) = table.slots.iter().filter(|c| c.start != NOT_IN_BATCH).fold(
                (usize::MAX, 0),
                |(lo, hi), c| {
                    (
                        lo.min(usize::from(c.ymin) / 2),
                        hi.max(usize::from(c.ymax) / 2),
                    )
                },
            );
            // The points fill the buffer below the run cache. When they do not all fit there
            // and no later batch reads the cache, a cluster may take words of the cache's
            // rows that the scan has read before it sends the cluster's first point (rows
            // up to one below the cluster's top row), from the buffer's end down.
            let mut low = offset;
            if let Some(at) = cache_at
                && offset > at
                && table.slots.get(cursor).is_none()
            {
                (low, _) = place_over_cache(table.slots, ws.points, at);
            }
            let cached = cache_at.filter(|&at| low <= at);
            if cached.is_none() {
                cache_at = None;
            }
            let mut filler = Filler { table: &mut table };
            match cached {
                Some(at) => boundary_scan_cached::<_, false>(
                    ws.points,
                    at,
                    (src.w, src.h),
                    (ylo, yhi),
                    &mut rows,
                    parent,
                    size,
                    &mut filler,
                ),
                None => boundary_scan(
                    &src,
                    &tiles,
                    &mut rows,
                    parent,
                    size,
                    lab.labels,
                    ws.points,
                    &mut filler,
                ),
            }
            ws.stats.points += offset as u32;
            probe.stage_done(Stage::Points);
            for c in table.slots.iter_mut() {
                if c.start == NOT_IN_BATCH {
                    continue;
                }
                let (start, fill) = (c.start as usize, usize::from(c.fill));
                c.start = NOT_IN_BATCH;
                c.n = 0;
                let Some(pts) = ws.points.get_mut(start..start + fill) else {
                    continue;
                };
                let fitted = fit_quad(
                    &src,
                    pts,
                    ws.keys,
                    (c.xmin, c.xmax, c.ymin, c.ymax),
                    c.dot() < 0,
                    &prm,
                );
                probe.stage_done(Stage::QuadFit);
                let Some(mut q) = fitted else {
                    continue;
                };
                ws.stats.quads += 1;
                if quads >= u32::from(self.cfg.max_quads) {
                    ws.stats.quads_skipped += 1;
                    continue;
                }
                quads += 1;
                if d > 1 {
                    for p in q.p.iter_mut() {
                        *p = Point2::new(p.x * d as f32, p.y * d as f32);
                    }
                }
                if self.cfg.refine_edges {
                    refine_edges(frame, &mut q, d);
                    probe.stage_done(Stage::Refine);
                }
                self.decode_quad(frame, &q, keep, ws.stats, sink);
                probe.stage_done(Stage::Decode);
            }
        }
        ws.stats.clusters_skipped = table.slots.iter().filter(|c| c.n > 0).count() as u32;
        Ok(())
    }

    /// Decodes one quad with every family of its border kind, handing each tag to `sink`.
    fn decode_quad(
        &self,
        frame: &ImageView<'_, u8>,
        q: &Quad,
        keep: &impl Fn(&Family, u16) -> bool,
        stats: &mut Stats,
        sink: &mut impl FnMut(Detection, &mut Stats),
    ) {
        let tag = [
            Point2::new(-1.0, -1.0),
            Point2::new(1.0, -1.0),
            Point2::new(1.0, 1.0),
            Point2::new(-1.0, 1.0),
        ];
        let Ok(h) = Homography::from_four_points(&tag, &q.p) else {
            return;
        };
        for (&family, lim) in self.families.iter().zip(self.limits.iter()) {
            if family.reversed_border != q.reversed_border {
                continue;
            }
            let Some(reading) = read_code(frame, h.matrix(), family, self.cfg.decode_sharpening)
            else {
                continue;
            };
            if reading.border_errors > lim.max_border_errors
                || !crate::scalar::at_most(lim.min_contrast, reading.contrast)
            {
                continue;
            }
            if self.cfg.reject_clipped && !reading.ring_in_view {
                continue;
            }
            let (rcode, margin) = (reading.rcode, reading.margin);
            if !crate::scalar::at_most(self.cfg.min_decision_margin.max(0.0), margin) {
                continue;
            }
            // A border wider than a cell: its inner rings are known bits, corrected within
            // the same bound as the payload's (`border_errors` is 0 for other AprilTag
            // families; an ArUco dictionary's is bounded on its own above).
            let inner = if family.is_aruco() {
                0
            } else {
                reading.border_errors
            };
            let Some(budget) = u16::from(lim.max_hamming).checked_sub(inner) else {
                continue;
            };
            let Some(mut dec) = family.decode(rcode, budget as u8) else {
                continue;
            };
            dec.hamming = dec.hamming.saturating_add(inner as u8);
            if !keep(family, dec.id) {
                continue;
            }
            // H R(rotation · 90°) (AprilTag's orientation fix), exact in quarter turns.
            let (c, s) = match dec.rotation & 3 {
                0 => (1.0, 0.0),
                1 => (0.0, 1.0),
                2 => (-1.0, 0.0),
                _ => (0.0, -1.0),
            };
            let r = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
            let Ok(hd) = Homography::from_matrix(&(h.matrix() * r)) else {
                continue;
            };
            let m = *hd.matrix();
            let mut corners = [Point2::origin(); 4];
            let mut ok = true;
            for (p, &(x, y)) in corners.iter_mut().zip(CORNER_TAG_COORDS.iter()) {
                match project(&m, x, y) {
                    Some(v) => *p = v,
                    None => ok = false,
                }
            }
            let Some(center) = project(&m, 0.0, 0.0) else {
                continue;
            };
            if !ok {
                continue;
            }
            stats.decoded += 1;
            sink(
                Detection {
                    family,
                    id: dec.id,
                    hamming: dec.hamming,
                    decision_margin: margin,
                    corners,
                    center,
                    homography: hd,
                },
                stats,
            );
        }
    }
}

/// The counting scan's sink: every run of points into its cluster of the table, as it comes
/// (the table remembers the last cluster's slot: consecutive points mostly share it).
struct Counter<'t, 'a, K: ClusterKey> {
    table: &'t mut Table<'a, K>,
    emitted: u32,
}

impl<K: ClusterKey> Sink<K> for Counter<'_, '_, K> {
    // Always into the scan, as when the scan was not generic over the label type (the board's
    // code is unchanged by it).
    #[inline(always)]
    fn run(&mut self, _: &mut [u32], key: K, x2: usize, y2: usize, count: usize, gx: i32, gy: i32) {
        let m = count.min(usize::from(u16::MAX)) as u16;
        self.table.add_run(key, x2 as u16, y2 as u16, m, gx, gy);
        // A frame has fewer than 4 MAX_SIDE² < 2^28 boundary points: the sum cannot wrap.
        self.emitted = self.emitted.wrapping_add(count as u32);
    }

    #[inline(always)]
    fn point(&mut self, buf: &mut [u32], key: K, x2: usize, y2: usize, gx: i32, gy: i32) {
        self.run(buf, key, x2, y2, 1, gx, gy);
    }

    #[inline(always)]
    fn pair(&mut self, _: &mut [u32], key: K, p: &PairPoints) {
        self.table.add_pair(key, p);
        self.emitted = self.emitted.wrapping_add(p.count() as u32);
    }
}

/// The storing scan's sink: the points of the clusters of the batch into their ranges of the
/// scan's buffer.
struct Filler<'t, 'a, K: ClusterKey> {
    table: &'t mut Table<'a, K>,
}

/// Stores `count` points `(x2 + 2i, y2)` with direction `(gx, gy)` into cluster `c`'s range
/// of `points`, as far as its count leaves room.
#[inline(always)]
fn store<K>(
    c: &mut Cluster<K>,
    points: &mut [u32],
    (x2, y2): (usize, usize),
    count: usize,
    (gx, gy): (i32, i32),
) {
    let room = usize::from(c.n.saturating_sub(c.fill)).min(count);
    let at = c.start as usize + usize::from(c.fill);
    if let Some(out) = points.get_mut(at..at + room) {
        for (i, p) in out.iter_mut().enumerate() {
            *p = pack(x2 + 2 * i, y2, gx, gy);
        }
        c.fill += room as u16;
    }
}

impl<K: ClusterKey> Sink<K> for Filler<'_, '_, K> {
    #[inline]
    fn run(
        &mut self,
        buf: &mut [u32],
        key: K,
        x2: usize,
        y2: usize,
        count: usize,
        gx: i32,
        gy: i32,
    ) {
        let Some(c) = self.table.get_mut(key) else {
            return;
        };
        if c.start == NOT_IN_BATCH {
            return;
        }
        store(c, buf, (x2, y2), count, (gx, gy));
    }

    /// One look-up for the pair's points.
    #[inline(always)]
    fn pair(&mut self, buf: &mut [u32], key: K, p: &PairPoints) {
        let Some(c) = self.table.get_mut(key) else {
            return;
        };
        if c.start == NOT_IN_BATCH {
            return;
        }
        let (y2, s) = (p.y2, p.s);
        if p.below.1 > p.below.0 {
            store(c, buf, (2 * p.below.0, y2), p.below.1 - p.below.0, (0, s));
        }
        if p.right.1 > p.right.0 {
            store(
                c,
                buf,
                (2 * p.right.0 + 1, y2),
                p.right.1 - p.right.0,
                (s, s),
            );
        }
        for &x in p.left.iter().take(p.nleft) {
            store(c, buf, (2 * x - 1, y2), 1, (-s, s));
        }
    }
}

/// Marks the clusters in `slots` that are in the batch.
#[allow(dead_code)]
fn in_batch<K>(c: &Cluster<K>) -> bool {
    c.start != NOT_IN_BATCH
}

/// Places the batch's clusters (those with a range) in `buf` around the run cache at `at`
/// (segment docs), in table order: from the buffer's end down while a cluster's range stays
/// within the cache rows read before its first point is sent (rows `0..=r + 1`, `r` its top
/// row, [`cache_rows_end`]), the others from the buffer's start up. Returns the words used at
/// the start and the end (disjoint: together the batch's points, at most `buf.len()`).
fn place_over_cache<K>(slots: &mut [Cluster<K>], buf: &[u32], at: usize) -> (usize, usize) {
    let (mut low, mut top) = (0usize, buf.len());
    for c in slots.iter_mut().filter(|c| c.start != NOT_IN_BATCH) {
        let n = usize::from(c.n);
        let row = usize::from(c.ymin) / 2;
        let read = cache_rows_end(buf, at, row + 2).unwrap_or(buf.len());
        if top >= n && top - n >= read {
            top -= n;
            c.start = top as u32;
        } else {
            c.start = low as u32;
            low += n;
        }
    }
    (low, buf.len() - top)
}

/// A deterministic order of two detections by their corners (AprilTag's last tie-break).
fn order_corners(a: &Detection, b: &Detection) -> core::cmp::Ordering {
    for (p, q) in a.corners.iter().zip(b.corners.iter()) {
        for (u, v) in [(p.x, q.x), (p.y, q.y)] {
            match u.partial_cmp(&v) {
                Some(core::cmp::Ordering::Equal) | None => {}
                Some(o) => return o,
            }
        }
    }
    core::cmp::Ordering::Equal
}

/// `Less` when `a` is the better of two detections: smaller Hamming distance, then larger
/// margin, then by corners (AprilTag's `prefer_smaller` chain).
fn better(a: &Detection, b: &Detection) -> bool {
    match a.hamming.cmp(&b.hamming) {
        core::cmp::Ordering::Less => return true,
        core::cmp::Ordering::Greater => return false,
        core::cmp::Ordering::Equal => {}
    }
    if a.decision_margin != b.decision_margin {
        return a.decision_margin > b.decision_margin;
    }
    order_corners(a, b) == core::cmp::Ordering::Less
}

/// Adds `det` to `out`, removing duplicates: detections of the same family and id whose
/// outlines overlap keep only the better; a full `out` keeps the best `N`.
fn merge<const N: usize>(out: &mut Vec<Detection, N>, det: Detection, stats: &mut Stats) {
    let dup = |o: &Detection| {
        core::ptr::eq(o.family, det.family)
            && o.id == det.id
            && polygons_overlap(&o.corners, &det.corners)
    };
    if out.iter().filter(|o| dup(o)).any(|o| !better(&det, o)) {
        stats.duplicates += 1;
        return;
    }
    let before = out.len();
    out.retain(|o| !dup(o));
    stats.duplicates += (before - out.len()) as u32;
    if out.push(det).is_err() {
        stats.dropped += 1;
        // Replace the worst if the new one is better.
        let worst = out
            .iter()
            .enumerate()
            .fold(None::<(usize, &Detection)>, |w, (i, o)| match w {
                Some((_, wo)) if better(wo, o) => Some((i, o)),
                Some(w) => Some(w),
                None => Some((i, o)),
            })
            .map(|(i, _)| i);
        if let Some(i) = worst
            && let Some(slot) = out.get_mut(i)
            && better(&det, slot)
        {
            *slot = det;
        }
    }
}

/// Whether two quadrilaterals overlap: an edge of one crosses an edge of the other, or one
/// holds a corner or the centre of the other (AprilTag's `g2d_polygon_overlaps_polygon`, plus
/// the centres).
pub(crate) fn polygons_overlap(a: &[Point2<f32>; 4], b: &[Point2<f32>; 4]) -> bool {
    let cross = |o: Point2<f32>, p: Point2<f32>, q: Point2<f32>| {
        (p.x - o.x) * (q.y - o.y) - (p.y - o.y) * (q.x - o.x)
    };
    let edge = |v: &[Point2<f32>; 4], i: usize| (at4(v, i), at4(v, i + 1));
    for i in 0..4 {
        let (p1, p2) = edge(a, i);
        for j in 0..4 {
            let (q1, q2) = edge(b, j);
            let (d1, d2) = (cross(q1, q2, p1), cross(q1, q2, p2));
            let (d3, d4) = (cross(p1, p2, q1), cross(p1, p2, q2));
            if ((d1 > 0.0) != (d2 > 0.0)) && ((d3 > 0.0) != (d4 > 0.0)) {
                return true;
            }
        }
    }
    let inside = |poly: &[Point2<f32>; 4], p: Point2<f32>| {
        // Even-odd rule.
        let mut c = false;
        for i in 0..4 {
            let (u, v) = edge(poly, i);
            if (u.y > p.y) != (v.y > p.y) {
                let x = u.x + (p.y - u.y) / (v.y - u.y) * (v.x - u.x);
                if p.x < x {
                    c = !c;
                }
            }
        }
        c
    };
    // A corner or the centre of one inside the other (the centre settles two outlines that
    // share edges exactly, where the corners sit on the other's boundary).
    let centre = |v: &[Point2<f32>; 4]| {
        let s = v
            .iter()
            .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords);
        Point2::from(s / 4.0)
    };
    inside(b, at4(a, 0)) || inside(a, at4(b, 0)) || inside(b, centre(a)) || inside(a, centre(b))
}

/// [`merge`] for the unit tests.
#[cfg(test)]
pub(crate) fn merge_for_tests<const N: usize>(
    out: &mut Vec<Detection, N>,
    det: Detection,
    stats: &mut Stats,
) {
    merge(out, det, stats);
}
