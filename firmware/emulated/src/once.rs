//! [`Once`]: a static handed out once as `&'static mut`, for the buffers of the binaries (the
//! main job's pipeline, the bench and stack inputs): placed by the linker from a `const`
//! initial value, never built on the stack.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

use crate::board;

/// A static handed out once as `&'static mut` (its `const` value is placed by the linker, in
/// `.bss` when all zeros, and never built on the stack). A second [`take`](Self::take) logs an
/// error and fails the run.
pub struct Once<T> {
    taken: AtomicBool,
    v: UnsafeCell<T>,
}
// SAFETY: the value is only reached through `take`, which hands it out at most once.
unsafe impl<T: Send> Sync for Once<T> {}
impl<T> Once<T> {
    pub const fn new(v: T) -> Self {
        Self {
            taken: AtomicBool::new(false),
            v: UnsafeCell::new(v),
        }
    }
    // Sound: the flag hands the value out at most once, so the `&mut` is unique.
    #[allow(clippy::mut_from_ref)]
    pub fn take(&'static self) -> &'static mut T {
        if self.taken.swap(true, Ordering::AcqRel) {
            defmt::error!("static buffer taken twice");
            board::exit_failure()
        }
        // SAFETY: first and only take: no other reference exists.
        unsafe { &mut *self.v.get() }
    }
}
