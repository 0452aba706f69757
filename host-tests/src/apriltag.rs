//! AprilTag detection on image files (`camgeom apriltag`, `camgeom ar --tag`): the options
//! checked once, a host workspace sized at run time for each frame (any frame up to 8192
//! pixels a side after decimation), the JSON form of a frame's detections and their overlay.

use camgeom::apriltag::quad::Cluster;
use camgeom::apriltag::segment::Run;
use camgeom::apriltag::{
    APRILTAG_PIXEL_OFFSET, Detection, Detector, DetectorConfig, Family, PartialView, Stats,
    WorkspaceView, families, sort_len, tag_pose, tiles_len,
};
use camgeom::camera::Camera;
use camgeom::draw::draw_line;
use camgeom::image::ImageView;
use camgeom::nalgebra::Matrix3;
use camgeom::nalgebra::Point2;
use camgeom::pose::{PlanarConfig, PoseEstimate};
use camgeom::target::{Acquire, Tracked};
use serde::Serialize;

use crate::images::GrayImage;
use crate::rgb::{Overlay, RgbImage, label_size};
use crate::{Error, Result};

/// Widest and tallest frame [`HostWorkspace`] takes: the detector's own limit, that of any
/// image view ([`camgeom::apriltag::MAX_SIDE`]; boundary points hold doubled coordinates in 14
/// bits).
pub const MAX_SIDE: usize = camgeom::apriltag::MAX_SIDE;

/// The host's workspace: buffers sized at run time for the frame (after decimation), with
/// `u32` labels (a 1920x1080 frame of texture or noise needs more than the 65533 of `u16`).
///
/// For a `w x h` frame after decimation (`n = w h` pixels) it holds exactly what the frame
/// needs of the per-frame buffers (tiles `⌊w/4⌋ ⌊h/4⌋`, two rows of runs, sort keys
/// `4 (w + h)`), and starts the capacities that depend on the content at `n / 16` labels,
/// `n / 256` cluster slots and `n / 8` points a batch (at least 4096, 1024, 16384): the
/// bundled 799x533 photos use at most 21,713 labels, 711 clusters and 64,463 kept points
/// (`docs/notes/apriltag.md`). When a frame runs out of one of them ([`Stats::label_overflow`],
/// [`Stats::cluster_overflow`], [`Stats::clusters_skipped`]), [`HostWorkspace::run`] grows it
/// (labels up to `n`, which no frame exceeds: a label starts at a run; cluster slots up to
/// `n / 4`; points to what the kept clusters need) and detects again, so no frame is cut.
/// It never shrinks: the next frames of a sequence reuse it. Memory: [`HostWorkspace::bytes`]
/// (BENCHMARKS.md, "AprilTag at 1920x1080": 2.4 MB at 1920x1080).
#[derive(Default)]
pub struct HostWorkspace {
    /// The frame size (after decimation) the buffers hold.
    w: usize,
    h: usize,
    tiles: Vec<u8>,
    ring_min: Vec<u8>,
    ring_max: Vec<u8>,
    runs: [Vec<Run<u32>>; 2],
    parent: Vec<u32>,
    size: Vec<u8>,
    clusters: Vec<Cluster<u64>>,
    points: Vec<u32>,
    keys: Vec<u16>,
    stats: Stats,
}

/// Most detections of one frame: a growth and a repeat for each capacity at most.
pub const MAX_ATTEMPTS: usize = 4;

impl HostWorkspace {
    /// An empty workspace (it grows with the first frame).
    pub fn new() -> Self {
        Self::default()
    }

