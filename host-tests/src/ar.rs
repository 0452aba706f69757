//! The AR loop on owned frames: [`camgeom::target::PlanarTarget::step`] over a sequence, and
//! overlays with the target outline, the tracked features and a cube standing on the target
//! (for `camgeom ar` and the sequence tests).

use camgeom::camera::Camera;
use camgeom::draw::{WireframeParams, cube, draw_line, draw_wireframe};
use camgeom::image::ImageMut;
use camgeom::klt::Fixed;
use camgeom::nalgebra::{Point2, Point3};
use camgeom::pose::PlanarPose;
use camgeom::pyramid::{PyramidPair, buffer_len};
use camgeom::target::{
    Acquire, PlanarTarget, TargetConfig, TargetFrame, TargetParams, TargetState,
    corner_scratch_len, flow_scratch_len,
};

use crate::images::GrayImage;
use crate::klt::{Path, levels};
use crate::rgb::{Overlay, RgbImage};

/// Most features the target tracks (the `N` of [`PlanarTarget`]).
pub const MAX_FEATURES: usize = 128;

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArOptions {
    /// The target's size `(w, h)` (metres): its corners are `(0, 0), (w, 0), (w, h), (0, h)`.
    pub size: [f32; 2],
    /// Edge of the cube drawn on the target, centred on it.
    pub cube: f32,
    /// Flow arithmetic.
    pub path: Path,
    /// The tracker's configuration.
    pub target: TargetConfig,
}

/// The outcome of one frame: the core's [`TargetFrame`] and the features behind it.
#[derive(Debug, Clone, PartialEq)]
pub struct ArFrame {
    /// 0-based index in the sequence.
    pub index: usize,
    /// What the loop found: state, poses, outline, counts.
    pub frame: TargetFrame,
    /// Image positions of the features tracked after the frame.
    pub features: Vec<Point2<f32>>,
    /// Their target-plane positions, in the same order.
    pub targets: Vec<Point2<f32>>,
}

impl ArFrame {
    /// Largest distance (pixels) between the target's corners projected through the best pose
    /// and the frame's outline (the homography's corners): how well the pose explains the
    /// homography. `None` without both.
    pub fn outline_error_px(&self, camera: &Camera<f32>, size: [f32; 2]) -> Option<f32> {
        let (pose, outline) = (self.frame.pose?, self.frame.outline?);
        let corners = camgeom::target::corners_3d(size[0], size[1]);
        let mut worst = 0.0f32;
        for (c, o) in corners.iter().zip(outline.iter()) {
            let p = camera.project(&pose.best.pose, c).ok()?;
            worst = worst.max((p - o).norm());
        }
        Some(worst)
    }
}

/// The target tracker of the host: `MAX_FEATURES` tracks, work buffers for any window up to
/// [`camgeom::klt::MAX_WIN`] and frames up to [`MAX_WIDTH`] pixels wide.
pub type HostTarget<A> = PlanarTarget<
    A,
    MAX_FEATURES,
    { flow_scratch_len(camgeom::klt::MAX_WIN) },
    { corner_scratch_len(MAX_WIDTH) },
    2048,
>;

/// Widest frame [`run_ar`] takes.
pub const MAX_WIDTH: usize = 4096;

/// Runs the AR loop ([`PlanarTarget::step`], the same per-frame policy as the board) over
/// `frames`; `acquire` finds the target (e.g. [`camgeom::target::GivenCorners`] from the corners picked in
/// frame 0). `on_frame` sees every frame's outcome as it is computed.
///
/// Errors: as [`TargetParams::new`] and [`PlanarTarget::step`]; [`camgeom::Error::InvalidImage`]
/// for frames of different sizes or wider than [`MAX_WIDTH`].
pub fn run_ar(
    frames: &[GrayImage],
    acquire: &mut dyn Acquire,
    camera: &Camera<f32>,
    opts: &ArOptions,
    mut on_frame: impl FnMut(&ArFrame),
) -> camgeom::Result<Vec<ArFrame>> {
    if frames.is_empty() {
        return Err(camgeom::Error::TooFewPoints);
    }
    let mut tracker = ArTracker::new(camera, opts)?;
    let mut out = Vec::with_capacity(frames.len());
    for img in frames {
        let f = tracker.step(img, acquire)?;
        on_frame(&f);
        out.push(f);
    }
    Ok(out)
}

