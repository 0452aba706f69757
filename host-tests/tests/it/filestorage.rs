//! OpenCV's own `FileStorage` files: `data/fixtures/filestorage/opencv.{yml,xml}`, written by
//! `cv2.FileStorage` (`scripts/make_filestorage_fixtures.py`, which also checked that OpenCV
//! reads them back), must read to the values the script recorded in `expected.json`; malformed
//! copies of them are one-line errors naming the file and the line.

use std::path::PathBuf;

use camgeom_host::storage::{Node, Value};
use camgeom_host::{ErrorKind, FileStorage};
use serde_json::Value as Json;

use crate::common::scratch_file;

fn fixture(name: &str) -> PathBuf {
    camgeom_host::data_dir()
        .join("fixtures")
        .join("filestorage")
        .join(name)
}

/// A recorded real: a JSON number, or `"nan"`, `"inf"`, `"-inf"`.
fn real(v: &Json) -> f64 {
    match v.as_str() {
        Some("nan") => f64::NAN,
        Some("inf") => f64::INFINITY,
        Some("-inf") => f64::NEG_INFINITY,
        _ => v.as_f64().expect("a number"),
    }
}

/// Bit-identical doubles (any NaN equals any NaN, as OpenCV writes every NaN as `.Nan`).
fn same(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a.to_bits() == b.to_bits()
}

/// `[key, node]` pairs of the record.
fn entries(v: &Json) -> &Vec<Json> {
    v.as_array().expect("a list of [key, node]")
}

/// Checks `node` against the script's record `want` (`{"int": ..}`, `{"matrix": ..}`, ...);
/// `at` names the node in failures.
fn check(fs: &FileStorage, node: &Node, want: &Json, at: &str) {
    let (kind, v) = want
        .as_object()
        .and_then(|o| o.iter().next())
        .expect("a one-key object");
    match kind.as_str() {
        "int" => {
            let n = v.as_i64().unwrap();
            assert_eq!(node.as_scalar().map(str::parse::<i64>), Some(Ok(n)), "{at}");
            assert_eq!(node.as_f64(), Some(n as f64), "{at}");
        }
        "real" => {
            let got = node
                .as_f64()
                .unwrap_or_else(|| panic!("{at}: not a number"));
            assert!(same(got, real(v)), "{at}: {got:?} != {v}");
        }
        "string" => {
            assert_eq!(node.as_scalar(), v.as_str(), "{at}");
            // A string, even one that looks like a number ("42"), is not read as a number.
            assert_eq!(node.as_f64(), None, "{at}");
        }
        "matrix" => {
            let m = fs
                .node_matrix(node, at)
                .unwrap_or_else(|e| panic!("{at}: {e}"));
            let dt = v["dt"].as_str().unwrap();
            assert_eq!(
                (m.rows, m.cols, m.channels),
                (
                    v["rows"].as_u64().unwrap() as usize,
                    v["cols"].as_u64().unwrap() as usize,
                    v["channels"].as_u64().unwrap() as usize
                ),
                "{at}"
            );
            assert_eq!(Some(m.dt), dt.chars().last(), "{at}");
            let want: Vec<f64> = v["data"].as_array().unwrap().iter().map(real).collect();
            assert_eq!(m.data.len(), want.len(), "{at}");
            for (i, (&g, &w)) in m.data.iter().zip(&want).enumerate() {
                if m.dt == 'f' {
                    // The record holds each float32 exactly; the file holds it as OpenCV's 9
                    // significant digits, which name that float32 uniquely. The reader keeps the
                    // text's nearest double: rounded to f32 it must be OpenCV's value, bit for bit.
                    assert_eq!(w as f32 as f64, w, "{at}[{i}]: the record is not a float32");
                    assert_eq!((g as f32).to_bits(), (w as f32).to_bits(), "{at}[{i}]");
                } else {
                    // Doubles are written with 17 significant digits (and integers exactly):
                    // the nearest double of that text is the value written.
                    assert!(same(g, w), "{at}[{i}]: {g:?} != {w:?}");
                }
            }
        }
        "map" => {
            let Value::Map(got) = &node.value else {
                panic!("{at}: not a mapping: {node:?}")
            };
            let want = entries(v);
            let keys: Vec<&str> = got.iter().map(|(k, _)| k.as_str()).collect();
            let want_keys: Vec<&str> = want.iter().map(|e| e[0].as_str().unwrap()).collect();
            assert_eq!(keys, want_keys, "{at}: keys in file order");
            for ((k, n), e) in got.iter().zip(want) {
                check(fs, n, &e[1], &format!("{at}.{k}"));
            }
        }
        "seq" => {
            let Value::Seq(items) = &node.value else {
                panic!("{at}: not a sequence: {node:?}")
            };
            let want = v.as_array().unwrap();
            assert_eq!(items.len(), want.len(), "{at}");
            for (i, (n, w)) in items.iter().zip(want).enumerate() {
                check(fs, n, w, &format!("{at}[{i}]"));
            }
        }
        other => panic!("{at}: unknown record kind {other}"),
    }
}