    /// Grows the buffers for a `width x height` frame at `decimate` (never shrinks).
    ///
    /// Errors: [`camgeom::Error::BufferTooSmall`] (`"workspace.width"`) when the frame after
    /// decimation is wider or taller than [`MAX_SIDE`].
    pub fn fit(&mut self, width: usize, height: usize, decimate: u8) -> camgeom::Result<()> {
        let d = usize::from(decimate.max(1));
        let (w, h) = (width.div_ceil(d), height.div_ceil(d));
        if w > MAX_SIDE || h > MAX_SIDE {
            return Err(camgeom::Error::BufferTooSmall("workspace.width"));
        }
        let n = w * h;
        let grow = |v: &mut Vec<_>, len: usize, fill| {
            if v.len() < len {
                v.resize(len, fill);
            }
        };
        grow(&mut self.tiles, tiles_len(w, h, 1), 0u8);
        grow(&mut self.ring_min, w, 0u8);
        grow(&mut self.ring_max, w, 0u8);
        for r in &mut self.runs {
            if r.len() < w {
                r.resize(w, Run::empty());
            }
        }
        let labels = (n / 16).max(4096);
        if self.parent.len() < labels {
            self.parent.resize(labels, 0);
        }
        grow(&mut self.size, labels, 0u8);
        let clusters = (n / 256).max(1024);
        if self.clusters.len() < clusters {
            self.clusters.resize(clusters, Cluster::empty());
        }
        if self.points.len() < (n / 8).max(16384) {
            self.points.resize((n / 8).max(16384), 0);
        }
        if self.keys.len() < sort_len(w, h, 1) {
            self.keys.resize(sort_len(w, h, 1), 0);
        }
        (self.w, self.h) = (self.w.max(w), self.h.max(h));
        Ok(())
    }

    /// Bytes of the buffers (their lengths times their element sizes).
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.tiles.len()
            + self.ring_min.len()
            + self.ring_max.len()
            + self.runs.iter().map(Vec::len).sum::<usize>() * size_of::<Run<u32>>()
            + self.parent.len() * size_of::<u32>()
            + self.size.len()
            + self.clusters.len() * size_of::<Cluster<u64>>()
            + self.points.len() * size_of::<u32>()
            + self.keys.len() * size_of::<u16>()
    }

    /// The label capacity (`u32` labels).
    pub fn labels(&self) -> usize {
        self.parent.len().min(self.size.len())
    }

    /// The counts of the last detection.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The buffers as the detector takes them.
    pub fn view(&mut self) -> WorkspaceView<'_, u32> {
        let [r0, r1] = &mut self.runs;
        WorkspaceView::with_labels(
            &mut self.tiles,
            &mut self.ring_min,
            &mut self.ring_max,
            [r0, r1],
            &mut self.parent,
            &mut self.size,
            &mut self.clusters,
            &mut self.points,
            &mut self.keys,
            &mut self.stats,
        )
    }

    /// Runs `detect` (a detection of `frame` at `decimate`) on the workspace grown for the
    /// frame; when the frame ran out of labels, cluster slots or points, grows what ran out
    /// and runs it again (the type's docs), at most [`MAX_ATTEMPTS`] times.
    ///
    /// Errors: [`Self::fit`]'s, and `detect`'s.
    pub fn run<R>(
        &mut self,
        frame: &ImageView<'_, u8>,
        decimate: u8,
        mut detect: impl FnMut(&mut WorkspaceView<'_, u32>) -> camgeom::Result<R>,
    ) -> camgeom::Result<R> {
        self.fit(frame.width(), frame.height(), decimate)?;
        let n = self.w * self.h;
        let mut attempt = 0;
        loop {
            let out = detect(&mut self.view())?;
            attempt += 1;
            let s = self.stats;
            let mut grown = false;
            if s.label_overflow > 0 && self.labels() < n {
                let labels = (4 * self.labels()).min(n);
                self.parent.resize(labels, 0);
                self.size.resize(labels, 0);
                grown = true;
            }
            if s.cluster_overflow > 0 && self.clusters.len() < n / 4 {
                let len = (4 * self.clusters.len()).min(n / 4);
                self.clusters.resize(len, Cluster::empty());
                grown = true;
            }
            if s.clusters_skipped > 0 && self.points.len() < s.cluster_points as usize {
                self.points.resize(s.cluster_points as usize, 0);
                grown = true;
            }
            if !grown || attempt >= MAX_ATTEMPTS {
                return Ok(out);
            }
        }
    }

    /// The tags of `det`'s families in `frame`, at most `N` ([`Detector::detect`] with
    /// [`Self::run`]).
    ///
    /// Errors: [`Self::run`]'s.
    pub fn detect<const N: usize>(
        &mut self,
        det: &Detector,
        frame: &ImageView<'_, u8>,
    ) -> camgeom::Result<camgeom::heapless::Vec<Detection, N>> {
        self.run(frame, det.config().decimate, |ws| det.detect(frame, ws))
    }
}

