//! camgeom's multi-step commands, run from anywhere in the repository: `cargo xtask --help`
//! lists them, `cargo xtask <command> --help` describes one (each is a variant of
//! [`Command`], its doc comment the help text). `cargo xtask ci` runs every check in order and
//! `cargo xtask run` is the main job.
//!
//! Environment: `CI=true` adds `--locked` to cargo builds; `XTASK_QEMU_TIMEOUT` (seconds,
//! default 120) bounds the emulator run.

mod charuco_bench;
mod ci;
mod firmware;
mod fuzz;
mod imports;
mod jobs;
mod mainjob;
mod openmv;
mod panic_check;
mod profile;
mod setup;
mod size;
mod tag_bench;
mod util;

use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::builder::PossibleValuesParser;
use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    about = "camgeom's multi-step commands: the main job on the emulated boards, the firmware \
             benches, size and panic checks, fuzzing, and every CI check",
    after_help = "Environment: CI=true adds --locked to cargo builds; XTASK_QEMU_TIMEOUT \
                  (seconds, default 120) bounds the emulator run.",
    arg_required_else_help = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

// One variant a command; its doc comment is its help (the first paragraph: the line in the
// list).
#[derive(Subcommand, Debug)]
enum Command {
    /// Install what the other commands need: rustup targets, components, qemu-system-arm.
    ///
    /// Installs QEMU with apt-get when root.
    Setup,
    /// The main job: the firmware over the recorded box sequence on the emulated boards,
    /// checked against the host replay.
    ///
    /// Every emulated board (mps2-an500 Cortex-M7, mps2-an385 Cortex-M3, mps2-an505
    /// Cortex-M33, virt RV32IMAC) or only --board, at 320x240 and 160x120: per-stage cost,
    /// overlays and contact sheets (target/camgeom-run/), each frame checked against the host
    /// replay; then the size check. With the Cortex-M7 also the projection checks and the
    /// fault, forward-backward, tag and calibration jobs.
    Run {
        /// Only this board (its QEMU machine name).
        #[arg(long, value_name = "NAME", value_parser = PossibleValuesParser::new(jobs::BOARDS.map(|b| b.name)))]
        board: Option<String>,
    },
    /// Build and run the homography and two-view bench firmware on QEMU: instruction counts,
    /// flash size.
    BenchFw,
    /// A firmware on the emulated Cortex-M7 with QEMU's block logs: its instructions by
    /// function.
    ///
    /// The bench firmware by default; or BIN of camgeom-fw-emulated, started in DIR (the main
    /// job's is target/camgeom-run/320x240 after `run`).
    ProfileFw {
        /// The binary of camgeom-fw-emulated to run.
        #[arg(value_name = "BIN", default_value = firmware::BENCH_BIN)]
        bin: String,
        /// The directory to start it in, relative to the repository root.
        #[arg(value_name = "DIR")]
        dir: Option<String>,
    },
    /// Build the OpenMV Cam H7 firmware (release), check its memory map, print its size.
    BuildOpenmv,
    /// Build the OpenMV Cam H7 firmware and write it to the board over USB DFU (dfu-util),
    /// the board started in its ROM bootloader (BOOT to 3.3 V; see firmware/README.md).
    FlashOpenmv,
    /// Main-job firmware flash and static RAM against firmware/size-snapshot.txt.
    Size {
        /// Rewrite the snapshot with the sizes measured (the stack bounds are kept).
        #[arg(long)]
        update: bool,
    },
    /// Build and run the stack-painting firmware on QEMU (thumbv7em on the Cortex-M7,
    /// thumbv6m on the Cortex-M3): stack high-water mark per entry point.
    Stack,
    /// Link one firmware binary per area of the core, scalar type and target with a panic
    /// handler that cannot link; print the coverage table.
    ///
    /// With --locate: link that one selection with the handler's symbol defined and name the
    /// functions that call the panic machinery.
    PanicCheck {
        /// Features of camgeom-panic-check (areas and scalar types, comma-separated, e.g.
        /// `klt,f32`) and the target to link them for (e.g. thumbv7em-none-eabihf).
        #[arg(long, num_args = 2, value_names = ["FEATURES", "TARGET"])]
        locate: Option<Vec<String>>,
    },
    /// Build the cargo-fuzz targets of fuzz/ and run each (or only TARGET) for SECONDS from
    /// the committed corpus fuzz/corpus/TARGET.
    ///
    /// Without SECONDS: the CI smoke run. A crash fails the command.
    Fuzz {
        /// Seconds per target.
        #[arg(value_name = "SECONDS", default_value_t = fuzz::SMOKE_SECONDS)]
        seconds: u64,
        /// Only this fuzz target.
        #[arg(value_name = "TARGET")]
        target: Option<String>,
    },
    /// Merge the run corpora (fuzz/target/corpus) into fuzz/corpus and minimise it.
    FuzzCmin {
        /// Only this fuzz target.
        #[arg(value_name = "TARGET")]
        target: Option<String>,
    },
    /// Check that imports point down: no two files (or subdirectories) of a module import
    /// each other, directly or around a loop, in the core, the board app, the host crate and
    /// xtask.
    Imports,
    /// Every check in order: fmt, clippy, tests, no_std builds, docs, then `run`.
    Ci {
        /// Only the steps whose name contains this text (to time or rerun one step).
        #[arg(long, value_name = "TEXT")]
        only: Option<String>,
    },
}

