//! The figures of `camgeom_host::figures`: each writes a PNG of the expected size that is not
//! blank and holds its colours where they belong (the inlier and outlier lines, the observed
//! and reprojected points, each camera's frustum, a point's own colour).

use std::path::PathBuf;

use camgeom::nalgebra::{Matrix3, Point2, Point3, Vector2, Vector3};
use camgeom_host::ErrorKind;
use camgeom_host::figures::{
    CAMERA_COLOURS, INLIER, OBSERVED, OUTLIER, REPROJECTED, RESIDUAL, SCENE_SIZE, SceneCamera,
    TITLE_HEIGHT, correspondences_plot, reprojection_plot, scene_plot,
};
use camgeom_host::rgb::RgbImage;

/// A fresh output path under the tests' scratch directory.
fn out(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("camgeom-host-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{}-figure-{name}", std::process::id()))
}

/// A textured test image (smooth gradients and a checker).
fn picture(w: u32, h: u32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let c = if (x / 20 + y / 20) % 2 == 0 { 60 } else { 0 };
        image::Rgb([
            (x * 255 / w) as u8 / 2 + c,
            (y * 255 / h) as u8 / 2 + c,
            120,
        ])
    })
}

fn read(path: &PathBuf) -> RgbImage {
    image::open(path).unwrap().to_rgb8()
}

fn count(img: &RgbImage, c: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == c).count()
}

/// Channel `i` of `p` 40 above channel `j`.
fn above(p: [u8; 3], i: usize, j: usize) -> bool {
    i16::from(p[i]) > i16::from(p[j]) + 40
}

/// Pixels of `c`'s hue: wherever `c` has a channel 100 above another, so does the pixel, by
/// 40 (lines are antialiased, so few pixels are exactly `c`; the backdrops are grey).
fn tinted(img: &RgbImage, c: [u8; 3]) -> usize {
    let pairs: Vec<(usize, usize)> = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .filter(|&(i, j)| i16::from(c[i]) > i16::from(c[j]) + 100)
        .collect();
    img.pixels()
        .filter(|p| pairs.iter().all(|&(i, j)| above(p.0, i, j)))
        .count()
}

/// Not blank: many distinct grey levels.
fn assert_not_blank(img: &RgbImage) {
    let mut seen = [false; 256];
    for p in img.pixels() {
        seen[usize::from(p.0[1])] = true;
    }
    let levels = seen.iter().filter(|&&s| s).count();
    assert!(levels > 30, "{levels} levels");
}

#[test]
fn correspondences_in_two_colours() {
    let (a, b) = (picture(400, 300), picture(320, 240));
    let mut matches = Vec::new();
    for i in 0..20 {
        let p = Point2::new(20.0 + 17.0 * i as f64, 40.0 + 9.0 * i as f64);
        matches.push((p, Point2::new(p.x * 0.7 + 10.0, p.y * 0.7 + 5.0), true));
    }
    // Outliers: crossing lines, one leaving the image, one not finite.
    matches.push((Point2::new(50.0, 250.0), Point2::new(300.0, 20.0), false));
    matches.push((Point2::new(380.0, 20.0), Point2::new(10.0, 230.0), false));
    matches.push((
        Point2::new(100.0, 100.0),
        Point2::new(5000.0, -900.0),
        false,
    ));
    matches.push((Point2::new(f64::NAN, 1.0), Point2::new(2.0, 3.0), false));
    let path = out("pair.png");
    correspondences_plot(&path, &a, &b, &matches, "synthetic pair").unwrap();
    let img = read(&path);
    // No scaling below 1600 px: the widths add up, the taller image sets the height.
    assert_eq!(img.dimensions(), (720, 300 + TITLE_HEIGHT));
    assert_not_blank(&img);
    let (green, red) = (tinted(&img, INLIER), tinted(&img, OUTLIER));
    println!(
        "{}: {green} inlier and {red} outlier pixels",
        path.display()
    );
    assert!(green > 1000 && red > 300, "{green} {red}");
    // An inlier line's middle pixel (away from the legend and the outliers' crossings).
    let (p, q) = (matches[15].0, matches[15].1);
    let mid = (
        (p.x + q.x + 400.0) / 2.0,
        (p.y + q.y) / 2.0 + f64::from(TITLE_HEIGHT),
    );
    let near = (-2..=2).any(|dy| {
        (-2..=2).any(|dx| {
            let (x, y) = ((mid.0 as i64 + dx) as u32, (mid.1 as i64 + dy) as u32);
            let p = img.get_pixel(x, y).0;
            above(p, 1, 0) && above(p, 1, 2)
        })
    });
    assert!(near, "no inlier colour near {mid:?}");
}

#[test]
fn correspondences_of_large_images_are_scaled_down() {
    let (a, b) = (picture(2000, 1000), picture(2000, 1500));
    let m = [(Point2::new(1000.0, 500.0), Point2::new(1000.0, 700.0), true)];
    let path = out("pair-large.png");
    correspondences_plot(&path, &a, &b, &m, "large").unwrap();
    let img = read(&path);
    assert_eq!(img.dimensions(), (1600, 600 + TITLE_HEIGHT));
    assert!(tinted(&img, INLIER) > 100);
    // No outlier lines: the red is the legend's sample line alone.
    assert!(tinted(&img, OUTLIER) < 150);
}

