//! `cargo xtask ci`: every check, in order, stopping at the first failure.

use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow};

use crate::firmware::{firmware_cargo, firmware_dir};
use crate::setup::setup;
use crate::util::{cargo, in_ci, locked, output, root, run};

type Step = (String, Box<dyn FnOnce() -> Result<()>>);

fn root_cargo(args: &[&str]) -> Command {
    let mut cmd = cargo();
    cmd.current_dir(root()).args(args);
    cmd
}

fn steps() -> Vec<Step> {
    let mut steps: Vec<Step> = Vec::new();
    let mut add = |name: &str, f: Box<dyn FnOnce() -> Result<()>>| steps.push((name.into(), f));

    add("setup", Box::new(setup));
    add(
        "fmt (root)",
        Box::new(|| run(&mut root_cargo(&["fmt", "--all", "--check"]))),
    );
    add(
        "fmt (firmware)",
        Box::new(|| {
            // Not `--all`: that also takes path dependencies, i.e. the core, which the root
            // check already covers.
            let mut cmd = cargo();
            cmd.current_dir(firmware_dir()).args(["fmt", "--check"]);
            run(&mut cmd)
        }),
    );
    add(
        "fmt (fuzz targets)",
        Box::new(|| {
            // rustfmt on the files: `cargo fmt` there would resolve the fuzz workspace first.
            let dir = root().join("fuzz").join("fuzz_targets");
            let mut files: Vec<_> = std::fs::read_dir(&dir)?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "rs"))
                .collect();
            files.sort();
            let mut cmd = Command::new("rustfmt");
            cmd.args(["--check", "--edition", "2024"]).args(&files);
            run(&mut cmd)
        }),
    );
    add(
        "imports point down (core, board app, host crate, xtask)",
        Box::new(|| crate::imports::check(&root())),
    );
    add(
        "clippy (root)",
        Box::new(|| {
            let mut cmd = root_cargo(&["clippy", "--workspace", "--all-targets"]);
            run(locked(&mut cmd).args(["--", "-D", "warnings"]))
        }),
    );
    add(
        "clippy (firmware)",
        Box::new(|| {
            // The app's test target needs std: it is linted for the host in the next step and
            // its tests run in the root test step.
            let mut cmd = firmware_cargo("clippy");
            cmd.args([
                "--workspace",
                "--all-targets",
                "--exclude",
                "camgeom-fw-app",
            ]);
            run(locked(&mut cmd).args(["--", "-D", "warnings"]))
        }),
    );
    add(
        "firmware app: clippy (host; its tests run in the root test step, a path dependency there)",
        Box::new(|| {
            let host = host_triple()?;
            let target = ["--target", host.as_str()];
            let mut cmd = firmware_cargo("clippy");
            // With `mavlink`, which only the M7 build turns on: its module is linted here.
            cmd.args([
                "-p",
                "camgeom-fw-app",
                "--all-targets",
                "--features",
                "mavlink",
            ]);
            run(locked(cmd.args(target)).args(["--", "-D", "warnings"]))
        }),
    );
    add(
        "ov7725 driver: clippy + register-transaction tests (host)",
        Box::new(|| {
            // The driver's tests need std (embedded-hal-mock), so they run for the host, not
            // the firmware's default bare-metal target. About 20 s from cold.
            let host = host_triple()?;
            let target = ["--target", host.as_str()];
            let mut cmd = firmware_cargo("clippy");
            cmd.args([
                "-p",
                "ov7725",
                "--all-targets",
                "--features=host-tests,defmt",
            ]);
            run(locked(cmd.args(target)).args(["--", "-D", "warnings"]))?;
            let mut cmd = firmware_cargo("test");
            cmd.args(["-p", "ov7725", "--features=host-tests"])
                .args(target);
            run(locked(&mut cmd))
        }),
    );
    add(
        "test (root)",
        Box::new(|| run(locked(&mut root_cargo(&["test", "--workspace"])))),
    );
    add(
        "peer harness smoke run: each bench once, its answers and OpenCV's scored (no timing)",
        Box::new(|| {
            // The benches run in criterion's test mode in the test profile, whose dependencies
            // the previous step built; the script installs opencv-python-headless when missing.
            let mut cmd = Command::new("python3");
            cmd.current_dir(root())
                .args(["host-tests/scripts/peers.py", "--smoke"]);
            run(&mut cmd)
        }),
    );
    // The core's only target-specific code is `cfg!` constants that pick a SIMD or a scalar form
    // of a kernel, so one compilation per feature set and instruction set is what catches a
    // `std` leak or a missing `core` item. The firmware steps below give every one: the panic
    // check compiles it without `defmt` for thumbv7em and thumbv6m, the pipeline cross-compile
    // without it for thumbv6m, and the main job with it for every emulated board's target
    // (thumbv7em, thumbv7m, thumbv8m.main, riscv32imac), the OpenMV step for the H7. (A separate
    // riscv32imac build without `defmt` was dropped: it repeated these, 30 s of the budget.)
    add(
        "doc (public, then with the private items: their links are checked too)",
        Box::new(|| {
            let mut cmd = root_cargo(&["doc", "-p", "camgeom", "--no-deps"]);
            run(locked(&mut cmd).env("RUSTDOCFLAGS", "-D warnings"))?;
            let mut cmd = root_cargo(&[
                "doc",
                "-p",
                "camgeom",
                "--no-deps",
                "--document-private-items",
            ]);
            run(locked(&mut cmd).env("RUSTDOCFLAGS", "-D warnings"))
        }),
    );
    add(
        "examples: each runs (the test step built them: cargo test builds every example)",
        Box::new(|| {
            // `cargo run -p camgeom --example NAME` would resolve camgeom's features alone and
            // rebuild it and its dependencies; `cargo build --workspace --examples` resolves
            // them as a build, not a test, and rebuilt the host crate and a dozen dependencies
            // (44 s). The binaries `cargo test --workspace` left in the target directory are the
            // same programs: they are built here only when one is missing or older than the
            // sources (a step run alone).
            let dir = target_dir().join("debug").join("examples");
            if examples_stale(&dir, &EXAMPLES) {
                run(locked(&mut root_cargo(&[
                    "build",
                    "--workspace",
                    "--examples",
                ])))?;
            }
            let dir = target_dir().join("debug").join("examples");
            for example in EXAMPLES {
                let mut cmd = Command::new(dir.join(example));
                run(cmd.current_dir(root()))?;
            }
            Ok(())
        }),
    );
    add(
        "package: cargo package -p camgeom (the published crate builds on its own)",
        Box::new(|| run(locked(&mut root_cargo(&["package", "-p", "camgeom"])))),
    );
    // Measured on the shared 2-core machine (load average 5): panic check ~3.5 min (one release
    // LTO link of every area with f32 and f64 per target, thumbv7em ~110 s and thumbv6m ~90 s,
    // each building camgeom for its target); fuzz smoke: the build of every target (most of the step)
    // then 1 s for each after replaying its committed corpus; a fresh machine also spends ~95 s in `setup`
    // installing cargo-fuzz.
    add(
        "panic freedom (firmware link check)",
        Box::new(crate::panic_check::check_panic_free),
    );
    add(
        "fuzz smoke run",
        Box::new(|| crate::fuzz::fuzz(crate::fuzz::SMOKE_SECONDS, None)),
    );
    add(
        // About 4 min from cold measured at load average 7 on 2 cores (95 s of CPU): embassy-stm32
        // and its generated register access for the H743 dominate.
        "build OpenMV Cam H7 firmware (not run: no board in CI)",
        Box::new(crate::openmv::build_and_check),
    );
    add(
        "firmware pipeline cross-compile (thumbv6m: RP2040's Cortex-M0+, no emulated board)",
        Box::new(|| {
            // `camgeom-fw-app` instantiates the 320x240 pipeline (`qvga::step_qvga`), so this
            // compiles and optimises the whole per-frame path. The other cores run it in the
            // main job.
            let mut cmd = firmware_cargo("build");
            cmd.args([
                "--release",
                "-p",
                "camgeom-fw-app",
                "--target",
                "thumbv6m-none-eabi",
            ]);
            run(locked(&mut cmd))
        }),
    );
    add(
        "clippy (emulated board firmware for riscv32imac: its own runtime code)",
        Box::new(|| {
            let mut cmd = firmware_cargo("clippy");
            cmd.args([
                "-p",
                "camgeom-fw-emulated",
                "--lib",
                "--bin",
                "camgeom-fw-emulated",
                "--bin",
                "camgeom-fw-qqvga",
                "--target",
                "riscv32imac-unknown-none-elf",
            ]);
            run(locked(&mut cmd).args(["--", "-D", "warnings"]))
        }),
    );
    add(
        "main job: firmware on every emulated board over the box sequence, checked against the host replay",
        Box::new(|| crate::mainjob::run(&crate::mainjob::Options::full())),
    );
    steps
}

