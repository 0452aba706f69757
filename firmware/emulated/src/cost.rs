//! Cost measurement: an instruction counter on every emulated core.
//!
//! **Arm** (`mps2-an385`, `-an500`, `-an505`): SysTick runs free from the core clock as a
//! 24-bit down-counter (reload `0xFF_FFFF`); its exception counts the wraps, so [`now`] is a
//! 64-bit tick count that never wraps in practice. On QEMU with `-icount shift=0` every
//! instruction advances virtual time by exactly 1 ns, and the MPS2 core clock that drives
//! SysTick is 25 MHz: one tick is 40 instructions. The ratio is not hard-coded: [`start`]
//! measures a loop of known length and keeps the instructions-per-tick it finds, so
//! [`measure`] reports instructions (to within one tick). On real hardware the same code
//! counts core cycles per tick (1), see firmware/README.md.
//!
//! **RISC-V** (`virt`): the `minstret` counter (instructions retired, 64 bits) is read
//! directly: one tick is one instruction, exactly (QEMU derives it from `-icount`).

use core::hint::black_box;
use core::sync::atomic::{Ordering, compiler_fence};

pub use counter::{Calibration, now, per_tick, start};

#[cfg(target_arch = "arm")]
mod counter {
    use portable_atomic::{AtomicU32, Ordering};

    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m::peripheral::{SCB, SYST};
    use cortex_m_rt::exception;

    const RELOAD: u32 = 0x00FF_FFFF;

    /// Completed SysTick periods (the counter reached zero), counted by the exception.
    static WRAPS: AtomicU32 = AtomicU32::new(0);
    /// Instructions (QEMU -icount) or cycles (hardware) per SysTick tick, from `init`.
    static PER_TICK: AtomicU32 = AtomicU32::new(1);

    #[exception]
    fn SysTick() {
        WRAPS.fetch_add(1, Ordering::Relaxed);
    }

    /// The calibration loop runs `2 * CALIBRATION_LOOPS` instructions (`subs` + `bne`).
    const CALIBRATION_LOOPS: u32 = 100_000;

    /// What `init` found.
    pub struct Calibration {
        /// Instructions the calibration loop ran.
        pub instructions: u32,
        /// SysTick ticks it took.
        pub ticks: u32,
        /// Instructions per tick, rounded.
        pub per_tick: u32,
    }

    /// Board start-up shared by every binary: takes the core peripherals, starts and calibrates
    /// SysTick with `init` and logs the calibration. Exits with failure if the peripherals were
    /// already taken.
    pub fn start() -> Calibration {
        let Some(cp) = cortex_m::Peripherals::take() else {
            defmt::error!("core peripherals already taken");
            crate::board::exit_failure()
        };
        let cal = init(cp.SYST);
        defmt::info!(
            "SysTick calibrated: {=u32} instructions in {=u32} ticks, 1 tick = {=u32} instructions",
            cal.instructions,
            cal.ticks,
            cal.per_tick
        );
        cal
    }

    /// Starts SysTick as a free-running counter from the core clock and calibrates it.
    pub fn init(mut syst: SYST) -> Calibration {
        syst.disable_counter();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();

        let instructions = 2 * CALIBRATION_LOOPS;
        let start = now();
        spin(CALIBRATION_LOOPS);
        let ticks = (now() - start).max(1);
        let per_tick = ((u64::from(instructions) + ticks / 2) / ticks).max(1);
        let per_tick = u32::try_from(per_tick).unwrap_or(u32::MAX);
        PER_TICK.store(per_tick, Ordering::Relaxed);
        Calibration {
            instructions,
            ticks: u32::try_from(ticks).unwrap_or(u32::MAX),
            per_tick,
        }
    }

    /// Runs `2 * n` instructions (`n >= 1`): a `subs`/`bne` loop the compiler cannot change.
    #[inline(never)]
    fn spin(n: u32) {
        // SAFETY: register-only loop; touches no memory and no stack.
        unsafe {
            core::arch::asm!(
                "2:",
                "subs {n}, #1",
                "bne 2b",
                n = inout(reg) n => _,
                options(nomem, nostack),
            );
        }
    }

