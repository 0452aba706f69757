//! What a frame cost, stage by stage: [`Cost`] names the stages of the board's frame loop
//! (capture, pyramid, every stage of the core's [`Stage`], drawing) and [`StageCosts`] is an
//! array indexed by it, with the total.
//!
//! A new stage of the core's loop is one variant of [`Stage`] (and the probe call that reports
//! it): its cost slot, its name in the tables and its place on the wire
//! ([`crate::report`]) follow from [`Stage::ALL`]. A new stage of the board's own loop is one
//! variant here.

use core::ops::{Index, IndexMut};

use camgeom::probe::StageProbe;
use camgeom::target::Stage;

/// A stage of the board's frame loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cost {
    /// Reading the frame from the source (not part of the total: a camera's DMA does it).
    Capture,
    /// The pyramid of the new frame.
    Pyramid,
    /// A stage of the core's per-frame loop ([`camgeom::target::PlanarTarget::step`]).
    Step(Stage),
    /// Drawing the previous frame's overlay.
    Draw,
}

impl Cost {
    /// Stages, the core's included.
    pub const COUNT: usize = 3 + Stage::ALL.len();

    /// Columns of a cost table: every stage, then the total.
    pub const COLUMNS: usize = Self::COUNT + 1;

    /// Every stage in table order: capture, pyramid, the core's stages in [`Stage::ALL`]
    /// order, draw.
    pub const ALL: [Cost; Self::COUNT] = {
        let mut all = [Cost::Capture; Self::COUNT];
        all[1] = Cost::Pyramid;
        let mut i = 0;
        while i < Stage::ALL.len() {
            all[2 + i] = Cost::Step(Stage::ALL[i]);
            i += 1;
        }
        all[Self::COUNT - 1] = Cost::Draw;
        all
    };

    /// Its place in [`Self::ALL`].
    pub const fn index(self) -> usize {
        match self {
            Cost::Capture => 0,
            Cost::Pyramid => 1,
            Cost::Step(s) => 2 + s.index(),
            Cost::Draw => Self::COUNT - 1,
        }
    }

    /// Its name in tables (the core stage's own name for [`Cost::Step`]).
    pub const fn name(self) -> &'static str {
        match self {
            Cost::Capture => "capture",
            Cost::Pyramid => "pyramid",
            Cost::Step(s) => s.name(),
            Cost::Draw => "draw",
        }
    }
}

/// The column names of a cost table: the stages in [`Cost::ALL`] order, then `total`.
pub const STAGES: [&str; Cost::COLUMNS] = {
    let mut names = ["total"; Cost::COLUMNS];
    let mut i = 0;
    while i < Cost::COUNT {
        names[i] = Cost::ALL[i].name();
        i += 1;
    }
    names
};

/// The board's clock: a monotonic count in its own unit (cycles on hardware, instructions on
/// QEMU with `-icount`). Differences are what the cost record holds.
pub trait Clock {
    /// The count now.
    fn now(&mut self) -> u64;
}

/// A clock that always reads 0 (every cost 0): for replays where only the results matter.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn now(&mut self) -> u64 {
        0
    }
}

/// What one frame cost, in the [`Clock`]'s unit (saturating at
/// `u32::MAX`), per [`Cost`] (`costs[Cost::Pyramid]`); a stage that did not run costs 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StageCosts {
    stages: [u32; Cost::COUNT],
    /// Pyramid to draw: everything but the capture.
    pub total: u32,
}

impl Index<Cost> for StageCosts {
    type Output = u32;

    fn index(&self, c: Cost) -> &u32 {
        // `Cost::index` is below `COUNT` for every stage: the fallback is never taken.
        self.stages.get(c.index()).unwrap_or(&self.total)
    }
}

impl IndexMut<Cost> for StageCosts {
    fn index_mut(&mut self, c: Cost) -> &mut u32 {
        // As above: the fallback is never taken.
        match self.stages.get_mut(c.index()) {
            Some(slot) => slot,
            None => &mut self.total,
        }
    }
}

impl StageCosts {
    /// The costs in the order of [`STAGES`] (the total last).
    pub fn to_array(&self) -> [u32; Cost::COLUMNS] {
        let mut a = [self.total; Cost::COLUMNS];
        a.iter_mut()
            .zip(self.stages)
            .for_each(|(slot, c)| *slot = c);
        a
    }

    /// The inverse of [`Self::to_array`].
    pub fn from_array(a: [u32; Cost::COLUMNS]) -> Self {
        let mut stages = [0; Cost::COUNT];
        stages.iter_mut().zip(a).for_each(|(slot, c)| *slot = c);
        let [.., total] = a;
        Self { stages, total }
    }

    /// Adds `d` to stage `c`, saturating.
    pub fn add(&mut self, c: Cost, d: u32) {
        self[c] = self[c].saturating_add(d);
    }
}

/// `to - from` as a cost (saturating at `u32::MAX`, 0 for a clock that went back).
pub fn span(from: u64, to: u64) -> u32 {
    u32::try_from(to.saturating_sub(from)).unwrap_or(u32::MAX)
}

/// Attributes the time between the core's stage reports to the stages of a [`StageCosts`].
pub struct Probe<'a, C: Clock> {
    /// The board's clock.
    pub clock: &'a mut C,
    /// The clock when the last stage ended.
    pub last: u64,
    /// Where the costs go.
    pub costs: &'a mut StageCosts,
}

impl<C: Clock> StageProbe<Stage> for Probe<'_, C> {
    fn stage_done(&mut self, stage: Stage) {
        let now = self.clock.now();
        self.costs.add(Cost::Step(stage), span(self.last, now));
        self.last = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stage_has_its_own_slot_and_name() {
        for (i, c) in Cost::ALL.iter().enumerate() {
            assert_eq!(c.index(), i);
            assert_eq!(STAGES[i], c.name());
        }
        assert_eq!(STAGES[Cost::COUNT], "total");
        let mut names = STAGES.to_vec();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Cost::COLUMNS, "{STAGES:?}");
    }

    #[test]
    fn costs_round_trip_through_the_array() {
        let mut c = StageCosts::default();
        for (k, s) in Cost::ALL.into_iter().enumerate() {
            c.add(s, k as u32 * 10 + 1);
        }
        c.total = 99;
        c.add(Cost::Draw, u32::MAX);
        assert_eq!(c[Cost::Draw], u32::MAX);
        assert_eq!(StageCosts::from_array(c.to_array()), c);
        assert_eq!(c.to_array()[Cost::COUNT], 99);
        assert_eq!(
            c[Cost::Step(Stage::Flow)],
            Cost::Step(Stage::Flow).index() as u32 * 10 + 1
        );
    }
}
