//! The figures of structure from motion (`sfm`, `twoview`): the reconstructed scene seen from
//! above and from the side, the correspondences between two views, and the reprojection error
//! of one view. Each is a PNG drawn with `plotters` into an RGB buffer and written as the other
//! overlays ([`Overlay::save_png`]); its text (axes, ticks, legends) comes from the DejaVu Sans
//! subset bundled in `data/fonts/` (plotters' `ab_glyph` backend), so no system font is read.
//!
//! | function | figure |
//! |---|---|
//! | [`scene_plot`] | points and camera frusta, top view (X–Z) and side view (Z–up), axes in the reconstruction's unit, a legend naming the cameras |
//! | [`correspondences_plot`] | two images side by side, a line per match: inliers [`INLIER`], outliers [`OUTLIER`] |
//! | [`reprojection_plot`] | one image, observed points (circles, [`OBSERVED`]), reprojected points (crosses, [`REPROJECTED`]), the residuals ([`RESIDUAL`], magnified ×k), the RMS |
//!
//! Conventions: camera frames are OpenCV's (x right, y down, z forward), `X_cam = R (X − C)`
//! with `R` world-to-camera and `C` the centre in the world frame; pixels have their origin at
//! the top-left corner of the image. Non-finite points are left out of every figure.

use std::path::Path;
use std::sync::OnceLock;

use camgeom::nalgebra::{Matrix3, Point2, Point3, Vector3};
use image::imageops::{self, FilterType};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::error::{Error, ErrorKind, Result};
use crate::rgb::{Overlay, RgbImage};

/// Colour of the inlier matches of [`correspondences_plot`].
pub const INLIER: [u8; 3] = [0, 210, 0];
/// Colour of the outlier matches of [`correspondences_plot`].
pub const OUTLIER: [u8; 3] = [235, 0, 0];
/// Colour of the observed points (circles) of [`reprojection_plot`].
pub const OBSERVED: [u8; 3] = [0, 200, 255];
/// Colour of the reprojected points (crosses) of [`reprojection_plot`].
pub const REPROJECTED: [u8; 3] = [255, 40, 40];
/// Colour of the residual lines (observed to reprojected, magnified) of [`reprojection_plot`].
pub const RESIDUAL: [u8; 3] = [255, 220, 0];
/// The colours of the cameras of [`scene_plot`], camera `i` in `CAMERA_COLOURS[i % 10]`
/// (bright, for the dark plotting area).
pub const CAMERA_COLOURS: [[u8; 3]; 10] = [
    [86, 180, 233],
    [255, 150, 0],
    [0, 220, 120],
    [255, 80, 80],
    [200, 140, 255],
    [240, 228, 66],
    [255, 140, 200],
    [0, 230, 230],
    [180, 230, 100],
    [255, 200, 140],
];
/// Most points [`scene_plot`] draws: more are subsampled (every k-th).
pub const MAX_SCENE_POINTS: usize = 20_000;
/// Width and height of [`scene_plot`]'s figure, pixels.
pub const SCENE_SIZE: (u32, u32) = (1640, 800);
/// Widest [`correspondences_plot`] figure (the two images side by side, scaled down to fit).
pub const MAX_PAIR_WIDTH: u32 = 1600;
/// Largest side of a [`reprojection_plot`] figure (the image scaled down to fit).
pub const MAX_VIEW_SIDE: u32 = 1200;
/// Height of the title bar above the images of [`correspondences_plot`] and
/// [`reprojection_plot`], pixels.
pub const TITLE_HEIGHT: u32 = 36;

const FONT: &[u8] = include_bytes!("../data/fonts/DejaVuSans-subset.ttf");
const SANS: &str = "sans-serif";
/// Background of the plotting areas of [`scene_plot`] and of the legends drawn on images.
const DARK: RGBColor = RGBColor(32, 32, 36);

/// One camera of [`scene_plot`].
#[derive(Clone, Debug)]
pub struct SceneCamera {
    /// Its name in the legend (an image file name, say).
    pub label: String,
    /// World-to-camera rotation `R` (`X_cam = R (X − C)`).
    pub rotation: Matrix3<f64>,
    /// Its centre `C` in the world frame.
    pub center: Point3<f64>,
    /// `(fx, fy, cx, cy)`, pixels.
    pub intrinsics: (f64, f64, f64, f64),
    /// Image width and height, pixels.
    pub size: (u32, u32),
}

