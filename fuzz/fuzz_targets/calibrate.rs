//! Camera calibration (`calib::Calibrator`, both lens models, `f32` and `f64`) on edits of a
//! valid synthetic set: a board of arbitrary size seen in up to 6 views through a camera and
//! poses the fuzzer chooses, then noise, points replaced by arbitrary values (NaN, ±inf,
//! huge), duplicated points and views, collinear points, views dropped, truncated or added at
//! another image size; arbitrary flags, iteration counts and initial guesses. Contract
//! (`Calibrator::new`, `add_view`, `solve` docs): no panic; `Ok` has a finite camera (positive
//! focal lengths), a finite RMS `≥ 0` (overall, initial and per used view), at least 3 views
//! used and finite poses for them; otherwise a documented typed error. With `partial`, the
//! same board as identified points (`with_points`) and views of any subset (`add_points`):
//! the same contract, and every rejected view has its reason.
#![no_main]

use arbitrary::Arbitrary;
use camgeom::Error;
use camgeom::Real;
use camgeom::calib::{CalibrationConfig, CalibrationFlags, CalibrationReport, Calibrator};
use camgeom::camera::{Camera, Distortion, Fisheye, Intrinsics, Lens, LensModel};
use camgeom::chessboard::BoardSize;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::transform::Pose;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::{Edit, Num, apply_edits};

/// Views and corners a calibrator holds.
const V: usize = 6;
const P: usize = 42;

#[derive(Debug, Arbitrary)]
struct View {
    /// Rotation, 1/128 rad a step (up to about 1 rad each way).
    rvec: (i8, i8, i8),
    /// Board centre offset (1/16 of the board a step) and distance (board sizes).
    offset: (i8, i8),
    distance: u8,
}

#[derive(Debug, Arbitrary)]
enum ViewEdit {
    /// Add uniform noise of amplitude `a / 16` px to every point of a view.
    Noise { view: u8, a: u8 },
    /// Replace one point by arbitrary coordinates.
    Set { view: u8, point: u8, to: (Num, Num) },
    /// Degenerate edits of one view's points.
    Points { view: u8, edits: [Edit; 2] },
    /// Copy a view over another.
    CopyView { from: u8, to: u8 },
    /// Remove a view.
    Drop(u8),
    /// Keep only the first `len` points of a view (a length mismatch).
    Truncate { view: u8, len: u8 },
    /// Add this view at another image size.
    WrongSize(u8),
}

#[derive(Debug, Arbitrary)]
struct Input {
    f64: bool,
    fisheye: bool,
    /// Focal length 100 + 4 f px, aspect 1 + a/256, principal point offset from the centre.
    f: u8,
    aspect: i8,
    pp: (i8, i8),
    lens: [i8; 5],
    board: (u8, u8),
    /// `None`: 25 mm.
    square: Option<Num>,
    /// `None`: 640x480.
    size: Option<(u16, u16)>,
    views: std::vec::Vec<View>,
    edits: std::vec::Vec<ViewEdit>,
    model_fisheye: bool,
    fix_aspect_ratio: Option<Num>,
    fix_principal_point: bool,
    zero_tangent: bool,
    fix_k3: bool,
    fix_k4: bool,
    max_iterations: u8,
    guess: Option<[Num; 9]>,
    /// `Some(mask)`: the board as identified points (`Calibrator::with_points`) and each view
    /// a subset of them (`add_points`): point `i` of view `v` kept when bit `(i + 7 v) % 64` of
    /// `mask` is set (a ChArUco or AprilGrid board seen in part).
    partial: Option<u64>,
}

fn lit<T: Real>(v: f32) -> T {
    T::lit(f64::from(v))
}

