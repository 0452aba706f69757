//! Camera-file loaders: the four formats agree, and malformed files are errors (never panics)
//! that name the file and what is wrong.

use crate::common::{bundled_camera, chessboard, scratch_file};
use camgeom_host::intrinsics::{camera_from_json, camera_from_storage, camera_from_toml};
use camgeom_host::storage::Value;
use camgeom_host::{CameraSpec, ErrorKind, FileStorage, load_camera, read_matrix_text};

/// A malformed-file case: what it is, the file text, and the error kind it must produce.
type Case<S> = (&'static str, S, fn(&ErrorKind) -> bool);

// The calibration exactly as printed in `left_intrinsics.yml` (17 significant digits, more than
// a double holds, as OpenCV writes them): the loaders must round this text as Rust does.
#[allow(clippy::excessive_precision)]
const FX: f64 = 5.3591573396163199e+02;
const CX: f64 = 3.4228315473308373e+02;
const CY: f64 = 2.3557082909788173e+02;
#[allow(clippy::excessive_precision)]
const DIST: [f64; 5] = [
    -2.6637260909660682e-01,
    -3.8588898922304653e-02,
    1.7831947042852964e-03,
    -2.8122100441115472e-04,
    2.3839153080878486e-01,
];

fn yaml(text: &str) -> camgeom_host::Result<CameraSpec> {
    camera_from_storage(&FileStorage::parse_yaml(text, "test.yml")?)
}

fn xml(text: &str) -> camgeom_host::Result<CameraSpec> {
    camera_from_storage(&FileStorage::parse_xml(text, "test.xml")?)
}

/// A YAML calibration with the given camera-matrix and distortion blocks.
fn yaml_with(k: &str, d: &str) -> String {
    format!("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n{k}\n{d}\n")
}

const GOOD_K: &str = "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 5.3591573396163199e+02, 0., 3.4228315473308373e+02, 0.,\n       5.3591573396163199e+02, 2.3557082909788173e+02, 0., 0., 1. ]";
const GOOD_D: &str = "distortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ -2.6637260909660682e-01, -3.8588898922304653e-02,\n       1.7831947042852964e-03, -2.8122100441115472e-04,\n       2.3839153080878486e-01 ]";

#[test]
fn bundled_camera_has_the_printed_values() {
    let spec = bundled_camera();
    let k = &spec.camera.intrinsics;
    // Bit-exact: every loader must parse decimal text to the nearest double, as OpenCV does.
    assert_eq!(
        (k.fx(), k.fy(), k.cx(), k.cy(), k.skew()),
        (FX, FX, CX, CY, 0.0)
    );
    assert_eq!(spec.camera.lens.coefficients(), DIST);
    assert_eq!(spec.image_size, Some((640, 480)));
}

#[test]
fn all_formats_give_the_identical_camera() {
    let reference = bundled_camera();
    for name in ["left_intrinsics.xml", "camera.json", "camera.toml"] {
        let spec = load_camera(chessboard(name)).unwrap();
        // Exact equality: JSON/TOML hold the shortest round-trip text of each double, and the
        // XML was written by OpenCV from the same doubles with 17 significant digits.
        assert_eq!(spec, reference, "{name}");
        assert_eq!(spec.camera_f32(), reference.camera_f32(), "{name}");
    }
    // The flow-mapping form of an opencv-matrix and the `%YAML 1.0` spelling read the same.
    let flow = format!(
        "%YAML 1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix {{ rows: 3, cols: 3, dt: d,\n   data: [ {FX:e}, 0., {CX:e}, 0., {FX:e}, {CY:e}, 0., 0., 1. ] }}\ndistortion_coefficients: !!opencv-matrix {{ rows: 1, cols: 5, dt: d, data: [ {}, {}, {}, {}, {} ] }}\n",
        DIST[0], DIST[1], DIST[2], DIST[3], DIST[4]
    );
    assert_eq!(yaml(&flow).unwrap(), reference);
}

#[test]
fn f32_camera_rounds_each_parameter() {
    let spec = bundled_camera();
    let c = spec.camera_f32();
    assert_eq!(c.intrinsics.fx(), FX as f32);
    assert_eq!(c.lens.coefficients()[4], DIST[4] as f32);
}

#[test]
fn four_and_eight_coefficients() {
    // 4 coefficients: k3 = 0.
    let d4 = "distortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 4\n  dt: d\n  data: [ -0.2, 0.05, 0.001, -0.002 ]";
    let spec = yaml(&yaml_with(GOOD_K, d4)).unwrap();
    assert_eq!(
        spec.camera.lens.coefficients(),
        [-0.2, 0.05, 0.001, -0.002, 0.0]
    );
    // 8 coefficients whose rational part is zero: the 5-coefficient model, accepted.
    let d8 = "distortion_coefficients: !!opencv-matrix\n  rows: 8\n  cols: 1\n  dt: d\n  data: [ -0.2, 0.05, 0.001, -0.002, 0.01, 0., 0., 0. ]";
    let spec = yaml(&yaml_with(GOOD_K, d8)).unwrap();
    assert_eq!(
        spec.camera.lens.coefficients(),
        [-0.2, 0.05, 0.001, -0.002, 0.01]
    );
    // A real rational model is refused, and the message says why.
    let r8 = d8.replace("0., 0., 0. ]", "0.3, 0., 0. ]");
    let e = yaml(&yaml_with(GOOD_K, &r8)).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Unsupported(_)), "{e}");
    assert!(e.to_string().contains("rational model"), "{e}");
    // 14 coefficients with a thin-prism term.
    let c14: Vec<String> = (0..14)
        .map(|i| if i == 9 { "0.01".into() } else { "0.".into() })
        .collect();
    let t14 = format!(
        "distortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 14\n  dt: d\n  data: [ {} ]",
        c14.join(", ")
    );
    let e = yaml(&yaml_with(GOOD_K, &t14)).unwrap_err();
    assert!(e.to_string().contains("thin-prism"), "{e}");
    // 3 or 6 coefficients do not exist in OpenCV.
    let d3 = "distortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 3\n  dt: d\n  data: [ 0.1, 0., 0. ]";
    let e = yaml(&yaml_with(GOOD_K, d3)).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Shape(_)), "{e}");
}