#[test]
fn opencv_files_read_back_to_the_recorded_values() {
    let record: Json =
        serde_json::from_str(&std::fs::read_to_string(fixture("expected.json")).unwrap()).unwrap();
    for name in ["opencv.yml", "opencv.xml"] {
        let fs = FileStorage::open(fixture(name)).unwrap_or_else(|e| panic!("{e}"));
        let want = serde_json::json!({ "map": record[name] });
        // Many kinds of node in each file (the script's docs list them).
        assert!(entries(&want["map"]).len() >= 20, "{name}");
        check(&fs, fs.root(), &want, name);
    }
}

/// The 1-based line of the first line of `text` that contains `needle`, after line `from`.
fn line_of(text: &str, needle: &str, from: usize) -> usize {
    text.lines()
        .enumerate()
        .skip(from)
        .find(|(_, l)| l.contains(needle))
        .map(|(i, _)| i + 1)
        .unwrap_or_else(|| panic!("`{needle}` not in the text"))
}

/// A malformed copy of a fixture: `text` written to a file named `name`, read, and (when
/// `matrix` is given) that matrix read. The error must be one line naming the file and `line`.
fn expect_error(name: &str, text: &str, matrix: Option<&str>, line: usize) -> camgeom_host::Error {
    let path = scratch_file(name, text);
    let result = FileStorage::open(&path).and_then(|fs| match matrix {
        Some(key) => fs.matrix(key).map(|_| ()),
        None => Ok(()),
    });
    let e = result.expect_err(name);
    let msg = e.to_string();
    assert_eq!(e.line(), Some(line), "{name}: {msg}");
    assert!(
        msg.starts_with(&format!("{}:{line}: ", path.display())),
        "{name}: {msg}"
    );
    assert!(!msg.contains('\n'), "{name}: not one line: {msg}");
    e
}

#[test]
fn malformed_files_name_the_file_and_the_line() {
    let yml = std::fs::read_to_string(fixture("opencv.yml")).unwrap();
    let xml = std::fs::read_to_string(fixture("opencv.xml")).unwrap();
    let k = line_of(&yml, "camera_matrix:", 0);
    let kx = line_of(&xml, "<camera_matrix", 0);

    // YAML, bad indentation: a field of the camera matrix indented deeper than its siblings.
    let bad = yml.replacen("   dt: d\n", "      dt: d\n", 1);
    let e = expect_error("indent.yml", &bad, None, line_of(&bad, "      dt: d", k));
    assert!(matches!(e.kind(), ErrorKind::Syntax(_)), "{e}");

    // YAML, an unclosed flow sequence: the parser stops where the text stops making sense
    // (the next key) and the message says where the `[` was opened.
    let open = line_of(&yml, "flow_sequence: [", 0);
    let bad = yml.replacen(
        "flow_sequence: [ 1, 2, 3.5 ]",
        "flow_sequence: [ 1, 2, 3.5",
        1,
    );
    let e = expect_error("unclosed.yml", &bad, None, open + 1);
    assert!(
        e.to_string()
            .contains(&format!("the `[` on line {open} is never closed")),
        "{e}"
    );

    // A matrix whose data does not hold rows * cols numbers: the line of its `data`.
    for (name, text, data) in [
        (
            "rows.yml",
            yml.replacen("   rows: 3\n", "   rows: 4\n", 1),
            line_of(&yml, "data:", k),
        ),
        (
            "rows.xml",
            xml.replacen("<rows>3</rows>", "<rows>4</rows>", 1),
            line_of(&xml, "<data>", kx),
        ),
    ] {
        let e = expect_error(name, &text, Some("camera_matrix"), data);
        assert!(matches!(e.kind(), ErrorKind::Shape(_)), "{e}");
        assert!(e.to_string().contains("declares 4x3"), "{e}");
    }

    // A non-number in the data: the line of that number, and its index.
    for (name, text) in [
        (
            "nan.yml",
            yml.replacen("318.25709999999998", "318.2571x", 1),
        ),
        (
            "nan.xml",
            xml.replacen("318.25709999999998", "318.2571x", 1),
        ),
    ] {
        let line = line_of(&text, "318.2571x", 0);
        let e = expect_error(name, &text, Some("camera_matrix"), line);
        assert!(
            e.to_string()
                .contains("`camera_matrix.data[2]` is not a number: `318.2571x`"),
            "{e}"
        );
    }

    // XML, an unclosed tag: found at the close tag of its parent, which names where it opened.
    let bad = xml.replacen("<rows>3</rows>", "<rows>3", 1);
    let close = line_of(&bad, "</camera_matrix>", kx);
    let e = expect_error("unclosed.xml", &bad, None, close);
    assert!(
        e.to_string().contains(&format!(
            "`<rows>` (line {}) is closed by `</camera_matrix>`",
            kx + 1
        )),
        "{e}"
    );

    // A key given twice.
    let bad = yml.replacen("offset: -7", "count: -7", 1);
    let e = expect_error("twice.yml", &bad, None, line_of(&bad, "count: -7", 0));
    assert!(e.to_string().contains("duplicate key `count`"), "{e}");
}
