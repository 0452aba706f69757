//! Building the firmware, running it on QEMU, decoding its defmt log, checking it. The main
//! job (`cargo xtask run`) is in `mainjob.rs`.
//!
//! The firmware writes defmt frames to semihosting stdout, which QEMU (`target=native`) writes
//! to its own stdout. The firmware never touches the UART that `-nographic` also connects to
//! stdout, and QEMU's own diagnostics go to stderr, so stdout holds only defmt frames.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use std::{fs, thread};

use anyhow::{Context, Result, bail};
use defmt_decoder::{DecodeError, Table};
use object::{Object, ObjectSection, SectionFlags, elf};

use crate::jobs::{Board, M7};
use crate::util::{cargo, locked, root, run};

pub const PACKAGE: &str = "camgeom-fw-emulated";
/// The projection checks (run by `cargo xtask run` before the main job).
pub const PROJECTION_BIN: &str = "camgeom-fw-projection";
/// The homography benchmark binary (`cargo xtask bench-fw`).
pub const BENCH_BIN: &str = "camgeom-fw-bench";
/// The line the firmware logs when it has done all its work; the run fails without it.
const SUMMARY: &str = "projected ";
const SUMMARY_REST: &str = " points, cost ";
/// The bench binary's summary line.
const BENCH_SUMMARY: &str = "homography bench: ";
const BENCH_SUMMARY_REST: &str = " instructions";

pub fn firmware_dir() -> PathBuf {
    root().join("firmware")
}

/// The firmware's own target directory (whatever `CARGO_TARGET_DIR` the caller has, so the
/// ELF is always found at the same place and the root workspace's build lock is not shared).
pub fn firmware_target_dir() -> PathBuf {
    firmware_dir().join("target")
}

/// A cargo command run inside `firmware/` (where its `.cargo/config.toml` sets the target and
/// the linker scripts).
pub fn firmware_cargo(subcommand: &str) -> Command {
    let mut cmd = cargo();
    cmd.current_dir(firmware_dir())
        .arg(subcommand)
        .arg("--target-dir")
        .arg(firmware_target_dir())
        // RUSTFLAGS in the environment would replace the config's linker arguments.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET");
    cmd
}

/// Builds binary `bin` of the firmware package (release) for the reference board with extra
/// cargo arguments; returns its ELF.
pub fn build_bin(bin: &str, extra: &[&str]) -> Result<PathBuf> {
    build_bin_for(M7, bin, extra)
}

/// [`build_bin`] for `board`.
pub fn build_bin_for(board: Board, bin: &str, extra: &[&str]) -> Result<PathBuf> {
    let mut cmd = firmware_cargo("build");
    cmd.args([
        "--release",
        "-p",
        PACKAGE,
        "--bin",
        bin,
        "--target",
        board.target,
    ])
    .args(extra);
    run(locked(&mut cmd))?;
    let elf = firmware_target_dir()
        .join(board.target)
        .join("release")
        .join(bin);
    if !elf.is_file() {
        bail!("the build did not produce {}", elf.display());
    }
    Ok(elf)
}

/// Builds binaries `bins` of the firmware package (release) for `board` in one cargo call, so
/// their release links (each an LTO of the whole app, single-threaded) run side by side on the
/// machine's cores instead of one after another; a later [`build_bin_for`] of one of them is a
/// no-op.
pub fn build_bins_for(board: Board, bins: &[&str]) -> Result<()> {
    build_bins_for_all(&[board], bins)
}

/// [`build_bins_for`] for several boards in one cargo call: the core and its dependencies are
/// compiled for every target side by side (one target's compile is mostly one core's work).
pub fn build_bins_for_all(boards: &[Board], bins: &[&str]) -> Result<()> {
    let mut cmd = firmware_cargo("build");
    cmd.args(["--release", "-p", PACKAGE]);
    let mut targets: Vec<&str> = boards.iter().map(|b| b.target).collect();
    targets.sort_unstable();
    targets.dedup();
    for t in targets {
        cmd.args(["--target", t]);
    }
    for bin in bins {
        cmd.args(["--bin", bin]);
    }
    run(locked(&mut cmd))
}

/// Builds and runs the projection checks; returns their summary line.
pub fn build_and_run_projection() -> Result<String> {
    let elf = build_bin(PROJECTION_BIN, &[])?;
    size_report(&elf)?;
    run_on_qemu_checked(&elf, SUMMARY, SUMMARY_REST)
}