/// Tag `id` of `family` as the AR loop's acquisition step (`camgeom ar --tag`): the core's
/// [`camgeom::apriltag::TagTarget`] with a [`HostWorkspace`] grown for each frame. It tracks
/// the tag by detection as `TagTarget` does (the same core calls:
/// [`Detector::refine_target`], then [`Detector::refine_partial`] for a partly seen tag,
/// flagged as such, then [`Detector::find_target_near`]) unless
/// [`Self::track_by_detection`] turns it off.
pub struct HostTagTarget<'a> {
    detector: &'a Detector,
    workspace: HostWorkspace,
    family: &'static Family,
    id: u16,
    by_detection: bool,
}

impl<'a> HostTagTarget<'a> {
    /// Tag `id` of `family` (one of `detector`'s families).
    pub fn new(detector: &'a Detector, family: &'static Family, id: u16) -> Self {
        Self {
            detector,
            workspace: HostWorkspace::new(),
            family,
            id,
            by_detection: true,
        }
    }

    /// Tracks by detection (`true`, the default) or lets the loop track with KLT between
    /// acquisitions (`false`).
    pub fn track_by_detection(mut self, on: bool) -> Self {
        self.by_detection = on;
        self
    }

    /// The workspace (its [`Stats`] after the last detection).
    pub fn workspace(&self) -> &HostWorkspace {
        &self.workspace
    }
}

impl Acquire for HostTagTarget<'_> {
    fn acquire(
        &mut self,
        frame: &ImageView<'_, u8>,
        _lost: u32,
    ) -> camgeom::Result<Option<[Point2<f32>; 4]>> {
        let (det, family, id) = (self.detector, self.family, self.id);
        self.workspace.run(frame, det.config().decimate, |ws| {
            det.find_target(frame, ws, family, id)
        })
    }

    fn tracks(&self) -> bool {
        self.by_detection
    }

    fn track(
        &mut self,
        frame: &ImageView<'_, u8>,
        predicted: &[Point2<f32>; 4],
    ) -> camgeom::Result<Option<Tracked>> {
        let (det, family, id) = (self.detector, self.family, self.id);
        if let Some(c) = det.refine_target(frame, family, id, predicted) {
            return Ok(Some(Tracked::whole(c)));
        }
        if let Ok(p) = det.refine_partial(frame, family, id, predicted) {
            return Ok(Some(Tracked {
                corners: p.detection.target_corners(),
                partial: true,
            }));
        }
        let near = self.workspace.run(frame, det.config().decimate, |ws| {
            det.find_target_near(frame, ws, family, id, predicted)
        })?;
        Ok(near.map(Tracked::whole))
    }
}

/// Most detections reported per frame.
pub const MAX_DETECTIONS: usize = 256;

/// The family called `name` (AprilTag's names: `tag36h11`, `tag25h9`, `tag16h5`,
/// `tagStandard41h12`; OpenCV's ArUco dictionaries: `DICT_4X4_50` .. `DICT_7X7_1000`,
/// `DICT_ARUCO_ORIGINAL`, `DICT_ARUCO_MIP_36h12`).
///
/// Errors: a usage error naming the families there are.
pub fn family(name: &str) -> Result<&'static Family> {
    families::by_name(name).ok_or_else(|| {
        let names: Vec<&str> = families::ALL
            .iter()
            .chain(families::ARUCO.iter())
            .map(|f| f.name())
            .collect();
        Error::usage(format!(
            "--family: unknown family `{name}` (one of {})",
            names.join(", ")
        ))
    })
}

