//! `cargo xtask build-openmv`: builds the OpenMV Cam H7 firmware (release) and checks that it
//! linked with the board's own memory map (`firmware/openmv-h7/memory.x`), not the emulated
//! board's: every section in the STM32H743's flash or AXI SRAM, the initial stack pointer at
//! the top of DTCM. Prints flash and static RAM use. Built in CI, never run there (no board).
//!
//! `cargo xtask flash-openmv`: the same build, written to the board over USB DFU by the
//! STM32's ROM bootloader (`dfu-util`; the steps are in firmware/README.md).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, anyhow, bail, ensure};
use object::read::elf::{ElfFile32, ProgramHeader};
use object::{Object, ObjectSection};

use crate::firmware::{alloc_sections, firmware_cargo, firmware_target_dir, section_list};
use crate::jobs::M7;
use crate::util::{locked, output, run};

const PACKAGE: &str = "camgeom-fw-openmv-h7";
/// memory.x's `FLASH`: the 2 MiB but the last 128 KiB sector, which holds the board's settings.
const FLASH: (u64, u64) = (0x0800_0000, 2 * 1024 * 1024 - 128 * 1024);
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

/// The STM32 ROM bootloader's DFU device (ST's VID:PID, AN3156).
const DFU_DEVICE: &str = "0483:df11";

/// Builds and checks the firmware, writes its flash image next to the ELF (`.bin`) and
/// downloads it with `dfu-util` to the board waiting in its ROM bootloader.
pub fn flash() -> Result<()> {
    if output("dfu-util", ["--version"]).is_none() {
        bail!(
            "dfu-util not found: `cargo xtask setup` installs it (Debian/Ubuntu: `apt-get install dfu-util`)"
        );
    }
    let elf = build()?;
    check(&elf)?;
    let image = flash_image(&fs::read(&elf)?)?;
    let bin = elf.with_extension("bin");
    fs::write(&bin, &image).with_context(|| format!("cannot write {}", bin.display()))?;
    println!(
        "flash image: {} B from {:#010x}, {}",
        image.len(),
        FLASH.0,
        bin.display()
    );
    run(Command::new("dfu-util")
        .args(["-d", DFU_DEVICE, "-a", "0", "-s"])
        .arg(format!("{:#010x}:leave", FLASH.0))
        .arg("-D")
        .arg(Path::new(&bin)))
}

/// What is written to flash from its start: each loadable segment's file bytes at its load
/// (physical) address, `.data`'s initial values included, the gaps erased flash (`0xff`): the
/// bytes `objcopy -O binary` gives. Errors: an ELF that is not 32-bit, or a segment with bytes
/// outside the flash.
pub fn flash_image(elf: &[u8]) -> Result<Vec<u8>> {
    let file = ElfFile32::<object::Endianness>::parse(elf).context("cannot parse the ELF")?;
    let endian = file.endian();
    let mut image = Vec::new();
    for ph in file.elf_program_headers() {
        let size = u64::from(ph.p_filesz(endian));
        if ph.p_type(endian) != object::elf::PT_LOAD || size == 0 {
            continue;
        }
        let addr = u64::from(ph.p_paddr(endian));
        ensure!(
            within(addr, size, FLASH),
            "a loadable segment at {addr:#x} ({size} B) is outside the flash"
        );
        let data = ph
            .data(endian, elf)
            .map_err(|()| anyhow!("a segment's bytes are outside the ELF"))?;
        let start = usize::try_from(addr - FLASH.0)?;
        let end = start + data.len();
        if image.len() < end {
            image.resize(end, 0xff);
        }
        image[start..end].copy_from_slice(data);
    }
    ensure!(!image.is_empty(), "the ELF has nothing to flash");
    Ok(image)
}