/// `cargo xtask bench-fw`: builds the homography bench binary with the `size-baseline`
/// feature (no solver calls) and without it, reports the flash the homography code adds, then
/// runs the full one on QEMU and prints its decoded cost table.
pub fn bench() -> Result<()> {
    let baseline = build_bin(BENCH_BIN, &["--features", "size-baseline"])?;
    let (base_flash, _) = size_report(&baseline)?;
    // The same path: copy the baseline away before the second build replaces it.
    let kept = baseline.with_file_name(format!("{BENCH_BIN}-size-baseline"));
    fs::copy(&baseline, &kept)?;
    let elf = build_bin(BENCH_BIN, &[])?;
    let (flash, _) = size_report(&elf)?;
    println!(
        "homography code: {} B of flash ({flash} B with the solver calls, {base_flash} B without; \
         the baseline ELF is {})",
        flash as i64 - base_flash as i64,
        kept.display()
    );
    crate::charuco_bench::prepare()?;
    crate::tag_bench::prepare()?;
    let summary = run_on_qemu_checked(&elf, BENCH_SUMMARY, BENCH_SUMMARY_REST)?;
    println!("bench-fw: {summary}");
    bench_twoview()
}

fn timeout() -> Duration {
    let secs = std::env::var("XTASK_QEMU_TIMEOUT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(120);
    Duration::from_secs(secs)
}

/// Runs `elf` on QEMU and checks its log; its summary line starts with `summary` and contains
/// `summary_rest`.
pub fn run_on_qemu_checked(elf: &Path, summary_start: &str, summary_rest: &str) -> Result<String> {
    run_on_qemu_in(M7, elf, None, summary_start, summary_rest, Some(&|_| true)).map(|(s, _)| s)
}

/// [`run_on_qemu_checked`] on `board` with QEMU started in `dir` (where the firmware's
/// semihosting file calls land), printing the command and the log lines `show` accepts (and
/// every warning and error); with `show` `None` only warnings, errors and, on failure, the
/// command. Returns the summary line and every decoded message.
pub fn run_on_qemu_in(
    board: Board,
    elf: &Path,
    dir: Option<&Path>,
    summary_start: &str,
    summary_rest: &str,
    show: Option<&dyn Fn(&str) -> bool>,
) -> Result<(String, Vec<String>)> {
    run_on_qemu_with(board, elf, dir, None, summary_start, summary_rest, show)
}

/// [`run_on_qemu_in`] with UART0 (the record stream) connected to the TCP server at `uart0`
/// (QEMU's `-serial tcp:HOST:PORT`, a client: the server listens before QEMU starts) instead
/// of `serial.bin` in `dir`.
pub fn run_on_qemu_with(
    board: Board,
    elf: &Path,
    dir: Option<&Path>,
    uart0: Option<std::net::SocketAddr>,
    summary_start: &str,
    summary_rest: &str,
    show: Option<&dyn Fn(&str) -> bool>,
) -> Result<(String, Vec<String>)> {
    let verbose = show.is_some();
    let show = show.unwrap_or(&|_| false);
    let image = fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let table = Table::parse(&image)
        .context("cannot read the defmt table")?
        .context("the ELF has no .defmt section")?;
    // Locations need the debug info; without it the log still decodes.
    let locations = table.get_locations(&image).unwrap_or_default();

    let qemu = board.qemu;
    let mut cmd = Command::new(qemu);
    cmd.args(board.machine)
        .arg("-nographic")
        .args(["-semihosting-config", "enable=on,target=native"])
        // One virtual nanosecond per instruction: SysTick then counts instructions (see
        // firmware/README.md), and runs are deterministic.
        .args(["-icount", "shift=0"])
        // UART0 (the record stream of the jobs that stream, `firmware/emulated/src/uart.rs`)
        // to `serial.bin` in the run's directory, or to a TCP server, and UART1 (MAVLink) to
        // `mavlink.bin`; the monitor nowhere, so that stdout carries only the defmt log.
        .args(["-monitor", "none"])
        .args(match (uart0, dir) {
            (Some(addr), Some(_)) => [
                "-serial".to_string(),
                format!("tcp:{addr}"),
                "-serial".to_string(),
                "file:mavlink.bin".to_string(),
            ],
            (Some(addr), None) => [
                "-serial".to_string(),
                format!("tcp:{addr}"),
                "-serial".to_string(),
                "null".to_string(),
            ],
            (None, Some(_)) => {
                ["-serial", "file:serial.bin", "-serial", "file:mavlink.bin"].map(String::from)
            }
            (None, None) => ["-serial", "null", "-serial", "null"].map(String::from),
        })
        .arg("-kernel")
        .arg(elf)
        .current_dir(dir.unwrap_or(&root()))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let shown = crate::util::show(&cmd);
    if verbose {
        println!("$ {shown}");
    }
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start {qemu} (run `cargo xtask setup`)"))?;
    let mut stdout = child.stdout.take().context("no stdout")?;
    let mut stderr = child.stderr.take().context("no stderr")?;
    let out_reader = thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stdout.read_to_end(&mut v);
        v
    });
    let err_reader = thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stderr.read_to_end(&mut v);
        v
    });

    let limit = timeout();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break Some(status);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        thread::sleep(Duration::from_millis(20));
    };
    let bytes = out_reader.join().unwrap_or_default();
    let errors = err_reader.join().unwrap_or_default();

    // Decode whatever arrived, also when the run failed: the log says why.
    let mut decoder = table.new_stream_decoder();
    decoder.received(&bytes);
    let mut summary = None;
    let mut messages = Vec::new();
    let (mut lines, mut malformed, mut error_logs) = (0usize, 0usize, 0usize);
    if verbose {
        println!("---- firmware log (defmt) ----");
    }
    loop {
        match decoder.decode() {
            Ok(frame) => {
                lines += 1;
                let level = frame.level().map_or("", |l| l.as_str());
                let message = frame.display_message().to_string();
                let location = locations.get(&frame.index()).map(|l| {
                    let file = l.file.file_name().map(|f| f.to_string_lossy().into_owned());
                    format!("{}:{}", file.unwrap_or_default(), l.line)
                });
                match (level, location) {
                    ("warn" | "error", Some(loc)) => {
                        println!("{:<5} {message}  ({loc})", level.to_uppercase())
                    }
                    _ if show(&message) => println!("{:<5} {message}", level.to_uppercase()),
                    _ => {}
                }
                if level == "error" {
                    error_logs += 1;
                }
                if message.starts_with(summary_start) && message.contains(summary_rest) {
                    summary = Some(message.clone());
                }
                messages.push(message);
            }
            Err(DecodeError::UnexpectedEof) => break,
            Err(DecodeError::Malformed) => malformed += 1,
        }
    }
    if verbose {
        println!(
            "---- end of log ({lines} frames, {} bytes) ----",
            bytes.len()
        );
    }
    let errors = String::from_utf8_lossy(&errors);
    if !errors.trim().is_empty() {
        println!("---- {qemu} stderr ----\n{}", errors.trim_end());
    }

    let Some(status) = status else {
        bail!(
            "{qemu} did not finish within {} s: $ {shown}",
            limit.as_secs()
        );
    };
    if !status.success() {
        bail!("the firmware failed: {qemu} exited with {status}: $ {shown}");
    }
    if malformed > 0 {
        bail!("{malformed} defmt frame(s) could not be decoded: the log is corrupted");
    }
    if error_logs > 0 {
        bail!("the firmware logged {error_logs} error(s)");
    }
    let Some(summary) = summary else {
        bail!("the log has no summary line (`{summary_start}...{summary_rest}...`)");
    };
    if verbose {
        println!("firmware run OK: {summary}");
    }
    Ok((summary, messages))
}

