//! `cargo xtask fuzz [SECONDS]`: builds the cargo-fuzz targets of `fuzz/` and runs each for
//! `SECONDS` (the CI smoke run uses [`SMOKE_SECONDS`]). A crash fails the command; libFuzzer
//! writes the input to `fuzz/artifacts/<target>/` (turn it into a regression test in
//! `tests/it/fuzz_regressions.rs`).
//!
//! cargo-fuzz needs a nightly compiler: the `nightly` rustup toolchain when installed,
//! otherwise the current (stable) one with `RUSTC_BOOTSTRAP=1`.

use std::path::PathBuf;
use std::process::Command;

use anyhow::Result;

use crate::util::{output, root, run};

/// Seconds per target of the CI smoke run.
pub const SMOKE_SECONDS: u64 = 5;

/// The targets, in `fuzz/Cargo.toml` order.
pub const TARGETS: [&str; 5] = [
    "image_pyramid_features",
    "homography",
    "pose",
    "twoview",
    "klt",
];

/// Build flags: release with debug assertions (so integer overflow panics), no sanitizer (the
/// core forbids `unsafe`; a sanitizer would only slow the search down).
const BUILD: [&str; 4] = ["-O", "-a", "-s", "none"];

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

pub fn fuzz(seconds: u64) -> Result<()> {
    crate::setup::cargo_fuzz()?;
    run(cargo_fuzz("build").args(BUILD))?;
    for target in TARGETS {
        run(cargo_fuzz("run")
            .args(BUILD)
            .arg(target)
            .arg("--")
            .arg(format!("-max_total_time={seconds}"))
            .arg("-rss_limit_mb=1024"))?;
    }
    Ok(())
}
