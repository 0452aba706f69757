//! The ChArUco view the bench firmware detects (`cargo xtask bench-fw`, `charuco_bench` in
//! `firmware/emulated/src/bin/bench.rs`), and what it must find there.
//!
//! The view is `host-tests/data/charuco/brown-320x240/02.png` (an OpenCV render reduced to
//! 320x240, see that folder's row in `host-tests/data/README.md`). The expectation comes from
//! outside camgeom: the ids OpenCV's `CharucoDetector` found in it (`opencv.csv`), the true
//! pixel of each (`truth.csv`, the rendered truth), and OpenCV's worst distance to them, the
//! bound on camgeom's corners.

use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, ensure};
use camgeom_host::images::load_gray;

use crate::util::root;

/// The view of the set the bench detects.
const VIEW: usize = 2;

/// Where the bench reads them (relative to the repository root, as in the firmware).
pub fn dir() -> PathBuf {
    root().join("target/camgeom-bench")
}

/// `view,id,x,y` rows of `path` for view [`VIEW`], id order.
fn rows(path: &Path) -> Result<Vec<(u32, f32, f32)>> {
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut out = Vec::new();
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let f: Vec<&str> = line.split(',').collect();
        ensure!(
            f.len() == 4,
            "{}: `{line}` is not view,id,x,y",
            path.display()
        );
        let bad = || format!("{}: `{line}`", path.display());
        let view: usize = f[0].trim().parse().with_context(bad)?;
        if view == VIEW {
            out.push((
                f[1].trim().parse().with_context(bad)?,
                f[2].trim().parse().with_context(bad)?,
                f[3].trim().parse().with_context(bad)?,
            ));
        }
    }
    out.sort_by_key(|r| r.0);
    Ok(out)
}

/// Writes `charuco-view.raw` (the 320x240 view, one byte a pixel) and `charuco-expect.bin`
/// (little-endian `u32` n, `f32` bound, then n times `u32` id, `f32` x, y) into [`dir`].
pub fn prepare() -> Result<()> {
    let set = camgeom_host::data_dir().join("charuco/brown-320x240");
    let img = load_gray(set.join(format!("{VIEW:02}.png")))?;
    ensure!(
        (img.width, img.height) == (320, 240),
        "the ChArUco bench view is not 320x240"
    );
    let found = rows(&set.join("opencv.csv"))?;
    let truth = rows(&set.join("truth.csv"))?;
    ensure!(
        !found.is_empty(),
        "OpenCV found no corner in the bench view"
    );
    let mut bound = 0.0f32;
    let mut body = Vec::new();
    for &(id, x, y) in &found {
        let &(_, tx, ty) = truth
            .iter()
            .find(|t| t.0 == id)
            .with_context(|| format!("corner {id} found by OpenCV has no truth"))?;
        bound = bound.max((x - tx).hypot(y - ty));
        body.extend_from_slice(&id.to_le_bytes());
        body.extend_from_slice(&tx.to_le_bytes());
        body.extend_from_slice(&ty.to_le_bytes());
    }
    let mut expect = Vec::new();
    expect.extend_from_slice(&(found.len() as u32).to_le_bytes());
    expect.extend_from_slice(&bound.to_le_bytes());
    expect.extend_from_slice(&body);
    let d = dir();
    fs::create_dir_all(&d)?;
    fs::write(d.join("charuco-view.raw"), &img.data)?;
    fs::write(d.join("charuco-expect.bin"), expect)?;
    Ok(())
}
