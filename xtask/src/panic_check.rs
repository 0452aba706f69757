//! `cargo xtask panic-check`: links `firmware/panic-check` once per area of the core (a cargo
//! feature each: `camera`, `klt`, `twoview`, ...), scalar type (`f32`, `f64`) and target
//! ([`TARGETS`]). Its panic handler references a symbol that exists nowhere, so a binary links
//! only when no panic path of that selection survives optimisation.
//!
//! Every case not in [`KNOWN_PANICS`] must link (the command fails otherwise: a panic path came
//! back); the known ones are built too and reported, and the command says so when one of them
//! starts linking (remove it from [`KNOWN_PANICS`]). README "Panic freedom" holds the table
//! this prints.

use anyhow::{Result, bail};

use crate::firmware::firmware_cargo;
use crate::util::{locked, run};

const PACKAGE: &str = "camgeom-panic-check";

/// The targets every case is linked for: the reference Cortex-M7 (FPU, DSP instructions) and
/// the smallest Cortex-M (v6-M: no FPU, no division instruction, no unaligned access), whose
/// code after optimisation differs (soft-float calls, other inlining decisions).
pub const TARGETS: [&str; 2] = ["thumbv7em-none-eabihf", "thumbv6m-none-eabi"];

/// The scalar types: `f32` builds every entry point of an area (the integer and `f32`-only
/// ones with it); `f64` the generic ones again with `f64`.
pub const SCALARS: [&str; 2] = ["f32", "f64"];

/// One area of the core (a feature of `firmware/panic-check`): its feature, whether its
/// entry points are generic over the scalar type (so also linked with `f64`), and what it
/// calls (the first column of the table).
pub struct Area {
    pub feature: &'static str,
    pub generic: bool,
    pub entry_points: &'static str,
}

const fn area(feature: &'static str, generic: bool, entry_points: &'static str) -> Area {
    Area {
        feature,
        generic,
        entry_points,
    }
}

/// Every public no_std entry point of the core, by area (`firmware/panic-check/src/main.rs`
/// calls them).
pub const AREAS: [Area; 19] = [
    area(
        "camera",
        true,
        "`Camera::project`, `project_points`, `project_with_jacobian`, `project_with_parameter_jacobian`, `back_project`, `undistort_pixel`, `distort_pixel`, normalised (un)distortion; Brown-Conrady and fisheye",
    ),
    area(
        "fixed",
        true,
        "`FixedHomography::from_matrix`, `from_parts`, `transfer`; `FixedProjection::from_camera`, `project`; `Q16::from_float`",
    ),
    area(
        "pyramid",
        false,
        "`Pyramid::build`, `from_buffer`, `level`; `pyr_down`",
    ),
    area(
        "gradient",
        false,
        "`scharr_row`, `scharr_level`, `scharr_window`",
    ),
    area(
        "corners",
        false,
        "`good_features` (Shi-Tomasi, heapsort of the candidates)",
    ),
    area(
        "klt",
        false,
        "`calc_flow` and `forward_backward`, `Fixed` and `f32`, per-window and per-level gradients; `Tracker::replenish`, `update` (both arithmetics)",
    ),
    area(
        "homography",
        true,
        "`Homography::from_four_points`, `transfer`, `inverse`; `dlt`, `find_homography`, `refine`",
    ),
    area(
        "pose",
        true,
        "`solve_planar` (IPPE + LM), `ippe`, `p3p`, `epnp`, `solve_pnp`, `solve_pnp_ransac`, `refine_pose`",
    ),
    area(
        "target",
        false,
        "`PlanarTarget::step` twice (acquisition, tracking) with `GivenCorners` and with `apriltag::TagTarget`",
    ),
    area(
        "draw",
        true,
        "`draw_wireframe` (with `cube`), `draw_line`, `draw_line_i32`",
    ),
    area(
        "features",
        false,
        "`fast_detect`, `orb_detect`, `match_descriptors`",
    ),
    area(
        "warp",
        false,
        "`warp_into_quad`, `warp_perspective_into`, float and integer arithmetic",
    ),
    area(
        "twoview",
        true,
        "`eight_point`, `seven_point`, `five_point`, `find_fundamental`, `find_essential`, `refine_fundamental`, `refine_essential`, `recover_pose`, `triangulate_dlt`, `_midpoint`, `_optimal`",
    ),
    area("sfm", true, "`reconstruct_three_views`, `bundle_adjust`"),
    area(
        "calib",
        true,
        "`Calibrator::add_view`, `solve`, `solve_with_guess`; Brown-Conrady and fisheye",
    ),
    area(
        "chessboard",
        false,
        "`ChessboardDetector::detect` with each `Refinement`; `corner_subpix`, `saddle_subpix`",
    ),
    area(
        "apriltag",
        false,
        "`Detector::detect` (all four families), `find_target`, `Family::decode`, `tag_pose`",
    ),
    area(
        "remap",
        true,
        "`new_camera_matrix`, `build_map` + `remap`, `GridMap::build` + `GridMap::remap`; Brown-Conrady and fisheye",
    ),
    area("resize", false, "`resize_bilinear`"),
];

