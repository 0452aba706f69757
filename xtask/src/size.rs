//! `cargo xtask size [--update]`: the main-job firmware's flash and static RAM against the
//! committed snapshot `firmware/size-snapshot.txt`.
//!
//! `cargo xtask run` (and so CI) compares too: a binary that grows by more than
//! [`MARGIN_PERCENT`] in flash or static RAM fails the run with a readable diff, so a size
//! regression is seen where it is made. After an intended change, `cargo xtask size --update`
//! rewrites the snapshot (commit it with the change).

use std::collections::BTreeMap;
use std::fs;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use crate::firmware::{build_bin_for, firmware_dir, size_of};
use crate::jobs::{BOARDS, FULL, HALF, snapshot_key};

/// Growth allowed before the comparison fails (compiler updates move sizes by a few tenths of
/// a percent; a real regression, such as a buffer doubling or a panic path pulling in
/// formatting, is larger).
pub const MARGIN_PERCENT: f64 = 3.0;

fn snapshot_path() -> PathBuf {
    firmware_dir().join("size-snapshot.txt")
}

/// `bin -> (flash, ram)` from the snapshot file (`bin flash=N ram=N` lines, `#` comments).
fn read_snapshot() -> Result<BTreeMap<String, (u64, u64)>> {
    let path = snapshot_path();
    let text = fs::read_to_string(&path)
        .with_context(|| format!("cannot read {} (cargo xtask size --update)", path.display()))?;
    let mut out = BTreeMap::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut it = line.split_whitespace();
        let (Some(bin), Some(f), Some(r)) = (it.next(), it.next(), it.next()) else {
            bail!("{}: bad line `{line}`", path.display());
        };
        let num = |kv: &str, key: &str| -> Result<u64> {
            kv.strip_prefix(key)
                .and_then(|v| v.parse().ok())
                .with_context(|| format!("{}: bad field `{kv}`", path.display()))
        };
        out.insert(bin.to_string(), (num(f, "flash=")?, num(r, "ram=")?));
    }
    Ok(out)
}

/// Compares `(bin, flash, ram)` with the snapshot; fails on growth beyond the margin.
pub fn compare(measured: &[(String, u64, u64)]) -> Result<()> {
    let snap = read_snapshot()?;
    let mut bad = Vec::new();
    println!("size vs firmware/size-snapshot.txt (fails above +{MARGIN_PERCENT} %):");
    for (bin, flash, ram) in measured {
        let (bin, flash, ram) = (bin.as_str(), *flash, *ram);
        let Some(&(f0, r0)) = snap.get(bin) else {
            bail!("{bin} is not in firmware/size-snapshot.txt: run cargo xtask size --update");
        };
        let pct = |now: u64, was: u64| 100.0 * (now as f64 - was as f64) / (was.max(1) as f64);
        let (df, dr) = (pct(flash, f0), pct(ram, r0));
        println!(
            "  {bin:<34} flash {f0} -> {flash} B ({df:+.2} %), static RAM {r0} -> {ram} B ({dr:+.2} %)"
        );
        if df > MARGIN_PERCENT || dr > MARGIN_PERCENT {
            bad.push(bin);
        }
    }
    if !bad.is_empty() {
        bail!(
            "firmware size regression in {}: check the diff above; if intended, run \
             `cargo xtask size --update` and commit firmware/size-snapshot.txt",
            bad.join(", ")
        );
    }
    Ok(())
}

/// Builds the main-job binaries for every board and returns `(snapshot key, flash, ram)` for
/// each.
fn measure() -> Result<Vec<(String, u64, u64)>> {
    let mut out = Vec::new();
    for board in BOARDS {
        for size in [FULL, HALF] {
            let elf = build_bin_for(board, size.bin, &[])?;
            let (flash, ram, line) = size_of(board, &elf)?;
            println!("{line}");
            out.push((snapshot_key(board, size.bin), flash, ram));
        }
    }
    Ok(out)
}

/// `cargo xtask size [--update]`.
pub fn size(update: bool) -> Result<()> {
    let measured = measure()?;
    if !update {
        return compare(&measured);
    }
    let mut text = String::from(
        "# Flash and static RAM (bytes) of the main-job firmware, release builds: `bin` for the\n\
         # Cortex-M7 (thumbv7em-none-eabihf), `bin@board` for the other emulated boards.\n\
         # Compared by `cargo xtask run` / CI, rewritten by `cargo xtask size --update`.\n",
    );
    for (bin, flash, ram) in &measured {
        text.push_str(&format!("{bin} flash={flash} ram={ram}\n"));
    }
    fs::write(snapshot_path(), text)?;
    println!("wrote {}", snapshot_path().display());
    Ok(())
}
