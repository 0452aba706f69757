//! Puts the repository's `memory.x` on the linker's path (cortex-m-rt's `link.x` includes
//! it) and turns the two-view bench fixtures into `f32` arrays (`OUT_DIR/data.rs`).

use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let root = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo")).join("../..");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo"));
    fs::copy(root.join("memory.x"), out.join("memory.x")).expect("memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    let dir = root.join("host-tests/data/fixtures/twoview_bench");
    let mut code = String::new();
    for (name, file) in [
        ("FIVE", "five.csv"),
        ("RANSAC", "ransac_200.csv"),
        ("EIGHT", "eight_64.csv"),
    ] {
        let text = fs::read_to_string(dir.join(file)).expect("fixture");
        let rows: Vec<&str> = text
            .lines()
            .skip(1)
            .filter(|l| !l.trim().is_empty())
            .collect();
        code.push_str(&format!(
            "pub const {name}: [[f32; 4]; {}] = [\n",
            rows.len()
        ));
        for r in rows {
            let v: Vec<String> = r.split(',').map(|x| format!("{}_f32", x.trim())).collect();
            code.push_str(&format!("    [{}],\n", v.join(", ")));
        }
        code.push_str("];\n");
        println!("cargo:rerun-if-changed={}", dir.join(file).display());
    }
    fs::write(out.join("data.rs"), code).expect("data.rs");
    println!("cargo:rerun-if-changed=build.rs");
}