/// A comma-separated list of families (`tag36h11,tag25h9`), each at most once.
pub fn families_list(list: &str) -> Result<Vec<&'static Family>> {
    let mut out: Vec<&'static Family> = Vec::new();
    for name in list.split(',').map(str::trim) {
        let f = family(name)?;
        if out.iter().any(|g| g.name() == f.name()) {
            return Err(Error::usage(format!("--family: `{name}` given twice")));
        }
        out.push(f);
    }
    Ok(out)
}

/// The detector of `families` with camgeom's defaults and `decimate`, `max_hamming`,
/// `refine_edges` (AprilTag's option of the same name; its detection test turns it off).
///
/// Errors (usage): decimation outside 1..=8, `max_hamming` above 3 or not below half a
/// family's minimum distance (tag16h5: at most 2).
pub fn detector(
    families: &[&'static Family],
    decimate: u8,
    max_hamming: u8,
    refine_edges: bool,
) -> Result<Detector> {
    if !(1..=8).contains(&decimate) {
        return Err(Error::usage(format!(
            "--decimate must be 1..=8, got {decimate}"
        )));
    }
    let cfg = DetectorConfig {
        decimate,
        max_hamming,
        refine_edges,
        ..DetectorConfig::default()
    };
    Detector::new(cfg, families).map_err(|e| match e {
        camgeom::Error::InvalidParameter("max_hamming") => {
            let limit = families
                .iter()
                .filter(|f| !f.is_aruco())
                .map(|f| (u32::from(f.min_distance()).saturating_sub(1) / 2).min(3))
                .min()
                .unwrap_or(0);
            Error::usage(format!(
                "--max-hamming must be at most {limit} for these families, got {max_hamming}"
            ))
        }
        e => Error::camgeom("detector configuration", e),
    })
}

/// The tag size and camera a pose needs: both or neither.
///
/// Errors (usage): one without the other; a size that is not finite and positive.
pub fn pose_inputs(
    tag_size: Option<f32>,
    intrinsics: Option<&std::path::Path>,
) -> Result<Option<(f32, Camera<f32>)>> {
    match (tag_size, intrinsics) {
        (None, None) => Ok(None),
        (Some(_), None) => Err(Error::usage("--tag-size needs --intrinsics")),
        (None, Some(_)) => Err(Error::usage("--intrinsics needs --tag-size")),
        (Some(s), Some(path)) => {
            check_tag_size(s)?;
            Ok(Some((s, crate::load_camera(path)?.camera_f32())))
        }
    }
}

/// A tag size must be finite and positive.
pub fn check_tag_size(s: f32) -> Result<()> {
    if s.is_finite() && s > 0.0 {
        Ok(())
    } else {
        Err(Error::usage(format!(
            "--tag-size must be positive, got {s}"
        )))
    }
}

/// Detects the tags in `img` (read from `path`, named in errors).
///
/// Errors: [`camgeom::Error::BufferTooSmall`] (as a [`crate::ErrorKind::Camgeom`]) when the
/// frame after decimation is wider or taller than [`MAX_SIDE`].
pub fn detect(
    det: &Detector,
    ws: &mut HostWorkspace,
    img: &GrayImage,
    path: &std::path::Path,
) -> Result<camgeom::heapless::Vec<Detection, MAX_DETECTIONS>> {
    let too_large = |e| {
        Error::camgeom(
            format!(
                "{}: {}x{} is too large for the workspace (at most {MAX_SIDE}x{MAX_SIDE})",
                path.display(),
                img.width,
                img.height,
            ),
            e,
        )
    };
    if img.width > MAX_SIDE || img.height > MAX_SIDE {
        return Err(too_large(camgeom::Error::BufferTooSmall("workspace.width")));
    }
    let view = img.view().ok_or_else(|| {
        Error::camgeom(
            format!("{}: not an image camgeom can take", path.display()),
            camgeom::Error::InvalidImage,
        )
    })?;
    ws.detect(det, &view).map_err(|e| match e {
        camgeom::Error::BufferTooSmall(_) => too_large(e),
        e => Error::camgeom(format!("{}: detection failed", path.display()), e),
    })
}

/// Which pixel coordinates the output uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Coords {
    /// camgeom's and OpenCV's: pixel `(i, j)` centred at `(i, j)`.
    #[default]
    Camgeom,
    /// AprilTag's (and pupil_apriltags'): camgeom's plus [`APRILTAG_PIXEL_OFFSET`].
    AprilTag,
}

