//! Videos in and out (#38): `ar`, `apriltag` and `warp` on a video give what they give on the
//! folder the video was made from, with each frame's time; colour frames give colour overlays;
//! `warp --corners-per-frame` pastes the logo into the frames that have corners and passes the
//! others through.
//!
//! The videos are made here, from the bundled frames, by ffmpeg (lossless FFV1 in AVI where
//! the test compares numbers, H.264 in MP4 where it only reads it back). Without ffmpeg these
//! tests fail and say how to install it (`cargo xtask setup`).

use std::path::{Path, PathBuf};
use std::process::Command;

use camgeom::nalgebra::Point2;
use camgeom::warp::{WarpConfig, warp_into_quad};
use camgeom_host::data_dir;
use camgeom_host::images::{GrayImage, load_gray, load_rgb};
use image::{Rgb, RgbImage};
use serde_json::Value;

use crate::common::{camgeom, json, scratch_file};

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn tag_dir() -> PathBuf {
    data_dir().join("sequences/tag")
}

/// A fresh, empty directory (created) under the tests' scratch directory.
fn scratch_dir(name: &str) -> PathBuf {
    let dir = scratch_file(name, "").with_extension("d");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs ffmpeg (quiet, overwriting); a missing ffmpeg fails the test with the install hint.
fn ffmpeg(args: &[&str]) {
    let out = Command::new("ffmpeg")
        .args(["-v", "error", "-y"])
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "the video tests make their videos with ffmpeg, which could not be run ({e}): \
                 install it with `cargo xtask setup` (Debian/Ubuntu: apt-get install ffmpeg)"
            )
        });
    assert!(
        out.status.success(),
        "ffmpeg {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The tag sequence's frames 0..n tinted (`r = v, g = v, b = v / 2`) into `dir` as colour PNGs.
fn tinted_frames(dir: &Path, n: usize) {
    for k in 0..n {
        let g = load_gray(tag_dir().join(format!("{k:04}.png"))).unwrap();
        let img = RgbImage::from_fn(g.width as u32, g.height as u32, |x, y| {
            let v = g.at(x as usize, y as usize);
            Rgb([v, v, v / 2])
        });
        img.save(dir.join(format!("{k:04}.png"))).unwrap();
    }
}

/// The share of `overlay`'s pixels equal to `frame`'s: the overlay is drawn on the frame's
/// own colours, not on its grey.
fn same_pixels(overlay: &RgbImage, frame: &RgbImage) -> f64 {
    assert_eq!(overlay.dimensions(), frame.dimensions());
    let same = overlay
        .pixels()
        .zip(frame.pixels())
        .filter(|(a, b)| a == b)
        .count();
    same as f64 / (frame.width() * frame.height()) as f64
}

fn ar_args<'a>(input: &'a Path, out: &'a Path, camera: &'a Path) -> Vec<&'a str> {
    vec![
        "ar",
        "--frames",
        path(input),
        "--tag",
        "42",
        "--tag-size",
        "0.08",
        "--intrinsics",
        path(camera),
        "--out",
        path(out),
    ]
}

