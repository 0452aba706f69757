//! `cargo xtask profile-fw [BIN [DIR]]`: where a firmware's instructions go on the emulated
//! Cortex-M7, function by function: the board's counterpart of callgrind on the host. `DIR`
//! is where QEMU starts (the firmware's semihosting files): the main job's
//! `target/camgeom-run/320x240` after a `cargo xtask run`, for `camgeom-fw-emulated`. Each
//! instruction's count goes to `target/profile-fw.txt`, to read beside `llvm-objdump -d`.
//!
//! QEMU logs each translated block's instructions once (`-d in_asm`) and each run of a block
//! (`-d exec`, with `nochain` so that chained blocks are logged too); the count of an
//! instruction is the number of runs of the blocks that hold it. Counts are instructions as
//! `-icount shift=0` counts them, so the total matches the bench's own figures (plus start-up).

use std::collections::HashMap;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};
use object::{Object, ObjectSymbol, SymbolKind};

use crate::firmware::build_bin;
use crate::jobs::M7;
use crate::util::{root, show};

/// Functions listed.
const TOP: usize = 30;

/// Builds `bin` of the emulated-board crate, runs it on the Cortex-M7 in `dir` (default the
/// repository root) with QEMU's block logs and prints the functions that ran the most
/// instructions.
pub fn profile(bin: &str, dir: Option<&str>) -> Result<()> {
    let elf = build_bin(bin, &[])?;
    if bin == crate::firmware::BENCH_BIN {
        // The bench reads its ChArUco view from the host.
        crate::charuco_bench::prepare()?;
    }
    let image = std::fs::read(&elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let mut cmd = Command::new(M7.qemu);
    cmd.args(M7.machine)
        .arg("-nographic")
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0"])
        .args(["-d", "in_asm,exec,nochain"])
        .arg("-kernel")
        .arg(&elf)
        .current_dir(dir.map_or_else(root, |d| root().join(d)))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    println!("$ {}", show(&cmd));
    let mut child = cmd
        .spawn()
        .context("cannot start QEMU (run `cargo xtask setup`)")?;
    let log = child.stderr.take().context("no stderr")?;

    // Block start -> its instructions' addresses; block start -> runs.
    let mut blocks: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut runs: HashMap<u32, u64> = HashMap::new();
    let mut current: Option<Vec<u32>> = None;
    for line in BufReader::with_capacity(1 << 20, log).lines() {
        let line = line.context("reading QEMU's log")?;
        if let Some(rest) = line.strip_prefix("Trace ") {
            // `Trace N: HOST [CS_BASE/PC/FLAGS/CFLAGS] SYMBOL`
            let pc = rest
                .split_once('[')
                .and_then(|(_, r)| r.split('/').nth(1))
                .and_then(|h| u32::from_str_radix(h, 16).ok());
            if let Some(pc) = pc {
                *runs.entry(pc).or_default() += 1;
            }
        } else if line.starts_with("IN:") {
            current = Some(Vec::new());
        } else if let Some(addr) = line.strip_prefix("0x") {
            let a = addr
                .split(':')
                .next()
                .and_then(|h| u32::from_str_radix(h, 16).ok());
            if let (Some(a), Some(block)) = (a, current.as_mut()) {
                block.push(a);
            }
        } else if line.trim().is_empty()
            && let Some(block) = current.take()
            && let Some(&start) = block.first()
        {
            blocks.entry(start).or_insert(block);
        }
    }
    let status = child.wait()?;
    if !status.success() {
        bail!("the firmware failed on QEMU ({status})");
    }

    // Functions by address, from the ELF's symbol table.
    let file = object::File::parse(&*image).context("cannot parse the ELF")?;
    let funcs = functions(&file);
    let mut per_fn: HashMap<usize, u64> = HashMap::new();
    let mut per_insn: HashMap<u32, u64> = HashMap::new();
    let (mut total, mut unknown) = (0u64, 0u64);
    for (pc, n) in &runs {
        let fallback = [*pc];
        let insns = blocks.get(pc).map_or(&fallback[..], |b| &b[..]);
        for &a in insns {
            total += n;
            *per_insn.entry(a).or_default() += n;
            match holding(&funcs, u64::from(a)) {
                Some(i) => *per_fn.entry(i).or_default() += n,
                None => unknown += n,
            }
        }
    }
    let mut rows: Vec<(u64, &str)> = per_fn
        .iter()
        .filter_map(|(&i, &n)| funcs.get(i).map(|f| (n, f.name.as_str())))
        .collect();
    rows.sort_by_key(|r| std::cmp::Reverse(r.0));
    println!(
        "{total} instructions on {} (Cortex-M7), by function:",
        M7.name
    );
    println!("| instructions | share | function |\n|---:|---:|---|");
    for (n, name) in rows.iter().take(TOP) {
        let share = 100.0 * *n as f64 / total.max(1) as f64;
        println!("| {n} | {share:.1} % | `{name}` |");
    }
    if unknown > 0 {
        println!("| {unknown} | | (outside every sized symbol) |");
    }
    // Each instruction's count, to read beside `llvm-objdump -d` of the ELF.
    let mut lines: Vec<(u32, u64)> = per_insn.into_iter().collect();
    lines.sort_unstable();
    let text: String = lines
        .iter()
        .map(|(a, n)| format!("{a:08x} {n}\n"))
        .collect();
    let out = root().join("target").join("profile-fw.txt");
    std::fs::write(&out, text).with_context(|| format!("cannot write {}", out.display()))?;
    println!(
        "instruction by instruction (address, count): {}",
        out.display()
    );
    Ok(())
}

/// A function of an ELF: its address (the Thumb bit cleared), size and demangled name.
pub struct Function {
    pub start: u64,
    pub size: u64,
    pub name: String,
}

/// The sized text symbols of `file`, by address.
pub fn functions(file: &object::File<'_>) -> Vec<Function> {
    let mut funcs: Vec<Function> = file
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text && s.size() > 0)
        .filter_map(|s| {
            Some(Function {
                start: s.address() & !1,
                size: s.size(),
                name: demangle(s.name().ok()?),
            })
        })
        .collect();
    funcs.sort_by_key(|f| f.start);
    funcs
}

