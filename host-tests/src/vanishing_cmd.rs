//! `camgeom vanishing`: the vanishing points of image line segments and the horizon
//! ([`camgeom::vanishing`]: sequential RANSAC over segment pairs, each point by least squares,
//! the horizon from two horizontal points or from the vertical one and `K`).
//!
//! Input: `--segments S.csv`, rows `x1,y1,x2,y2` (pixels; optional header), or
//! `x1,y1,x2,y2,group` where `group` is an integer of the user's (the true direction of a
//! synthetic segment, say), used only to grade the result: each point reports the most common
//! group among its segments and its share. `--intrinsics FILE` (optional): the
//! segments' endpoints are undistorted first when the camera has lens distortion; each point
//! gets its direction in the camera frame `K⁻¹ v / |K⁻¹ v|`, each pair of points the angle
//! between their directions, and the horizon can come from the vertical point alone.
//!
//! Output: JSON `{"segments", "short_segments", "centre", "vanishing_points": [{"x", "y",
//! "h", "ideal", "direction_deg", "segments", "rms_px", "vertical", ..}], "horizon": {"line",
//! "from", "roll_deg"} | null, "horizon_reason": string | null, "angles_deg": [..]}` (see
//! CLI.md). No vanishing point (no `--min-segments` segments meet at one point) is an
//! answer, not an error: an empty list and the reason. Errors (status 2): an unreadable or
//! malformed CSV, fewer rows than `--min-segments`, an option out of range.
//!
//! `--overlay O.png`: the segments over `--image` (or over a dark canvas of the camera file's
//! size, or of the segments' extent), coloured by the point they were assigned to (grey:
//! none), each point inside the picture marked with a ring and its index, the horizon in
//! white across the picture. `--labels-out L.csv`: `segment,label` per input row (the index in
//! `vanishing_points`, -1 for none).

use std::path::{Path, PathBuf};