impl Coords {
    fn offset(self) -> f32 {
        match self {
            Coords::Camgeom => 0.0,
            Coords::AprilTag => APRILTAG_PIXEL_OFFSET,
        }
    }
}

/// A pose in the JSON output.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct JsonTagPose {
    /// Rotation tag to camera, row-major.
    #[serde(rename = "R")]
    pub r: [f32; 9],
    /// Translation, in the tag size's unit.
    pub t: [f32; 3],
    /// RMS reprojection error of the four corners, pixels.
    pub rms_px: f32,
}

impl JsonTagPose {
    fn new(e: &PoseEstimate<f32>) -> Self {
        let m = *e.pose.rotation().matrix();
        let t = e.pose.translation();
        Self {
            r: std::array::from_fn(|k| m[(k / 3, k % 3)]),
            t: [t.x, t.y, t.z],
            rms_px: e.rms_px,
        }
    }
}

/// One detection in the JSON output.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct JsonTag {
    /// Tag id.
    pub id: u16,
    /// Family name.
    pub family: &'static str,
    /// Bits corrected.
    pub hamming: u8,
    /// Decision margin (AprilTag's `decision_margin`).
    pub margin: f32,
    /// Corners in the chosen [`Coords`]: for an AprilTag family in AprilTag's order (tag
    /// coordinates `(-1, 1)`, `(1, 1)`, `(1, -1)`, `(-1, -1)`), for an ArUco dictionary in
    /// OpenCV's (`detectMarkers`: the marker's top-left first, clockwise; tag coordinates
    /// `(-1, -1)`, `(1, -1)`, `(1, 1)`, `(-1, 1)`).
    pub corners: [[f32; 2]; 4],
    /// Tag coordinates to pixels (in the chosen [`Coords`]), row-major, `h33 = 1`.
    #[serde(rename = "H")]
    pub h: [f32; 9],
    /// The best pose (with `--tag-size` and `--intrinsics`; null when it cannot be solved).
    #[serde(rename = "R", skip_serializing_if = "Option::is_none")]
    pub r: Option<Option<[f32; 9]>>,
    /// Its translation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t: Option<Option<[f32; 3]>>,
    /// Its RMS reprojection error, pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_px: Option<Option<f32>>,
    /// The other solution of the planar ambiguity.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alternative: Option<Option<JsonTagPose>>,
    /// The tag was found partly seen (`camgeom apriltag --track`: `Detector::refine_partial`):
    /// what of it was measured; absent for a tag seen whole. Its `hamming` counts the seen
    /// cells that differ from the code.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub partial: Option<JsonPartial>,
}

/// What of a partly seen tag was measured (`camgeom::apriltag::PartialView`).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct JsonPartial {
    /// Per edge (the tag's top, right, bottom, left): the share of its length its inlier edge
    /// points span.
    pub edge_span: [f32; 4],
    /// Per edge: inlier edge points, of the positions sampled.
    pub edge_inliers: [u8; 4],
    /// Per edge: positions sampled.
    pub edge_samples: [u8; 4],
    /// Payload cells seen.
    pub cells_seen: u8,
    /// Seen cells allowed to differ from the code.
    pub cells_budget: u8,
    /// Something lay over the tag's edges (not only the frame's edge).
    pub occluded: bool,
}