/// Every malformed camera file must give an `Err` of the right kind: never a panic, never a
/// camera.
#[test]
fn malformed_yaml_is_an_error() {
    let cases: Vec<Case<String>> = vec![
        (
            "missing camera_matrix",
            yaml_with("", GOOD_D),
            |k| matches!(k, ErrorKind::MissingKey(s) if s == "camera_matrix"),
        ),
        (
            "missing distortion",
            yaml_with(GOOD_K, ""),
            |k| matches!(k, ErrorKind::MissingKey(s) if s == "distortion_coefficients"),
        ),
        (
            "missing data",
            yaml_with(
                "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d",
                GOOD_D,
            ),
            |k| matches!(k, ErrorKind::MissingKey(s) if s == "camera_matrix.data"),
        ),
        (
            "rows do not match data",
            yaml_with(&GOOD_K.replace("rows: 3", "rows: 2"), GOOD_D),
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "data too short",
            yaml_with(&GOOD_K.replace(" 0., 0., 1. ]", " 0., 1. ]"), GOOD_D),
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "3x4 camera matrix",
            yaml_with(
                "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 4\n  dt: d\n  data: [ 500., 0., 320., 0., 0., 500., 240., 0., 0., 0., 1., 0. ]",
                GOOD_D,
            ),
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "2-D distortion",
            yaml_with(
                GOOD_K,
                "distortion_coefficients: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n  data: [ 0., 0., 0., 0. ]",
            ),
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "non-numeric data",
            yaml_with(&GOOD_K.replace("0., 0., 1. ]", "0., zero, 1. ]"), GOOD_D),
            |k| matches!(k, ErrorKind::Syntax(m) if m.contains("camera_matrix.data[7]")),
        ),
        (
            "non-numeric rows",
            yaml_with(&GOOD_K.replace("rows: 3", "rows: three"), GOOD_D),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "unknown dt",
            yaml_with(&GOOD_K.replace("dt: d", "dt: q"), GOOD_D),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "zero focal length",
            yaml_with(
                &GOOD_K.replace("[ 5.3591573396163199e+02,", "[ 0.,"),
                GOOD_D,
            ),
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        (
            "negative focal length",
            yaml_with(
                &GOOD_K.replace("\n       5.3591573396163199e+02,", "\n       -5.,"),
                GOOD_D,
            ),
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        (
            "last row not 0 0 1",
            yaml_with(&GOOD_K.replace("0., 0., 1. ]", "0., 0., 2. ]"), GOOD_D),
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        (
            "NaN in the matrix",
            yaml_with(&GOOD_K.replace("0., 0., 1. ]", "0., .NaN, 1. ]"), GOOD_D),
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::NonFinite)),
        ),
        (
            "unterminated flow sequence",
            yaml_with(&GOOD_K.replace(" 1. ]", " 1."), GOOD_D),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "bad indentation",
            "camera_matrix: !!opencv-matrix\n  rows: 3\n    cols: 3\n".to_string(),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "not a mapping",
            "%YAML:1.0\n---\n- 1\n- 2\n".to_string(),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "matrix is a scalar",
            yaml_with("camera_matrix: 5", GOOD_D),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
    ];
    for (what, text, expected) in cases {
        match yaml(&text) {
            Ok(spec) => panic!("{what}: accepted as {spec:?}"),
            Err(e) => {
                assert!(expected(e.kind()), "{what}: wrong error kind: {e}");
                let msg = e.to_string();
                assert!(msg.starts_with("test.yml"), "{what}: {msg}");
                assert!(
                    !msg.contains('\n'),
                    "{what}: message is not one line: {msg}"
                );
            }
        }
    }
}

#[test]
fn errors_point_at_the_line() {
    let text = yaml_with(&GOOD_K.replace("0., 0., 1. ]", "0., zero, 1. ]"), GOOD_D);
    let e = yaml(&text).unwrap_err();
    // Lines: 1 %YAML, 2 ---, 3 width, 4 height, 5 camera_matrix, 6 rows, 7 cols, 8 dt, 9 data;
    // `zero` is on 10, the continuation line of `data`.
    assert_eq!(e.line(), Some(10), "{e}");
    assert!(e.to_string().starts_with("test.yml:10: "), "{e}");
}

#[test]
fn malformed_xml_is_an_error() {
    let good = std::fs::read_to_string(chessboard("left_intrinsics.xml")).unwrap();
    assert_eq!(xml(&good).unwrap(), bundled_camera());
    let cases: Vec<Case<String>> = vec![
        ("unclosed element", good.replace("</rows>", ""), |k| {
            matches!(k, ErrorKind::Syntax(_))
        }),
        (
            "wrong root",
            good.replace("opencv_storage", "storage"),
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "wrong cols",
            good.replacen("<cols>3</cols>", "<cols>4</cols>", 1),
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "non-numeric data",
            good.replacen("0. 0. 1.</data>", "0. x 1.</data>", 1),
            |k| matches!(k, ErrorKind::Syntax(m) if m.contains("data[7]")),
        ),
        (
            "zero focal length",
            good.replacen("<data>\n    535.91573396163199", "<data>\n    0.", 1),
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        (
            "missing distortion",
            {
                let start = good.find("<distortion_coefficients").unwrap();
                let end = good.find("</distortion_coefficients>").unwrap();
                format!(
                    "{}{}",
                    &good[..start],
                    &good[end + "</distortion_coefficients>".len()..]
                )
            },
            |k| matches!(k, ErrorKind::MissingKey(_)),
        ),
        ("trailing junk", format!("{good}<extra/>"), |k| {
            matches!(k, ErrorKind::Syntax(_))
        }),
    ];
    for (what, text, expected) in cases {
        match xml(&text) {
            Ok(spec) => panic!("{what}: accepted as {spec:?}"),
            Err(e) => assert!(expected(e.kind()), "{what}: wrong error kind: {e}"),
        }
    }
}

#[test]
fn malformed_json_and_toml_are_errors() {
    let json_cases: Vec<Case<&str>> = vec![
        (
            "missing fx",
            r#"{"fy": 500, "cx": 320, "cy": 240}"#,
            |k| matches!(k, ErrorKind::MissingKey(s) if s == "fx"),
        ),
        (
            "non-numeric",
            r#"{"fx": "500", "fy": 500, "cx": 320, "cy": 240}"#,
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "unknown key",
            r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "k1": 0.1}"#,
            |k| matches!(k, ErrorKind::Syntax(m) if m.contains("k1")),
        ),
        (
            "zero focal length",
            r#"{"fx": 0, "fy": 500, "cx": 320, "cy": 240}"#,
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        (
            "three coefficients",
            r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "distortion": [0.1, 0, 0]}"#,
            |k| matches!(k, ErrorKind::Shape(_)),
        ),
        (
            "width without height",
            r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640}"#,
            |k| matches!(k, ErrorKind::MissingKey(_)),
        ),
        ("truncated", r#"{"fx": 500, "fy": 500,"#, |k| {
            matches!(k, ErrorKind::Syntax(_))
        }),
    ];
    for (what, text, expected) in json_cases {
        match camera_from_json(text, "test.json") {
            Ok(spec) => panic!("{what}: accepted as {spec:?}"),
            Err(e) => {
                assert!(expected(e.kind()), "{what}: wrong error kind: {e}");
                assert!(!e.to_string().contains('\n'), "{what}: {e}");
            }
        }
    }
    let toml_cases: Vec<Case<&str>> = vec![
        (
            "missing cy",
            "fx = 500\nfy = 500\ncx = 320\n",
            |k| matches!(k, ErrorKind::MissingKey(s) if s == "cy"),
        ),
        (
            "non-numeric",
            "fx = 500\nfy = \"a\"\ncx = 320\ncy = 240\n",
            |k| matches!(k, ErrorKind::Syntax(_)),
        ),
        (
            "zero focal length",
            "fx = 500.0\nfy = 0.0\ncx = 320.0\ncy = 240.0\n",
            |k| matches!(k, ErrorKind::Camera(camgeom::Error::InvalidIntrinsics)),
        ),
        ("bad syntax", "fx = 500\nfy = = 500\n", |k| {
            matches!(k, ErrorKind::Syntax(_))
        }),
    ];
    for (what, text, expected) in toml_cases {
        match camera_from_toml(text, "test.toml") {
            Ok(spec) => panic!("{what}: accepted as {spec:?}"),
            Err(e) => {
                assert!(expected(e.kind()), "{what}: wrong error kind: {e}");
                assert!(!e.to_string().contains('\n'), "{what}: {e}");
            }
        }
    }
    // The minimal JSON file: integers are fine, the optional keys default.
    let s = camera_from_json(r#"{"fx": 500, "fy": 510, "cx": 320, "cy": 240}"#, "t.json").unwrap();
    assert!(s.camera.lens.is_pinhole());
    assert_eq!(s.image_size, None);
    assert_eq!(s.camera.intrinsics.fy(), 510.0);
}

#[test]
fn extension_and_io_errors() {
    let e = load_camera(chessboard("no-such-file.yml")).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Io(_)), "{e}");
    assert!(e.to_string().contains("no-such-file.yml"), "{e}");
    let p = scratch_file("camera.txt", "fx = 1\n");
    let e = load_camera(&p).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Unsupported(_)), "{e}");
    // The extension decides the parser: TOML text in a .json file is a JSON syntax error.
    let p = scratch_file("toml-in-json.json", "fx = 500\n");
    let e = load_camera(&p).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::Syntax(_)), "{e}");
}