/// Runs `command`.
fn run(command: Command) -> Result<()> {
    match command {
        Command::Setup => setup::setup(),
        Command::Run { board: None } => {
            setup::setup().and_then(|()| mainjob::run(&mainjob::Options::full()))
        }
        Command::Run { board: Some(name) } => {
            // The parser took only a board's name.
            let board = jobs::board(&name).with_context(|| format!("no board `{name}`"))?;
            setup::setup().and_then(|()| mainjob::run(&mainjob::Options::boards(vec![board])))
        }
        Command::BenchFw => setup::setup().and_then(|()| firmware::bench()),
        Command::ProfileFw { bin, dir } => {
            setup::setup().and_then(|()| profile::profile(&bin, dir.as_deref()))
        }
        Command::BuildOpenmv => openmv::build_and_check(),
        Command::FlashOpenmv => openmv::flash(),
        Command::Size { update } => setup::setup().and_then(|()| size::size(update)),
        Command::Stack => setup::setup().and_then(|()| firmware::stack()),
        Command::PanicCheck { locate: None } => panic_check::check(),
        Command::PanicCheck {
            locate: Some(selection),
        } => {
            // The parser took exactly two values.
            let [features, target] = selection.as_slice() else {
                anyhow::bail!("--locate takes FEATURES and TARGET");
            };
            panic_check::locate(features, target).map(|found| println!("{found}"))
        }
        Command::Fuzz { seconds, target } => fuzz::fuzz(seconds, target.as_deref()),
        Command::FuzzCmin { target } => fuzz::cmin(target.as_deref()),
        Command::Imports => imports::check(&util::root()),
        Command::Ci { only } => ci::ci(only.as_deref()),
    }
}

fn main() -> ExitCode {
    // A usage error (unknown command, flag or argument, a missing value) prints clap's message
    // and exits with status 2.
    let cli = Cli::parse();
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, Parser};

    use super::Cli;

    #[test]
    fn the_command_line_is_well_formed() {
        Cli::command().debug_assert();
    }

    /// Every command line README.md, BENCHMARKS.md, docs/, firmware/README.md and .ci/run
    /// quote parses (placeholders filled in).
    #[test]
    fn the_documented_command_lines_parse() {
        for line in [
            "setup",
            "run",
            "run --board mps2-an500",
            "run --board mps2-an385",
            "run --board mps2-an505",
            "run --board virt",
            "bench-fw",
            "profile-fw",
            "profile-fw camgeom-fw-bench",
            "profile-fw camgeom-fw-emulated target/camgeom-run/320x240",
            "build-openmv",
            "flash-openmv",
            "size",
            "size --update",
            "stack",
            "panic-check",
            "panic-check --locate klt,f32 thumbv7em-none-eabihf",
            "fuzz",
            "fuzz 240",
            "fuzz 3600",
            "fuzz 240 pose",
            "fuzz 600 chessboard",
            "fuzz-cmin",
            "fuzz-cmin chessboard",
            "imports",
            "ci",
        ] {
            let args = ["cargo xtask"].into_iter().chain(line.split(' '));
            if let Err(e) = Cli::try_parse_from(args) {
                panic!("`cargo xtask {line}` does not parse: {e}");
            }
        }
    }

    /// Mistakes are errors, not a run of something else.
    #[test]
    fn mistakes_are_rejected() {
        for line in [
            "size --typo",
            "size update",
            "run --board",
            "run --board qemu",
            "run mps2-an500",
            "panic-check --locate klt,f32",
            "panic-check klt,f32 thumbv7em-none-eabihf",
            "fuzz pose",
            "fuzz 240 pose extra",
            "fuzz-cmin a b",
            "profile-fw a b c",
            "ci --fast",
            "setup now",
            "frobnicate",
        ] {
            let args = ["cargo xtask"].into_iter().chain(line.split(' '));
            assert!(
                Cli::try_parse_from(args).is_err(),
                "`cargo xtask {line}` parses"
            );
        }
    }
}