/// The index in `funcs` ([`functions`]) of the function holding `addr`.
pub fn holding(funcs: &[Function], addr: u64) -> Option<usize> {
    let i = funcs.partition_point(|f| f.start <= addr).checked_sub(1)?;
    let f = funcs.get(i)?;
    (addr < f.start + f.size).then_some(i)
}

/// A legacy-mangled Rust symbol (`_ZN...E`) as a path without its hash; others as they are.
pub fn demangle(name: &str) -> String {
    let Some(mut rest) = name.strip_prefix("_ZN") else {
        return name.to_owned();
    };
    let mut parts = Vec::new();
    while let Some(len_end) = rest.find(|c: char| !c.is_ascii_digit()) {
        let Ok(len) = rest[..len_end].parse::<usize>() else {
            break;
        };
        let Some(part) = rest.get(len_end..len_end + len) else {
            break;
        };
        parts.push(part);
        rest = &rest[len_end + len..];
    }
    if parts
        .last()
        .is_some_and(|p| p.len() == 17 && p.starts_with('h'))
    {
        parts.pop();
    }
    let mut path = parts.join("::");
    for (from, to) in [
        ("$LT$", "<"),
        ("$GT$", ">"),
        ("$u20$", " "),
        ("$C$", ","),
        ("$RF$", "&"),
        ("$BP$", "*"),
        ("$u7b$", "{"),
        ("$u7d$", "}"),
        ("$u5b$", "["),
        ("$u5d$", "]"),
        ("$u3b$", ";"),
        ("..", "::"),
    ] {
        path = path.replace(from, to);
    }
    path.trim_start_matches('_').to_owned()
}

#[cfg(test)]
mod tests {
    use super::demangle;

    #[test]
    fn demangles_legacy_paths() {
        assert_eq!(
            demangle("_ZN7camgeom3klt6window11fetch_patch17h57c6ff6f5b7ec5a3E"),
            "camgeom::klt::window::fetch_patch"
        );
        assert_eq!(
            demangle(
                "_ZN77_$LT$camgeom..klt..packed..Packed$u20$as$u20$camgeom..klt..window..Window$GT$8mismatch17h29533a55fbf16d47E"
            ),
            "<camgeom::klt::packed::Packed as camgeom::klt::window::Window>::mismatch"
        );
        assert_eq!(demangle("memcpy"), "memcpy");
    }
}