/// No prefix of a real calibration file, and no single-byte corruption of it, may panic the
/// parsers: each either parses or returns an error.
#[test]
fn truncated_and_corrupted_files_never_panic() {
    for name in ["left_intrinsics.yml", "left_intrinsics.xml"] {
        let text = std::fs::read_to_string(chessboard(name)).unwrap();
        let parse = |t: &str| {
            let fs = if name.ends_with(".yml") {
                FileStorage::parse_yaml(t, name)
            } else {
                FileStorage::parse_xml(t, name)
            };
            // Also run the matrix readers on whatever parsed.
            fs.and_then(|fs| {
                let _ = fs.matrix("extrinsic_parameters");
                camera_from_storage(&fs)
            })
        };
        let mut accepted = 0;
        for cut in 0..text.len() {
            if parse(&text[..cut]).is_ok() {
                accepted += 1;
            }
        }
        // A prefix that still holds both matrices complete is a valid file; most prefixes are not.
        assert!(
            accepted < text.len() / 2,
            "{name}: {accepted} prefixes accepted"
        );
        let bytes = text.as_bytes();
        for i in 0..bytes.len() {
            for c in [b':', b'[', b'-', b'\n', b'<', b'"'] {
                let mut b = bytes.to_vec();
                b[i] = c;
                let t = String::from_utf8(b).unwrap();
                let _ = parse(&t);
            }
        }
    }
}