/// Cases with a panic path the linker still sees: `(area, scalar, target, reason)`; README
/// "Panic freedom" gives the same reason.
pub const KNOWN_PANICS: [(&str, &str, &str, &str); 0] = [];

/// The reason `area` does not link with `scalar` on `target`, if it is a known case.
fn known(area: &str, scalar: &str, target: &str) -> Option<&'static str> {
    KNOWN_PANICS
        .iter()
        .find(|k| (k.0, k.1, k.2) == (area, scalar, target))
        .map(|k| k.3)
}

/// Links the panic-check binary with `features` for `targets` (one cargo invocation, one LTO
/// link per target).
fn link(features: &str, targets: &[&str]) -> Result<()> {
    let mut cmd = firmware_cargo("build");
    cmd.args(["--release", "-p", PACKAGE, "--features", features]);
    for t in targets {
        cmd.args(["--target", t]);
    }
    run(locked(&mut cmd))
}

/// The CI step: for each target, one binary with every area and both scalar types. An area
/// with a known panic on that target in one scalar type only goes into a second binary with
/// the other. `cargo xtask panic-check` says which case failed.
pub fn check_panic_free() -> Result<()> {
    let mut links = 0;
    for target in TARGETS {
        // The scalar types each area links with on this target ([`SCALARS`] for an area
        // without `f64` entry points that links with `f32`: `f64` adds nothing to it).
        let mut sets: Vec<(Vec<&str>, Vec<&str>)> = Vec::new();
        for a in &AREAS {
            let scalars: Vec<&str> = if a.generic {
                SCALARS
                    .into_iter()
                    .filter(|s| known(a.feature, s, target).is_none())
                    .collect()
            } else if known(a.feature, "f32", target).is_none() {
                SCALARS.to_vec()
            } else {
                Vec::new()
            };
            if scalars.is_empty() {
                continue;
            }
            match sets.iter_mut().find(|(s, _)| *s == scalars) {
                Some((_, areas)) => areas.push(a.feature),
                None => sets.push((scalars, vec![a.feature])),
            }
        }
        for (scalars, areas) in sets {
            link(&[areas, scalars].concat().join(","), &[target])?;
            links += 1;
        }
    }
    println!(
        "panic-check: every area not in KNOWN_PANICS links without a panic path on {} ({links} links)",
        TARGETS.join(" and ")
    );
    Ok(())
}

/// Links every area with each scalar type on each target and prints the table (Markdown, as
/// README "Panic freedom" shows it).
pub fn check() -> Result<()> {
    let mut failed = Vec::new();
    let mut stale = Vec::new();
    let mut rows = Vec::new();
    for a in &AREAS {
        let mut cells = Vec::new();
        for scalar in SCALARS {
            for target in TARGETS {
                if !a.generic && scalar != "f32" {
                    cells.push("no `f64` API".to_string());
                    continue;
                }
                let ok = link(&format!("{},{scalar}", a.feature), &[target]).is_ok();
                let case = format!("{} {scalar} {target}", a.feature);
                cells.push(match (ok, known(a.feature, scalar, target)) {
                    (true, None) => "links".to_string(),
                    (false, None) => {
                        failed.push(case);
                        "**PANIC PATH**".to_string()
                    }
                    (true, Some(_)) => {
                        stale.push(case);
                        "links (remove from KNOWN_PANICS)".to_string()
                    }
                    (false, Some(reason)) => reason.to_string(),
                });
            }
        }
        rows.push(format!(
            "| `{}`: {} | {} |",
            a.feature,
            a.entry_points,
            cells.join(" | ")
        ));
    }
    println!("\npanic-check:\n");
    let mut header = String::from("| area: entry points |");
    let mut rule = String::from("|---|");
    for scalar in SCALARS {
        for target in TARGETS {
            let short = target.split('-').next().unwrap_or(target);
            header.push_str(&format!(" {scalar} {short} |"));
            rule.push_str("---|");
        }
    }
    println!("{header}\n{rule}");
    for row in rows {
        println!("{row}");
    }
    if !stale.is_empty() {
        println!(
            "\nnow panic-free, remove from KNOWN_PANICS in xtask/src/panic_check.rs: {}",
            stale.join(", ")
        );
    }
    if !failed.is_empty() {
        bail!("panic paths reachable from {}", failed.join(", "));
    }
    Ok(())
}