    /// SysTick ticks since `init`, across wraps.
    pub fn now() -> u64 {
        cortex_m::interrupt::free(|_| {
            // With interrupts off, WRAPS cannot change under us; a wrap that happened since they
            // were turned off shows as a pending SysTick exception instead.
            let mut wraps = WRAPS.load(Ordering::Relaxed);
            let mut value = SYST::get_current();
            if SCB::is_pendst_pending() {
                // The counter reached zero before the pending bit was read: count that wrap, and
                // read the value again so that it is from after the wrap too.
                wraps += 1;
                value = SYST::get_current();
            }
            // The counter reaches 0 at the end of each period (when the wrap is counted) and
            // reloads one tick later, so ticks into the current period are (2^24 - value) mod 2^24.
            (u64::from(wraps) << 24) + u64::from((RELOAD + 1 - value) & RELOAD)
        })
    }

    /// Instructions (on QEMU with `-icount`) per tick, as calibrated by `init`.
    pub fn per_tick() -> u32 {
        PER_TICK.load(Ordering::Relaxed)
    }
}

#[cfg(target_arch = "riscv32")]
mod counter {
    /// What [`start`] found: on RISC-V the counter is read directly, one tick an instruction.
    pub struct Calibration {
        pub per_tick: u32,
    }

    /// Board start-up shared by every binary: paints the stack (riscv-rt does not) and logs the
    /// counter used.
    pub fn start() -> Calibration {
        crate::board::paint_stack();
        defmt::info!("instruction counter: minstret, 1 tick = 1 instruction");
        Calibration { per_tick: 1 }
    }

    /// Instructions retired since reset (costs are differences of two readings).
    pub fn now() -> u64 {
        riscv::register::minstret::read64()
    }

    /// One instruction a tick.
    pub fn per_tick() -> u32 {
        1
    }
}

/// Runs `f` and returns its result with its cost in instructions (on QEMU `-icount`; core
/// cycles on hardware), to within one tick ([`per_tick`] instructions). Saturates at
/// `u32::MAX`.
///
/// Pass inputs through [`black_box`] so that the compiler cannot compute them ahead of the
/// measurement.
pub fn measure<R>(f: impl FnOnce() -> R) -> (R, u32) {
    let start = now();
    compiler_fence(Ordering::SeqCst);
    let r = f();
    // The result must exist before the second reading.
    black_box(&r);
    compiler_fence(Ordering::SeqCst);
    let ticks = now() - start;
    let cost = ticks.saturating_mul(u64::from(per_tick()));
    (r, u32::try_from(cost).unwrap_or(u32::MAX))
}

/// A fixed-capacity table of per-stage costs, logged at the end of a run.
pub struct CostTable<const N: usize> {
    rows: [Row; N],
    len: usize,
}

#[derive(Clone, Copy)]
struct Row {
    stage: &'static str,
    instructions: u32,
    items: u32,
}

impl<const N: usize> Default for CostTable<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> CostTable<N> {
    /// An empty table.
    pub const fn new() -> Self {
        Self {
            rows: [Row {
                stage: "",
                instructions: 0,
                items: 0,
            }; N],
            len: 0,
        }
    }

    /// Records a stage that handled `items` items (points, pixels, ...) for `instructions`.
    /// A row past the capacity is dropped with a warning.
    pub fn record(&mut self, stage: &'static str, instructions: u32, items: u32) {
        match self.rows.get_mut(self.len) {
            Some(row) => {
                *row = Row {
                    stage,
                    instructions,
                    items,
                };
                self.len += 1;
            }
            None => defmt::warn!("cost table full, `{=str}` dropped", stage),
        }
    }

    pub fn log(&self) {
        defmt::info!("cost per stage (instructions, +-{=u32}):", per_tick());
        for row in self.rows.iter().take(self.len) {
            defmt::info!(
                "  {=str}: {=u32} instructions, {=u32} per item ({=u32} items)",
                row.stage,
                row.instructions,
                row.instructions / row.items.max(1),
                row.items
            );
        }
    }
}
