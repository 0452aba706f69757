//! camgeom's KLT on owned images: the buffers a board would hold, allocated once, for the
//! tests, the benchmarks and the `flow` / `track` subcommands.

use camgeom::corners::{Corner, CornerConfig};
use camgeom::image::ImageView;
use camgeom::klt::{
    Borders, Coordinate, Fixed, Flow, FlowArith, FlowStatus, Gradients, LkConfig, Q16, Templates,
    Tracker, TrackerConfig, bordered_len, calc_flow, forward_backward, scratch_len,
};
use camgeom::pyramid::{Pyramid, PyramidPair, buffer_len};

use crate::images::GrayImage;

/// Which arithmetic path to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Path {
    /// Q16.16 coordinates and the integer solve ([`Fixed`]).
    Fixed,
    /// `f32` (as OpenCV).
    F32,
}

/// One tracked point in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowPoint {
    /// Column in the next frame.
    pub x: f64,
    /// Row in the next frame.
    pub y: f64,
    /// Outcome.
    pub status: FlowStatus,
    /// Mean absolute difference of the windows (grey levels).
    pub err: f64,
}

/// Levels a pyramid needs for `cfg.max_level`.
pub fn levels(cfg: &LkConfig) -> usize {
    (cfg.max_level + 1).min(camgeom::pyramid::MAX_LEVELS)
}

/// Builds the pyramid of `img` into `buf` (resized as needed).
pub fn pyramid<'a>(img: &'a GrayImage, buf: &'a mut Vec<u8>, levels: usize) -> Pyramid<'a> {
    buf.resize(buffer_len(img.width, img.height, levels), 0);
    let view = img.view().expect("image size camgeom accepts");
    Pyramid::build(view, buf, levels).expect("pyramid")
}

/// Where [`flow_pyramids`] takes the window derivatives from ([`Gradients`]; a level-0 sized
/// buffer for `Level`, a level-1 sized one for `Auto`, which also gets the bordered copies
/// ([`Borders::Copy`]) for the level-1 size: the host's fastest configuration).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Derivatives {
    /// [`Gradients::PerWindow`].
    Window,
    /// [`Gradients::PerLevel`].
    Level,
    /// [`Gradients::Auto`].
    Auto,
}

/// The caller's buffers of one [`flow_pyramids_in`] call, made once and reused from call to
/// call as a board (or any caller of the allocation-free library) keeps them.
#[derive(Debug, Clone)]
pub struct FlowScratch {
    scratch: Vec<i16>,
    grad: Vec<[i16; 2]>,
    borders: Vec<u8>,
    derivs: Derivatives,
}

impl FlowScratch {
    /// The buffers for `derivs` on pyramids whose levels 0 and 1 are `prev`'s.
    pub fn new(prev: &Pyramid<'_>, cfg: &LkConfig, derivs: Derivatives) -> Self {
        let size = |l: usize| prev.level(l).map_or((0, 0), |l| (l.width(), l.height()));
        let ((w0, h0), (w1, h1)) = (size(0), size(1));
        // `Auto` with the buffers its documentation suggests, the level-1 size: the coarse
        // levels per level (and bordered), level 0 per window.
        let (grad, borders) = match derivs {
            Derivatives::Window => (0, 0),
            Derivatives::Level => (w0 * h0, 0),
            Derivatives::Auto => (w1 * h1, bordered_len(w1, h1, cfg.win)),
        };
        Self {
            scratch: vec![0; scratch_len(cfg.win)],
            grad: vec![[0; 2]; grad],
            borders: vec![0; borders],
            derivs,
        }
    }
}

/// Runs `calc_flow` (and the forward-backward check when `cfg.fb_threshold` is set) on
/// pyramids already built, with buffers made for the call ([`flow_pyramids_in`]).
pub fn flow_pyramids(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: &[[f64; 2]],
    cfg: &LkConfig,
    path: Path,
    derivs: Derivatives,
) -> camgeom::Result<Vec<FlowPoint>> {
    let mut s = FlowScratch::new(prev, cfg, derivs);
    flow_pyramids_in(&mut s, prev, next, pts, cfg, path)
}

