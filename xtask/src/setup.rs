//! `cargo xtask setup`: what the other commands need, installed when missing. Idempotent, and
//! quick (a few queries, no installs) when everything is present.

use std::process::Command;

use anyhow::{Result, bail};

use crate::util::{output, run};

/// The targets the core must build for (CI builds it for each) and the emulated boards run.
pub const TARGETS: [&str; 5] = [
    "thumbv6m-none-eabi",
    "thumbv7m-none-eabi",
    "thumbv7em-none-eabihf",
    "thumbv8m.main-none-eabihf",
    "riscv32imac-unknown-none-elf",
];

const COMPONENTS: [&str; 2] = ["rustfmt", "clippy"];

pub fn setup() -> Result<()> {
    rustup()?;
    apt_tools()?;
    cargo_fuzz()?;
    opencv()?;
    Ok(())
}

fn rustup() -> Result<()> {
    let Some(installed) = output("rustup", ["target", "list", "--installed"]) else {
        // Without rustup (a distribution's Rust) nothing can be added: say what is needed.
        println!(
            "setup: rustup not found; make sure the Rust standard libraries for {} are installed",
            TARGETS.join(", ")
        );
        return Ok(());
    };
    let have: Vec<&str> = installed.lines().map(str::trim).collect();
    let missing: Vec<&str> = TARGETS.into_iter().filter(|t| !have.contains(t)).collect();
    if !missing.is_empty() {
        run(Command::new("rustup")
            .args(["target", "add"])
            .args(&missing))?;
    }

    let installed = output("rustup", ["component", "list", "--installed"]).unwrap_or_default();
    // Listed with the host triple appended: `clippy-x86_64-unknown-linux-gnu`.
    let missing: Vec<&str> = COMPONENTS
        .into_iter()
        .filter(|c| {
            !installed
                .lines()
                .any(|l| l.trim() == *c || l.starts_with(&format!("{c}-")))
        })
        .collect();
    if !missing.is_empty() {
        run(Command::new("rustup")
            .args(["component", "add"])
            .args(&missing))?;
    }
    Ok(())
}

/// Every system tool the commands need, with the Debian package that has it and the flag that
/// makes it print its version: the emulators of the boards, ffmpeg/ffprobe, through which the
/// CLI reads and writes videos (a `--no-install-recommends` install of ffmpeg took 18 s on
/// Debian 12, 57 MB of packages), and dfu-util, which `flash-openmv` writes the OpenMV Cam H7
/// with (`-version` would be a list of its short options to dfu-util).
const APT_TOOLS: [(&str, &str, &str); 5] = [
    ("qemu-system-arm", "qemu-system-arm", "-version"),
    ("qemu-system-riscv32", "qemu-system-misc", "-version"),
    ("ffmpeg", "ffmpeg", "-version"),
    ("ffprobe", "ffmpeg", "-version"),
    ("dfu-util", "dfu-util", "--version"),
];

fn apt_tools() -> Result<()> {
    let missing: Vec<(&str, &str, &str)> = APT_TOOLS
        .into_iter()
        .filter(|(bin, _, version)| output(bin, [version]).is_none())
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let mut packages: Vec<&str> = missing.iter().map(|(_, p, _)| *p).collect();
    packages.dedup();
    let root = output("id", ["-u"]).is_some_and(|u| u.trim() == "0");
    let apt = output("apt-get", ["--version"]).is_some();
    if !(root && apt) {
        bail!(
            "{} missing: install (Debian/Ubuntu) `sudo apt-get install -y {}`, then run again",
            missing
                .iter()
                .map(|(b, _, _)| *b)
                .collect::<Vec<_>>()
                .join(", "),
            packages.join(" ")
        );
    }
    println!("setup: installing {} with apt-get", packages.join(" "));
    run(Command::new("apt-get")
        .args(["update", "-q"])
        .env("DEBIAN_FRONTEND", "noninteractive"))?;
    run(Command::new("apt-get")
        .args(["install", "-y", "-q", "--no-install-recommends"])
        .args(&packages)
        .env("DEBIAN_FRONTEND", "noninteractive"))?;
    for (bin, _, version) in &missing {
        if output(bin, [version]).is_none() {
            bail!("{bin} still does not run after installing it");
        }
    }
    Ok(())
}

/// cargo-fuzz (for `cargo xtask fuzz`), installed with `cargo install --locked` when missing
/// (about 1.5 min on 2 cores).
pub fn cargo_fuzz() -> Result<()> {
    if output("cargo", ["fuzz", "--version"]).is_some() {
        return Ok(());
    }
    println!("setup: cargo-fuzz is missing, installing it");
    run(Command::new("cargo").args(["install", "cargo-fuzz", "--locked"]))
}

/// OpenCV for Python, the peer the host tests compare with where a comparison cannot be
/// recorded once (e.g. `cv2.FileStorage` reading a file camgeom has just written), and
/// pymavlink, the autopilot side's MAVLink parser that reads the tag job's MAVLink stream
/// (`host-tests/scripts/check_mavlink.py`), installed with pip when missing (OpenCV at the
/// version `host-tests/scripts/peers.py` pins).
fn opencv() -> Result<()> {
    let has = |m: &str| {
        Command::new("python3")
            .args(["-c", &format!("import {m}")])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if output("python3", ["--version"]).is_none() {
        println!("setup: python3 not found; the host tests that compare with OpenCV will skip");
        return Ok(());
    }
    if has("cv2") && has("numpy") && has("pymavlink") {
        return Ok(());
    }
    println!("setup: installing opencv-python-headless, numpy and pymavlink with pip");
    if let Err(e) = run(Command::new("python3").args([
        "-m",
        "pip",
        "install",
        "--quiet",
        "opencv-python-headless==5.0.0.93",
        "numpy",
        "pymavlink==2.4.50",
    ])) {
        // Not fatal: those comparisons then say they skipped (peers.py tries again).
        println!("setup: pip could not install OpenCV ({e}); the OpenCV comparisons will skip");
    }
    Ok(())
}