/// The tracker in either arithmetic.
enum Tracker {
    Fixed(Box<HostTarget<Fixed>>),
    F32(Box<HostTarget<f32>>),
}

/// The AR loop one frame at a time, for frames that arrive one by one (a video): the target
/// tracker, its parameters and the two pyramids, sized by the first frame.
pub struct ArTracker {
    params: TargetParams,
    tracker: Tracker,
    pair: Option<PyramidPair<Vec<u8>, Vec<u8>>>,
    size: (usize, usize),
    index: usize,
}

impl ArTracker {
    /// A tracker for `opts` through `camera`.
    ///
    /// Errors: as [`TargetParams::new`].
    pub fn new(camera: &Camera<f32>, opts: &ArOptions) -> camgeom::Result<Self> {
        Ok(Self {
            params: TargetParams::new(&opts.target, *camera, opts.size)?,
            tracker: match opts.path {
                Path::Fixed => Tracker::Fixed(Box::default()),
                Path::F32 => Tracker::F32(Box::default()),
            },
            pair: None,
            size: (0, 0),
            index: 0,
        })
    }

    /// Tracks the target into `img`, the next frame ([`PlanarTarget::step`]).
    ///
    /// Errors: as [`PlanarTarget::step`]; [`camgeom::Error::InvalidImage`] for a frame of
    /// another size than the first or wider than [`MAX_WIDTH`].
    pub fn step(&mut self, img: &GrayImage, acquire: &mut dyn Acquire) -> camgeom::Result<ArFrame> {
        let levels = levels(&self.params.config().lk);
        if self.pair.is_none() {
            let (w, h) = (img.width, img.height);
            if w > MAX_WIDTH {
                return Err(camgeom::Error::InvalidImage);
            }
            let mut pair = PyramidPair::new(
                [vec![0u8; w * h], vec![0u8; w * h]],
                [(); 2].map(|()| vec![0u8; buffer_len(w, h, levels)]),
            );
            pair.set_geometry(w, h, levels)?;
            self.pair = Some(pair);
            self.size = (w, h);
        }
        let pair = self.pair.as_mut().ok_or(camgeom::Error::InvalidImage)?;
        if (img.width, img.height) != self.size {
            return Err(camgeom::Error::InvalidImage);
        }
        pair.capture()?
            .copy_from(&img.view().ok_or(camgeom::Error::InvalidImage)?)?;
        let pyramids = pair.advance()?;
        let prev = pyramids.previous.as_ref();
        let p = &self.params;
        let (frame, features, targets) = match &mut self.tracker {
            Tracker::Fixed(t) => {
                let frame = t.step(p, prev, &pyramids.next, acquire, &mut ())?;
                (
                    frame,
                    t.features().map(|(p, _)| p).collect(),
                    t.features().map(|(_, q)| q).collect(),
                )
            }
            Tracker::F32(t) => {
                let frame = t.step(p, prev, &pyramids.next, acquire, &mut ())?;
                (
                    frame,
                    t.features().map(|(p, _)| p).collect(),
                    t.features().map(|(_, q)| q).collect(),
                )
            }
        };
        let f = ArFrame {
            index: self.index,
            frame,
            features,
            targets,
        };
        self.index += 1;
        Ok(f)
    }
}

/// Outline colour (green), cube (yellow), features (cyan), lost-frame marker (red).
const OUTLINE: [u8; 3] = [40, 230, 40];
const CUBE: [u8; 3] = [255, 220, 0];
const FEATURE: [u8; 3] = [0, 220, 255];
const LOST: [u8; 3] = [255, 40, 40];