/// Registers the bundled font with plotters, once per process.
fn fonts() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|name| register_font(name, FontStyle::Normal, FONT).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(Error::new(
            "data/fonts/DejaVuSans-subset.ttf",
            ErrorKind::Unsupported("the bundled font could not be read".into()),
        ))
    }
}

/// A drawing failure as an output error about `path`.
fn drawing<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> Error + '_ {
    move |e| {
        Error::new(
            path,
            ErrorKind::Write(std::io::Error::other(format!("drawing the figure: {e}"))),
        )
    }
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

fn text(size: u32, c: RGBColor) -> TextStyle<'static> {
    (SANS, size).into_font().color(&c)
}

/// Draws into `canvas` (its pixels the background) with `draw`, then writes it to `path`.
fn render<F>(path: &Path, canvas: RgbImage, draw: F) -> Result<()>
where
    F: FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
{
    fonts()?;
    let (w, h) = canvas.dimensions();
    let mut raw = canvas.into_raw();
    {
        let root = BitMapBackend::with_buffer(&mut raw, (w, h)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(drawing(path))?;
    }
    let out = RgbImage::from_raw(w, h, raw).ok_or_else(|| {
        Error::new(
            path,
            ErrorKind::Write(std::io::Error::other("figure buffer of the wrong size")),
        )
    })?;
    out.save_png(path)
}

/// `image` in grey, its contrast reduced (`40 + 0.7 v`) so coloured marks stand out, scaled by
/// `s` (box-like filter when shrinking).
fn backdrop(image: &RgbImage, s: f64) -> RgbImage {
    let (w, h) = image.dimensions();
    let (sw, sh) = (scaled(w, s), scaled(h, s));
    let small = if (sw, sh) == (w, h) {
        image.clone()
    } else {
        imageops::resize(image, sw, sh, FilterType::Triangle)
    };
    let mut out = small;
    for p in out.pixels_mut() {
        let [r, g, b] = p.0;
        let y = 0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b);
        let v = (40.0 + 0.7 * y).round().clamp(0.0, 255.0) as u8;
        p.0 = [v, v, v];
    }
    out
}

/// `n · s` rounded, at least 1.
fn scaled(n: u32, s: f64) -> u32 {
    ((f64::from(n) * s).round() as u32).max(1)
}

/// The segment `a`–`b` clipped to `[x0, x1] × [y0, y1]` (Liang–Barsky), or `None` when it
/// misses the rectangle or is not finite.
fn clip(
    a: (f64, f64),
    b: (f64, f64),
    (x0, y0, x1, y1): (f64, f64, f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return None;
    }
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

fn px(p: (f64, f64)) -> (i32, i32) {
    (p.0.round() as i32, p.1.round() as i32)
}

/// Draws the segment `a`–`b` (canvas pixels) clipped to the canvas below the title bar.
fn segment(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    a: (f64, f64),
    b: (f64, f64),
    style: ShapeStyle,
) -> std::result::Result<
    (),
    DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>,
> {
    let (w, h) = area.dim_in_pixel();
    let rect = (
        0.0,
        f64::from(TITLE_HEIGHT),
        f64::from(w) - 1.0,
        f64::from(h) - 1.0,
    );
    match clip(a, b, rect) {
        Some((p, q)) => area.draw(&PathElement::new(vec![px(p), px(q)], style)),
        None => Ok(()),
    }
}

/// A legend box at `(x, y)` on `area`: one row per `(marker, text)`, the marker drawn by
/// `marker(area, left, centre_y)`.
type Marker<'m> = Box<dyn Fn(&DrawingArea<BitMapBackend<'_>, Shift>, i32, i32) + 'm>;