/// `ar --tag` on the tag sequence and on a lossless video of it at 30000/1001 fps: the same
/// poses.csv, the video's with a `t` column of the frames' times (k · 1001/30000 s), the
/// summary with the rate; `--video-out` writes a video of every frame at that rate.
#[test]
fn ar_on_a_video_gives_the_folders_poses_with_times() {
    let dir = scratch_dir("ar-video");
    let video = dir.join("tag.avi");
    let frames = tag_dir().join("%04d.png");
    ffmpeg(&[
        "-framerate",
        "30000/1001",
        "-i",
        path(&frames),
        "-c:v",
        "ffv1",
        path(&video),
    ]);
    let camera = tag_dir().join("camera.yml");
    let (from_dir, from_video) = (dir.join("dir"), dir.join("video"));
    let a = json(&camgeom(&ar_args(&tag_dir(), &from_dir, &camera)));
    let mut args = ar_args(&video, &from_video, &camera);
    let overlay_video = dir.join("ar.mp4");
    args.extend(["--no-overlay", "--video-out", path(&overlay_video)]);
    let b = json(&camgeom(&args));
    assert_eq!(a["frames"], 160);
    assert_eq!(b["frames"], 160);
    assert!(a.get("fps").is_none());
    assert!(
        (b["fps"].as_f64().unwrap() - 30000.0 / 1001.0).abs() < 1e-9,
        "{b}"
    );
    for key in ["tracking", "lost", "mean_inliers", "worst_outline_px"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let read = |p: &Path| std::fs::read_to_string(p.join("poses.csv")).unwrap();
    let (folder, timed) = (read(&from_dir), read(&from_video));
    assert_eq!(folder.lines().count(), 161);
    for (k, (f, v)) in folder.lines().zip(timed.lines()).enumerate() {
        let mut v: Vec<&str> = v.split(',').collect();
        let t = v.remove(1);
        assert_eq!(f, v.join(","), "line {k}");
        if k == 0 {
            assert_eq!(t, "t");
        } else {
            let want = (k - 1) as f64 * 1001.0 / 30000.0;
            assert!((t.parse::<f64>().unwrap() - want).abs() < 1e-5, "{k}: {t}");
        }
    }
    // --no-overlay: no PNG but the contact sheet; the video has every frame at the rate.
    let pngs = std::fs::read_dir(&from_video)
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension().unwrap() == "png")
        .count();
    assert_eq!(pngs, 1);
    let probe = Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-show_entries"])
        .args([
            "stream=width,height,avg_frame_rate,nb_read_frames",
            "-of",
            "csv=p=0",
        ])
        .arg(&overlay_video)
        .output()
        .unwrap();
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        "320,240,30000/1001,160"
    );
}

/// `apriltag` on an H.264 video of colour frames: every frame with its index and time, the
/// tag found as in the frames, the overlays (every 10th) drawn on the colour frames; `ar` on
/// the colour folder draws in colour too.
#[test]
fn colour_frames_and_video_give_colour_overlays() {
    let dir = scratch_dir("colour-video");
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    tinted_frames(&frames, 30);
    let video = dir.join("tag.mp4");
    let pattern = frames.join("%04d.png");
    ffmpeg(&[
        "-framerate",
        "25",
        "-i",
        path(&pattern),
        "-c:v",
        "libx264",
        "-qp",
        "0",
        "-pix_fmt",
        "yuv444p",
        path(&video),
    ]);
    let overlays = dir.join("tags");
    let v = json(&camgeom(&[
        "apriltag",
        "--video",
        path(&video),
        "--overlay",
        path(&overlays),
        "--overlay-every",
        "10",
    ]));
    assert_eq!(v["fps"], 25.0);
    let list = v["frames"].as_array().unwrap();
    assert_eq!(list.len(), 30);
    for (k, f) in list.iter().enumerate() {
        assert_eq!(f["frame"], k);
        assert!(
            (f["t"].as_f64().unwrap() - k as f64 / 25.0).abs() < 1e-6,
            "{f}"
        );
        assert!(f.get("image").is_none());
        let ids: Vec<&Value> = f["detections"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| &d["id"])
            .collect();
        assert_eq!(ids, [&Value::from(42)], "frame {k}");
    }
    let names: Vec<String> = {
        let mut n: Vec<String> = std::fs::read_dir(&overlays)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        n.sort();
        n
    };
    assert_eq!(names, ["000000.png", "000010.png", "000020.png"]);
    // Drawn on the colour frame: most pixels are the frame's (near-lossless H.264 in 4:4:4 is
    // within a level or two of the PNG: compare with a tolerance), and they are not grey.
    let overlay = load_rgb(overlays.join("000010.png")).unwrap();
    let frame = load_rgb(frames.join("0010.png")).unwrap();
    let close = overlay
        .pixels()
        .zip(frame.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0).all(|(x, y)| x.abs_diff(y) <= 3))
        .count() as f64
        / (320.0 * 240.0);
    assert!(close > 0.9, "{close}");
    let tinted = overlay
        .pixels()
        .filter(|p| p.0[2] < p.0[0] / 2 + 8 && p.0[0] > 40)
        .count();
    assert!(tinted > 320 * 240 / 4, "{tinted}");

    // ar on the colour folder: the overlays are the colour frames with the drawing on top.
    let out = dir.join("ar");
    let camera = tag_dir().join("camera.yml");
    let mut args = ar_args(&frames, &out, &camera);
    args.extend(["--overlay-every", "10"]);
    json(&camgeom(&args));
    let share = same_pixels(
        &load_rgb(out.join("0020.png")).unwrap(),
        &load_rgb(frames.join("0020.png")).unwrap(),
    );
    assert!(share > 0.9, "{share}");
}

