//! `cargo xtask panic-check`: links `firmware/panic-check` once per area of the core (a cargo
//! feature each: `camera`, `klt`, `twoview`, ...), scalar type (`f32`, `f64`) and target
//! ([`TARGETS`]). Its panic handler references a symbol that exists nowhere, so a binary links
//! only when no panic path of that selection survives optimisation.
//!
//! Every case not in [`KNOWN_PANICS`] must link (the command fails otherwise: a panic path came
//! back); the known ones are built too and reported, and the command says so when one of them
//! starts linking (remove it from [`KNOWN_PANICS`]). README "Panic freedom" holds the table
//! this prints.
//!
//! When a link fails in the CI step, [`locate`] links the same selection once more with the
//! missing symbol defined and names the functions that call the panic machinery.

use std::collections::BTreeSet;

use anyhow::{Context, Result, bail};
use object::{Object, ObjectSection};

use crate::firmware::{firmware_cargo, firmware_target_dir};
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
pub const AREAS: [Area; 22] = [
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
        "`Pyramid::build`, `from_buffer`, `level`; `PyramidPair`; `pyr_down`",
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
        "`calc_flow` (without and with `Borders::Copy`) and `forward_backward`, `Fixed` and `f32`, per-window, per-level and `Auto` gradients; `Tracker::replenish`, `update` (both arithmetics)",
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
        "`fast_detect`, `orb_detect`, `sift_detect`, `match_descriptors`, `match_descriptors_guided`, `match_float_descriptors`",
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
    area(
        "sfm",
        true,
        "`reconstruct_three_views`, `bundle_adjust`; `TrackBuilder`, `TrackSet::new_checked`, `reconstruct` (with `bundle_adjust_views`)",
    ),
    area(
        "calib",
        true,
        "`Calibrator::add_view`, `solve`, `solve_with_guess`; Brown-Conrady and fisheye",
    ),
    area(
        "chessboard",
        false,
        "`ChessboardDetector::detect` with each `Refinement`, `detect_any_scale`; `corner_subpix`, `saddle_subpix`",
    ),
    area(
        "apriltag",
        false,
        "`Detector::detect` (all four families; `u16` and `u32` labels), `find_target`, `refine_target`, `refine_detection`, `refine_partial`, `find_target_near`, `Family::decode`, `tag_pose`; AprilGrid: `AprilGrid::new`, `point`, `tag_points`, `detect_corners`, `grid_corners`, `refine_corners`, `TAG36H11_B2` decode; ArUco: `Detector::new`, `detect`, `refine_detection` with OpenCV's dictionaries, `Detection::aruco_corners`, `Detector::max_hamming_for`, every dictionary's `decode`, `families::by_name`; boards: `grid_tags` (const), `GridBoard::fill`, `GridBoard::tag`, `TagBoard::new`, `board_pose`",
    ),
    area(
        "remap",
        true,
        "`new_camera_matrix`, `build_map` + `remap` (Q10.5 and wide maps, grey and RGB), `GridMap::build` + `GridMap::remap`; Brown-Conrady and fisheye",
    ),
    area("resize", false, "`resize_bilinear`"),
    area(
        "link",
        false,
        "the board application's record stream: `camgeom_fw_app::link::encode_frame`, `Deframer::push`; a frame's pixels: `frame_chunk::send_frame`, `FrameChunk::decode`",
    ),
    area(
        "command",
        false,
        "commands to the board and its stored settings: `Command::decode`, `Settings::apply`, `Settings::decode`, `Settings::encode`, `Ack::decode`",
    ),
    area(
        "vanishing",
        true,
        "`VanishingConfig::check`, `find_vanishing_points`, `fit_vanishing_point`, `horizon` with and without K",
    ),
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
/// the other. Targets with the same selection link in one cargo call, so their builds and LTO
/// links share the machine's cores. `cargo xtask panic-check` says which case failed.
pub fn check_panic_free() -> Result<()> {
    // Each selection (features) and the targets it is linked for.
    let mut selections: Vec<(String, Vec<&str>)> = Vec::new();
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
            let features = [areas, scalars].concat().join(",");
            match selections.iter_mut().find(|(f, _)| *f == features) {
                Some((_, targets)) => targets.push(target),
                None => selections.push((features, vec![target])),
            }
        }
    }
    let mut links = 0;
    for (features, targets) in &selections {
        if let Err(e) = link(features, targets) {
            let found: Vec<String> = targets
                .iter()
                .map(|t| match locate(features, t) {
                    Ok(f) => format!("{t}: {f}"),
                    Err(l) => format!("{t}: (could not locate it: {l:#})"),
                })
                .collect();
            return Err(e.context(format!("a panic path: {}", found.join("; "))));
        }
        links += targets.len();
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

/// Links the panic-check binary with `features` for `target` with the handler's symbol
/// defined (so it links), in its own target directory, and names the functions with a call
/// (`BL`, or `B.W` as a tail call) to one of the panic entry points: `core::panicking::*`, the
/// `*_fail` slice and `unwrap`/`expect` helpers.
pub fn locate(features: &str, target: &str) -> Result<String> {
    let dir = firmware_target_dir().join("panic-locate");
    let var = format!(
        "CARGO_TARGET_{}_RUSTFLAGS",
        target.to_uppercase().replace(['-', '.'], "_")
    );
    // As `firmware_cargo`, but in a target directory of its own (other flags: the main
    // directory's builds stay as they are).
    let mut cmd = crate::util::cargo();
    cmd.current_dir(crate::firmware::firmware_dir())
        .args(["build", "--release", "-p", PACKAGE, "--features", features])
        .args(["--target", target])
        .arg("--target-dir")
        .arg(&dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .env(var, "-C link-arg=--defsym=camgeom_panic_is_reachable=0");
    run(locked(&mut cmd))?;
    let elf = dir.join(target).join("release").join(PACKAGE);
    let data = std::fs::read(&elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let file = object::File::parse(&*data)?;
    let funcs = crate::profile::functions(&file);
    let is_panic = |name: &str| {
        name.contains("panicking") || name.ends_with("_fail") || name.contains("unwrap_failed")
    };
    let targets: BTreeSet<u64> = funcs
        .iter()
        .filter(|f| is_panic(&f.name))
        .map(|f| f.start)
        .collect();
    let text = file.section_by_name(".text").context("no .text")?;
    let (base, code) = (text.address(), text.data()?);
    let half = |i: usize| {
        code.get(i..i + 2)
            .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
    };
    let mut callers = BTreeSet::new();
    for i in (0..code.len().saturating_sub(3)).step_by(2) {
        let (Some(h1), Some(h2)) = (half(i), half(i + 2)) else {
            continue;
        };
        // Thumb-2 BL (T1) and B.W (T4): 11110 S imm10, 1 J1 x J2 imm11.
        if h1 & 0xF800 != 0xF000 || h2 & 0xD000 != 0xD000 && h2 & 0xD000 != 0x9000 {
            continue;
        }
        let s = (h1 >> 10) & 1;
        let (j1, j2) = ((h2 >> 13) & 1, (h2 >> 11) & 1);
        let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
        let imm = (s << 24) | (i1 << 23) | (i2 << 22) | ((h1 & 0x3FF) << 12) | ((h2 & 0x7FF) << 1);
        let offset = ((imm << 7) as i32 >> 7) as i64;
        let pc = base + i as u64;
        let to = (pc as i64 + 4 + offset) as u64;
        if targets.contains(&to)
            && let Some(f) = crate::profile::holding(&funcs, pc).and_then(|k| funcs.get(k))
            && !is_panic(&f.name)
        {
            callers.insert(f.name.clone());
        }
    }
    if callers.is_empty() {
        return Ok("no direct caller found (read the ELF: ".to_string()
            + &elf.display().to_string()
            + ")");
    }
    Ok(format!(
        "called from {} (ELF: {})",
        callers.into_iter().collect::<Vec<_>>().join(", "),
        elf.display()
    ))
}