fn legend(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    (x, y): (i32, i32),
    rows: &[(Marker<'_>, String)],
    path: &Path,
) -> Result<()> {
    let size = 16;
    let style = text(size, WHITE);
    let mut width = 0;
    for (_, t) in rows {
        let (tw, _) = area.estimate_text_size(t, &style).map_err(drawing(path))?;
        width = width.max(tw as i32);
    }
    let row_h = 22;
    let (w, h) = (width + 52, row_h * rows.len() as i32 + 10);
    area.draw(&Rectangle::new(
        [(x, y), (x + w, y + h)],
        DARK.mix(0.85).filled(),
    ))
    .map_err(drawing(path))?;
    for (i, (marker, t)) in rows.iter().enumerate() {
        let cy = y + 5 + row_h * i as i32 + row_h / 2;
        marker(area, x + 8, cy);
        area.draw(&Text::new(
            t.clone(),
            (x + 44, cy),
            style.pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
        ))
        .map_err(drawing(path))?;
    }
    Ok(())
}

/// A legend marker: a short line in `c`.
fn line_marker<'m>(c: [u8; 3]) -> Marker<'m> {
    Box::new(move |area, x, y| {
        let _ = area.draw(&PathElement::new(
            vec![(x, y), (x + 28, y)],
            rgb(c).stroke_width(2),
        ));
    })
}

/// Writes the two images side by side (scaled down to [`MAX_PAIR_WIDTH`] at most, in grey) with
/// a line per match from its pixel in `a` to its pixel in `b`: inliers ([`INLIER`]) over
/// outliers ([`OUTLIER`]), `title` above, a legend with the counts.
///
/// `matches`: `(pixel in a, pixel in b, inlier)`, pixels of the full-size images (for example
/// the rows of `camgeom twoview --matches-out`).
///
/// # Errors
/// [`ErrorKind::Write`] when the PNG cannot be written or drawing fails.
pub fn correspondences_plot(
    path: &Path,
    a: &RgbImage,
    b: &RgbImage,
    matches: &[(Point2<f64>, Point2<f64>, bool)],
    title: &str,
) -> Result<()> {
    let total = u64::from(a.width()) + u64::from(b.width());
    let s = (f64::from(MAX_PAIR_WIDTH) / total as f64).min(1.0);
    let (ga, gb) = (backdrop(a, s), backdrop(b, s));
    let (w, h) = (
        ga.width() + gb.width(),
        ga.height().max(gb.height()) + TITLE_HEIGHT,
    );
    let mut canvas = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    imageops::replace(&mut canvas, &ga, 0, i64::from(TITLE_HEIGHT));
    imageops::replace(
        &mut canvas,
        &gb,
        i64::from(ga.width()),
        i64::from(TITLE_HEIGHT),
    );
    let off_b = f64::from(ga.width());
    let top = f64::from(TITLE_HEIGHT);
    let on_image =
        |e: (f64, f64)| e.0 >= 0.0 && e.0 < f64::from(w) && e.1 >= top && e.1 < f64::from(h);
    let inliers = matches.iter().filter(|m| m.2).count();
    let outliers = matches.len() - inliers;
    render(path, canvas, |root| {
        let err = drawing(path);
        root.draw(&Text::new(title.to_string(), (10, 8), text(20, BLACK)))
            .map_err(&err)?;
        // Outliers first: the inliers, the answer, on top.
        for want in [false, true] {
            let c = if want { INLIER } else { OUTLIER };
            for (p, q, inlier) in matches {
                if *inlier != want {
                    continue;
                }
                let u = (p.x * s, p.y * s + top);
                let v = (q.x * s + off_b, q.y * s + top);
                segment(root, u, v, rgb(c).stroke_width(1)).map_err(&err)?;
                for e in [u, v] {
                    if on_image(e) {
                        root.draw(&Circle::new(px(e), 2, rgb(c).filled()))
                            .map_err(&err)?;
                    }
                }
            }
        }
        let share = |n: usize| {
            if matches.is_empty() {
                0.0
            } else {
                100.0 * n as f64 / matches.len() as f64
            }
        };
        let rows = vec![
            (
                line_marker(INLIER),
                format!("inliers: {inliers} ({:.1} %)", share(inliers)),
            ),
            (
                line_marker(OUTLIER),
                format!("outliers: {outliers} ({:.1} %)", share(outliers)),
            ),
        ];
        legend(root, (8, TITLE_HEIGHT as i32 + 8), &rows, path)
    })
}

/// The magnification of the residual lines: the largest of 1, 2, 5, 10, 20, 50, ... that draws
/// an RMS residual of `rms_px` (figure pixels) no longer than about 12 pixels.
fn auto_magnify(rms_px: f64) -> f64 {
    if !(rms_px.is_finite() && rms_px > 0.0) {
        return 1.0;
    }
    let want = 12.0 / rms_px;
    let mut k = 1.0;
    for step in [2.0, 2.5, 2.0].iter().cycle().take(30) {
        if k * step > want {
            break;
        }
        k *= step;
    }
    k
}

/// Writes `image` (scaled down to [`MAX_VIEW_SIDE`] at most, in grey) with each observed point
/// as a circle ([`OBSERVED`]), its reprojection as a cross ([`REPROJECTED`]) and a line
/// ([`RESIDUAL`]) from the observation along the residual `reprojected − observed`, magnified
/// `×k`; `title` above with the RMS residual `√(Σ|r_i − o_i|² / n)` in pixels of `image`, and a
/// legend saying `k`.
///
/// `magnify`: `k` (at least 1); `None` chooses it so that the RMS residual is drawn about 12
/// pixels long (1, 2, 5, 10, ...).
///
/// # Errors
/// [`ErrorKind::Shape`] when `observed` and `reprojected` differ in length;
/// [`ErrorKind::Write`] when the PNG cannot be written or drawing fails.
pub fn reprojection_plot(
    path: &Path,
    image: &RgbImage,
    observed: &[Point2<f64>],
    reprojected: &[Point2<f64>],
    magnify: Option<f64>,
    title: &str,
) -> Result<()> {
    if observed.len() != reprojected.len() {
        return Err(Error::new(
            path,
            ErrorKind::Shape(format!(
                "{} observed points but {} reprojected ones",
                observed.len(),
                reprojected.len()
            )),
        ));
    }
    let pairs: Vec<(Point2<f64>, Point2<f64>)> = observed
        .iter()
        .zip(reprojected)
        .filter(|(o, r)| {
            o.coords
                .iter()
                .chain(r.coords.iter())
                .all(|v| v.is_finite())
        })
        .map(|(o, r)| (*o, *r))
        .collect();
    let rms = if pairs.is_empty() {
        0.0
    } else {
        (pairs
            .iter()
            .map(|(o, r)| (r - o).norm_squared())
            .sum::<f64>()
            / pairs.len() as f64)
            .sqrt()
    };
    let side = image.width().max(image.height());
    let s = (f64::from(MAX_VIEW_SIDE) / f64::from(side)).min(1.0);
    let k = match magnify {
        Some(k) if k.is_finite() && k >= 1.0 => k,
        _ => auto_magnify(rms * s),
    };
    let g = backdrop(image, s);
    let mut canvas = RgbImage::from_pixel(
        g.width(),
        g.height() + TITLE_HEIGHT,
        image::Rgb([255, 255, 255]),
    );
    imageops::replace(&mut canvas, &g, 0, i64::from(TITLE_HEIGHT));
    let top = f64::from(TITLE_HEIGHT);
    let at = |p: &Point2<f64>| (p.x * s, p.y * s + top);
    render(path, canvas, |root| {
        let err = drawing(path);
        let heading = format!("{title} — RMS {rms:.2} px over {} points", pairs.len());
        root.draw(&Text::new(heading, (10, 8), text(20, BLACK)))
            .map_err(&err)?;
        for (o, r) in &pairs {
            let a = at(o);
            let d = (r - o) * (k * s);
            segment(
                root,
                a,
                (a.0 + d.x, a.1 + d.y),
                rgb(RESIDUAL).stroke_width(1),
            )
            .map_err(&err)?;
        }
        for (o, _) in &pairs {
            let a = at(o);
            if a.0 >= 0.0
                && a.0 < f64::from(g.width())
                && a.1 >= top
                && a.1 < top + f64::from(g.height())
            {
                root.draw(&Circle::new(px(a), 4, rgb(OBSERVED).stroke_width(1)))
                    .map_err(&err)?;
            }
        }
        for (_, r) in &pairs {
            let (x, y) = at(r);
            for (dx, dy) in [(3.0, 3.0), (3.0, -3.0)] {
                segment(
                    root,
                    (x - dx, y - dy),
                    (x + dx, y + dy),
                    rgb(REPROJECTED).stroke_width(1),
                )
                .map_err(&err)?;
            }
        }
        let circle: Marker<'_> = Box::new(|area, x, y| {
            let _ = area.draw(&Circle::new((x + 14, y), 4, rgb(OBSERVED).stroke_width(1)));
        });
        let cross: Marker<'_> = Box::new(|area, x, y| {
            let style = rgb(REPROJECTED).stroke_width(1);
            let _ = area.draw(&PathElement::new(
                vec![(x + 11, y - 3), (x + 17, y + 3)],
                style,
            ));
            let _ = area.draw(&PathElement::new(
                vec![(x + 11, y + 3), (x + 17, y - 3)],
                style,
            ));
        });
        let residual = if k == 1.0 {
            "residual".to_string()
        } else {
            format!("residual ×{k}")
        };
        let rows = vec![
            (circle, format!("observed ({})", pairs.len())),
            (cross, "reprojected".to_string()),
            (line_marker(RESIDUAL), residual),
            (
                Box::new(|_: &DrawingArea<BitMapBackend<'_>, Shift>, _, _| {}) as Marker<'_>,
                format!("RMS {rms:.2} px"),
            ),
        ];
        legend(root, (8, TITLE_HEIGHT as i32 + 8), &rows, path)
    })
}

