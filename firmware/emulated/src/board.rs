//! The emulated board: exit codes through semihosting, fault and panic handling, stack use.

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_rt::{ExceptionFrame, exception};
use cortex_m_semihosting::debug;

/// Ends the run: QEMU exits with status 0.
pub fn exit_success() -> ! {
    debug::exit(debug::EXIT_SUCCESS);
    // Only reached without a debugger/emulator listening to semihosting.
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Ends the run: QEMU exits with status 1.
pub fn exit_failure() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Set by the first panic or fault, so that a second one (say, inside the logger) does not try
/// to log again.
static FAILING: AtomicBool = AtomicBool::new(false);

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    if !FAILING.swap(true, Ordering::Relaxed) {
        defmt::error!("panic: {}", defmt::Display2Format(info));
    }
    exit_failure()
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    if !FAILING.swap(true, Ordering::Relaxed) {
        defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
    }
    exit_failure()
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    if !FAILING.swap(true, Ordering::Relaxed) {
        defmt::error!("unexpected exception {=i16}", irqn);
    }
    exit_failure()
}

unsafe extern "C" {
    /// Bottom of the stack region (end of static RAM), from cortex-m-rt's `link.x`.
    static _stack_end: u32;
    /// Top of the stack (the initial stack pointer), from cortex-m-rt's `link.x`.
    static _stack_start: u32;
}

/// Bytes of stack used so far at most, and the stack's size. cortex-m-rt's `paint-stack`
/// fills the stack with [`cortex_m_rt::STACK_PAINT_VALUE`] before `main`; the lowest word no
/// longer holding it is the deepest the stack has been.
pub fn stack_usage() -> (u32, u32) {
    let bottom = &raw const _stack_end;
    let top = &raw const _stack_start;
    let size = (top as usize - bottom as usize) as u32;
    let mut p = bottom;
    while p < top {
        // SAFETY: `p` is word-aligned (asserted by link.x) and inside the stack region, which
        // is RAM; volatile because the compiler knows nothing of what wrote it.
        if unsafe { p.read_volatile() } != cortex_m_rt::STACK_PAINT_VALUE {
            break;
        }
        p = p.wrapping_add(1);
    }
    ((top as usize - p as usize) as u32, size)
}
