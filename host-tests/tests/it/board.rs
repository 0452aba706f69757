//! Tag boards (issue #41): OpenCV's GridBoard layout, and `camgeom apriltag --board` on
//! OpenCV-rendered views of a 5x4 DICT_4X4_50 GridBoard with 100 %, 50 % and 25 % of its tags
//! visible (covered, or out of the frame), against the truth and OpenCV's own board pose
//! (`host-tests/data/board/`, made by `host-tests/scripts/board_render.py test`).

use camgeom::apriltag::{GridBoard, families};
use camgeom::nalgebra::{Matrix3, Rotation3, Vector3};
use serde_json::Value;

use crate::cli::assert_usage_error;
use crate::common::{camgeom, json};

fn data(name: &str) -> String {
    camgeom_host::data_dir()
        .join("board")
        .join(name)
        .display()
        .to_string()
}

fn read(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(data(name)).unwrap()).unwrap()
}

fn vec3(v: &Value) -> Vector3<f64> {
    Vector3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

/// Degrees between the rotations of two rotation vectors.
fn rot_err_deg(a: &Rotation3<f64>, rvec: &Vector3<f64>) -> f64 {
    (a * Rotation3::new(*rvec).inverse()).angle().to_degrees()
}

/// `GridBoard` is OpenCV's `GridBoard(...).getObjPoints()` (OpenCV's f32 sums: equal in f32),
/// ids row by row.
#[test]
fn grid_layout_is_opencvs() {
    let fx = read("objpoints.json");
    for g in fx["grids"].as_array().unwrap() {
        let n = |k: &str| g[k].as_u64().unwrap() as u16;
        let f = |k: &str| g[k].as_f64().unwrap();
        let grid = GridBoard::<f32> {
            markers_x: n("markers_x"),
            markers_y: n("markers_y"),
            marker_length: f("marker_length") as f32,
            marker_separation: f("marker_separation") as f32,
            first_id: n("first_id"),
        };
        let ids = g["ids"].as_array().unwrap();
        let obj = g["objpoints"].as_array().unwrap();
        assert_eq!(grid.len(), obj.len());
        for (k, (q, id)) in obj.iter().zip(ids).enumerate() {
            let tag = grid.tag(k).unwrap();
            assert_eq!(u64::from(tag.id), id.as_u64().unwrap());
            for (c, want) in tag.corners.iter().zip(q.as_array().unwrap()) {
                for (v, w) in c.iter().zip(want.as_array().unwrap()) {
                    assert_eq!(*v, w.as_f64().unwrap() as f32, "grid {g:?} tag {k}");
                }
            }
        }
    }
}

/// The board pose of every rendered view: within 0.1 deg and 0.5 mm of the truth, no worse
/// than OpenCV's (ArucoDetector, matchImagePoints, solvePnP ITERATIVE) in rotation, from exactly
/// the visible tags; the YAML board file gives the same pose as the JSON one.
#[test]
fn board_pose_against_truth_and_opencv() {
    let truth = read("truth.json");
    for v in truth["views"].as_array().unwrap() {
        let image = data(v["image"].as_str().unwrap());
        let out = json(&camgeom(&[
            "apriltag",
            "--image",
            &image,
            "--board",
            &data("board.json"),
            "--intrinsics",
            &data("camera.json"),
        ]));
        let b = &out["board"];
        let r: Vec<f64> = b["R"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let rot = Rotation3::from_matrix_unchecked(Matrix3::from_row_slice(&r));
        let e_rot = rot_err_deg(&rot, &vec3(&v["rvec"]));
        let e_t = (vec3(&b["t"]) - vec3(&v["tvec"])).norm();
        let cv = &v["opencv"];
        let cv_rot = Rotation3::new(vec3(&cv["rvec"]));
        let e_cv = rot_err_deg(&cv_rot, &vec3(&v["rvec"]));
        println!(
            "{image}: {} tags, rot {e_rot:.4} deg (OpenCV {e_cv:.4}), t {:.3} mm",
            b["tags"].as_array().unwrap().len(),
            1e3 * e_t
        );
        assert!(e_rot < 0.1 && e_rot <= e_cv, "{image}: {e_rot} vs {e_cv}");
        assert!(e_t < 5e-4, "{image}: {e_t}");
        assert_eq!(b["tags"], v["visible"], "{image}");
        assert_eq!(b["ambiguous"], false);
        assert!(b["rms_px"].as_f64().unwrap() < 0.2);
        let yml = json(&camgeom(&[
            "apriltag",
            "--image",
            &image,
            "--board",
            &data("board.yml"),
            "--intrinsics",
            &data("camera.json"),
        ]));
        assert_eq!(yml["board"], out["board"]);
    }
}

fn write(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("camgeom-board-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// No board tag in view: the detections, and a board entry saying why there is no pose.
#[test]
fn no_board_tag_in_view_is_said() {
    let far = write(
        "far.json",
        r#"{"family": "DICT_4X4_50", "grid": {"markers_x": 2, "markers_y": 2,
            "marker_length": 0.04, "marker_separation": 0.01, "first_id": 30}}"#,
    );
    let out = json(&camgeom(&[
        "apriltag",
        "--image",
        &data("0000.png"),
        "--board",
        &far,
        "--intrinsics",
        &data("camera.json"),
    ]));
    assert_eq!(out["detections"].as_array().unwrap().len(), 20);
    assert!(out["board"]["R"].is_null());
    assert_eq!(out["board"]["error"], "no board tag seen once");
}

/// One tag of a planar board listed by its corners: a pose, and the tags' list form.
#[test]
fn listed_tags_board() {
    let listed = write(
        "listed.json",
        r#"{"family": "DICT_4X4_50", "tags": [
            {"id": 0, "corners": [[0,0,0],[0.04,0,0],[0.04,0.04,0],[0,0.04,0]]},
            {"id": 19, "corners": [[0.2,0.15,0],[0.24,0.15,0],[0.24,0.19,0],[0.2,0.19,0]]}]}"#,
    );
    let out = json(&camgeom(&[
        "apriltag",
        "--image",
        &data("0000.png"),
        "--board",
        &listed,
        "--intrinsics",
        &data("camera.json"),
    ]));
    let truth = read("truth.json");
    let v = &truth["views"][0];
    assert_eq!(out["board"]["tags"], serde_json::json!([0, 19]));
    assert!((vec3(&out["board"]["t"]) - vec3(&v["tvec"])).norm() < 2e-3);
}