/// [`flow_pyramids`] with buffers made beforehand (`s`, for the derivatives it was made for).
pub fn flow_pyramids_in(
    s: &mut FlowScratch,
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: &[[f64; 2]],
    cfg: &LkConfig,
    path: Path,
) -> camgeom::Result<Vec<FlowPoint>> {
    fn go<A: FlowArith>(
        s: &mut FlowScratch,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        pts: Vec<[A::Coord; 2]>,
        cfg: &LkConfig,
    ) -> camgeom::Result<Vec<FlowPoint>> {
        let params = cfg.check()?;
        let derivs = s.derivs;
        let mut flows = vec![Flow::<A::Coord>::default(); pts.len()];
        fn g(grad: &mut [[i16; 2]], derivs: Derivatives) -> Gradients<'_> {
            match derivs {
                Derivatives::Window => Gradients::PerWindow,
                Derivatives::Level => Gradients::PerLevel(grad),
                Derivatives::Auto => Gradients::Auto(grad),
            }
        }
        let borders = match derivs {
            Derivatives::Auto => Borders::Copy(&mut s.borders),
            Derivatives::Window | Derivatives::Level => Borders::None,
        };
        calc_flow::<A>(
            prev,
            next,
            &pts,
            &mut flows,
            &params,
            g(&mut s.grad, derivs),
            borders,
            &mut s.scratch,
        )?;
        if cfg.fb_threshold.is_some() {
            let mut back = flows.clone();
            forward_backward::<A>(
                prev,
                next,
                &pts,
                &mut flows,
                &mut back,
                &params,
                g(&mut s.grad, derivs),
                &mut s.scratch,
            )?;
        }
        Ok(flows
            .iter()
            .map(|f| FlowPoint {
                x: f64::from(f.x.to_f32()),
                y: f64::from(f.y.to_f32()),
                status: f.status,
                err: f64::from(f.err.to_f32()),
            })
            .collect())
    }
    match path {
        Path::Fixed => go::<Fixed>(
            s,
            prev,
            next,
            pts.iter()
                .map(|p| {
                    [
                        Q16::saturating_from_f32(p[0] as f32),
                        Q16::saturating_from_f32(p[1] as f32),
                    ]
                })
                .collect(),
            cfg,
        ),
        Path::F32 => go::<f32>(
            s,
            prev,
            next,
            pts.iter().map(|p| [p[0] as f32, p[1] as f32]).collect(),
            cfg,
        ),
    }
}

/// `calc_flow` in `f32` from `pts` of `prev` to `next`, starting at `guesses` (OpenCV's
/// `OPTFLOW_USE_INITIAL_FLOW`): a sub-pixel alignment of windows already matched, per-window
/// derivatives, no forward-backward check.
pub fn flow_from_guesses(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: &[[f64; 2]],
    guesses: &[[f64; 2]],
    cfg: &LkConfig,
) -> camgeom::Result<Vec<FlowPoint>> {
    if pts.len() != guesses.len() {
        return Err(camgeom::Error::LengthMismatch);
    }
    let params = LkConfig {
        use_initial_flow: true,
        ..*cfg
    }
    .check()?;
    let from: Vec<[f32; 2]> = pts.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
    let mut flows: Vec<Flow<f32>> = guesses
        .iter()
        .map(|g| Flow {
            x: g[0] as f32,
            y: g[1] as f32,
            ..Flow::default()
        })
        .collect();
    let mut scratch = vec![0; scratch_len(cfg.win)];
    calc_flow::<f32>(
        prev,
        next,
        &from,
        &mut flows,
        &params,
        Gradients::PerWindow,
        Borders::None,
        &mut scratch,
    )?;
    Ok(flows
        .iter()
        .map(|f| FlowPoint {
            x: f64::from(f.x),
            y: f64::from(f.y),
            status: f.status,
            err: f64::from(f.err),
        })
        .collect())
}