#[test]
fn xml_homography_and_plain_text_matrix() {
    // The layout of the Oxford graffiti homography as OpenCV ships it (H1to3p.xml).
    let h_xml = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<H13 type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n\t7.6285898e-01  -2.9922929e-01   2.2567123e+02\n\t3.3443473e-01   1.0143901e+00  -7.6999973e+01\n\t3.4663091e-04  -1.4364524e-05   1.0000000e+00 </data></H13>\n</opencv_storage>\n";
    let p = scratch_file("H1to3p.xml", h_xml);
    let h = FileStorage::open(&p)
        .unwrap()
        .matrix("H13")
        .unwrap()
        .to_matrix3()
        .unwrap();
    assert_eq!(h[(0, 2)], 2.2567123e+02);
    assert_eq!(h[(2, 1)], -1.4364524e-05);
    // The same numbers as the Oxford data set's plain-text file.
    let p = scratch_file(
        "H1to3p",
        "7.6285898e-01  -2.9922929e-01   2.2567123e+02\n3.3443473e-01   1.0143901e+00  -7.6999973e+01\n3.4663091e-04  -1.4364524e-05   1.0000000e+00\n",
    );
    let t = read_matrix_text(&p).unwrap().to_matrix3().unwrap();
    assert_eq!(t, h);
}

