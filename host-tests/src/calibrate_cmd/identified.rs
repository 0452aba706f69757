//! The calibration of a board of identified points seen in part (ChArUco, AprilGrid): each
//! view's identified corners (from the board's own detector) through
//! `Calibrator::with_points` / `add_points`, then the shared outputs ([`write_outputs`]).

use super::*;

/// One image's identified corners: board point id and pixel.
pub(super) struct IdView {
    pub(super) path: PathBuf,
    pub(super) image: GrayImage,
    pub(super) corners: Vec<(u16, Point2<f32>)>,
}

/// A board of identified points, as the shared path sees it.
pub(super) struct IdBoard<'a> {
    /// Its name in messages ("ChArUco", "AprilGrid").
    pub(super) name: &'a str,
    /// Point `k` in the board frame, `z = 0`.
    pub(super) points: Vec<Point2<f64>>,
    /// A typical spacing of the points (the square or the tag side).
    pub(super) scale: f64,
    /// What the camera file names as the board's size (`board_width`, `board_height`).
    pub(super) size: BoardSize,
    /// Views with fewer corners are not used.
    pub(super) min_corners: usize,
}

/// The views read, the names of the images skipped (another size) and the images' size.
pub(super) type Loaded = (Vec<IdView>, Vec<String>, (usize, usize));

