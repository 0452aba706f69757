//! Puts the root `memory.x` on the linker's search path (as the emulated board does), and an
//! empty `defmt.x`: the firmware workspace's `.cargo/config.toml` links every binary with
//! `-Tdefmt.x`, and this binary must not contain defmt (its logger has panic paths of its own).

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let src = manifest.join("../../memory.x");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    let memory = fs::read(&src).unwrap_or_else(|e| panic!("cannot read {}: {e}", src.display()));
    fs::write(out.join("memory.x"), memory).expect("cannot write memory.x to OUT_DIR");
    fs::write(out.join("defmt.x"), "/* no defmt in the panic check */\n")
        .expect("cannot write defmt.x to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", src.display());
    println!("cargo:rerun-if-changed=build.rs");
}