/// The core's examples the examples step runs.
const EXAMPLES: [&str; 6] = [
    "project_points",
    "homography",
    "planar_pose",
    "klt_two_frames",
    "track_box",
    "vanishing",
];

/// The newest modification time of the files under `dir` (recursively), if any.
fn newest(dir: &std::path::Path) -> Option<std::time::SystemTime> {
    let mut best = None;
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        let p = e.path();
        let t = if p.is_dir() {
            newest(&p)
        } else {
            e.metadata().and_then(|m| m.modified()).ok()
        };
        best = best.max(t);
    }
    best
}

/// Some example binary in `dir` is missing or older than a source it may be built from (the
/// core's `src/` and `examples/`, the manifests).
fn examples_stale(dir: &std::path::Path, names: &[&str]) -> bool {
    let r = root();
    let sources = [r.join("src"), r.join("examples")]
        .iter()
        .filter_map(|d| newest(d))
        .chain(
            ["Cargo.toml", "Cargo.lock"]
                .iter()
                .filter_map(|f| std::fs::metadata(r.join(f)).and_then(|m| m.modified()).ok()),
        )
        .max();
    names.iter().any(|n| {
        let built = std::fs::metadata(dir.join(n))
            .and_then(|m| m.modified())
            .ok();
        match (built, sources) {
            (Some(b), Some(s)) => b < s,
            _ => true,
        }
    })
}

