//! The `camgeom` binary: output against the OpenCV fixture, and usage/input errors (exit status
//! 2, one line on stderr, nothing on stdout).

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use crate::common::{bundled_poses, chessboard, scratch_file};
use camgeom_host::points::parse_csv;

fn camgeom(args: &[&str], stdin: Option<&str>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_camgeom"));
    cmd.args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().expect("run camgeom");
    {
        let mut pipe = child.stdin.take().unwrap();
        if let Some(s) = stdin {
            pipe.write_all(s.as_bytes()).unwrap();
        }
    }
    child.wait_with_output().unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `--rvec`/`--tvec` values of bundled view `view`, written so they read back bit-identical.
fn pose_args(view: usize) -> (String, String) {
    let p = bundled_poses()[view];
    let f = |a: &[f64]| format!("{:?},{:?},{:?}", a[0], a[1], a[2]);
    (f(&p[..3]), f(&p[3..]))
}

/// OpenCV's `(u, v)` for every corner of `view`, in board_corners.csv order (j outer, i inner,
/// the fixture's order too).
fn opencv_view(view: usize) -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(chessboard("opencv_projections.csv")).unwrap();
    let t = parse_csv(
        &text,
        "opencv_projections.csv",
        &["view", "i", "j", "u", "v"],
    )
    .unwrap();
    t.rows
        .iter()
        .filter(|r| r[0] as usize == view)
        .map(|r| (r[3], r[4]))
        .collect()
}

/// Parses the CLI's CSV output: header `u,v,status`, then one row per point.
fn parse_output(stdout: &[u8]) -> Vec<(f64, f64, String)> {
    let text = std::str::from_utf8(stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("u,v,status"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 3, "row `{l}`");
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].to_string(),
            )
        })
        .collect()
}

pub(crate) fn assert_usage_error(out: &Output, needle: &str) {
    assert_eq!(out.status.code(), Some(2), "exit status; stderr: {out:?}");
    assert!(out.stdout.is_empty(), "stdout on error: {out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.ends_with('\n') && err.trim_end().lines().count() == 1,
        "stderr is not one line: {err:?}"
    );
    assert!(err.starts_with("camgeom: error: "), "{err}");
    assert!(err.contains(needle), "stderr `{err}` lacks `{needle}`");
}

#[test]
fn project_matches_opencv() {
    let yml = chessboard("left_intrinsics.yml");
    let corners = chessboard("board_corners.csv");
    for view in [0, 1, 4, 12] {
        let (rvec, tvec) = pose_args(view);
        let out = camgeom(
            &[
                "project",
                "--intrinsics",
                path(&yml),
                "--points",
                path(&corners),
                "--rvec",
                &rvec,
                "--tvec",
                &tvec,
            ],
            None,
        );
        assert!(out.status.success(), "{out:?}");
        assert!(out.stderr.is_empty());
        let rows = parse_output(&out.stdout);
        let reference = opencv_view(view);
        assert_eq!(rows.len(), reference.len());
        for ((u, v, status), (ru, rv)) in rows.iter().zip(&reference) {
            assert_eq!(status, "ok");
            // The CLI computes in f64 and prints the shortest text that reads back to the same
            // double, so the f64 library bound (1e-9 px, see tests/it/projection.rs) holds here too.
            assert!(
                (u - ru).abs() < 1e-9 && (v - rv).abs() < 1e-9,
                "view {view}"
            );
        }
    }
}

