//! Puts this board's `memory.x` (next to this file) on the linker's search path, where
//! cortex-m-rt's `link.x` includes it.
//!
//! Each board crate writes its own `memory.x` into its own `OUT_DIR` and adds only that
//! directory to its own link: the emulated board's `memory.x` (the repository root's) and this
//! one never meet, even in one `cargo build` of the whole firmware workspace. (No dependency
//! may add a `memory.x` of its own: embassy-stm32's `memory-x` feature stays off.)

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let src = manifest.join("memory.x");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    let memory = fs::read(&src).unwrap_or_else(|e| panic!("cannot read {}: {e}", src.display()));
    fs::write(out.join("memory.x"), memory).expect("cannot write memory.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", src.display());
    println!("cargo:rerun-if-changed=build.rs");
}