/// The root workspace's target directory (`CARGO_TARGET_DIR`, relative to the root when
/// relative, else `target/`).
fn target_dir() -> std::path::PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) => root().join(dir),
        None => root().join("target"),
    }
}

/// The host's target triple (`rustc -vV`), for the firmware workspace's host-side tests.
fn host_triple() -> Result<String> {
    let info = output("rustc", ["-vV"]).ok_or_else(|| anyhow!("cannot run `rustc -vV`"))?;
    info.lines()
        .find_map(|l| l.strip_prefix("host: "))
        .map(|h| h.trim().to_string())
        .ok_or_else(|| anyhow!("`rustc -vV` names no host"))
}

fn secs(d: Duration) -> String {
    format!("{:.1} s", d.as_secs_f64())
}

/// Runs every step, or with `only` the steps whose name contains it.
pub fn ci(only: Option<&str>) -> Result<()> {
    let all: Vec<Step> = steps()
        .into_iter()
        .filter(|(name, _)| only.is_none_or(|o| name.contains(o)))
        .collect();
    let count = all.len();
    println!(
        "xtask ci: {count} steps{}",
        if in_ci() { " (CI: cargo --locked)" } else { "" }
    );
    let start = Instant::now();
    let mut done: Vec<(String, Duration)> = Vec::new();
    for (i, (name, step)) in all.into_iter().enumerate() {
        println!("\n==> [{}/{count}] {name}", i + 1);
        let t = Instant::now();
        let result = step();
        let took = t.elapsed();
        if let Err(e) = result {
            print_timings(&done);
            return Err(anyhow!(
                "step {}/{count} `{name}` failed after {}: {e:#}",
                i + 1,
                secs(took)
            ));
        }
        println!("<== {name}: ok ({})", secs(took));
        done.push((name, took));
    }
    print_timings(&done);
    println!(
        "xtask ci: all {count} steps passed in {}",
        secs(start.elapsed())
    );
    Ok(())
}

fn print_timings(done: &[(String, Duration)]) {
    if done.is_empty() {
        return;
    }
    println!("\nstep timings:");
    for (name, took) in done {
        println!("  {:>8}  {name}", secs(*took));
    }
}