#[test]
fn project_json_f32_and_stdin() {
    let (rvec, tvec) = pose_args(3);
    let corners = std::fs::read_to_string(chessboard("board_corners.csv")).unwrap();
    let yml = chessboard("left_intrinsics.yml");
    let reference = opencv_view(3);
    // JSON, points from stdin, camera from the JSON camera file.
    let json_cam = chessboard("camera.json");
    let out = camgeom(
        &[
            "project",
            "--intrinsics",
            path(&json_cam),
            "--points",
            "-",
            &format!("--rvec={rvec}"),
            &format!("--tvec={tvec}"),
            "--json",
        ],
        Some(&corners),
    );
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let points = v["points"].as_array().unwrap();
    assert_eq!(points.len(), reference.len());
    for (p, (ru, rv)) in points.iter().zip(&reference) {
        assert_eq!(p["status"], "ok");
        let (u, v) = (p["u"].as_f64().unwrap(), p["v"].as_f64().unwrap());
        assert!((u - ru).abs() < 1e-9 && (v - rv).abs() < 1e-9);
    }
    // --f32: the firmware's arithmetic; bound as in tests/it/projection.rs (2e-3 px, measured
    // ~1.2e-4 px).
    let out = camgeom(
        &[
            "project",
            "--intrinsics",
            path(&yml),
            "--points",
            path(&chessboard("board_corners.csv")),
            "--rvec",
            &rvec,
            "--tvec",
            &tvec,
            "--f32",
        ],
        None,
    );
    assert!(out.status.success(), "{out:?}");
    for ((u, v, _), (ru, rv)) in parse_output(&out.stdout).iter().zip(&reference) {
        assert!((u - ru).abs() < 2e-3 && (v - rv).abs() < 2e-3);
    }
}

#[test]
fn unprojectable_points_get_a_status() {
    // Identity pose: the camera looks down +Z. A point on the optical axis lands on the
    // principal point; points at or behind Z = 0 have no image.
    let csv = "X,Y,Z\n0,0,2\n0.1,0,-1\n0,0,0\n";
    let yml = chessboard("left_intrinsics.yml");
    let out = camgeom(
        &["project", "--intrinsics", path(&yml), "--points", "-"],
        Some(csv),
    );
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    assert_eq!(lines[1], "342.28315473308373,235.57082909788173,ok");
    assert_eq!(lines[2], "nan,nan,behind_camera");
    assert_eq!(lines[3], "nan,nan,behind_camera");
    let out = camgeom(
        &[
            "project",
            "--intrinsics",
            path(&yml),
            "--points",
            "-",
            "--json",
        ],
        Some(csv),
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["points"][1]["status"], "behind_camera");
    assert!(v["points"][1]["u"].is_null());
}

#[test]
fn camera_subcommand_reproduces_the_bundled_files() {
    // camera.json / camera.toml are this command's output on left_intrinsics.yml.
    let yml = chessboard("left_intrinsics.yml");
    for (flag, file) in [(None, "camera.json"), (Some("--toml"), "camera.toml")] {
        let mut args = vec!["camera", "--intrinsics", path(&yml)];
        args.extend(flag);
        let out = camgeom(&args, None);
        assert!(out.status.success(), "{out:?}");
        let expected = std::fs::read_to_string(chessboard(file)).unwrap();
        assert_eq!(String::from_utf8(out.stdout).unwrap(), expected, "{file}");
    }
}

#[test]
fn usage_and_input_errors_exit_2_with_one_line() {
    let yml = chessboard("left_intrinsics.yml");
    let yml = path(&yml);
    let good = scratch_file("cli-good.csv", "X,Y,Z\n0,0,1\n");
    let good = path(&good);

    let missing = camgeom(
        &[
            "project",
            "--intrinsics",
            yml,
            "--points",
            "/no/such/points.csv",
        ],
        None,
    );
    assert_usage_error(&missing, "/no/such/points.csv");

    let no_camera = camgeom(
        &[
            "project",
            "--intrinsics",
            "/no/such/cam.yml",
            "--points",
            good,
        ],
        None,
    );
    assert_usage_error(&no_camera, "/no/such/cam.yml");

    let bad_row = scratch_file("cli-bad-row.csv", "X,Y,Z\n0,0,1\n0,1\n");
    let out = camgeom(
        &["project", "--intrinsics", yml, "--points", path(&bad_row)],
        None,
    );
    // The message names the file and the line.
    assert_usage_error(&out, "cli-bad-row.csv:3:");

    let not_number = camgeom(
        &["project", "--intrinsics", yml, "--points", "-"],
        Some("0,zero,1\n0,0,1\n"),
    );
    assert_usage_error(&not_number, "-:1: Y is not a number");

    let nan = scratch_file("cli-nan.csv", "0,0,1\nNaN,0,1\n");
    let out = camgeom(
        &["project", "--intrinsics", yml, "--points", path(&nan)],
        None,
    );
    assert_usage_error(&out, "cli-nan.csv:2: X is not finite");

    let bad_cam = scratch_file(
        "cli-zero-focal.json",
        r#"{"fx": 0, "fy": 500, "cx": 320, "cy": 240}"#,
    );
    let out = camgeom(
        &["project", "--intrinsics", path(&bad_cam), "--points", good],
        None,
    );
    assert_usage_error(
        &out,
        "invalid_intrinsics (intrinsics do not describe a camera)",
    );

    let out = camgeom(
        &[
            "project",
            "--intrinsics",
            yml,
            "--points",
            good,
            "--rvec",
            "0,nan,0",
        ],
        None,
    );
    assert_usage_error(&out, "--rvec");
    let out = camgeom(
        &[
            "project",
            "--intrinsics",
            yml,
            "--points",
            good,
            "--tvec",
            "1,2",
        ],
        None,
    );
    assert_usage_error(&out, "--tvec");
    assert_usage_error(
        &camgeom(&["project", "--intrinsics", yml], None),
        "--points",
    );
    assert_usage_error(&camgeom(&["frobnicate"], None), "frobnicate"); // an unknown subcommand (`warp` exists now)
    assert_usage_error(&camgeom(&[], None), "subcommand");
}