/// What `cv2.FileStorage` (OpenCV 5.0.0) writes for each kind of node, in YAML (now `%YAML 1.2`)
/// and XML: scalars, quoted strings, matrices (multi-channel too), nested mappings, block
/// sequences of scalars and of mappings, a flow mapping without spaces (`{ p:1, q:2. }`), `.Nan`
/// and `-.Inf`. Written by cv2.FileStorage with `startWriteStruct`, copied verbatim.
#[test]
fn reads_what_opencv_writes() {
    const YML: &str = r#"%YAML 1.2
---
i: 5
r: 2.5
s: "hello world: x # y"
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 8
   dt: d
   data: [ 0.10000000000000001, -0.20000000000000001, 0.001, 0.002,
       0.029999999999999999, 0., 0., 0. ]
mc: !!opencv-matrix
   rows: 2
   cols: 2
   dt: "3u"
   data: [ 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1 ]
nested:
   a: 1
   seq:
      - 0
      - 1
      - 2
   seqmaps:
      -
         x: 0
         name: n0
      -
         x: 1
         name: n1
   flowmap: { p:1, q:2. }
nan: .Nan
inf: -.Inf
"#;
    const XML: &str = r#"<?xml version="1.0"?>
<opencv_storage>
<i>5</i>
<r>2.5</r>
<s>"hello world: x # y"</s>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    500. 0. 320. 0. 500. 240. 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix">
  <rows>1</rows>
  <cols>8</cols>
  <dt>d</dt>
  <data>
    0.10000000000000001 -0.20000000000000001 0.001 0.002
    0.029999999999999999 0. 0. 0.</data></distortion_coefficients>
<mc type_id="opencv-matrix">
  <rows>2</rows>
  <cols>2</cols>
  <dt>"3u"</dt>
  <data>
    1 1 1 1 1 1 1 1 1 1 1 1</data></mc>
<nested>
  <a>1</a>
  <seq>
    0 1 2</seq>
  <seqmaps>
    <_>
      <x>0</x>
      <name>n0</name></_>
    <_>
      <x>1</x>
      <name>n1</name></_></seqmaps>
  <flowmap><p>1</p>
    <q>2.</q></flowmap></nested>
<nan>.Nan</nan>
<inf>-.Inf</inf>
</opencv_storage>
"#;
    for fs in [
        FileStorage::parse_yaml(YML, "cv.yml").unwrap(),
        FileStorage::parse_xml(XML, "cv.xml").unwrap(),
    ] {
        let name = fs.path().display().to_string();
        assert_eq!(fs.integer("i").unwrap(), Some(5), "{name}");
        assert_eq!(fs.number("r").unwrap(), Some(2.5), "{name}");
        assert_eq!(
            fs.get("s").unwrap().as_scalar(),
            Some("hello world: x # y"),
            "{name}"
        );
        let mc = fs.matrix("mc").unwrap();
        assert_eq!(
            (mc.rows, mc.cols, mc.channels, mc.dt),
            (2, 2, 3, 'u'),
            "{name}"
        );
        let nested = fs.get("nested").unwrap();
        assert_eq!(nested.get("a").unwrap().as_f64(), Some(1.0), "{name}");
        let Value::Seq(seq) = &nested.get("seq").unwrap().value else {
            panic!("{name}: seq")
        };
        let seq: Vec<f64> = seq.iter().map(|n| n.as_f64().unwrap()).collect();
        assert_eq!(seq, [0.0, 1.0, 2.0], "{name}");
        let Value::Seq(maps) = &nested.get("seqmaps").unwrap().value else {
            panic!("{name}: seqmaps")
        };
        assert_eq!(maps.len(), 2, "{name}");
        assert_eq!(
            maps[1].get("name").unwrap().as_scalar(),
            Some("n1"),
            "{name}"
        );
        assert_eq!(maps[1].get("x").unwrap().as_f64(), Some(1.0), "{name}");
        let flow = nested.get("flowmap").unwrap();
        assert_eq!(flow.get("p").unwrap().as_f64(), Some(1.0), "{name}");
        assert_eq!(flow.get("q").unwrap().as_f64(), Some(2.0), "{name}");
        assert!(fs.number("nan").unwrap().unwrap().is_nan(), "{name}");
        assert_eq!(fs.number("inf").unwrap(), Some(f64::NEG_INFINITY), "{name}");
        // An 8-coefficient file whose rational terms are zero reads as the 5-coefficient model.
        let spec = camera_from_storage(&fs).unwrap();
        assert_eq!(
            spec.camera.lens.coefficients(),
            [0.1, -0.2, 0.001, 0.002, 0.03],
            "{name}"
        );
        assert_eq!(spec.image_size, None, "{name}");
    }
}