/// An allocated section of a firmware ELF.
pub struct Section {
    pub name: String,
    pub address: u64,
    pub size: u64,
    /// Whether the image holds its bytes: `.data` does (flash holds its initial value), NOBITS
    /// sections (`.bss`, `.uninit`) do not.
    pub has_bytes: bool,
}

/// The non-empty allocated sections of the ELF at `elf`.
pub fn alloc_sections(elf: &Path) -> Result<Vec<Section>> {
    let image = fs::read(elf)?;
    let file = object::File::parse(&*image).context("cannot parse the ELF")?;
    let mut out = Vec::new();
    for s in file.sections() {
        let SectionFlags::Elf { sh_flags } = s.flags() else {
            continue;
        };
        if sh_flags & u64::from(elf::SHF_ALLOC) == 0 || s.size() == 0 {
            continue;
        }
        out.push(Section {
            name: s.name().unwrap_or("?").to_string(),
            address: s.address(),
            size: s.size(),
            has_bytes: s.file_range().is_some(),
        });
    }
    Ok(out)
}

/// `name=size` of each section, for the size lines.
pub fn section_list(sections: &[Section]) -> String {
    let rows: Vec<String> = sections
        .iter()
        .map(|s| format!("{}={}", s.name, s.size))
        .collect();
    rows.join(" ")
}

