//! `cargo xtask setup`: what the other commands need, installed when missing. Idempotent, and
//! quick (a few queries, no installs) when everything is present.

use std::process::Command;

use anyhow::{Result, bail};

use crate::util::{output, run};

/// The targets the core must build for (CI builds it for each); the firmware uses the second.
pub const TARGETS: [&str; 4] = [
    "thumbv6m-none-eabi",
    "thumbv7em-none-eabihf",
    "thumbv8m.main-none-eabihf",
    "riscv32imac-unknown-none-elf",
];

/// The firmware's target.
pub const FIRMWARE_TARGET: &str = "thumbv7em-none-eabihf";

const COMPONENTS: [&str; 2] = ["rustfmt", "clippy"];

/// The emulator.
pub const QEMU: &str = "qemu-system-arm";

pub fn setup() -> Result<()> {
    rustup()?;
    qemu()?;
    cargo_fuzz()?;
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

fn qemu() -> Result<()> {
    if output(QEMU, ["--version"]).is_some() {
        return Ok(());
    }
    let root = output("id", ["-u"]).is_some_and(|u| u.trim() == "0");
    let apt = output("apt-get", ["--version"]).is_some();
    if !(root && apt) {
        bail!(
            "{QEMU} is missing: install it (Debian/Ubuntu: `sudo apt-get install -y {QEMU}`), \
             then run again"
        );
    }
    println!("setup: {QEMU} is missing, installing it with apt-get");
    run(Command::new("apt-get")
        .args(["update", "-q"])
        .env("DEBIAN_FRONTEND", "noninteractive"))?;
    run(Command::new("apt-get")
        .args(["install", "-y", "-q", "--no-install-recommends", QEMU])
        .env("DEBIAN_FRONTEND", "noninteractive"))?;
    if output(QEMU, ["--version"]).is_none() {
        bail!("{QEMU} still does not run after installing it");
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