/// Tracks `pts` from `a` to `b` (same size) with the given path.
pub fn flow(
    a: &GrayImage,
    b: &GrayImage,
    pts: &[[f64; 2]],
    cfg: &LkConfig,
    path: Path,
) -> camgeom::Result<Vec<FlowPoint>> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(camgeom::Error::InvalidImage);
    }
    let l = levels(cfg);
    let (mut ba, mut bb) = (Vec::new(), Vec::new());
    let pa = pyramid(a, &mut ba, l);
    let pb = pyramid(b, &mut bb, l);
    flow_pyramids(&pa, &pb, pts, cfg, path, Derivatives::Window)
}

/// Shi-Tomasi corners of `img` (up to `max`), strongest first, as pixel positions.
pub fn corners(img: &GrayImage, cfg: &CornerConfig, max: usize) -> camgeom::Result<Vec<[u16; 2]>> {
    let view = img.view().ok_or(camgeom::Error::InvalidImage)?;
    let mut out: camgeom::heapless::Vec<Corner, 4096> = camgeom::heapless::Vec::new();
    let mut cands = vec![Corner::default(); 16384];
    let mut scratch = vec![0u32; camgeom::corners::scratch_len(img.width)];
    let c = CornerConfig {
        max_corners: max.min(4096),
        ..*cfg
    }
    .check()?;
    camgeom::corners::good_features(
        &view,
        &c,
        std::iter::empty(),
        &mut out,
        &mut cands,
        &mut scratch,
    )?;
    Ok(out.iter().map(|c| [c.x, c.y]).collect())
}

/// One row of a track file: frame index, track id, position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackRow {
    /// Frame index (0-based).
    pub frame: usize,
    /// Track id.
    pub id: u32,
    /// Column.
    pub x: f64,
    /// Row.
    pub y: f64,
    /// Frames since detection.
    pub age: u32,
}

/// Tracks features through `frames` with at most 1024 tracks (`cfg.max_tracks` fewer): detection on the first
/// frame, then flow + removal + replenishment on every frame. `on_frame(k, rows)` is called
/// after frame `k` with that frame's tracks. The frames of a slice; [`track_stream`] takes
/// them one at a time.
pub fn track_sequence(
    frames: &[GrayImage],
    cfg: &TrackerConfig,
    path: Path,
    mut on_frame: impl FnMut(usize, &[TrackRow]),
) -> camgeom::Result<Vec<TrackRow>> {
    track_stream(
        frames.iter().map(Ok::<_, camgeom::Error>),
        cfg,
        path,
        |k, _, rows| on_frame(k, rows),
    )
}