use camgeom::camera::Camera;
use camgeom::draw::draw_line;
use camgeom::homogeneous::Line2h;
use camgeom::nalgebra::{Point2, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::vanishing::{
    HorizonSource, MAX_POINTS, NO_POINT, Segment, VanishingConfig, VanishingPoint,
    find_vanishing_points, horizon,
};
use camgeom_host::cli::files::write_file;
use camgeom_host::images::{GrayImage, load_rgb, save_rgb};
use camgeom_host::points::{format_csv, parse_csv, to_json};
use camgeom_host::rgb::{Overlay, RgbImage, label_size};
use camgeom_host::storage::read_text;
use camgeom_host::{Error, ErrorKind, Result, describe, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct VanishingArgs {
    /// Line segments, CSV rows `x1,y1,x2,y2` (pixels) with an optional fifth column `group`
    /// (an integer, for grading only); optional header; `-` reads stdin.
    #[arg(long, value_name = "S.csv")]
    pub segments: PathBuf,
    /// Camera file (OpenCV YAML/XML, camgeom JSON/TOML; see `camgeom camera`): directions of
    /// the points in the camera frame, their angles, the horizon from the vertical point alone;
    /// lens distortion is removed from the endpoints first.
    #[arg(long, value_name = "FILE")]
    pub intrinsics: Option<PathBuf>,
    /// The image the segments come from (PNG, JPEG): the overlay's background, and its centre
    /// the origin of `direction_deg` when there is no camera file.
    #[arg(long, value_name = "I.png")]
    pub image: Option<PathBuf>,
    /// Writes the segments coloured by vanishing point, the points and the horizon (PNG, or
    /// JPEG for .jpg).
    #[arg(long, value_name = "O.png")]
    pub overlay: Option<PathBuf>,
    /// Writes `segment,label` per input row: the index of its vanishing point, -1 for none.
    #[arg(long, value_name = "L.csv")]
    pub labels_out: Option<PathBuf>,
    /// Largest distance, pixels, of a segment's endpoint from the line through its midpoint
    /// and the vanishing point, for the segment to belong to it.
    #[arg(long, value_name = "PX", default_value_t = VanishingConfig::<f64>::default().ransac.threshold)]
    pub threshold: f64,
    /// Most vanishing points looked for, 1..=8.
    #[arg(long, value_name = "N", default_value_t = VanishingConfig::<f64>::default().max_points)]
    pub max_points: usize,
    /// Segments a vanishing point needs, at least 3; the search stops at the first point with
    /// fewer.
    #[arg(long, value_name = "N", default_value_t = VanishingConfig::<f64>::default().min_segments)]
    pub min_segments: usize,
    /// Shorter segments (pixels) are left out of the search (label -1).
    #[arg(long, value_name = "PX", default_value_t = VanishingConfig::<f64>::default().min_length)]
    pub min_length: f64,
    /// Most RANSAC samples drawn per vanishing point.
    #[arg(long, value_name = "N", default_value_t = VanishingConfig::<f64>::default().ransac.max_iterations)]
    pub max_iters: u32,
    /// Seed of RANSAC's sampler: the same seed and input give the same output everywhere.
    #[arg(long, value_name = "SEED", default_value_t = RansacConfig::<f64>::default().seed)]
    pub seed: u64,
}

/// One vanishing point of the JSON output.
#[derive(Serialize, Debug)]
pub struct PointOutput {
    /// Position, pixels (`null` for an ideal point).
    pub x: Option<f64>,
    /// Position, pixels (`null` for an ideal point).
    pub y: Option<f64>,
    /// Homogeneous coordinates, unit norm, `w ≥ 0`.
    pub h: [f64; 3],
    /// Whether the point is ideal (its segments are parallel in the image).
    pub ideal: bool,
    /// Finite: the angle of `(x, y) - centre`, degrees in (-180, 180]; ideal: the angle of its
    /// direction, in (-90, 90]. Image axes (y down: positive is clockwise on screen).
    pub direction_deg: f64,
    /// Segments assigned to it.
    pub segments: usize,
    /// RMS of their residuals, pixels.
    pub rms_px: f64,
    /// Whether its segments run within 26.6° of the image's vertical axis.
    pub vertical: bool,
    /// The most common `group` among its segments (input with a group column only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<i64>,
    /// The share of its segments in that group.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group_share: Option<f64>,
    /// `K⁻¹ h` normalised, the sign with `z ≥ 0` (with `--intrinsics` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direction_camera: Option<[f64; 3]>,
}

/// The horizon of the JSON output.
#[derive(Serialize, Debug)]
pub struct HorizonOutput {
    /// `(a, b, c)` with `a x + b y + c = 0`, `a² + b² = 1` (unless it is the line at
    /// infinity).
    pub line: [f64; 3],
    /// `two_horizontal` or `vertical_and_camera`.
    pub from: &'static str,
    /// The angle of the line's direction `(b, -a)` from the image x axis, degrees in
    /// (-90, 90] (positive descends to the right); `null` for the line at infinity.
    pub roll_deg: Option<f64>,
}

/// The angle between the camera directions of two points.
#[derive(Serialize, Debug)]
pub struct AngleOutput {
    /// Indices in `vanishing_points`.
    pub points: [usize; 2],
    /// `acos |dᵢ · dⱼ|`, degrees in [0, 90].
    pub deg: f64,
}

/// The JSON result.
#[derive(Serialize, Debug)]
pub struct VanishingOutput {
    /// Input rows.
    pub segments: usize,
    /// Rows shorter than `--min-length` (left out).
    pub short_segments: usize,
    /// The origin of `direction_deg`: the principal point with a camera file, else the
    /// image's centre, else the centre of the segments' bounding box.
    pub centre: [f64; 2],
    /// The points found, the best supported first.
    pub vanishing_points: Vec<PointOutput>,
    /// The horizon, when the points determine it.
    pub horizon: Option<HorizonOutput>,
    /// Why there is no horizon (`null` when there is one).
    pub horizon_reason: Option<String>,
    /// With a camera file: the angle between each pair of points' directions.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angles_deg: Option<Vec<AngleOutput>>,
}

/// The segments of `--segments` and, with a fifth column, their groups.
type SegmentRows = (Vec<Segment<f64>>, Option<Vec<i64>>);

/// The rows of `--segments`: the segments and, with a fifth column, their groups.
fn read_segments(path: &Path) -> Result<SegmentRows> {
    let text = read_text(path)?;
    // Four or five columns, from the first line that is neither blank nor a comment.
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'));
    let five = first.is_some_and(|l| l.split(',').count() == 5);
    let columns: &[&str] = if five {
        &["x1", "y1", "x2", "y2", "group"]
    } else {
        &["x1", "y1", "x2", "y2"]
    };
    let table = parse_csv(&text, path, columns)?;
    let segments = table
        .rows
        .iter()
        .map(|r| Segment::new(Point2::new(r[0], r[1]), Point2::new(r[2], r[3])))
        .collect();
    let groups = if five {
        let mut g = Vec::with_capacity(table.rows.len());
        for (r, &line) in table.rows.iter().zip(&table.lines) {
            let v = r[4];
            if v.fract() != 0.0 || v.abs() > 1e15 {
                return Err(Error::at_line(
                    path,
                    line,
                    ErrorKind::Syntax(format!("group must be an integer, got {v}")),
                ));
            }
            g.push(v as i64);
        }
        Some(g)
    } else {
        None
    };
    Ok((segments, groups))
}

/// Runs the subcommand: the JSON result (and the files asked for).
pub fn run(a: &VanishingArgs) -> Result<String> {
    let (raw, groups) = read_segments(&a.segments)?;
    if raw.len() < a.min_segments.max(2) {
        return Err(Error::new(
            &a.segments,
            ErrorKind::Shape(format!(
                "{} segments, fewer than --min-segments ({}): no vanishing point can be found",
                raw.len(),
                a.min_segments.max(2)
            )),
        ));
    }
    let spec = a.intrinsics.as_deref().map(load_camera).transpose()?;
    let camera: Option<Camera<f64>> = spec.map(|s| s.camera);
    let config = VanishingConfig {
        ransac: RansacConfig {
            threshold: a.threshold,
            max_iterations: a.max_iters,
            seed: a.seed,
            ..VanishingConfig::<f64>::default().ransac
        },
        min_segments: a.min_segments,
        max_points: a.max_points,
        min_length: a.min_length,
    };
    let params = config
        .check()
        .map_err(|e| Error::camgeom("invalid options", e))?;
    // The pinhole image of the segments: lens distortion removed when there is any.
    let segments: Vec<Segment<f64>> = match camera.filter(|c| !c.lens.is_pinhole()) {
        Some(c) => {
            let mut out = Vec::with_capacity(raw.len());
            for (row, s) in raw.iter().enumerate() {
                let fail = |e| Error::camgeom(format!("undistorting segment {row}"), e);
                out.push(Segment::new(
                    c.undistort_pixel(&s.a).map_err(fail)?,
                    c.undistort_pixel(&s.b).map_err(fail)?,
                ));
            }
            out
        }
        None => raw.clone(),
    };
    let n = segments.len();
    let (mut labels, mut index, mut mask) = (vec![0u8; n], vec![0u32; n], vec![false; n]);
    let mut found = [VanishingPoint::default(); MAX_POINTS];
    let count = find_vanishing_points(
        &segments,
        &params,
        &mut labels,
        &mut index,
        &mut mask,
        &mut found,
    )
    .map_err(|e| {
        Error::camgeom(
            format!(
                "{}: find_vanishing_points failed on {n} segments",
                a.segments.display()
            ),
            e,
        )
    })?;
    let points = found.get(..count).unwrap_or(&[]);

    let background = a.image.as_deref().map(load_rgb).transpose()?;
    let centre = match (&camera, &background) {
        (Some(c), _) => [c.intrinsics.cx(), c.intrinsics.cy()],
        (None, Some(img)) => [
            (f64::from(img.width()) - 1.0) / 2.0,
            (f64::from(img.height()) - 1.0) / 2.0,
        ],
        (None, None) => {
            let (lo, hi) = extent(&segments);
            [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0]
        }
    };

    let out_points: Vec<PointOutput> = points
        .iter()
        .enumerate()
        .map(|(k, v)| point_output(k, v, &labels, groups.as_deref(), &camera, centre))
        .collect();
    let angles = camera.map(|_| {
        let mut angles = Vec::new();
        for i in 0..out_points.len() {
            for j in i + 1..out_points.len() {
                if let (Some(di), Some(dj)) = (
                    out_points[i].direction_camera,
                    out_points[j].direction_camera,
                ) {
                    let dot: f64 = di.iter().zip(&dj).map(|(p, q)| p * q).sum();
                    angles.push(AngleOutput {
                        points: [i, j],
                        deg: dot.abs().min(1.0).acos().to_degrees(),
                    });
                }
            }
        }
        angles
    });
    let (horizon_out, reason) = match horizon(points, camera.as_ref().map(|c| &c.intrinsics)) {
        Ok((line, source)) => (Some(horizon_output(&line, source)), None),
        Err(e) => (None, Some(horizon_reason(points, camera.is_some(), &e, a))),
    };

    if let Some(path) = &a.labels_out {
        let rows = labels.iter().enumerate().map(|(i, &l)| {
            let label = if l == NO_POINT {
                "-1".to_string()
            } else {
                l.to_string()
            };
            [i.to_string(), label]
        });
        write_file(path, format_csv(&["segment", "label"], rows))?;
    }
    if let Some(path) = &a.overlay {
        let size = spec.and_then(|s| s.image_size);
        let picture = draw_overlay(
            background,
            size,
            &raw,
            &labels,
            points,
            horizon_out.as_ref(),
        );
        save_picture(&picture, path)?;
    }
    Ok(to_json(&VanishingOutput {
        segments: n,
        short_segments: segments
            .iter()
            .filter(|s| !(s.length() >= a.min_length && s.length() > 0.0))
            .count(),
        centre,
        vanishing_points: out_points,
        horizon: horizon_out,
        horizon_reason: reason,
        angles_deg: angles,
    }))
}

/// The smallest and largest endpoint coordinates of `segments` (`[0, 0]` twice for none).
fn extent(segments: &[Segment<f64>]) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in segments.iter().flat_map(|s| [s.a, s.b]) {
        lo = [lo[0].min(p.x), lo[1].min(p.y)];
        hi = [hi[0].max(p.x), hi[1].max(p.y)];
    }
    if lo[0] > hi[0] {
        return ([0.0; 2], [0.0; 2]);
    }
    (lo, hi)
}

/// Angle of `(x, y)` in degrees, folded into (-90, 90] (a direction without sign).
fn fold_deg(x: f64, y: f64) -> f64 {
    let d = y.atan2(x).to_degrees();
    if d > 90.0 {
        d - 180.0
    } else if d <= -90.0 {
        d + 180.0
    } else {
        d
    }
}

fn point_output(
    k: usize,
    v: &VanishingPoint<f64>,
    labels: &[u8],
    groups: Option<&[i64]>,
    camera: &Option<Camera<f64>>,
    centre: [f64; 2],
) -> PointOutput {
    let h = *v.point.normalized().coords();
    let finite = v.point.to_euclidean().ok();
    let direction_deg = match finite {
        Some(p) => (p.y - centre[1]).atan2(p.x - centre[0]).to_degrees(),
        None => fold_deg(h.x, h.y),
    };
    let (group, group_share) = match groups {
        Some(g) => {
            let mine: Vec<i64> = labels
                .iter()
                .zip(g)
                .filter(|(l, _)| usize::from(**l) == k)
                .map(|(_, g)| *g)
                .collect();
            let mut counts = std::collections::BTreeMap::new();
            for g in &mine {
                *counts.entry(*g).or_insert(0usize) += 1;
            }
            match counts
                .into_iter()
                .max_by_key(|&(g, c)| (c, std::cmp::Reverse(g)))
            {
                Some((g, c)) => (Some(g), Some(c as f64 / mine.len() as f64)),
                None => (None, None),
            }
        }
        None => (None, None),
    };
    let direction_camera = camera.as_ref().and_then(|c| {
        let d: Vector3<f64> = c.intrinsics.inverse_matrix() * h;
        let n = d.norm();
        if !(n > 0.0 && n.is_finite()) {
            return None;
        }
        let mut d = d / n;
        if d.z < 0.0 || (d.z == 0.0 && (d.x < 0.0 || (d.x == 0.0 && d.y < 0.0))) {
            d = -d;
        }
        Some([d.x, d.y, d.z])
    });
    PointOutput {
        x: finite.map(|p| p.x),
        y: finite.map(|p| p.y),
        h: [h.x, h.y, h.z],
        ideal: finite.is_none(),
        direction_deg,
        segments: v.segments,
        rms_px: v.rms_px,
        vertical: v.is_vertical(),
        group,
        group_share,
        direction_camera,
    }
}

fn horizon_output(line: &Line2h<f64>, source: HorizonSource) -> HorizonOutput {
    let l = line.coords();
    HorizonOutput {
        line: [l.x, l.y, l.z],
        from: match source {
            HorizonSource::TwoHorizontal => "two_horizontal",
            _ => "vertical_and_camera",
        },
        roll_deg: (!line.is_at_infinity()).then(|| fold_deg(l.y, -l.x)),
    }
}

/// Why [`horizon`] gave no line, in the terms of the command line.
fn horizon_reason(
    points: &[VanishingPoint<f64>],
    with_camera: bool,
    e: &camgeom::Error,
    a: &VanishingArgs,
) -> String {
    let vertical = points.iter().filter(|p| p.is_vertical()).count();
    let horizontal = points.len() - vertical;
    match e {
        _ if points.is_empty() => format!(
            "no vanishing point: no {} segments (--min-segments) meet at one point within {} px \
             (--threshold)",
            a.min_segments, a.threshold
        ),
        camgeom::Error::TooFewPoints if vertical > 0 && !with_camera => format!(
            "{horizontal} horizontal vanishing point(s) and a vertical one: the horizon needs \
             two horizontal ones, or the vertical one and the camera (--intrinsics)"
        ),
        camgeom::Error::TooFewPoints => format!(
            "{horizontal} horizontal vanishing point(s) and no vertical one: the horizon needs \
             two horizontal ones, or the vertical one and the camera (--intrinsics)"
        ),
        camgeom::Error::Degenerate => "the two horizontal vanishing points coincide".to_string(),
        other => format!("no horizon: {}", describe(other)),
    }
}

/// Colours of the points, in order (then again).
const PALETTE: [[u8; 3]; 8] = [
    [255, 60, 60],
    [60, 220, 60],
    [70, 140, 255],
    [255, 210, 40],
    [230, 70, 230],
    [40, 220, 220],
    [255, 140, 30],
    [160, 100, 255],
];
const UNASSIGNED: [u8; 3] = [150, 150, 150];
const HORIZON: [u8; 3] = [255, 255, 255];

/// The overlay: `background` (or a dark canvas of `size`, or of the segments' extent), the
/// segments by label, a ring and the index at each point inside the picture, the horizon.
fn draw_overlay(
    background: Option<RgbImage>,
    size: Option<(u32, u32)>,
    segments: &[Segment<f64>],
    labels: &[u8],
    points: &[VanishingPoint<f64>],
    horizon: Option<&HorizonOutput>,
) -> RgbImage {
    let mut img = background.unwrap_or_else(|| {
        let (w, h) = size.unwrap_or_else(|| {
            let (_, hi) = extent(segments);
            let side = |v: f64| (v.ceil() + 1.0).clamp(1.0, 8192.0) as u32;
            (side(hi[0]), side(hi[1]))
        });
        RgbImage::from_pixel(w, h, image::Rgb([40, 40, 40]))
    });
    let (w, h) = (img.width() as usize, img.height() as usize);
    let ink = |img: &mut RgbImage, draw: &dyn Fn(&mut GrayImage), colour: [u8; 3]| {
        let mut mask = GrayImage::filled(w, h, 0);
        draw(&mut mask);
        img.ink(&mask, colour);
    };
    let line_mask = |mask: &mut GrayImage, which: &dyn Fn(u8) -> bool| {
        if let Some(mut v) = mask.view_mut() {
            for (s, _) in segments.iter().zip(labels).filter(|(_, l)| which(**l)) {
                let _ = draw_line(&mut v, &s.a, &s.b, 255);
            }
        }
    };
    ink(&mut img, &|m| line_mask(m, &|l| l == NO_POINT), UNASSIGNED);
    for k in 0..points.len() {
        let colour = PALETTE[k % PALETTE.len()];
        ink(
            &mut img,
            &|m| line_mask(m, &|l| usize::from(l) == k),
            colour,
        );
    }
    if let Some(hz) = horizon
        && hz.roll_deg.is_some()
    {
        let [a, b, c] = hz.line;
        // The foot of the picture's centre on the line, and far along it both ways (the
        // drawing clips).
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let d = a * cx + b * cy + c;
        let foot = Point2::new(cx - d * a, cy - d * b);
        let along = (w + h) as f64 * 2.0;
        let (p, q) = (
            Point2::new(foot.x + b * along, foot.y - a * along),
            Point2::new(foot.x - b * along, foot.y + a * along),
        );
        ink(
            &mut img,
            &|m| {
                if let Some(mut v) = m.view_mut() {
                    let _ = draw_line(&mut v, &p, &q, 255);
                }
            },
            HORIZON,
        );
    }
    for (k, v) in points.iter().enumerate() {
        let Ok(p) = v.point.to_euclidean() else {
            continue;
        };
        if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= (w - 1) as f64 && p.y <= (h - 1) as f64) {
            continue;
        }
        let colour = PALETTE[k % PALETTE.len()];
        ink(
            &mut img,
            &|m| {
                if let Some(mut view) = m.view_mut() {
                    // A ring of radius 7 as 24 chords, and a cross.
                    let at = |t: f64, r: f64| Point2::new(p.x + r * t.cos(), p.y + r * t.sin());
                    for i in 0..24 {
                        let t = |i: i32| f64::from(i) * std::f64::consts::TAU / 24.0;
                        let _ = draw_line(&mut view, &at(t(i), 7.0), &at(t(i + 1), 7.0), 255);
                    }
                    let _ = draw_line(
                        &mut view,
                        &at(0.0, 3.0),
                        &at(std::f64::consts::PI, 3.0),
                        255,
                    );
                    let _ = draw_line(
                        &mut view,
                        &at(std::f64::consts::FRAC_PI_2, 3.0),
                        &at(-std::f64::consts::FRAC_PI_2, 3.0),
                        255,
                    );
                }
            },
            colour,
        );
        let text = k.to_string();
        let (lw, lh) = label_size(&text);
        img.label(p.x as usize + 9, p.y as usize + 9, &text, lw, lh);
    }
    img
}

/// PNG (fast compression), or JPEG for `.jpg` / `.jpeg`.
fn save_picture(img: &RgbImage, path: &Path) -> Result<()> {
    let jpeg = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "jpg" | "jpeg"));
    if jpeg {
        save_rgb(img, path)
    } else {
        img.save_png(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folded_angles() {
        assert_eq!(fold_deg(1.0, 0.0), 0.0);
        assert_eq!(fold_deg(-1.0, 0.0), 0.0);
        assert!((fold_deg(0.0, 1.0) - 90.0).abs() < 1e-12);
        assert!((fold_deg(0.0, -1.0) - 90.0).abs() < 1e-12);
        assert!((fold_deg(-1.0, -1.0) - 45.0).abs() < 1e-12);
        assert!((fold_deg(1.0, -1.0) + 45.0).abs() < 1e-12);
    }
}
