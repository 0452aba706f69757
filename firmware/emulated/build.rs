//! Puts the memory map of the board the firmware is built for on the linker's search path as
//! `memory.x`, where the runtime's `link.x` includes it. The target picks the emulated board:
//!
//! | target | QEMU board | memory map |
//! |---|---|---|
//! | `thumbv7em-none-eabihf` | `mps2-an500` (Cortex-M7) | the repository root's `memory.x` (the one copy, shared with the docs) |
//! | `thumbv7m-none-eabi` | `mps2-an385` (Cortex-M3, no FPU) | `memory/mps2-an385.x` |
//! | `thumbv6m-none-eabi` | `mps2-an385` (Cortex-M0+ code on the Cortex-M3: the stack table only) | `memory/mps2-an385-stack.x` |
//! | `thumbv8m.main-none-eabihf` | `mps2-an505` (Cortex-M33) | `memory/mps2-an505.x` |
//! | `riscv32imac-unknown-none-elf` | `virt` (RV32IMAC, no FPU) | `memory/riscv-virt.x` |

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let target = env::var("TARGET").expect("set by cargo");
    let src = match target.as_str() {
        "thumbv7m-none-eabi" => manifest.join("memory/mps2-an385.x"),
        "thumbv6m-none-eabi" => manifest.join("memory/mps2-an385-stack.x"),
        "thumbv8m.main-none-eabihf" => manifest.join("memory/mps2-an505.x"),
        "riscv32imac-unknown-none-elf" => manifest.join("memory/riscv-virt.x"),
        _ => manifest.join("../../memory.x"),
    };
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    let memory = fs::read(&src).unwrap_or_else(|e| panic!("cannot read {}: {e}", src.display()));
    fs::write(out.join("memory.x"), memory).expect("cannot write memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", src.display());
    println!("cargo:rerun-if-changed=build.rs");
    // The M7 build sends MAVLink (Cargo.toml turns camgeom-fw-app's `mavlink` on for every
    // Cortex-M with atomics, so that a build of several targets resolves as each alone does).
    println!("cargo::rustc-check-cfg=cfg(mavlink)");
    if target == "thumbv7em-none-eabihf" {
        println!("cargo:rustc-cfg=mavlink");
    }
}