/// [`track_sequence`] over frames that arrive one at a time (a video being decoded): only the
/// current frame and the two pyramids are held. Every frame must have the first one's size
/// (else [`camgeom::Error::InvalidImage`]); the first error of `frames` stops the run and
/// is returned. `on_frame(k, frame, rows)` is called after frame `k`.
pub fn track_stream<B, E>(
    frames: impl Iterator<Item = Result<B, E>>,
    cfg: &TrackerConfig,
    path: Path,
    mut on_frame: impl FnMut(usize, &GrayImage, &[TrackRow]),
) -> Result<Vec<TrackRow>, E>
where
    B: core::borrow::Borrow<GrayImage>,
    E: From<camgeom::Error>,
{
    /// The tracker's state for one arithmetic path.
    struct State<A: FlowArith> {
        params: camgeom::klt::TrackerParams,
        tracker: Box<Tracker<A, 1024>>,
        levels: usize,
        scratch: Vec<i16>,
        cands: Vec<Corner>,
        cs: Vec<u32>,
        pair: Option<PyramidPair<Vec<u8>, Vec<u8>>>,
        size: (usize, usize),
    }
    impl<A: FlowArith> State<A> {
        fn new(cfg: &TrackerConfig) -> camgeom::Result<Self> {
            Ok(Self {
                params: cfg.check()?,
                tracker: Box::new(Tracker::new()),
                levels: levels(&cfg.lk),
                scratch: vec![0i16; scratch_len(cfg.lk.win)],
                cands: vec![Corner::default(); 8192],
                cs: Vec::new(),
                pair: None,
                size: (0, 0),
            })
        }
        fn step(&mut self, k: usize, img: &GrayImage) -> camgeom::Result<Vec<TrackRow>> {
            let (w, h) = (img.width, img.height);
            let pair = match &mut self.pair {
                Some(p) if self.size == (w, h) => p,
                Some(_) => return Err(camgeom::Error::InvalidImage),
                None => {
                    let l = self.levels;
                    let mut p = PyramidPair::new(
                        [vec![0u8; w * h], vec![0u8; w * h]],
                        [
                            vec![0u8; buffer_len(w, h, l)],
                            vec![0u8; buffer_len(w, h, l)],
                        ],
                    );
                    p.set_geometry(w, h, l)?;
                    self.size = (w, h);
                    self.pair.insert(p)
                }
            };
            let view = img.view().ok_or(camgeom::Error::InvalidImage)?;
            pair.capture()?.copy_from(&view)?;
            let pyramids = pair.advance()?;
            if let Some(prev) = &pyramids.previous {
                self.tracker.update(
                    &self.params,
                    prev,
                    &pyramids.next,
                    Templates::Compute,
                    &mut self.scratch,
                )?;
            }
            self.cs.resize(camgeom::corners::scratch_len(w), 0);
            self.tracker
                .replenish(&self.params, &view, &mut self.cands, &mut self.cs)?;
            Ok(self
                .tracker
                .tracks()
                .iter()
                .map(|t| TrackRow {
                    frame: k,
                    id: t.id,
                    x: f64::from(t.x.to_f32()),
                    y: f64::from(t.y.to_f32()),
                    age: t.age,
                })
                .collect())
        }
    }
    /// Either path, chosen once.
    enum Either {
        Fixed(State<Fixed>),
        F32(State<f32>),
    }
    let mut state = match path {
        Path::Fixed => Either::Fixed(State::new(cfg)?),
        Path::F32 => Either::F32(State::new(cfg)?),
    };
    let mut rows = Vec::new();
    for (k, img) in frames.enumerate() {
        let img = img?;
        let img = img.borrow();
        let now = match &mut state {
            Either::Fixed(s) => s.step(k, img)?,
            Either::F32(s) => s.step(k, img)?,
        };
        on_frame(k, img, &now);
        rows.extend(now);
    }
    Ok(rows)
}

/// Draws tracks onto a copy of `img`: a 5x5 cross at each position and a line to the
/// position `trail` frames before (from `history`, rows of earlier frames).
pub fn overlay(img: &GrayImage, now: &[TrackRow], history: &[TrackRow]) -> GrayImage {
    let mut out = img.clone();
    let mut put = |x: i64, y: i64, v: u8| {
        if x >= 0 && y >= 0 && (x as usize) < out.width && (y as usize) < out.height {
            let i = y as usize * out.width + x as usize;
            out.data[i] = v;
        }
    };
    for r in now {
        let (cx, cy) = (r.x.round() as i64, r.y.round() as i64);
        if let Some(h) = history.iter().find(|h| h.id == r.id) {
            let n = ((h.x - r.x).abs().max((h.y - r.y).abs()).ceil() as i64).clamp(1, 400);
            for s in 0..=n {
                let t = s as f64 / n as f64;
                let x = (r.x + (h.x - r.x) * t).round() as i64;
                let y = (r.y + (h.y - r.y) * t).round() as i64;
                put(x, y, 255);
            }
        }
        for d in -2..=2 {
            put(cx + d, cy, 0);
            put(cx, cy + d, 0);
        }
        put(cx, cy, 255);
    }
    out
}

/// The view of an owned image (panics on a size camgeom rejects; tests and tools only).
pub fn view(img: &GrayImage) -> ImageView<'_, u8> {
    img.view().expect("image size camgeom accepts")
}