/// Prints what the ELF takes of the reference board's flash and RAM (from its allocated
/// sections); returns `(flash, static RAM)` in bytes.
pub fn size_report(elf: &Path) -> Result<(u64, u64)> {
    let (flash, ram, line) = size_of(M7, elf)?;
    println!("{line}");
    Ok((flash, ram))
}

/// What the ELF built for `board` takes of its flash and RAM: `(flash, static RAM, a line
/// saying so)` in bytes.
pub fn size_of(board: Board, elf: &Path) -> Result<(u64, u64, String)> {
    let sections = alloc_sections(elf)?;
    let (mut flash, mut ram) = (0u64, 0u64);
    // riscv-rt's linker script reserves the heap and the stack as sections of their own
    // (cortex-m-rt leaves them to the rest of RAM): they are not static data.
    let reserved = |name: &str| name == ".stack" || name == ".heap";
    for s in sections.iter().filter(|s| !reserved(&s.name)) {
        let in_ram = s.address >= board.ram_origin;
        if in_ram {
            ram += s.size;
        }
        if !in_ram || s.has_bytes {
            flash += s.size;
        }
    }
    let line = format!(
        "firmware size ({}): flash {flash} B of {} KiB ({:.1}%), static RAM {ram} B of {} KiB, \
         the rest of RAM is stack [{}]",
        board.name,
        board.flash_len / 1024,
        100.0 * flash as f64 / board.flash_len as f64,
        board.ram_len / 1024,
        section_list(&sections)
    );
    Ok((flash, ram, line))
}

/// The two-view bench binary (`cargo xtask bench-fw`, after the homography bench).
const TWOVIEW_BENCH_BIN: &str = "camgeom-fw-bench-twoview";

/// Builds and runs the two-view bench binary on QEMU and prints its cost table and summary.
fn bench_twoview() -> Result<()> {
    let elf = build_bin(TWOVIEW_BENCH_BIN, &[])?;
    size_report(&elf)?;
    let summary = run_on_qemu_checked(&elf, "twoview bench: ", BENCH_SUMMARY_REST)?;
    println!("bench-fw: {summary}");
    Ok(())
}

/// The stack-painting binary (`cargo xtask stack`).
const STACK_BIN: &str = "camgeom-fw-stack";

/// `cargo xtask stack`: builds `firmware/emulated/src/bin/stack.rs` for `thumbv7em-none-eabihf`
/// (run on the Cortex-M7 board) and for `thumbv6m-none-eabi` (run on the Cortex-M3 board,
/// [`crate::jobs::M0_ON_M3`]); each log holds one `stack <entry point>: <bytes> bytes` line per
/// public entry point. Prints both as one Markdown table (BENCHMARKS.md, "Stack").
pub fn stack() -> Result<()> {
    let mut columns = Vec::new();
    for board in [M7, crate::jobs::M0_ON_M3] {
        let elf = build_bin_for(board, STACK_BIN, &[])?;
        let (summary, lines) =
            run_on_qemu_in(board, &elf, None, "stack table: ", " entry points", None)?;
        println!("stack ({}): {summary}", board.target);
        let rows: Vec<(String, String)> = lines
            .iter()
            .filter_map(|l| {
                let rest = l.split("stack ").nth(1)?;
                let (name, bytes) = rest.split_once(": ")?;
                let bytes = bytes.strip_suffix(" bytes")?;
                Some((name.to_string(), bytes.to_string()))
            })
            .collect();
        columns.push(rows);
    }
    let (Some(m7), Some(m0)) = (columns.first(), columns.get(1)) else {
        bail!("the stack runs gave no table");
    };
    if m7.len() != m0.len() || m7.iter().zip(m0).any(|(a, b)| a.0 != b.0) {
        bail!("the two stack runs measured different entry points");
    }
    println!(
        "\n| entry point | thumbv7em-none-eabihf (Cortex-M7), bytes | thumbv6m-none-eabi (on the Cortex-M3), bytes |\n|---|---:|---:|"
    );
    for ((name, a), (_, b)) in m7.iter().zip(m0) {
        println!("| {name} | {a} | {b} |");
    }
    Ok(())
}
