//! What the criterion benches share: their input files and the answers they leave for the
//! peer harness.
//!
//! Every bench reads its inputs from CSV files under `data/fixtures/<bench>_bench/`, which
//! the OpenCV scripts (and the kornia peer crate) read too, so that every library sees the
//! very same numbers. A bench generates those files itself and checks, each run, that the
//! committed copies still match ([`sync_fixtures`]; `CAMGEOM_WRITE_FIXTURES=1` rewrites them).
//!
//! Each bench also records what camgeom answered on each input ([`Answers`]: a JSON object
//! per bench in `<target>/tmp/peers/`), so that `scripts/peers.py` can score camgeom's
//! accuracy with the same code that scores OpenCV's, on the same inputs the timings use.

use std::path::{Path, PathBuf};

use camgeom::Real;
use nalgebra::Point2;
use serde_json::{Map, Value};

use crate::points::{format_csv, read_csv};

/// The directory of a bench's input files, `data/fixtures/<name>/`.
pub fn fixture_dir(name: &str) -> PathBuf {
    crate::data_dir().join("fixtures").join(name)
}

/// The CSV text of point pairs: a header `x1,y1,x2,y2` and one row per pair, each number in
/// the shortest form that reads back to the same `f64`.
pub fn pairs_csv(rows: &[(Point2<f64>, Point2<f64>)]) -> String {
    let rows = rows
        .iter()
        .map(|(a, b)| [a.x, a.y, b.x, b.y].map(|v| format!("{v:?}")));
    format_csv(&["x1", "y1", "x2", "y2"], rows)
}

/// Writes `files` (`(name, text)`) into `dir` when `CAMGEOM_WRITE_FIXTURES=1`, otherwise
/// checks that every file on disk holds exactly that text.
///
/// # Panics
/// On a missing or stale file (the bench's generator and the committed inputs disagree), or
/// when a file cannot be written.
pub fn sync_fixtures(dir: &Path, files: &[(String, String)]) {
    let write = std::env::var("CAMGEOM_WRITE_FIXTURES").is_ok_and(|v| v == "1");
    for (name, text) in files {
        let path = dir.join(name);
        if write {
            std::fs::create_dir_all(dir).expect("create the fixture directory");
            std::fs::write(&path, text).expect("write a fixture");
        } else {
            let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
            assert!(
                on_disk == *text,
                "{} is missing or stale: rerun with CAMGEOM_WRITE_FIXTURES=1",
                path.display()
            );
        }
    }
}

/// The rows of a file of `columns`, as numbers.
///
/// # Panics
/// When the file cannot be read or parsed (a bench input must be there).
pub fn load_rows(path: &Path, columns: &[&str]) -> Vec<Vec<f64>> {
    match read_csv(path, columns) {
        Ok(t) => t.rows,
        Err(e) => panic!("bench input {}: {e}", path.display()),
    }
}

/// `(x1, x2)` of a file of pairs (`x1,y1,x2,y2`), in `T`.
///
/// # Panics
/// As [`load_rows`].
pub fn load_pairs<T: Real>(path: &Path) -> (Vec<Point2<T>>, Vec<Point2<T>>) {
    let p = |x: f64, y: f64| Point2::new(T::lit(x), T::lit(y));
    load_rows(path, &["x1", "y1", "x2", "y2"])
        .iter()
        .map(|r| (p(r[0], r[1]), p(r[2], r[3])))
        .unzip()
}

/// camgeom's answers of one bench, keyed by case (`"dlt_64/f32"`), saved as one JSON object.
#[derive(Debug)]
pub struct Answers {
    path: PathBuf,
    map: Map<String, Value>,
}

impl Answers {
    /// The answers of bench `name`, to be saved in `<target_tmp>/peers/<name>.json`; pass
    /// `env!("CARGO_TARGET_TMPDIR")` (set by cargo for benches).
    pub fn new(target_tmp: &str, name: &str) -> Self {
        Self {
            path: Path::new(target_tmp)
                .join("peers")
                .join(format!("{name}.json")),
            map: Map::new(),
        }
    }

    /// Records `value` under `case` (replacing an earlier one).
    pub fn record(&mut self, case: &str, value: Value) {
        self.map.insert(case.to_string(), value);
    }

    /// Writes the file.
    ///
    /// # Panics
    /// When it cannot be written.
    pub fn save(&self) {
        let dir = self.path.parent().expect("a directory");
        std::fs::create_dir_all(dir).expect("create the answers directory");
        let text = serde_json::to_string_pretty(&Value::Object(self.map.clone()))
            .expect("answers are JSON");
        std::fs::write(&self.path, text + "\n").expect("write the answers");
    }
}

/// The entries of a 3x3 matrix, row-major, as `f64`.
pub fn row_major<T: Real>(m: &nalgebra::Matrix3<T>) -> Vec<f64> {
    m.transpose().iter().map(|v| v.to_f64()).collect()
}

/// Points as `[[x, y], ..]` in `f64`.
pub fn points_json<T: Real>(p: &[Point2<T>]) -> Value {
    Value::from(
        p.iter()
            .map(|q| vec![q.x.to_f64(), q.y.to_f64()])
            .collect::<Vec<_>>(),
    )
}

/// FNV-1a (64-bit) over `values`, each taken whole (`h = (h ^ v) * 0x100000001b3`): the
/// checksums the instruction-count drivers print and the peer table compares.
pub fn fnv1a(values: impl IntoIterator<Item = u64>) -> u64 {
    values.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, v| {
        (h ^ v).wrapping_mul(0x0100_0000_01b3)
    })
}

/// One warp of the [`warp_case`] logo into `frame`; the destination pixels written.
pub fn warp_once<A: camgeom::arith::Arithmetic>(
    logo: &crate::images::GrayImage,
    frame: &mut crate::images::GrayImage,
    quad: &[Point2<f32>; 4],
    cfg: &camgeom::warp::WarpConfig,
) -> u32 {
    let (src, mut dst) = (logo.view().unwrap(), frame.view_mut().unwrap());
    camgeom::warp::warp_into_quad::<A>(&src, &mut dst, quad, cfg)
        .unwrap()
        .written
}

/// The warp case of the features bench, the peer table and `examples/warp_count.rs`: a
/// 128x128 checker logo (16-pixel cells of 230 and 30) and the quadrilateral of a 320x240
/// frame it goes to (`warp_checker` in `data/features/opencv_orb_figures.json`).
pub fn warp_case() -> (crate::images::GrayImage, [Point2<f32>; 4]) {
    let mut logo = crate::images::GrayImage::filled(128, 128, 0);
    for (i, p) in logo.data.iter_mut().enumerate() {
        *p = if ((i % 128) / 16 + (i / 128) / 16) % 2 == 0 {
            230
        } else {
            30
        };
    }
    let quad = [
        (60.3f32, 40.7f32),
        (250.2, 62.9),
        (231.6, 205.1),
        (41.8, 180.4),
    ]
    .map(|(x, y)| Point2::new(x, y));
    (logo, quad)
}
