//! `cargo xtask build-openmv`: builds the OpenMV Cam H7 firmware (release) and checks that it
//! linked with the board's own memory map (`firmware/openmv-h7/memory.x`), not the emulated
//! board's: every section in the STM32H743's flash or AXI SRAM, the initial stack pointer at
//! the top of DTCM. Prints flash and static RAM use. Built in CI, never run there (no board).

use std::fs;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use object::{Object, ObjectSection};

use crate::firmware::{alloc_sections, firmware_cargo, firmware_target_dir, section_list};
use crate::jobs::M7;
use crate::util::{locked, run};

const PACKAGE: &str = "camgeom-fw-openmv-h7";
const FLASH: (u64, u64) = (0x0800_0000, 2 * 1024 * 1024);
const AXI_SRAM: (u64, u64) = (0x2400_0000, 512 * 1024);
/// Top of DTCM (128 KiB at 0x2000_0000): the stack.
const STACK_TOP: u32 = 0x2002_0000;

pub fn build() -> Result<PathBuf> {
    let mut cmd = firmware_cargo("build");
    cmd.args(["--release", "-p", PACKAGE]);
    run(locked(&mut cmd))?;
    let elf = firmware_target_dir()
        .join(M7.target)
        .join("release")
        .join(PACKAGE);
    if !elf.is_file() {
        bail!("the build did not produce {}", elf.display());
    }
    Ok(elf)
}

fn within(addr: u64, size: u64, (origin, len): (u64, u64)) -> bool {
    addr >= origin && addr + size <= origin + len
}

/// Checks the memory map and returns `(flash, static RAM)` bytes.
pub fn check(elf: &std::path::Path) -> Result<(u64, u64)> {
    let sections = alloc_sections(elf)?;
    let (mut flash, mut ram) = (0u64, 0u64);
    for s in &sections {
        let (name, addr, size) = (&s.name, s.address, s.size);
        if within(addr, size, AXI_SRAM) {
            ram += size;
            if s.has_bytes {
                flash += size;
            }
        } else if within(addr, size, FLASH) {
            flash += size;
        } else {
            bail!(
                "section {name} at {addr:#x} ({size} B) is outside the board's flash and AXI SRAM: wrong memory.x?"
            );
        }
    }
    let image = fs::read(elf)?;
    let file = object::File::parse(&*image).context("cannot parse the ELF")?;
    let vectors = file
        .section_by_name(".vector_table")
        .context("no .vector_table")?;
    if vectors.address() != FLASH.0 {
        bail!(
            "the vector table is at {:#x}, not at the start of flash",
            vectors.address()
        );
    }
    let data = vectors.data()?;
    let sp = data
        .first_chunk::<4>()
        .map(|b| u32::from_le_bytes(*b))
        .context("empty vector table")?;
    if sp != STACK_TOP {
        bail!("initial stack pointer {sp:#x}, expected the top of DTCM {STACK_TOP:#x}");
    }
    println!(
        "openmv-h7 size: flash {flash} B of {} KiB ({:.1}%), static RAM {ram} B of {} KiB AXI SRAM \
         ({:.1}%), stack in DTCM (128 KiB) [{}]",
        FLASH.1 / 1024,
        100.0 * flash as f64 / FLASH.1 as f64,
        AXI_SRAM.1 / 1024,
        100.0 * ram as f64 / AXI_SRAM.1 as f64,
        section_list(&sections)
    );
    Ok((flash, ram))
}

pub fn build_and_check() -> Result<()> {
    let elf = build()?;
    check(&elf).map(|_| ())
}