fn check<T: Real>(r: &CalibrationReport<T, V>, views: usize, what: &str) {
    let k = &r.camera.intrinsics;
    let kk = [k.fx(), k.fy(), k.cx(), k.cy(), k.skew()];
    assert!(
        kk.iter().all(|v| v.finite()),
        "{what}: K not finite: {kk:?}"
    );
    assert!(
        k.fx() > T::zero() && k.fy() > T::zero(),
        "{what}: focal {kk:?}"
    );
    match &r.camera.lens {
        Lens::BrownConrady(d) => {
            let d = d.to_opencv();
            assert!(d.iter().all(|v| v.finite()), "{what}: distortion {d:?}");
        }
        Lens::KannalaBrandt(f) => {
            let c = f.to_opencv();
            assert!(c.iter().all(|v| v.finite()), "{what}: fisheye {c:?}");
        }
    }
    for (name, rms) in [("rms", r.rms_px), ("initial rms", r.initial_rms_px)] {
        assert!(rms.finite() && rms >= T::zero(), "{what}: {name} {rms:?}");
    }
    assert_eq!(r.views_added, views, "{what}: views added");
    assert!(
        r.views_used >= 3 && r.views_used <= views,
        "{what}: views used {}",
        r.views_used
    );
    let used = r.per_view_rms_px.iter().flatten().count();
    assert_eq!(used, r.views_used, "{what}: per-view count");
    for (rms, pose) in r.per_view_rms_px.iter().zip(&r.poses) {
        match (rms, pose) {
            (Some(e), Some(p)) => {
                assert!(e.finite() && *e >= T::zero(), "{what}: view rms {e:?}");
                let (rot, t) = (p.rotation(), p.translation());
                assert!(
                    rot.matrix().iter().chain(t.iter()).all(|v| v.finite()),
                    "{what}: pose"
                );
            }
            (None, None) => {}
            _ => panic!("{what}: a view with an RMS and no pose or the reverse"),
        }
    }
}