/// An output that cannot be written (a file a subcommand writes, or standard output) exits
/// with status 1 and one line naming it.
#[test]
fn output_errors_exit_1_with_one_line() {
    let features = camgeom_host::data_dir().join("features");
    let corners = scratch_file("cli-quad.csv", "10,10\n100,12\n98,90\n12,95\n");
    let out = camgeom(
        &[
            "warp",
            "--logo",
            path(&features.join("box.png")),
            "--frame",
            path(&features.join("box_in_scene.png")),
            "--corners",
            path(&corners),
            "--out",
            "/no/such/dir/out.png",
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(out.stdout.is_empty(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("camgeom: error: /no/such/dir/out.png: cannot write: "),
        "{err}"
    );

    // Standard output on a full device (Linux's /dev/full).
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return;
    };
    let out = Command::new(env!("CARGO_BIN_EXE_camgeom"))
        .args([
            "camera",
            "--intrinsics",
            path(&chessboard("left_intrinsics.yml")),
        ])
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with("camgeom: error: standard output: cannot write: ")
            && err.lines().count() == 1,
        "{err}"
    );
}

#[test]
fn help_and_version_succeed() {
    let out = camgeom(&["--help"], None);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("project"));
    let out = camgeom(&["--version"], None);
    assert!(out.status.success());
}

/// Images too small for any detector's window are refused with a typed error (exit 2), not
/// answered with an empty result; 16-bit images keep their high byte (OpenCV's `imread` rule).
#[test]
fn degenerate_and_16_bit_images() {
    let dir = std::env::temp_dir().join(format!("camgeom-degenerate-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let one = dir.join("one.png");
    image::GrayImage::from_pixel(1, 1, image::Luma([0]))
        .save(&one)
        .unwrap();
    let out = camgeom(&["apriltag", "--image", one.to_str().unwrap()], None);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.contains("1x1 is smaller than") && err.lines().count() == 1,
        "{err}"
    );
    let pts = dir.join("p.csv");
    std::fs::write(&pts, "x,y\n0,0\n").unwrap();
    let (o, p) = (one.to_str().unwrap(), pts.to_str().unwrap());
    let out = camgeom(&["flow", "--from", o, "--to", o, "--points", p], None);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("tracking window")
    );
    // 16-bit grey: each sample's high byte.
    let wide = dir.join("wide.png");
    let px: Vec<u16> = (0..64u16).map(|i| i * 1000 + 255).collect();
    image::ImageBuffer::<image::Luma<u16>, _>::from_raw(8, 8, px.clone())
        .unwrap()
        .save(&wide)
        .unwrap();
    let g = camgeom_host::images::load_gray(&wide).unwrap();
    let expect: Vec<u8> = px.iter().map(|v| (v >> 8) as u8).collect();
    assert_eq!(g.data, expect);
}