/// The overlay of one frame: the target outline (the homography's corners), a cube of edge
/// `opts.cube` centred on the target and standing on it (drawn with the best pose through
/// [`draw_wireframe`]), the tracked features as small crosses, and a red frame border when the
/// target is lost.
pub fn draw_ar(img: &GrayImage, camera: &Camera<f32>, f: &ArFrame, opts: &ArOptions) -> RgbImage {
    draw_ar_on(RgbImage::from_gray(img), camera, f, opts)
}

/// [`draw_ar`] on a frame already in colour (`frame`, the frame's own colours or its grey).
pub fn draw_ar_on(
    frame: RgbImage,
    camera: &Camera<f32>,
    f: &ArFrame,
    opts: &ArOptions,
) -> RgbImage {
    draw_target_on(
        frame,
        Some(camera),
        &f.frame,
        &f.features,
        opts.size,
        opts.cube,
    )
}

/// The overlay of [`draw_ar_on`] from what the loop found (`f`, a target of `size` metres,
/// with a cube of edge `cube_edge` drawn through `camera`, none without one) and the features
/// tracked (none for a board's record, which does not carry them).
pub fn draw_target_on(
    frame: RgbImage,
    camera: Option<&Camera<f32>>,
    f: &TargetFrame,
    features: &[Point2<f32>],
    size: [f32; 2],
    cube_edge: f32,
) -> RgbImage {
    let mut out = frame;
    let (width, height) = (out.width() as usize, out.height() as usize);
    let blank = || GrayImage::filled(width, height, 0);
    if let Some(outline) = f.outline {
        let mut m = blank();
        if let Some(mut v) = m.view_mut() {
            for (a, b) in outline.iter().zip(outline.iter().cycle().skip(1)) {
                let _ = draw_line(&mut v, a, b, 255);
            }
        }
        out.ink(&m, OUTLINE);
    }
    if let (Some(pose), Some(camera)) = (f.pose, camera) {
        let s = cube_edge;
        let (x, y) = ((size[0] - s) / 2.0, (size[1] - s) / 2.0);
        let (vertices, edges) = cube(x, y, s);
        let mut m = blank();
        if let Some(mut v) = m.view_mut() {
            let _ = draw_cube(&mut v, camera, &pose, &vertices, &edges);
        }
        out.ink(&m, CUBE);
    }
    for p in features {
        let (cx, cy) = (p.x.round() as i64, p.y.round() as i64);
        for d in -1..=1 {
            out.put(cx + d, cy, FEATURE);
            out.put(cx, cy + d, FEATURE);
        }
    }
    if f.state != TargetState::Tracking {
        let (w, h) = (i64::from(out.width()), i64::from(out.height()));
        for x in 0..w {
            for t in 0..2 {
                out.put(x, t, LOST);
                out.put(x, h - 1 - t, LOST);
            }
        }
        for y in 0..h {
            for t in 0..2 {
                out.put(t, y, LOST);
                out.put(w - 1 - t, y, LOST);
            }
        }
    }
    out
}

fn draw_cube(
    v: &mut ImageMut<'_, u8>,
    camera: &Camera<f32>,
    pose: &PlanarPose<f32>,
    vertices: &[Point3<f32>],
    edges: &[(u8, u8)],
) -> camgeom::Result<usize> {
    draw_wireframe(
        v,
        camera,
        &pose.best.pose,
        vertices,
        edges,
        &WireframeParams::default(),
    )
}

/// `count` frame indices evenly spaced over `0..n`, first and last included.
pub fn evenly_spaced(n: usize, count: usize) -> Vec<usize> {
    if n == 0 || count == 0 {
        return Vec::new();
    }
    if count == 1 || n == 1 {
        return vec![0];
    }
    let count = count.min(n);
    (0..count)
        .map(|i| (i * (n - 1) + (count - 1) / 2) / (count - 1))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evenly_spaced_frames() {
        assert_eq!(evenly_spaced(150, 4), vec![0, 50, 99, 149]);
        assert_eq!(evenly_spaced(3, 16), vec![0, 1, 2]);
        assert_eq!(evenly_spaced(1, 16), vec![0]);
        assert!(evenly_spaced(0, 4).is_empty());
    }
}
