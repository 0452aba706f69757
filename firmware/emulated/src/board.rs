//! The emulated boards: exit codes through semihosting, the panic and fault handlers, stack use.
//!
//! The same code for every core: exits go through the `semihosting` crate (`SYS_EXIT` on Arm
//! and RISC-V alike), the panic handler logs once and exits with failure; the fault handlers
//! and the stack-region symbols are the runtime's (cortex-m-rt on Arm, riscv-rt on RISC-V).

use core::panic::PanicInfo;
use portable_atomic::{AtomicBool, Ordering};

/// Ends the run: QEMU exits with status 0.
pub fn exit_success() -> ! {
    semihosting::process::exit(0)
}

/// Ends the run: QEMU exits with status 1.
pub fn exit_failure() -> ! {
    semihosting::process::exit(1)
}

/// Set by the first panic or fault, so that a second one (say, inside the logger) does not try
/// to log again.
static FAILING: AtomicBool = AtomicBool::new(false);

fn fail_once(log: impl FnOnce()) -> ! {
    if !FAILING.swap(true, Ordering::Relaxed) {
        log();
    }
    exit_failure()
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    fail_once(|| defmt::error!("panic: {}", defmt::Display2Format(info)))
}

#[cfg(target_arch = "arm")]
mod arm {
    use cortex_m_rt::{ExceptionFrame, exception};

    #[exception]
    unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
        super::fail_once(|| defmt::error!("hard fault at pc {=u32:#010x}", frame.pc()))
    }

    #[exception]
    unsafe fn DefaultHandler(irqn: i16) {
        super::fail_once(|| defmt::error!("unexpected exception {=i16}", irqn))
    }

    unsafe extern "C" {
        /// Bottom of the stack region (end of static RAM), from cortex-m-rt's `link.x`.
        pub static _stack_end: u32;
        /// Top of the stack (the initial stack pointer), from cortex-m-rt's `link.x`.
        pub static _stack_start: u32;
    }

    /// `(bottom, top)` of the stack region.
    pub fn stack_region() -> (*const u32, *const u32) {
        (&raw const _stack_end, &raw const _stack_start)
    }

    /// The word cortex-m-rt's `paint-stack` fills the stack with before `main`.
    pub const PAINT: u32 = cortex_m_rt::STACK_PAINT_VALUE;

    /// cortex-m-rt painted the stack before `main`.
    pub fn paint_stack() {}
}

#[cfg(target_arch = "riscv32")]
mod riscv {
    /// An exception (illegal instruction, access fault, misaligned access, ...): log it and fail
    /// the run, rather than riscv-rt's default of looping for ever.
    #[unsafe(export_name = "ExceptionHandler")]
    fn exception_handler(frame: &riscv_rt::TrapFrame) -> ! {
        let cause = riscv::register::mcause::read().bits();
        let pc = riscv::register::mepc::read();
        super::fail_once(|| {
            defmt::error!(
                "exception: mcause {=usize:#x} at pc {=usize:#010x} (ra {=usize:#010x})",
                cause,
                pc,
                frame.ra
            )
        })
    }

    /// An interrupt nobody enabled, or an abort from the runtime before `main`: fail the run
    /// (nothing is logged: the logger's statics may not be initialised yet).
    #[unsafe(export_name = "DefaultHandler")]
    fn default_handler() -> ! {
        super::exit_failure()
    }

    unsafe extern "C" {
        /// Bottom of the stack region (riscv-rt's `.stack` section starts here).
        static __estack: u32;
        /// Top of the stack (the initial stack pointer), from riscv-rt's `link.x`.
        static _stack_start: u32;
    }

    /// `(bottom, top)` of the stack region.
    pub fn stack_region() -> (*const u32, *const u32) {
        (&raw const __estack, &raw const _stack_start)
    }

    /// What [`paint_stack`] fills the free stack with (cortex-m-rt's value, for one pattern on
    /// every board).
    pub const PAINT: u32 = 0xCCCC_CCCC;

    /// Fills the free stack, from its bottom to 256 bytes below the stack pointer, with
    /// [`PAINT`] (riscv-rt has no `paint-stack`): call first thing in `main`.
    #[inline(never)]
    pub fn paint_stack() {
        let sp: usize;
        // SAFETY: reads the stack pointer register; no memory access.
        unsafe { core::arch::asm!("mv {}, sp", out(reg) sp, options(nomem, nostack)) };
        let (bottom, _) = stack_region();
        let end = (sp - 256) & !3;
        let mut p = bottom as usize;
        while p < end {
            // SAFETY: word-aligned addresses between the bottom of the stack region and below
            // the live stack: free stack RAM that nothing else uses.
            unsafe { (p as *mut u32).write_volatile(PAINT) };
            p += 4;
        }
    }
}

#[cfg(target_arch = "arm")]
pub use arm::{PAINT, paint_stack, stack_region};
#[cfg(target_arch = "riscv32")]
pub use riscv::{PAINT, paint_stack, stack_region};

/// Bytes of stack used so far at most, and the stack's size: the stack is painted with
/// [`PAINT`] before the work ([`paint_stack`]); the lowest word no longer holding it is the
/// deepest the stack has been.
pub fn stack_usage() -> (u32, u32) {
    let (bottom, top) = stack_region();
    let size = (top as usize - bottom as usize) as u32;
    let mut p = bottom;
    while p < top {
        // SAFETY: `p` is word-aligned (asserted by the runtime's link.x) and inside the stack
        // region, which is RAM; volatile because the compiler knows nothing of what wrote it.
        if unsafe { p.read_volatile() } != PAINT {
            break;
        }
        p = p.wrapping_add(1);
    }
    ((top as usize - p as usize) as u32, size)
}