/// Quantile `q` in `[0, 1]` of `sorted` (not empty), nearest rank.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// The axis-aligned box of the scene: the 2 %–98 % quantiles of the points along each axis
/// (outliers do not stretch it), with the camera centres, padded by 5 %.
fn scene_box(points: &[Point3<f64>], cameras: &[SceneCamera]) -> [(f64, f64); 3] {
    let mut out = [(f64::INFINITY, f64::NEG_INFINITY); 3];
    for (axis, range) in out.iter_mut().enumerate() {
        let mut v: Vec<f64> = points.iter().map(|p| p[axis]).collect();
        if !v.is_empty() {
            v.sort_by(f64::total_cmp);
            *range = (quantile(&v, 0.02), quantile(&v, 0.98));
        }
        for c in cameras {
            let x = c.center[axis];
            if x.is_finite() {
                *range = (range.0.min(x), range.1.max(x));
            }
        }
        if !(range.0.is_finite() && range.1.is_finite()) {
            *range = (-1.0, 1.0);
        }
    }
    let extent = out
        .iter()
        .map(|(a, b)| b - a)
        .fold(0.0_f64, f64::max)
        .max(1e-9);
    for range in &mut out {
        let pad = 0.05 * extent;
        *range = (range.0 - pad, range.1 + pad);
    }
    out
}

