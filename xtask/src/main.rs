//! camgeom's multi-step commands, run from anywhere in the repository:
//!
//! | command | what |
//! |---|---|
//! | `cargo xtask setup` | installs what the other commands need: rustup targets, components, QEMU |
//! | `cargo xtask run [--board NAME]` | the main job: the firmware over the recorded sequence on every emulated board (or one), checked against the host replay |
//! | `cargo xtask bench-fw` | the homography bench firmware on QEMU: instruction counts, flash size |
//! | `cargo xtask profile-fw [BIN [DIR]]` | the bench firmware (or BIN of the emulated-board crate, started in DIR) on QEMU's Cortex-M7 with its block logs: instructions by function |
//! | `cargo xtask build-openmv` | builds the OpenMV Cam H7 firmware, checks its memory map, prints its size |
//! | `cargo xtask size [--update]` | main-job firmware flash and static RAM against `firmware/size-snapshot.txt` |
//! | `cargo xtask stack` | the stack-painting firmware on QEMU (thumbv7em on the Cortex-M7, thumbv6m on the Cortex-M3): stack high-water mark per entry point |
//! | `cargo xtask panic-check [--locate FEATURES TARGET]` | links one firmware binary per area of the core, scalar type and target (thumbv7em, thumbv6m) with a panic handler that cannot link; prints the coverage table (with `--locate`: names the functions that call the panic machinery in that selection) |
//! | `cargo xtask fuzz [SECONDS] [TARGET]` | builds the cargo-fuzz targets in `fuzz/` and runs each (or TARGET) for SECONDS (default 5, the CI smoke run) from the committed corpus |
//! | `cargo xtask fuzz-cmin [TARGET]` | merges the local run corpora into the committed `fuzz/corpus/` and minimises it |
//! | `cargo xtask ci` | every check in order (fmt, clippy, tests, no_std builds, docs, `run`) |
//!
//! Environment: `CI=true` adds `--locked` to cargo builds; `XTASK_QEMU_TIMEOUT` (seconds,
//! default 120) bounds the emulator run.

mod ci;
mod firmware;
mod fuzz;
mod jobs;
mod mainjob;
mod openmv;
mod panic_check;
mod profile;
mod setup;
mod size;
mod util;

use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask <command>

commands:
  setup   install the rustup targets and components and qemu-system-arm the other commands need
  run [--board NAME]  the main job: the firmware over the recorded box sequence on every
          emulated board (mps2-an500 Cortex-M7, mps2-an385 Cortex-M3, mps2-an505 Cortex-M33,
          virt RV32IMAC; or only NAME), 320x240 and 160x120, per-stage cost, overlays, each
          checked against the host replay
  bench-fw  build and run the homography bench firmware on QEMU: instruction counts, flash size
  profile-fw [BIN [DIR]]  run the bench firmware (or BIN of camgeom-fw-emulated, in DIR: the
          main job's is target/camgeom-run/320x240 after `run`) on the emulated Cortex-M7 with
          QEMU's block logs and list its instructions by function
  build-openmv  build the OpenMV Cam H7 firmware (release), check its memory map, print its size
  stack   build and run the stack-painting firmware on QEMU (thumbv7em, thumbv6m): stack per entry point
  panic-check [--locate FEATURES TARGET]  link one firmware binary per area, scalar type and
          target with a panic handler that cannot link (--locate: which functions of that
          selection call the panic machinery)
  size [--update]  main-job firmware flash and static RAM against firmware/size-snapshot.txt
  fuzz [SECONDS] [TARGET]  build the fuzz targets and run each (or only TARGET) for SECONDS
          (default 5), from the committed corpus fuzz/corpus/<target>
  fuzz-cmin [TARGET]  merge the run corpora (fuzz/target/corpus) into fuzz/corpus and minimise
  ci      every check in order: fmt, clippy, test, no_std builds, doc, then `run`";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("setup") => setup::setup(),
        Some("run") => match args.get(1).map(String::as_str) {
            None => setup::setup().and_then(|()| mainjob::run(&mainjob::Options::full())),
            Some("--board") => match args.get(2).and_then(|n| jobs::board(n)) {
                Some(b) => {
                    setup::setup().and_then(|()| mainjob::run(&mainjob::Options::boards(vec![b])))
                }
                None => {
                    eprintln!(
                        "xtask: run --board takes one of: {}",
                        jobs::BOARDS.map(|b| b.name).join(", ")
                    );
                    return ExitCode::from(2);
                }
            },
            Some(other) => {
                eprintln!("xtask: unknown argument to run: `{other}`\n\n{USAGE}");
                return ExitCode::from(2);
            }
        },
        Some("bench-fw") => setup::setup().and_then(|()| firmware::bench()),
        Some("profile-fw") => setup::setup().and_then(|()| {
            let bin = args.get(1).map_or(firmware::BENCH_BIN, String::as_str);
            profile::profile(bin, args.get(2).map(String::as_str))
        }),
        Some("build-openmv") => openmv::build_and_check(),
        Some("size") => {
            setup::setup().and_then(|()| size::size(args.get(1).is_some_and(|a| a == "--update")))
        }
        Some("stack") => setup::setup().and_then(|()| firmware::stack()),
        Some("panic-check") => match (args.get(1).map(String::as_str), args.get(2), args.get(3)) {
            (Some("--locate"), Some(features), Some(target)) => {
                panic_check::locate(features, target).map(|found| println!("{found}"))
            }
            _ => panic_check::check(),
        },
        Some("fuzz") => match args.get(1).map(|s| s.parse::<u64>()) {
            None => fuzz::fuzz(fuzz::SMOKE_SECONDS, None),
            Some(Ok(secs)) => fuzz::fuzz(secs, args.get(2).map(String::as_str)),
            Some(Err(_)) => {
                eprintln!("xtask: fuzz takes a number of seconds per target, then a target");
                return ExitCode::from(2);
            }
        },
        Some("fuzz-cmin") => fuzz::cmin(args.get(1).map(String::as_str)),
        Some("ci") => ci::ci(),
        Some("help" | "-h" | "--help") => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        other => {
            if let Some(cmd) = other {
                eprintln!("xtask: unknown command `{cmd}`\n");
            }
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