impl JsonPartial {
    /// The JSON form of `v`.
    pub fn new(v: &PartialView) -> Self {
        Self {
            edge_span: v.edge_span,
            edge_inliers: v.edge_inliers,
            edge_samples: v.edge_samples,
            cells_seen: v.cells_seen,
            cells_budget: v.cells_budget,
            occluded: v.occluded,
        }
    }
}

/// One frame's detections in the JSON output.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct JsonFrame {
    /// The image file (with `--frames`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    /// Detections, sorted by id (then family).
    pub detections: Vec<JsonTag>,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
}

/// The JSON form of `d`, with the pose when `pose` gives the tag size and camera.
pub fn json_tag(d: &Detection, coords: Coords, pose: Option<&(f32, Camera<f32>)>) -> JsonTag {
    let o = coords.offset();
    let shift = Matrix3::new(1.0, 0.0, o, 0.0, 1.0, o, 0.0, 0.0, 1.0);
    let m = shift * d.homography.matrix();
    let s = if m[(2, 2)] != 0.0 { m[(2, 2)] } else { 1.0 };
    let mut tag = JsonTag {
        id: d.id,
        family: d.family.name(),
        hamming: d.hamming,
        margin: d.decision_margin,
        corners: if d.family.is_aruco() {
            d.aruco_corners()
        } else {
            d.corners
        }
        .map(|c| [c.x + o, c.y + o]),
        h: std::array::from_fn(|k| m[(k / 3, k % 3)] / s),
        r: None,
        t: None,
        rms_px: None,
        alternative: None,
        partial: None,
    };
    if let Some((size, camera)) = pose {
        let p = tag_pose(d, *size, camera, &PlanarConfig::default()).ok();
        let best = p.map(|p| JsonTagPose::new(&p.best));
        tag.r = Some(best.as_ref().map(|b| b.r));
        tag.t = Some(best.as_ref().map(|b| b.t));
        tag.rms_px = Some(best.as_ref().map(|b| b.rms_px));
        tag.alternative = Some(p.map(|p| JsonTagPose::new(&p.alternative)));
    }
    tag
}

/// Outline (green), corner 0 (red square) and id (white on black, at the centre) of each tag
/// drawn over `img`.
pub fn draw_tags(img: &GrayImage, tags: &[Detection]) -> RgbImage {
    draw_tags_on(RgbImage::from_gray(img), tags)
}

/// [`draw_tags`] on a frame already in colour (the frame's own colours, or its grey).
pub fn draw_tags_on(frame: RgbImage, tags: &[Detection]) -> RgbImage {
    const OUTLINE: [u8; 3] = [40, 230, 40];
    const CORNER0: [u8; 3] = [255, 40, 40];
    let mut out = frame;
    let (width, height) = (out.width() as usize, out.height() as usize);
    let mut mask = GrayImage::filled(width, height, 0);
    if let Some(mut v) = mask.view_mut() {
        for d in tags {
            let c = &d.corners;
            for (a, b) in c.iter().zip(c.iter().cycle().skip(1)) {
                let _ = draw_line(&mut v, a, b, 255);
            }
        }
    }
    out.ink(&mask, OUTLINE);
    for d in tags {
        let (x, y) = (d.corners[0].x.round() as i64, d.corners[0].y.round() as i64);
        for dy in -2..=2 {
            for dx in -2..=2 {
                out.put(x + dx, y + dy, CORNER0);
            }
        }
        let text = d.id.to_string();
        let (w, h) = label_size(&text);
        let at = |c: f32, half: usize| (c.round().max(0.0) as usize).saturating_sub(half);
        out.label(at(d.center.x, w / 2), at(d.center.y, h / 2), &text, w, h);
    }
    out
}
