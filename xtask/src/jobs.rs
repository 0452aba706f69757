//! The emulated boards and the main job's firmware binaries (what `run` runs and `size`
//! measures).

/// An emulated board: the QEMU machine, the Rust target its firmware is built for, and the
/// memory the linker gives it (`firmware/emulated/build.rs` picks the memory map by target).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Board {
    /// The QEMU machine name, also the board's name on the command line.
    pub name: &'static str,
    /// The core, for tables.
    pub core: &'static str,
    /// The board class whose memory it is capped to, for tables.
    pub class: &'static str,
    /// The Rust target.
    pub target: &'static str,
    /// The QEMU binary.
    pub qemu: &'static str,
    /// QEMU's machine arguments.
    pub machine: &'static [&'static str],
    /// Start of RAM: sections at or above it take RAM, the others flash.
    pub ram_origin: u64,
    /// Bytes of RAM and of flash the memory map gives.
    pub ram_len: u64,
    pub flash_len: u64,
}

/// The Cortex-M7 (STM32H7 class, the OpenMV Cam H7's core): the reference board.
pub const M7: Board = Board {
    name: "mps2-an500",
    core: "Cortex-M7",
    class: "STM32H7 (OpenMV Cam H7), 512 KB",
    target: "thumbv7em-none-eabihf",
    qemu: "qemu-system-arm",
    machine: &["-cpu", "cortex-m7", "-machine", "mps2-an500"],
    ram_origin: 0x2000_0000,
    ram_len: 512 * 1024,
    flash_len: 2 * 1024 * 1024,
};

/// The Cortex-M3, no FPU: the RP2040 class (264 KB; the RP2040's M0+ has no QEMU machine
/// with that much RAM).
pub const M3: Board = Board {
    name: "mps2-an385",
    core: "Cortex-M3 (no FPU)",
    class: "RP2040, 264 KB",
    target: "thumbv7m-none-eabi",
    qemu: "qemu-system-arm",
    machine: &["-cpu", "cortex-m3", "-machine", "mps2-an385"],
    ram_origin: 0x2000_0000,
    ram_len: 264 * 1024,
    flash_len: 2 * 1024 * 1024,
};

/// Cortex-M0+ code (`thumbv6m-none-eabi`, the RP2040's instruction set) on the Cortex-M3
/// machine, which runs ARMv6-M code (a subset of ARMv7-M); QEMU has no Cortex-M0+ machine with
/// enough RAM. Only the stack table runs here (`firmware/emulated/memory/mps2-an385-stack.x`).
pub const M0_ON_M3: Board = Board {
    name: "mps2-an385",
    core: "Cortex-M0+ code on the Cortex-M3",
    class: "RP2040 (stack table only)",
    target: "thumbv6m-none-eabi",
    qemu: "qemu-system-arm",
    machine: &["-cpu", "cortex-m3", "-machine", "mps2-an385"],
    ram_origin: 0x2000_0000,
    ram_len: 1024 * 1024,
    flash_len: 2 * 1024 * 1024,
};

/// The Cortex-M33 with its single-precision FPU: the RP2350 class (520 KB).
pub const M33: Board = Board {
    name: "mps2-an505",
    core: "Cortex-M33",
    class: "RP2350, 520 KB",
    target: "thumbv8m.main-none-eabihf",
    qemu: "qemu-system-arm",
    machine: &["-cpu", "cortex-m33", "-machine", "mps2-an505"],
    ram_origin: 0x3800_0000,
    ram_len: 520 * 1024,
    flash_len: 2 * 1024 * 1024,
};

/// RV32IMAC, no FPU: the ESP32-C3 class (about 400 KB).
pub const RISCV: Board = Board {
    name: "virt",
    core: "RV32IMAC (no FPU)",
    class: "ESP32-C3, 400 KB",
    target: "riscv32imac-unknown-none-elf",
    qemu: "qemu-system-riscv32",
    machine: &["-machine", "virt", "-bios", "none"],
    ram_origin: 0x8020_0000,
    ram_len: 400 * 1024,
    flash_len: 2 * 1024 * 1024,
};

/// Every board `cargo xtask run` runs, the reference first.
pub const BOARDS: [Board; 4] = [M7, M3, M33, RISCV];

/// The board named `name` (its QEMU machine name).
pub fn board(name: &str) -> Option<Board> {
    BOARDS.into_iter().find(|b| b.name == name)
}

/// One frame size of the main job and the firmware binary built for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    /// Frame width (pixels).
    pub width: u32,
    /// Frame height (pixels).
    pub height: u32,
    /// The firmware binary for this size.
    pub bin: &'static str,
}

impl Size {
    /// `WxH`.
    pub fn name(&self) -> String {
        format!("{}x{}", self.width, self.height)
    }
}

/// 320x240: the main job proper.
pub const FULL: Size = Size {
    width: 320,
    height: 240,
    bin: "camgeom-fw-emulated",
};

/// 160x120: the same pipeline on the sequence downscaled by `pyrDown`.
pub const HALF: Size = Size {
    width: 160,
    height: 120,
    bin: "camgeom-fw-qqvga",
};

/// The name a binary built for `board` has in `firmware/size-snapshot.txt`: the binary's own
/// on the reference board, `bin@board` on the others.
pub fn snapshot_key(board: Board, bin: &str) -> String {
    if board == M7 {
        bin.to_string()
    } else {
        format!("{bin}@{}", board.name)
    }
}
