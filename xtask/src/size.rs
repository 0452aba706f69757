//! `cargo xtask size [--update]`: the main-job firmware's flash and static RAM against the
//! committed snapshot `firmware/size-snapshot.txt`.
//!
//! `cargo xtask run` (and so CI) compares too: a binary that grows by more than
//! [`MARGIN_PERCENT`] in flash or static RAM fails the run with a readable diff, so a size
//! regression is seen where it is made. After an intended change, `cargo xtask size --update`
//! rewrites the snapshot (commit it with the change).
//!
//! A line may also carry `stack=N`: a bound, set by hand, on the stack high-water mark the
//! board reports for that main job. `cargo xtask run` fails when a board's job goes above it
//! (`size --update` keeps the bounds as they are).

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

/// One line of the snapshot.
#[derive(Debug, Clone, Copy)]
struct Entry {
    flash: u64,
    ram: u64,
    /// The committed bound on the stack high-water mark, if any.
    stack: Option<u64>,
}

/// `bin -> entry` from the snapshot file (`bin flash=N ram=N [stack=N]` lines, `#` comments).
fn read_snapshot() -> Result<BTreeMap<String, Entry>> {
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
        let stack = it.next().map(|kv| num(kv, "stack=")).transpose()?;
        if let Some(extra) = it.next() {
            bail!("{}: unexpected field `{extra}`", path.display());
        }
        out.insert(
            bin.to_string(),
            Entry {
                flash: num(f, "flash=")?,
                ram: num(r, "ram=")?,
                stack,
            },
        );
    }
    Ok(out)
}

/// What a job measured of one binary: flash, static RAM and, when it ran, the stack
/// high-water mark.
pub struct Measured {
    pub bin: String,
    pub flash: u64,
    pub ram: u64,
    pub stack: Option<u64>,
}

/// Compares what was measured with the snapshot; fails on growth beyond the margin, or on a
/// stack above its committed bound.
pub fn compare(measured: &[Measured]) -> Result<()> {
    let snap = read_snapshot()?;
    let mut bad = Vec::new();
    println!(
        "size vs firmware/size-snapshot.txt (fails above +{MARGIN_PERCENT} %, or a stack above its bound):"
    );
    for m in measured {
        let (bin, flash, ram) = (m.bin.as_str(), m.flash, m.ram);
        let Some(&Entry {
            flash: f0,
            ram: r0,
            stack: bound,
        }) = snap.get(bin)
        else {
            bail!("{bin} is not in firmware/size-snapshot.txt: run cargo xtask size --update");
        };
        if let (Some(used), Some(bound)) = (m.stack, bound) {
            println!("  {bin:<34} stack {used} B of the committed bound {bound} B");
            if used > bound {
                bad.push(bin);
            }
        }
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

/// Builds the main-job binaries for every board and returns their sizes (not run: no stack).
fn measure() -> Result<Vec<Measured>> {
    let mut out = Vec::new();
    for board in BOARDS {
        for size in [FULL, HALF] {
            let elf = build_bin_for(board, size.bin, &[])?;
            let (flash, ram, line) = size_of(board, &elf)?;
            println!("{line}");
            out.push(Measured {
                bin: snapshot_key(board, size.bin),
                flash,
                ram,
                stack: None,
            });
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
    // The stack bounds are set by hand: keep them.
    let bounds = read_snapshot().unwrap_or_default();
    let mut text = String::from(
        "# Flash and static RAM (bytes) of the main-job firmware, release builds: `bin` for the\n\
         # Cortex-M7 (thumbv7em-none-eabihf), `bin@board` for the other emulated boards.\n\
         # Compared by `cargo xtask run` / CI, rewritten by `cargo xtask size --update`.\n\
         # `stack=N` (optional, kept by --update): the bound on the job's stack high-water mark\n\
         # as the board reports it; set by hand.\n",
    );
    for m in &measured {
        let (bin, flash, ram) = (&m.bin, m.flash, m.ram);
        match bounds.get(bin).and_then(|e| e.stack) {
            Some(stack) => text.push_str(&format!("{bin} flash={flash} ram={ram} stack={stack}\n")),
            None => text.push_str(&format!("{bin} flash={flash} ram={ram}\n")),
        }
    }
    fs::write(snapshot_path(), text)?;
    println!("wrote {}", snapshot_path().display());
    Ok(())
}
