//! Tag board files (JSON, or YAML as OpenCV's `FileStorage` writes it) and the board pose of a
//! frame's detections in the CLI's JSON (`camgeom apriltag --board`, `camgeom ar --board`).
//!
//! A board file names the family and either a grid, OpenCV's `aruco::GridBoard`:
//!
//! ```json
//! {"family": "DICT_4X4_50",
//!  "grid": {"markers_x": 5, "markers_y": 4, "marker_length": 0.04,
//!           "marker_separation": 0.01, "first_id": 0}}
//! ```
//!
//! (`first_id` optional, 0; or `"ids": [..]`, `markers_x · markers_y` of them, row by row, as
//! OpenCV's `ids` argument), or the tags one by one, each with its four corners in board
//! coordinates in OpenCV's marker corner order (top-left, top-right, bottom-right, bottom-left
//! of the tag as drawn; AprilTag families too):
//!
//! ```json
//! {"family": "tag36h11",
//!  "tags": [{"id": 3, "corners": [[0,0,0], [0.05,0,0], [0.05,0.05,0], [0,0.05,0]]}]}
//! ```
//!
//! The same keys in YAML (`.yml`/`.yaml`, `%YAML:1.0` header optional). Unknown keys, a
//! missing or unknown family, ids outside the family or repeated, and degenerate tags are
//! errors naming the file.

use std::path::Path;

use camgeom::apriltag::{
    BoardBuffers, BoardConfig, BoardTag, Detection, Family, GridBoard, TagBoard, board_pose,
    families,
};
use camgeom::camera::Camera;
use serde::{Deserialize, Serialize};

use crate::error::{Error, ErrorKind, Result, describe};
use crate::storage::{FileStorage, Node, Value, ext_display, extension, read_text};

/// A board read from a file: its family and tags (`f64`, the files' precision).
#[derive(Debug, Clone)]
pub struct HostBoard {
    /// The family.
    pub family: &'static Family,
    /// The tags, corners in OpenCV's order.
    pub tags: Vec<BoardTag<f64>>,
}