fn run<T: Real>(inp: &Input) {
    let (w, h) = inp
        .size
        .map_or((640, 480), |(w, h)| (usize::from(w), usize::from(h)));
    let Ok(board) = BoardSize::new(usize::from(inp.board.0), usize::from(inp.board.1)) else {
        return;
    };
    let square: T = lit(inp.square.map_or(0.025, Num::get));
    let mut cal = match Calibrator::<T, V, P>::new(board, square, w, h) {
        Ok(c) => std::boxed::Box::new(c),
        Err(Error::InvalidParameter("square")) => {
            assert!(
                !(square.finite() && square > T::zero()),
                "square {square:?} refused"
            );
            return;
        }
        Err(Error::BufferTooSmall("corners")) => return assert!(board.corners() > P),
        Err(Error::InvalidImage) => return assert!(w == 0 || h == 0 || w > 8192 || h > 8192),
        Err(e) => panic!("new: undocumented error {e:?}"),
    };
    if !(square.finite() && square > T::zero()) {
        return;
    }

    // The truth camera.
    let f = 100.0 + 4.0 * f32::from(inp.f);
    let fy = f * (1.0 + f32::from(inp.aspect) / 256.0);
    let (cx, cy) = (
        (w as f32 - 1.0) / 2.0 + f32::from(inp.pp.0),
        (h as f32 - 1.0) / 2.0 + f32::from(inp.pp.1),
    );
    let Ok(k) = Intrinsics::new(lit::<T>(f), lit(fy), lit(cx), lit(cy)) else {
        return;
    };
    let l = inp.lens.map(|v| lit::<T>(f32::from(v) / 512.0));
    let camera = if inp.fisheye {
        match Fisheye::from_opencv([l[0], l[1], l[2], l[3]]) {
            Ok(fe) => Camera::fisheye(k, fe),
            Err(_) => return,
        }
    } else {
        match Distortion::from_opencv(l) {
            Ok(d) => Camera::new(k, d),
            Err(_) => return,
        }
    };

    // The views: the board centred in front of the camera, then the fuzzer's edits.
    let (cols, rows) = (board.cols(), board.rows());
    let model: std::vec::Vec<Point3<T>> = (0..board.corners())
        .map(|i| {
            Point3::new(
                square * T::lit((i % cols) as f64),
                square * T::lit((i / cols) as f64),
                T::zero(),
            )
        })
        .collect();
    let size = square * T::lit(cols.max(rows) as f64);
    let mut views: std::vec::Vec<(std::vec::Vec<Point2<T>>, bool)> = std::vec::Vec::new();
    for v in inp.views.iter().take(V + 1) {
        let r = Vector3::new(v.rvec.0, v.rvec.1, v.rvec.2).map(|a| T::lit(f64::from(a) / 128.0));
        let Ok(rot) = Pose::from_rodrigues(r, Vector3::zeros()) else {
            continue;
        };
        let centre = Vector3::new(
            square * T::lit((cols - 1) as f64 * 0.5),
            square * T::lit((rows - 1) as f64 * 0.5),
            T::zero(),
        );
        let dist = size * T::lit(1.0 + f64::from(v.distance) / 32.0);
        let t = Vector3::new(
            size * T::lit(f64::from(v.offset.0) / 16.0),
            size * T::lit(f64::from(v.offset.1) / 16.0),
            dist,
        ) - rot.rotation() * centre;
        let Ok(pose) = Pose::from_rodrigues(r, t) else {
            continue;
        };
        let px: std::vec::Vec<Point2<T>> = model
            .iter()
            .map(|x| {
                camera
                    .project(&pose, x)
                    .unwrap_or(Point2::new(T::lit(-1.0), T::lit(-1.0)))
            })
            .collect();
        views.push((px, false));
    }
    for e in inp.edits.iter().take(8) {
        let n = views.len();
        if n == 0 {
            break;
        }
        let at = |i: u8| usize::from(i) % n;
        match e {
            ViewEdit::Noise { view, a } => {
                let amp = T::lit(f64::from(*a) / 16.0);
                let mut s = u32::from(*a) | 1;
                for p in views[at(*view)].0.iter_mut() {
                    for c in p.coords.iter_mut() {
                        s ^= s << 13;
                        s ^= s >> 17;
                        s ^= s << 5;
                        *c += amp * T::lit(f64::from(s % 2001) / 1000.0 - 1.0);
                    }
                }
            }
            ViewEdit::Set { view, point, to } => {
                let v = &mut views[at(*view)].0;
                let m = v.len().max(1);
                if let Some(p) = v.get_mut(usize::from(*point) % m) {
                    *p = Point2::new(lit(to.0.get()), lit(to.1.get()));
                }
            }
            ViewEdit::Points { view, edits } => {
                let v = &mut views[at(*view)].0;
                let mut f: std::vec::Vec<Point2<f32>> = v
                    .iter()
                    .map(|p| Point2::new(p.x.to_f64() as f32, p.y.to_f64() as f32))
                    .collect();
                apply_edits(&mut f, edits);
                for (d, s) in v.iter_mut().zip(&f) {
                    *d = Point2::new(lit(s.x), lit(s.y));
                }
            }
            ViewEdit::CopyView { from, to } => {
                let src = views[at(*from)].clone();
                views[at(*to)] = src;
            }
            ViewEdit::Drop(i) => {
                views.remove(at(*i));
            }
            ViewEdit::Truncate { view, len } => views[at(*view)].0.truncate(usize::from(*len)),
            ViewEdit::WrongSize(i) => views[at(*i)].1 = true,
        }
    }
    if let Some(mask) = inp.partial {
        let plane: std::vec::Vec<Point2<T>> = model.iter().map(|x| Point2::new(x.x, x.y)).collect();
        cal = match Calibrator::<T, V, P>::with_points(&plane, square, w, h) {
            Ok(c) => std::boxed::Box::new(c),
            Err(Error::NonFinite) => {
                return assert!(
                    plane
                        .iter()
                        .any(|p| !(p.x / square).finite() || !(p.y / square).finite())
                );
            }
            Err(e) => panic!("with_points: undocumented error {e:?}"),
        };
        let mut added = 0;
        for (v, (px, wrong)) in views.iter().enumerate() {
            let (vw, vh) = if *wrong { (w + 1, h) } else { (w, h) };
            let ids: std::vec::Vec<usize> = (0..px.len().min(board.corners()))
                .filter(|i| (mask >> ((i + 7 * v) % 64)) & 1 == 1)
                .collect();
            let pts: std::vec::Vec<Point2<T>> = ids.iter().map(|&i| px[i]).collect();
            match cal.add_points(vw, vh, &ids, &pts) {
                Ok(i) => {
                    assert_eq!(i, added, "view index");
                    added += 1;
                }
                Err(Error::InvalidImage) => assert!(*wrong),
                Err(Error::NonFinite) => {
                    assert!(pts.iter().any(|p| !(p.x.finite() && p.y.finite())))
                }
                Err(Error::BufferTooSmall("views")) => assert_eq!(added, V),
                Err(e) => panic!("add_points: undocumented error {e:?}"),
            }
        }
        if let Ok(p) = CalibrationConfig::default().check() {
            match cal.solve(&p) {
                Ok(r) => {
                    check(&r, added, "solve (partial views)");
                    for (k, rej) in r.rejections.iter().enumerate().take(added) {
                        assert_eq!(
                            rej.is_some(),
                            r.per_view_rms_px[k].is_none(),
                            "rejection reason"
                        );
                    }
                }
                Err(e) => assert!(
                    matches!(
                        e,
                        Error::TooFewPoints | Error::Degenerate | Error::NoConvergence
                    ),
                    "solve (partial views): undocumented error {e:?}"
                ),
            }
        }
        return;
    }
    let mut added = 0;
    for (px, wrong) in &views {
        let (vw, vh) = if *wrong { (w + 1, h) } else { (w, h) };
        match cal.add_view(vw, vh, px) {
            Ok(i) => {
                assert_eq!(i, added, "view index");
                added += 1;
            }
            Err(Error::InvalidImage) => assert!(*wrong),
            Err(Error::LengthMismatch) => assert_ne!(px.len(), board.corners()),
            Err(Error::NonFinite) => {
                assert!(px.iter().any(|p| !(p.x.finite() && p.y.finite())))
            }
            Err(Error::BufferTooSmall("views")) => assert_eq!(added, V),
            Err(e) => panic!("add_view: undocumented error {e:?}"),
        }
    }
    assert_eq!(cal.views(), added);

    let cfg = CalibrationConfig {
        model: if inp.model_fisheye {
            LensModel::KannalaBrandt
        } else {
            LensModel::BrownConrady
        },
        flags: CalibrationFlags {
            fix_aspect_ratio: inp.fix_aspect_ratio.map(|a| f64::from(a.get())),
            fix_principal_point: inp.fix_principal_point,
            zero_tangent: inp.zero_tangent,
            fix_k3: inp.fix_k3,
            fix_k4: inp.fix_k4,
        },
        // Small counts keep a run short; 0 must be refused.
        max_iterations: inp.max_iterations % 40,
        ..CalibrationConfig::default()
    };
    let documented = |e: &Error| {
        matches!(
            e,
            Error::TooFewPoints
                | Error::Degenerate
                | Error::NoConvergence
                | Error::InvalidParameter("flags.fix_aspect_ratio" | "max_iterations")
        )
    };
    match cfg.check().and_then(|p| cal.solve(&p)) {
        Ok(r) => check(&r, added, "solve"),
        Err(e) => assert!(documented(&e), "solve: undocumented error {e:?}"),
    }
    if let Some(g) = &inp.guess {
        let g = g.map(|v| lit::<T>(v.get()));
        let Ok(k) = Intrinsics::new(g[0], g[1], g[2], g[3]) else {
            return;
        };
        let guess = match Distortion::from_opencv([g[4], g[5], g[6], g[7], g[8]]) {
            Ok(d) => Camera::new(k, d),
            Err(_) => return,
        };
        match cfg.check().and_then(|p| cal.solve_with_guess(&p, &guess)) {
            Ok(r) => check(&r, added, "solve_with_guess"),
            Err(e) => assert!(
                documented(&e) || matches!(e, Error::NonFinite | Error::InvalidIntrinsics),
                "solve_with_guess: undocumented error {e:?}"
            ),
        }
    }
}

fuzz_target!(|inp: Input| {
    if inp.f64 {
        run::<f64>(&inp);
    } else {
        run::<f32>(&inp);
    }
});