/// The five corners of camera `c`'s frustum in the world frame: the centre, then the image
/// corners `(0, 0)`, `(w, 0)`, `(w, h)`, `(0, h)` back-projected to depth `depth`.
fn frustum(c: &SceneCamera, depth: f64) -> Option<[Point3<f64>; 5]> {
    let (fx, fy, cx, cy) = c.intrinsics;
    if !(fx.is_finite() && fy.is_finite() && fx != 0.0 && fy != 0.0) {
        return None;
    }
    let (w, h) = (f64::from(c.size.0), f64::from(c.size.1));
    let rt = c.rotation.transpose();
    let corner = |u: f64, v: f64| {
        let ray = Vector3::new((u - cx) / fx, (v - cy) / fy, 1.0) * depth;
        c.center + rt * ray
    };
    let out = [
        c.center,
        corner(0.0, 0.0),
        corner(w, 0.0),
        corner(w, h),
        corner(0.0, h),
    ];
    out.iter()
        .all(|p| p.coords.iter().all(|v| v.is_finite()))
        .then_some(out)
}

/// Writes the reconstructed scene: two panels, the top view (X to the right, Z up: the scene
/// seen from above, camera frames' `−Y` being up) and the side view (Z to the right, `−Y` up:
/// seen from `+X`), each with its axes and ticks in `unit` (for example `"initial baseline"`
/// or `"m"`; empty: no unit), on an equal scale along both axes. The points are drawn in their
/// colours (at most [`MAX_SCENE_POINTS`]: every k-th beyond), each camera as a frustum (its
/// image corners back-projected to 8 % of the scene's extent) in `CAMERA_COLOURS[i % 10]`,
/// numbered `i + 1`; the legend names the cameras (`label`) and says how many points there
/// are. The view ranges follow the 2 %–98 % quantiles of the points and the cameras, so a few
/// far points do not shrink the scene. The figure is [`SCENE_SIZE`].
///
/// # Errors
/// [`ErrorKind::Write`] when the PNG cannot be written or drawing fails.
pub fn scene_plot(
    path: &Path,
    points: &[(Point3<f64>, [u8; 3])],
    cameras: &[SceneCamera],
    unit: &str,
) -> Result<()> {
    let finite: Vec<&(Point3<f64>, [u8; 3])> = points
        .iter()
        .filter(|(p, _)| p.coords.iter().all(|v| v.is_finite()))
        .collect();
    let stride = finite.len().div_ceil(MAX_SCENE_POINTS).max(1);
    let shown: Vec<&(Point3<f64>, [u8; 3])> = finite.iter().step_by(stride).copied().collect();
    let coords: Vec<Point3<f64>> = finite.iter().map(|(p, _)| *p).collect();
    let mut bbox = scene_box(&coords, cameras);
    let extent = bbox.iter().map(|(a, b)| b - a).fold(0.0_f64, f64::max);
    let depth = 0.08 * extent;
    let frusta: Vec<Option<[Point3<f64>; 5]>> = cameras.iter().map(|c| frustum(c, depth)).collect();
    for f in frusta.iter().flatten() {
        for p in f {
            for (axis, range) in bbox.iter_mut().enumerate() {
                *range = (range.0.min(p[axis]), range.1.max(p[axis]));
            }
        }
    }
    let (w, h) = SCENE_SIZE;
    let canvas = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let legend_w = 330;
    let n_points = finite.len();
    render(path, canvas, |root| {
        let err = drawing(path);
        let heading = format!(
            "Reconstruction: {n_points} points, {} cameras",
            cameras.len()
        );
        let body = root.titled(&heading, text(22, BLACK)).map_err(&err)?;
        let (panels, side) = body.split_horizontally(w - legend_w);
        let halves = panels.split_evenly((1, 2));
        let with_unit = |axis: &str| {
            if unit.is_empty() {
                axis.to_string()
            } else {
                format!("{axis} (unit: {unit})")
            }
        };
        // (panel caption, horizontal axis, vertical axis, projection)
        type Proj = fn(&Point3<f64>) -> (f64, f64);
        let views: [(&str, String, String, Proj); 2] = [
            (
                "top view (from above)",
                with_unit("X"),
                with_unit("Z"),
                |p| (p.x, p.z),
            ),
            (
                "side view (from +X)",
                with_unit("Z"),
                with_unit("−Y, up"),
                |p| (p.z, -p.y),
            ),
        ];
        // The eight corners of the scene's box, each panel's ranges being their projection.
        let corners: Vec<Point3<f64>> = (0..8)
            .map(|i| {
                let pick = |axis: usize| {
                    let (lo, hi) = bbox[axis];
                    if i & (1 << axis) == 0 { lo } else { hi }
                };
                Point3::new(pick(0), pick(1), pick(2))
            })
            .collect();
        let span = |f: &dyn Fn(&Point3<f64>) -> f64| {
            corners
                .iter()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        };
        for (area, (caption, xdesc, ydesc, proj)) in halves.iter().zip(views) {
            let area = area.titled(caption, text(18, BLACK)).map_err(&err)?;
            let (aw, ah) = area.dim_in_pixel();
            let (margin, xlab, ylab) = (12_i32, 52_i32, 70_i32);
            let pw = (aw as i32 - 2 * margin - ylab).max(10) as f64;
            let ph = (ah as i32 - 2 * margin - xlab).max(10) as f64;
            let (hr, vr) = (span(&|p| proj(p).0), span(&|p| proj(p).1));
            // Equal scale: the larger units-per-pixel of the two, both ranges grown about
            // their middles to it.
            let upp = ((hr.1 - hr.0) / pw).max((vr.1 - vr.0) / ph).max(1e-12);
            let grow = |r: (f64, f64), n: f64| {
                let mid = 0.5 * (r.0 + r.1);
                (mid - 0.5 * upp * n, mid + 0.5 * upp * n)
            };
            let (hr, vr) = (grow(hr, pw), grow(vr, ph));
            let mut chart = ChartBuilder::on(&area)
                .margin(margin)
                .x_label_area_size(xlab)
                .y_label_area_size(ylab)
                .build_cartesian_2d(hr.0..hr.1, vr.0..vr.1)
                .map_err(&err)?;
            chart.plotting_area().fill(&DARK).map_err(&err)?;
            chart
                .configure_mesh()
                .x_desc(xdesc)
                .y_desc(ydesc)
                .label_style(text(14, BLACK))
                .axis_desc_style(text(15, BLACK))
                .bold_line_style(RGBColor(80, 80, 88))
                .light_line_style(RGBColor(48, 48, 54))
                .x_labels(8)
                .y_labels(8)
                .draw()
                .map_err(&err)?;
            let inside = |(x, y): (f64, f64)| x >= hr.0 && x <= hr.1 && y >= vr.0 && y <= vr.1;
            chart
                .draw_series(shown.iter().filter_map(|(p, c)| {
                    let q = proj(p);
                    inside(q).then(|| Circle::new(q, 1, rgb(*c).filled()))
                }))
                .map_err(&err)?;
            for (i, f) in frusta.iter().enumerate() {
                let Some(f) = f else { continue };
                let colour = rgb(CAMERA_COLOURS[i % CAMERA_COLOURS.len()]);
                let style = colour.stroke_width(2);
                let q: Vec<(f64, f64)> = f.iter().map(proj).collect();
                let edges = [
                    (0, 1),
                    (0, 2),
                    (0, 3),
                    (0, 4),
                    (1, 2),
                    (2, 3),
                    (3, 4),
                    (4, 1),
                ];
                chart
                    .draw_series(
                        edges
                            .iter()
                            .map(|&(a, b)| PathElement::new(vec![q[a], q[b]], style)),
                    )
                    .map_err(&err)?;
                if cameras.len() <= 40 {
                    chart
                        .draw_series(std::iter::once(Text::new(
                            format!("{}", i + 1),
                            q[0],
                            text(13, colour),
                        )))
                        .map_err(&err)?;
                }
            }
        }
        // The legend: a dark column, the points then one row per camera (as many as fit).
        let side = side.margin(40, 12, 8, 12);
        side.fill(&DARK).map_err(&err)?;
        let (_, sh) = side.dim_in_pixel();
        let row_h = 22_i32;
        let mut y = 12;
        side.draw(&Text::new("legend", (12, y), text(16, WHITE)))
            .map_err(&err)?;
        y += row_h + 4;
        side.draw(&Circle::new(
            (22, y + 8),
            3,
            RGBColor(200, 200, 200).filled(),
        ))
        .map_err(&err)?;
        let pts = if stride > 1 {
            format!("points: {n_points} (1 in {stride} shown)")
        } else {
            format!("points: {n_points}")
        };
        side.draw(&Text::new(pts, (44, y), text(15, WHITE)))
            .map_err(&err)?;
        y += row_h;
        let room = ((sh as i32 - y - 8) / row_h).max(0) as usize;
        let listed = if cameras.len() > room {
            room.saturating_sub(1)
        } else {
            cameras.len()
        };
        for (i, c) in cameras.iter().enumerate().take(listed) {
            let colour = rgb(CAMERA_COLOURS[i % CAMERA_COLOURS.len()]);
            side.draw(&PathElement::new(
                vec![(12, y + 8), (36, y + 8)],
                colour.stroke_width(3),
            ))
            .map_err(&err)?;
            side.draw(&Text::new(
                format!("{} {}", i + 1, c.label),
                (44, y),
                text(15, WHITE),
            ))
            .map_err(&err)?;
            y += row_h;
        }
        if listed < cameras.len() {
            side.draw(&Text::new(
                format!("… and {} more cameras", cameras.len() - listed),
                (44, y),
                text(15, WHITE),
            ))
            .map_err(&err)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_inside_part() {
        let r = (0.0, 0.0, 10.0, 10.0);
        assert_eq!(
            clip((-5.0, 5.0), (15.0, 5.0), r),
            Some(((0.0, 5.0), (10.0, 5.0)))
        );
        assert_eq!(clip((-5.0, -5.0), (-1.0, 20.0), r), None);
        assert_eq!(clip((1.0, 1.0), (f64::NAN, 2.0), r), None);
        assert_eq!(
            clip((2.0, 3.0), (4.0, 5.0), r),
            Some(((2.0, 3.0), (4.0, 5.0)))
        );
    }

    #[test]
    fn magnification_steps() {
        assert_eq!(auto_magnify(0.0), 1.0);
        assert_eq!(auto_magnify(20.0), 1.0);
        assert_eq!(auto_magnify(5.0), 2.0);
        assert_eq!(auto_magnify(1.0), 10.0);
        assert_eq!(auto_magnify(0.3), 20.0);
    }
}