impl HostBoard {
    /// The core's view of the board (checked when the file was read).
    pub fn view(&self) -> camgeom::Result<TagBoard<'_, f64>> {
        TagBoard::new(self.family, &self.tags)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Spec {
    family: String,
    #[serde(default)]
    grid: Option<GridSpec>,
    #[serde(default)]
    tags: Option<Vec<TagSpec>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GridSpec {
    markers_x: u16,
    markers_y: u16,
    marker_length: f64,
    marker_separation: f64,
    #[serde(default)]
    first_id: u16,
    #[serde(default)]
    ids: Option<Vec<u16>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TagSpec {
    id: u16,
    corners: [[f64; 3]; 4],
}

/// A YAML tree as JSON: unquoted scalars that are integers or numbers become numbers.
fn to_json(node: &Node) -> serde_json::Value {
    match &node.value {
        Value::Scalar { text, quoted } => {
            let t = text.trim();
            if !quoted {
                if let Ok(i) = t.parse::<i64>() {
                    return i.into();
                }
                if let Some(v) =
                    crate::storage::parse_number(t).and_then(serde_json::Number::from_f64)
                {
                    return serde_json::Value::Number(v);
                }
            }
            serde_json::Value::String(text.clone())
        }
        Value::Seq(items) => items.iter().map(to_json).collect(),
        Value::Map(entries) => entries
            .iter()
            .map(|(k, v)| (k.clone(), to_json(v)))
            .collect::<serde_json::Map<_, _>>()
            .into(),
    }
}

/// Reads a board file (`.json`, `.yml`, `.yaml`).
///
/// Errors: unreadable file, syntax, unknown keys or family, neither or both of `grid` and
/// `tags`, and tables the core refuses ([`TagBoard::new`], [`GridBoard::fill`]).
pub fn load_board(path: impl AsRef<Path>) -> Result<HostBoard> {
    let path = path.as_ref();
    let value = match extension(path).as_str() {
        "json" => serde_json::from_str::<serde_json::Value>(&read_text(path)?)
            .map_err(|e| Error::new(path, ErrorKind::Syntax(e.to_string())))?,
        "yml" | "yaml" => to_json(FileStorage::parse_yaml(&read_text(path)?, path)?.root()),
        ext => {
            return Err(Error::new(
                path,
                ErrorKind::Unsupported(format!(
                    "board file extension `{}`: use .json, .yml or .yaml",
                    ext_display(ext)
                )),
            ));
        }
    };
    let spec: Spec = serde_json::from_value(value)
        .map_err(|e| Error::new(path, ErrorKind::Syntax(format!("board: {e}"))))?;
    let bad = |msg: String| Error::new(path, ErrorKind::Unsupported(msg));
    let family = families::by_name(&spec.family)
        .ok_or_else(|| bad(format!("unknown family `{}`", spec.family)))?;
    let tags = match (spec.grid, spec.tags) {
        (Some(g), None) => {
            let grid = GridBoard {
                markers_x: g.markers_x,
                markers_y: g.markers_y,
                marker_length: g.marker_length,
                marker_separation: g.marker_separation,
                first_id: g.first_id,
            };
            let mut tags = vec![
                BoardTag {
                    id: 0,
                    corners: [[0.0; 3]; 4]
                };
                grid.len()
            ];
            grid.fill(family, &mut tags)
                .map_err(|e| bad(format!("grid: {}", describe(&e))))?;
            if let Some(ids) = g.ids {
                if ids.len() != tags.len() {
                    return Err(bad(format!(
                        "grid: {} ids for {} tags",
                        ids.len(),
                        tags.len()
                    )));
                }
                for (t, id) in tags.iter_mut().zip(ids) {
                    t.id = id;
                }
            }
            tags
        }
        (None, Some(list)) => list
            .into_iter()
            .map(|t| BoardTag {
                id: t.id,
                corners: t.corners,
            })
            .collect(),
        _ => return Err(bad("give one of `grid` and `tags`".into())),
    };
    TagBoard::new(family, &tags).map_err(|e| bad(format!("tags: {}", describe(&e))))?;
    Ok(HostBoard { family, tags })
}

/// The board pose in the JSON output: the pose, or why there is none.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct JsonBoardPose {
    /// Rotation board to camera, row-major (`X_cam = R X_board + t`).
    #[serde(rename = "R", skip_serializing_if = "Option::is_none")]
    pub r: Option<[f64; 9]>,
    /// Rotation vector (OpenCV's `rvec`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rvec: Option<[f64; 3]>,
    /// Translation (`tvec`), in the board file's unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t: Option<[f64; 3]>,
    /// RMS reprojection error over all the corners used, pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_px: Option<f64>,
    /// The planar ambiguity's second solution's RMS error (planar boards).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alternative_rms_px: Option<f64>,
    /// The second solution fits nearly as well (one small tag, nearly fronto-parallel).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ambiguous: Option<bool>,
    /// Ids of the board tags used.
    pub tags: Vec<u16>,
    /// Corners used.
    pub points: usize,
    /// Board ids detected twice, left out.
    pub duplicates: Vec<u16>,
    /// Why there is no pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The board pose of `detections` through `camera` (`f64`), as the CLI prints it, and the pose
/// when there is one.
pub fn board_pose_json(
    board: &HostBoard,
    detections: &[Detection],
    camera: &Camera<f64>,
) -> (JsonBoardPose, Option<camgeom::transform::Pose<f64>>) {
    let on_board = |d: &Detection| {
        d.family.name() == board.family.name() && board.tags.iter().any(|t| t.id == d.id)
    };
    let count = |d: &Detection| {
        detections
            .iter()
            .filter(|o| o.id == d.id && o.family.name() == d.family.name())
            .count()
    };
    let mut tags: Vec<u16> = Vec::new();
    let mut duplicates: Vec<u16> = Vec::new();
    for d in detections.iter().filter(|d| on_board(d)) {
        let list = if count(d) == 1 {
            &mut tags
        } else {
            &mut duplicates
        };
        if !list.contains(&d.id) {
            list.push(d.id);
        }
    }
    tags.sort_unstable();
    duplicates.sort_unstable();
    let mut out = JsonBoardPose {
        r: None,
        rvec: None,
        t: None,
        rms_px: None,
        alternative_rms_px: None,
        ambiguous: None,
        points: 4 * tags.len(),
        tags,
        duplicates,
        error: None,
    };
    let result = board.view().and_then(|view| {
        // One buffer a frame, sized for every tag of the board.
        let mut buf: Box<BoardBuffers<f64, 1024>> = Box::default();
        if 4 * view.tags().len() > 1024 {
            return Err(camgeom::Error::BufferTooSmall("buffers"));
        }
        board_pose(&view, detections, camera, &BoardConfig::default(), &mut buf)
    });
    match result {
        Ok(p) => {
            let pose = p.estimate.pose;
            let m = *pose.rotation().matrix();
            let (v, t) = (pose.rotation_vector(), pose.translation());
            out.r = Some(std::array::from_fn(|k| m[(k / 3, k % 3)]));
            out.rvec = Some([v.x, v.y, v.z]);
            out.t = Some([t.x, t.y, t.z]);
            out.rms_px = Some(p.estimate.rms_px);
            out.alternative_rms_px = p
                .alternative_rms_px
                .is_finite()
                .then_some(p.alternative_rms_px);
            out.ambiguous = Some(p.ambiguous);
            (out, Some(pose))
        }
        Err(e) => {
            out.error = Some(match e {
                camgeom::Error::TooFewPoints => "no board tag seen once".into(),
                camgeom::Error::NoConvergence => {
                    "the corners do not fit the board (RMS above 3 px)".into()
                }
                e => describe(&e),
            });
            (out, None)
        }
    }
}