/// Wrong board files are input errors (exit 2, one line naming the problem).
#[test]
fn wrong_board_files_are_refused() {
    let cases = [
        (
            "family.json",
            r#"{"family": "DICT_9X9", "grid": {"markers_x": 2, "markers_y": 2, "marker_length": 0.04, "marker_separation": 0.01}}"#,
            "unknown family",
        ),
        (
            "key.json",
            r#"{"family": "DICT_4X4_50", "grid": {"markers_x": 2, "markers_y": 2, "marker_length": 0.04, "marker_separation": 0.01, "colour": 1}}"#,
            "unknown field",
        ),
        (
            "neither.json",
            r#"{"family": "DICT_4X4_50"}"#,
            "one of `grid` and `tags`",
        ),
        (
            "ids.json",
            r#"{"family": "DICT_4X4_50", "grid": {"markers_x": 5, "markers_y": 11, "marker_length": 0.04, "marker_separation": 0.01}}"#,
            "grid",
        ),
        (
            "length.yml",
            "family: DICT_4X4_50\ngrid:\n  markers_x: 2\n  markers_y: 2\n  marker_length: -1\n  marker_separation: 0.01\n",
            "marker_length",
        ),
        (
            "twice.json",
            r#"{"family": "DICT_4X4_50", "tags": [{"id": 1, "corners": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}, {"id": 1, "corners": [[2,0,0],[3,0,0],[3,1,0],[2,1,0]]}]}"#,
            "tags",
        ),
        ("board.txt", "{}", "extension"),
    ];
    for (name, text, needle) in cases {
        let f = write(name, text);
        let out = camgeom(&[
            "apriltag",
            "--image",
            &data("0000.png"),
            "--board",
            &f,
            "--intrinsics",
            &data("camera.json"),
        ]);
        assert_usage_error(&out, needle);
    }
    // --board needs the camera.
    let out = camgeom(&[
        "apriltag",
        "--image",
        &data("0000.png"),
        "--board",
        &data("board.json"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    // The family of a board file is one camgeom decodes.
    assert!(families::by_name("DICT_4X4_50").is_some());
}

/// `camgeom ar --board`: the board's pose on every rendered view, `poses.csv` with the tags
/// used, the overlays and the contact sheet.
#[test]
fn ar_on_the_board() {
    let out_dir = std::env::temp_dir().join(format!("camgeom-board-ar-{}", std::process::id()));
    let out = json(&camgeom(&[
        "ar",
        "--frames",
        &camgeom_host::data_dir().join("board").display().to_string(),
        "--board",
        &data("board.json"),
        "--intrinsics",
        &data("camera.json"),
        "--out",
        &out_dir.display().to_string(),
    ]));
    assert_eq!(out["frames"], 6);
    assert_eq!(out["tracking"], 6);
    let csv = std::fs::read_to_string(out_dir.join("poses.csv")).unwrap();
    let truth = read("truth.json");
    for (line, v) in csv.lines().skip(1).zip(truth["views"].as_array().unwrap()) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[1], "tracking");
        let num = |k: usize| f[k].parse::<f64>().unwrap();
        let t = Vector3::new(num(5), num(6), num(7));
        assert!((t - vec3(&v["tvec"])).norm() < 1e-3, "{line}");
        assert_eq!(
            f[11].parse::<usize>().unwrap(),
            v["visible"].as_array().unwrap().len()
        );
    }
    assert!(out_dir.join("0001.png").is_file() && out_dir.join("contact_sheet.png").is_file());
    let _ = std::fs::remove_dir_all(&out_dir);
}
