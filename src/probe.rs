//! Stage probes: a pipeline tells its caller as each of its stages ends, so that a board can
//! read its cycle counter there and attribute the time since the previous call to that stage.
//!
//! Each pipeline names its own stages (an enum `S`: [`crate::apriltag::Stage`],
//! [`crate::target::Stage`]) and takes any `StageProbe<S>`; `()` is the probe that does
//! nothing, which costs nothing once inlined.
//!
//! ```
//! use camgeom::probe::StageProbe;
//!
//! #[derive(Debug, Clone, Copy, PartialEq)]
//! enum Stage {
//!     Load,
//!     Solve,
//! }
//!
//! /// Counts the stages a run reports.
//! #[derive(Default)]
//! struct Count(usize);
//!
//! impl StageProbe<Stage> for Count {
//!     fn stage_done(&mut self, _stage: Stage) {
//!         self.0 += 1;
//!     }
//! }
//!
//! fn run(probe: &mut impl StageProbe<Stage>) {
//!     probe.stage_done(Stage::Load);
//!     probe.stage_done(Stage::Solve);
//! }
//!
//! let mut count = Count::default();
//! run(&mut count);
//! run(&mut ());
//! assert_eq!(count.0, 2);
//! ```

/// Told when a stage `S` of a pipeline ends: the time since the previous call (or since the
/// pipeline started) belongs to `stage`. A stage may be reported more than once in a run
/// (per-item stages repeat, interleaved); a stage that does not run is not reported. `()`
/// does nothing.
pub trait StageProbe<S> {
    /// `stage` has just finished.
    fn stage_done(&mut self, stage: S);
}

impl<S> StageProbe<S> for () {
    #[inline]
    fn stage_done(&mut self, _stage: S) {}
}