#[test]
fn reprojection_circles_crosses_and_residuals() {
    let img = picture(640, 480);
    let mut observed = Vec::new();
    let mut reprojected = Vec::new();
    for j in 0..6 {
        for i in 0..8 {
            let o = Point2::new(60.0 + 70.0 * i as f64, 90.0 + 65.0 * j as f64);
            observed.push(o);
            reprojected.push(o + Vector2::new(0.8, -0.6));
        }
    }
    let path = out("reprojection.png");
    reprojection_plot(&path, &img, &observed, &reprojected, None, "view 1").unwrap();
    let fig = read(&path);
    assert_eq!(fig.dimensions(), (640, 480 + TITLE_HEIGHT));
    assert_not_blank(&fig);
    let (o, r, l) = (
        tinted(&fig, OBSERVED),
        tinted(&fig, REPROJECTED),
        tinted(&fig, RESIDUAL),
    );
    println!(
        "{}: {o} observed, {r} reprojected, {l} residual pixels",
        path.display()
    );
    // 48 circles, 48 crosses, 48 residuals of 1 px magnified to 10 px (partly under the
    // crosses and circles), the legend's samples.
    assert!(o > 48 * 3 && r > 48 * 8 && l > 48 * 2, "{o} {r} {l}");
    // A circle around the observation at (270, 220) (in an 11x11 window), none between points.
    let cyan = |x: u32, y: u32| {
        let p = fig.get_pixel(x, y + TITLE_HEIGHT).0;
        above(p, 2, 0) && above(p, 1, 0)
    };
    let ring = (215..=225).any(|y| (265..=275).any(|x| cyan(x, y)));
    let gap = (240..=260).any(|y| (295..=315).any(|x| cyan(x, y)));
    assert!(ring && !gap);
    // Lists of different lengths are refused.
    let e =
        reprojection_plot(&path, &img, &observed[1..], &reprojected, Some(1.0), "x").unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Shape(_)), "{e}");
}

/// Camera `i` of a ring looking at the origin, `radius` away, 640x480, f = 500 px.
fn ring_camera(i: usize, n: usize, radius: f64) -> SceneCamera {
    let angle = (i as f64 - (n - 1) as f64 / 2.0) * 0.3;
    let center = Point3::new(radius * angle.sin(), -0.5, -radius * angle.cos());
    // z towards the origin, x to the right, y down (world y is down, as OpenCV's camera 1).
    let z = (-center.coords).normalize();
    let x = Vector3::new(0.0, 1.0, 0.0).cross(&z).normalize();
    let y = z.cross(&x);
    let rotation = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    assert!((rotation.determinant() - 1.0).abs() < 1e-9);
    SceneCamera {
        label: format!("{i:04}.jpg"),
        rotation,
        center,
        intrinsics: (500.0, 500.0, 320.0, 240.0),
        size: (640, 480),
    }
}

#[test]
fn scene_with_frusta_and_many_points() {
    // 50 000 points on a wall and a floor (subsampled to 20 000), one magenta, and far outliers
    // that must not shrink the scene.
    let mut points = Vec::new();
    for i in 0..50_000 {
        let (u, v) = ((i % 250) as f64 / 250.0, (i / 250) as f64 / 200.0);
        let p = if i % 2 == 0 {
            Point3::new(4.0 * u - 2.0, 2.0 * v - 1.0, 3.0)
        } else {
            Point3::new(4.0 * u - 2.0, 1.0, 3.0 * v)
        };
        let c = [(60.0 + 150.0 * u) as u8, (60.0 + 150.0 * v) as u8, 90];
        points.push((p, c));
    }
    // A magenta point in front of the wall, above the floor: alone in the side view.
    points[0] = (Point3::new(0.0, -0.5, 1.5), [255, 0, 255]);
    points.push((Point3::new(1e6, 0.0, 1e6), [255, 255, 255]));
    points.push((Point3::new(f64::NAN, 0.0, 1.0), [255, 255, 255]));
    let cameras: Vec<SceneCamera> = (0..3).map(|i| ring_camera(i, 3, 4.0)).collect();
    let path = out("scene.png");
    scene_plot(&path, &points, &cameras, "initial baseline").unwrap();
    let img = read(&path);
    assert_eq!(img.dimensions(), SCENE_SIZE);
    assert_not_blank(&img);
    for (i, c) in CAMERA_COLOURS.iter().enumerate().take(3) {
        let n = count(&img, *c);
        println!("camera {i}: {n} pixels");
        // Two panels' frusta and the legend's line.
        assert!(n > 200, "camera {i}: {n} pixels");
    }
    assert_eq!(count(&img, CAMERA_COLOURS[3]), 0);
    assert!(count(&img, [255, 0, 255]) > 0);
    println!("{}", path.display());
}

#[test]
fn scene_of_cameras_only_and_write_errors() {
    let cameras: Vec<SceneCamera> = (0..12).map(|i| ring_camera(i, 12, 2.0)).collect();
    let path = out("scene-cameras.png");
    scene_plot(&path, &[], &cameras, "").unwrap();
    let img = read(&path);
    assert_eq!(img.dimensions(), SCENE_SIZE);
    // The palette wraps: camera 10 is camera 0's colour.
    assert!(count(&img, CAMERA_COLOURS[9]) > 100);
    let bad = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("no-such-dir/x/scene.png");
    let e = scene_plot(&bad, &[], &cameras, "m").unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Write(_)), "{e}");
}
