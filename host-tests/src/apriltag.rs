//! AprilTag detection on image files (`camgeom apriltag`, `camgeom ar --tag`): the options
//! checked once, a host workspace for frames up to 1024x1024, the JSON form of a frame's
//! detections and their overlay.

use camgeom::apriltag::{
    APRILTAG_PIXEL_OFFSET, Detection, Detector, DetectorConfig, Family, Workspace, families,
    sort_len, tag_pose, tiles_len,
};
use camgeom::camera::Camera;
use camgeom::draw::draw_line;
use camgeom::nalgebra::Matrix3;
use camgeom::pose::{PlanarConfig, PoseEstimate};
use serde::Serialize;

use crate::images::GrayImage;
use crate::rgb::{Overlay, RgbImage, label_size};
use crate::{Error, Result};

/// Widest and tallest frame (after decimation) [`HostWorkspace`] takes.
pub const MAX_SIDE: usize = 1024;

/// The host's workspace: frames up to [`MAX_SIDE`] x [`MAX_SIDE`] after decimation, with
/// capacities (65533 labels, 8192 cluster slots, 262144 points a batch) above the largest
/// counts of the bundled 799x533 photos (21,713 labels, 711 clusters, 64,463 kept points:
/// `docs/notes/apriltag.md`), so nothing is cut on photos of that size. About 1.6 MB: box it.
pub type HostWorkspace = Workspace<
    MAX_SIDE,
    { tiles_len(MAX_SIDE, MAX_SIDE, 1) },
    65533,
    8192,
    262_144,
    { sort_len(MAX_SIDE, MAX_SIDE, 1) },
>;

/// Most detections reported per frame.
pub const MAX_DETECTIONS: usize = 256;

/// The family called `name` (AprilTag's names: `tag36h11`, `tag25h9`, `tag16h5`,
/// `tagStandard41h12`).
///
/// Errors: a usage error naming the families there are.
pub fn family(name: &str) -> Result<&'static Family> {
    families::ALL
        .iter()
        .copied()
        .find(|f| f.name() == name)
        .ok_or_else(|| {
            let names: Vec<&str> = families::ALL.iter().map(|f| f.name()).collect();
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
/// frame after decimation is larger than [`HostWorkspace`] holds.
pub fn detect(
    det: &Detector,
    ws: &mut HostWorkspace,
    img: &GrayImage,
    path: &std::path::Path,
) -> Result<camgeom::heapless::Vec<Detection, MAX_DETECTIONS>> {
    let view = img.view().ok_or_else(|| {
        Error::camgeom(
            format!("{}: not an image camgeom can take", path.display()),
            camgeom::Error::InvalidImage,
        )
    })?;
    det.detect(&view, &mut ws.as_mut_view())
        .map_err(|e| match e {
            camgeom::Error::BufferTooSmall(_) => Error::camgeom(
                format!(
                    "{}: {}x{} is too large for the workspace (at most {MAX_SIDE}x{MAX_SIDE} \
                 after decimation: try --decimate {})",
                    path.display(),
                    img.width,
                    img.height,
                    img.width.max(img.height).div_ceil(MAX_SIDE).max(2)
                ),
                e,
            ),
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
    /// Corners in AprilTag's order (tag coordinates `(-1, 1)`, `(1, 1)`, `(1, -1)`,
    /// `(-1, -1)`), in the chosen [`Coords`].
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
        corners: d.corners.map(|c| [c.x + o, c.y + o]),
        h: std::array::from_fn(|k| m[(k / 3, k % 3)] / s),
        r: None,
        t: None,
        rms_px: None,
        alternative: None,
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