/// Reads every image (those of another size than the first skipped with a warning) and finds
/// its identified corners with `detect`; the views, the skipped images' names and the size.
pub(super) fn load_views(
    a: &CalibrateArgs,
    mut detect: impl FnMut(&Path, &camgeom::image::ImageView<'_, u8>) -> Result<Vec<(u16, Point2<f32>)>>,
) -> Result<Loaded> {
    let mut views = Vec::new();
    let mut skipped = Vec::new();
    let mut size = None;
    for p in &a.images {
        let image = load_gray(p)?;
        let s = (image.width, image.height);
        if *size.get_or_insert(s) != s {
            eprintln!(
                "camgeom: warning: {}: {}x{} differs from the first image's size, skipped",
                p.display(),
                s.0,
                s.1
            );
            skipped.push(file_name(p));
            continue;
        }
        let view = image
            .view()
            .ok_or_else(|| Error::usage(format!("{}: empty image", p.display())))?;
        let corners = detect(p, &view)?;
        views.push(IdView {
            path: p.clone(),
            image,
            corners,
        });
    }
    Ok((views, skipped, size.unwrap_or((1, 1))))
}

/// Calibrates from the views' identified corners and writes the outputs.
pub(super) fn calibrate(
    a: &CalibrateArgs,
    board: &IdBoard<'_>,
    views: Vec<IdView>,
    skipped: Vec<String>,
    (width, height): (usize, usize),
) -> Result<String> {
    let cfg = calibration_config(a)?;
    let (name, min) = (board.name, board.min_corners);
    let found: Vec<&IdView> = views.iter().filter(|v| v.corners.len() >= min).collect();
    let missed: Vec<String> = views
        .iter()
        .filter(|v| v.corners.len() < min)
        .map(|v| file_name(&v.path))
        .collect();
    for v in &views {
        if v.corners.len() < min {
            eprintln!(
                "camgeom: note: {}: {} {name} corners (fewer than {min}), view not used",
                v.path.display(),
                v.corners.len()
            );
        }
    }
    if found.len() < 3 {
        return Err(Error::usage(format!(
            "the {name} board gave at least {min} corners in {} of {} images; calibration \
             needs at least 3 views (too few in: {})",
            found.len(),
            views.len(),
            name_list(&missed)
        )));
    }
    let mut cal = Box::new(
        Calibrator::<f64, MAX_VIEWS, MAX_CORNERS>::with_points(
            &board.points,
            board.scale,
            width,
            height,
        )
        .map_err(|e| Error::camgeom("calibration setup", e))?,
    );
    for v in &found {
        let ids: Vec<usize> = v.corners.iter().map(|c| usize::from(c.0)).collect();
        let px: Vec<Point2<f64>> = v
            .corners
            .iter()
            .map(|c| Point2::new(f64::from(c.1.x), f64::from(c.1.y)))
            .collect();
        cal.add_points(width, height, &ids, &px)
            .map_err(|e| Error::camgeom(format!("{}: view rejected", v.path.display()), e))?;
    }
    let report = cfg.check().and_then(|p| cal.solve(&p)).map_err(|e| {
        let why = match e {
            camgeom::Error::Degenerate => {
                "the views do not determine the camera (all parallel to each other: tilt the \
                 board between views)"
            }
            camgeom::Error::TooFewPoints => "fewer than 3 views are usable",
            _ => "calibration failed",
        };
        Error::camgeom(
            format!("calibration of {} views failed: {why}", found.len()),
            e,
        )
    })?;

    let mut rejected = missed.clone();
    let mut used: Vec<&IdView> = Vec::new();
    let mut per_view = Vec::new();
    let mut poses = Vec::new();
    let mut corners_csv = String::from("view,X,Y,Z,u,v\n");
    for (k, v) in found.iter().enumerate() {
        let (Some(Some(pose)), Some(Some(rms))) =
            (report.poses.get(k), report.per_view_rms_px.get(k))
        else {
            let why = report
                .rejections
                .get(k)
                .copied()
                .flatten()
                .map_or("rejected", |r| r.name());
            eprintln!("camgeom: note: {}: view not used ({why})", v.path.display());
            rejected.push(file_name(&v.path));
            continue;
        };
        used.push(v);
        per_view.push(*rms);
        let index = views.iter().position(|w| std::ptr::eq(w, *v)).unwrap_or(k);
        let (r, t) = (pose.rotation_vector(), pose.translation());
        poses.push(ViewPose {
            image: file_name(&v.path),
            view: index,
            rvec: [r.x, r.y, r.z],
            tvec: [t.x, t.y, t.z],
            rms_px: *rms,
        });
        for (id, p) in &v.corners {
            if let Some(b) = board.points.get(usize::from(*id)) {
                let _ = writeln!(corners_csv, "{index},{},{},0,{},{}", b.x, b.y, p.x, p.y);
            }
        }
    }

    let yaml = camera_yaml(
        &report,
        &cfg,
        board.size,
        board.scale,
        width,
        height,
        &per_view,
    );
    let tiles: Vec<(usize, RgbImage)> = views
        .iter()
        .enumerate()
        .map(|(i, v)| (i + 1, draw_ids(v, min)))
        .collect();
    let sheet = contact_sheet(&tiles, 4, width.div_ceil(320).max(1));
    let labels = used_labels(&views, &used);
    let images_used = used.iter().map(|v| file_name(&v.path)).collect();
    write_outputs(
        a,
        Solved {
            report,
            yaml,
            sheet,
            labels,
            images_used,
            per_view,
            poses,
            rejected,
            skipped,
            corners_csv,
            width,
            height,
        },
    )
}

/// The image with a circle at each identified corner (red when too few).
fn draw_ids(v: &IdView, min_corners: usize) -> RgbImage {
    let img = &v.image;
    let mut out = RgbImage::from_gray(img);
    let ok = v.corners.len() >= min_corners;
    let radius = (img.width as f32 / 160.0).max(3.0);
    let mut mask = GrayImage::filled(img.width, img.height, 0);
    if let Some(mut m) = mask.view_mut() {
        for (_, p) in &v.corners {
            for s in 0..12 {
                let a0 = s as f32 * core::f32::consts::TAU / 12.0;
                let a1 = (s + 1) as f32 * core::f32::consts::TAU / 12.0;
                let q0 = Point2::new(p.x + radius * a0.cos(), p.y + radius * a0.sin());
                let q1 = Point2::new(p.x + radius * a1.cos(), p.y + radius * a1.sin());
                let _ = draw_line(&mut m, &q0, &q1, 255);
            }
        }
    }
    out.ink(&mask, if ok { [40, 200, 40] } else { [255, 40, 40] });
    out
}