/// The warp test's checker logo, its fixture quadrilateral (`host-tests/scripts/
/// make_feature_fixtures.py`, the one `cv2.warpPerspective` was run on) and camgeom's warp of it
/// into a `w x h` frame of one value: what each channel of a pasted frame must be.
fn warp_plane(quad: &[Point2<f32>; 4], w: usize, h: usize, value: u8) -> GrayImage {
    let logo = camgeom_host::bench::warp_case().0;
    let mut out = GrayImage::filled(w, h, value);
    let (src, mut dst) = (logo.view().unwrap(), out.view_mut().unwrap());
    warp_into_quad::<f32>(&src, &mut dst, quad, &WarpConfig { alpha: 255 }).unwrap();
    out
}

fn fixture_quad() -> [Point2<f32>; 4] {
    let path = data_dir().join("features/opencv_orb_figures.json");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let q = v["warp_checker"]["quad"].as_array().unwrap();
    std::array::from_fn(|i| {
        Point2::new(
            q[i][0].as_f64().unwrap() as f32,
            q[i][1].as_f64().unwrap() as f32,
        )
    })
}

/// `warp --frames --corners-per-frame` on three colour frames with corners for frames 0 and
/// 2: those get the logo in each channel exactly as the single-frame warp (checked against
/// `cv2.warpPerspective` in `warp.rs`, channel R's background is that test's), frame 1 is
/// written unchanged; the same from a video into a video keeps the count and the rate.
#[test]
fn warp_per_frame_pastes_where_there_are_corners() {
    let dir = scratch_dir("warp-frames");
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    let colour = [100u8, 150, 200];
    for k in 0..3 {
        RgbImage::from_pixel(320, 240, Rgb(colour))
            .save(frames.join(format!("f{k}.png")))
            .unwrap();
    }
    let logo = dir.join("logo.png");
    camgeom_host::images::save_gray(&camgeom_host::bench::warp_case().0, &logo).unwrap();
    let quad = fixture_quad();
    let row = |k: usize| {
        let xy: Vec<String> = quad
            .iter()
            .flat_map(|p| [p.x, p.y])
            .map(|v| v.to_string())
            .collect();
        format!("{k},{}\n", xy.join(","))
    };
    let corners = dir.join("corners.csv");
    std::fs::write(
        &corners,
        format!(
            "frame,x0,y0,x1,y1,x2,y2,x3,y3\n{}{}{}",
            row(0),
            row(2),
            row(7)
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let args = |input: &Path, out: &Path| {
        camgeom(&[
            "warp",
            "--logo",
            path(&logo),
            "--frames",
            path(input),
            "--corners-per-frame",
            path(&corners),
            "--out",
            path(out),
        ])
    };
    let j = json(&args(&frames, &out));
    assert_eq!(j["frames"], 3);
    assert_eq!(j["warped"], 2);
    assert_eq!(j["without_corners"], 1);
    assert_eq!(j["unused_rows"], 1);
    let planes: Vec<GrayImage> = colour
        .iter()
        .map(|&c| warp_plane(&quad, 320, 240, c))
        .collect();
    for k in [0, 2] {
        let img = load_rgb(out.join(format!("f{k}.png"))).unwrap();
        for (c, plane) in planes.iter().enumerate() {
            let got: Vec<u8> = img.pixels().map(|p| p.0[c]).collect();
            assert!(got == plane.data, "frame {k} channel {c}");
        }
    }
    let passed = load_rgb(out.join("f1.png")).unwrap();
    assert!(passed.pixels().all(|p| p.0 == colour));

    // From a video into a video.
    let video = dir.join("in.mp4");
    let pattern = frames.join("f%d.png");
    ffmpeg(&[
        "-framerate",
        "10",
        "-i",
        path(&pattern),
        "-c:v",
        "libx264",
        path(&video),
    ]);
    let out_video = dir.join("out.mp4");
    let j = json(&args(&video, &out_video));
    assert_eq!(
        (j["frames"].as_u64(), j["warped"].as_u64()),
        (Some(3), Some(2))
    );
    assert_eq!(j["fps"], 10.0);
    assert!(std::fs::metadata(&out_video).unwrap().len() > 0);
}

/// Without ffmpeg on the PATH a video is refused with the install hint (status 2).
#[test]
fn a_video_without_ffmpeg_says_how_to_install_it() {
    let dir = scratch_dir("no-ffmpeg");
    let video = dir.join("any.mp4");
    std::fs::write(&video, b"not decoded").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_camgeom"))
        .args(["apriltag", "--video", path(&video)])
        .env("PATH", "")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cargo xtask setup") && err.contains("ffprobe"),
        "{err}"
    );
}

/// `track` on the first 12 frames of the tree sequence and on a lossless video of them at 25
/// fps: the same tracks to the bit, the video's rows with a `t` column (k / 25 s), the summary
/// with the rate, the overlays named for the frames' indices.
#[test]
fn track_on_a_video_gives_the_folders_tracks_with_times() {
    let dir = scratch_dir("track-video");
    let (frames, video) = (dir.join("frames"), dir.join("tree.avi"));
    std::fs::create_dir_all(&frames).unwrap();
    for k in 0..12 {
        let name = format!("{k:04}.png");
        std::fs::copy(
            data_dir().join("sequences/tree").join(&name),
            frames.join(&name),
        )
        .unwrap();
    }
    let pattern = frames.join("%04d.png");
    ffmpeg(&[
        "-framerate",
        "25",
        "-i",
        path(&pattern),
        "-c:v",
        "ffv1",
        path(&video),
    ]);
    let run = |input: &Path, name: &str| {
        let (out, overlay) = (dir.join(format!("{name}.csv")), dir.join(name));
        let s = json(&camgeom(&[
            "track",
            "--frames",
            path(input),
            "--out",
            path(&out),
            "--overlay",
            path(&overlay),
            "--max-tracks",
            "120",
        ]));
        (s, std::fs::read_to_string(out).unwrap(), overlay)
    };
    let (a, folder, _) = run(&frames, "from-folder");
    let (b, timed, overlays) = run(&video, "from-video");
    assert_eq!(
        (a["frames"].as_u64(), b["frames"].as_u64()),
        (Some(12), Some(12))
    );
    assert!(a["fps"].is_null(), "{a}");
    assert_eq!(b["fps"].as_f64(), Some(25.0), "{b}");
    assert_eq!(a["rows"], b["rows"]);
    assert!(a["rows"].as_u64().unwrap() > 12 * 60, "{a}");
    for (k, (f, v)) in folder.lines().zip(timed.lines()).enumerate() {
        let mut v: Vec<&str> = v.split(',').collect();
        let t = v.remove(1);
        assert_eq!(f, v.join(","), "line {k}");
        if k == 0 {
            assert_eq!(t, "t");
        } else {
            let frame: f64 = v[0].parse().unwrap();
            assert!(
                (t.parse::<f64>().unwrap() - frame / 25.0).abs() < 1e-6,
                "{k}: {t}"
            );
        }
    }
    assert!(overlays.join("000011.png").exists());
    assert_eq!(std::fs::read_dir(&overlays).unwrap().count(), 12);
}
