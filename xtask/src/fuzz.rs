//! `cargo xtask fuzz [SECONDS] [TARGET]`: builds the cargo-fuzz targets of `fuzz/` and runs each
//! (or only `TARGET`) for `SECONDS` (the CI smoke run uses [`SMOKE_SECONDS`]). A crash fails
//! the command; libFuzzer writes the input to `fuzz/artifacts/<target>/` (turn it into a
//! regression test in `tests/it/fuzz_regressions.rs`).
//!
//! Corpora: each run starts from the committed, minimised corpus `fuzz/corpus/<target>/`
//! (read only) and writes what it finds to `fuzz/target/corpus/<target>/` (ignored by git,
//! kept between local runs), so a run never changes the committed files.
//! `cargo xtask fuzz-cmin [TARGET]` merges that run corpus into the committed one and
//! minimises it (`cargo fuzz cmin`): what to commit after a long run.
//!
//! cargo-fuzz needs a nightly compiler: the `nightly` rustup toolchain when installed,
//! otherwise the current (stable) one with `RUSTC_BOOTSTRAP=1`.

use std::path::PathBuf;
use std::process::Command;

use anyhow::{Result, bail};

use crate::util::{output, root, run};

/// Seconds per target of the CI smoke run: the committed corpus replays in well under a second
/// on every target, and the rest is a few thousand (the slowest target) to a few hundred
/// thousand new inputs. Longer runs are `cargo xtask fuzz SECONDS`.
pub const SMOKE_SECONDS: u64 = 1;

/// The targets, in `fuzz/Cargo.toml` order.
pub const TARGETS: [&str; 15] = [
    "image_pyramid_features",
    "homography",
    "pose",
    "twoview",
    "klt",
    "chessboard",
    "calibrate",
    "apriltag",
    "board",
    "charuco",
    "remap",
    "sfm",
    "vanishing",
    "link",
    "command",
];

/// Build flags: release with debug assertions (so integer overflow panics), no sanitizer (the
/// core forbids `unsafe`; a sanitizer would only slow the search down).
const BUILD: [&str; 4] = ["-O", "-a", "-s", "none"];

/// libFuzzer flags of the corpus minimisation: coverage by edges, hit counts ignored.
const EDGES_ONLY: [&str; 1] = ["-use_counters=0"];

fn fuzz_dir() -> PathBuf {
    root().join("fuzz")
}

/// `cargo [+nightly] fuzz <subcommand>` in `fuzz/`, through the rustup proxy so that the
/// toolchain can be chosen.
fn cargo_fuzz(subcommand: &str) -> Command {
    let nightly = output("rustup", ["toolchain", "list"])
        .is_some_and(|l| l.lines().any(|t| t.starts_with("nightly")));
    let mut cmd = Command::new("cargo");
    cmd.current_dir(fuzz_dir())
        // Set by the outer cargo/rustup; they would pin the toolchain or move the build.
        .env_remove("RUSTUP_TOOLCHAIN")
        .env_remove("RUSTC")
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET");
    if nightly {
        cmd.arg("+nightly");
    } else {
        println!("fuzz: no nightly toolchain, using the current one with RUSTC_BOOTSTRAP=1");
        cmd.env("RUSTC_BOOTSTRAP", "1");
    }
    cmd.args(["fuzz", subcommand]);
    cmd
}

/// The committed corpus of `target` (the runs' seeds).
fn corpus(target: &str) -> PathBuf {
    fuzz_dir().join("corpus").join(target)
}

/// Where runs of `target` write the inputs they find (under the ignored `fuzz/target`).
fn run_corpus(target: &str) -> PathBuf {
    fuzz_dir().join("target").join("corpus").join(target)
}

/// Every target, or only `only` (which must be one of [`TARGETS`]).
fn targets(only: Option<&str>) -> Result<Vec<&'static str>> {
    match only {
        None => Ok(TARGETS.to_vec()),
        Some(t) => match TARGETS.iter().find(|&&n| n == t) {
            Some(&n) => Ok(vec![n]),
            None => bail!("no fuzz target `{t}` (targets: {})", TARGETS.join(", ")),
        },
    }
}

/// The targets to run (all, or `only`), built, each with its committed corpus and its run
/// corpus (both created when missing).
fn prepare(only: Option<&str>) -> Result<Vec<(&'static str, PathBuf, PathBuf)>> {
    let targets = targets(only)?;
    crate::setup::cargo_fuzz()?;
    run(cargo_fuzz("build").args(BUILD))?;
    let mut out = Vec::new();
    for target in targets {
        let (seeds, runs) = (corpus(target), run_corpus(target));
        std::fs::create_dir_all(&seeds)?;
        std::fs::create_dir_all(&runs)?;
        out.push((target, seeds, runs));
    }
    Ok(out)
}

/// How many targets run at once: one per core of the 2-core CI machine (each libFuzzer run is
/// single-threaded).
const PARALLEL: usize = 2;

pub fn fuzz(seconds: u64, only: Option<&str>) -> Result<()> {
    let targets = prepare(only)?;
    for batch in targets.chunks(PARALLEL) {
        std::thread::scope(|s| {
            let runs: Vec<_> = batch
                .iter()
                .map(|(target, seeds, out)| {
                    s.spawn(move || {
                        // libFuzzer reads every corpus directory given and writes new inputs
                        // to the first.
                        run(cargo_fuzz("run")
                            .args(BUILD)
                            .arg(target)
                            .arg(out)
                            .arg(seeds)
                            .arg("--")
                            .arg(format!("-max_total_time={seconds}"))
                            .arg("-rss_limit_mb=1024"))
                    })
                })
                .collect();
            runs.into_iter().try_for_each(|r| {
                r.join()
                    .unwrap_or_else(|_| bail!("a fuzz run's thread panicked"))
            })
        })?;
    }
    Ok(())
}

/// Merges each run corpus into the committed one and minimises the result: a small set of
/// inputs with the same coverage (`cargo fuzz cmin`, libFuzzer's `-merge=1`).
///
/// Coverage here means edges, not libFuzzer's features (which also count each edge's hit-count
/// bucket): `-use_counters=0` keeps about a quarter of the inputs (`pose`: 316 instead of
/// 1,343) with every edge, so the committed corpus stays a few hundred KB.
pub fn cmin(only: Option<&str>) -> Result<()> {
    for (target, seeds, out) in prepare(only)? {
        // Into the committed corpus: the run's inputs that add coverage.
        run(cargo_fuzz("run")
            .args(BUILD)
            .arg(target)
            .arg(&seeds)
            .arg(&out)
            .arg("--")
            .arg("-merge=1")
            .args(EDGES_ONLY)
            .arg("-rss_limit_mb=1024"))?;
        run(cargo_fuzz("cmin")
            .args(BUILD)
            .arg(target)
            .arg(&seeds)
            .arg("--")
            .args(EDGES_ONLY))?;
    }
    Ok(())
}
