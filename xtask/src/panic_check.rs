//! `cargo xtask panic-check`: links `firmware/panic-check` once per entry point (a cargo
//! feature each). Its panic handler references a symbol that exists nowhere, so a binary
//! links only when no panic path of that entry point survives optimisation.
//!
//! [`PANIC_FREE`] must link (the command fails otherwise: a panic path came back);
//! [`KNOWN_PANICS`] are built too and reported, and the command says so when one of them
//! starts linking (move it to [`PANIC_FREE`]). README "Panic freedom" says where their panics
//! are.

use anyhow::{Result, bail};

use crate::firmware::firmware_cargo;
use crate::util::{locked, run};

const PACKAGE: &str = "camgeom-panic-check";

/// Entry points proven panic-free: CI fails if one of them stops linking.
pub const PANIC_FREE: [&str; 8] = [
    "camera",
    "draw_wireframe",
    "solve_planar",
    "good_features",
    "pyramid",
    "calc_flow_fixed",
    "find_homography",
    "target_step",
];

/// Entry points with panic paths the linker still sees (see README "Panic freedom").
pub const KNOWN_PANICS: [&str; 0] = [];

fn link(feature: &str) -> Result<()> {
    let mut cmd = firmware_cargo("build");
    cmd.args(["--release", "-p", PACKAGE, "--features", feature]);
    run(locked(&mut cmd))
}

/// Links the [`PANIC_FREE`] entry points together, in one binary (the CI step: one LTO link
/// instead of one per entry point; `cargo xtask panic-check` says which one failed).
pub fn check_panic_free() -> Result<()> {
    link(&PANIC_FREE.join(","))?;
    println!(
        "panic-check: {} entry points link without a panic path",
        PANIC_FREE.len()
    );
    Ok(())
}

/// Links every entry point and prints the table.
pub fn check() -> Result<()> {
    let mut failed = Vec::new();
    let mut rows = Vec::new();
    for feature in PANIC_FREE {
        let ok = link(feature).is_ok();
        if !ok {
            failed.push(feature);
        }
        rows.push((feature, ok, true));
    }
    for feature in KNOWN_PANICS {
        rows.push((feature, link(feature).is_ok(), false));
    }
    println!("\npanic-check:");
    for (feature, ok, expected) in rows {
        let what = match (ok, expected) {
            (true, true) => "panic-free",
            (false, true) => "PANIC PATH (was panic-free)",
            (true, false) => "panic-free now: move it to PANIC_FREE in xtask/src/panic_check.rs",
            (false, false) => "panic path reachable (known, README \"Panic freedom\")",
        };
        println!("  {feature:<16} {what}");
    }
    if !failed.is_empty() {
        bail!("panic paths reachable from {}", failed.join(", "));
    }
    Ok(())
}
