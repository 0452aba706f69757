//! The fault job: the main job on the Cortex-M7 with a faulty virtual camera.
//!
//! The board reads a fault plan (`faults.bin`) beside the run and its camera
//! (`camgeom_fw_app::recorded::RecordedCamera`, the same code the host replay runs) delivers
//! black, white, noise, repeated, dropped, torn, wrongly sized and failed frames on the
//! planned frames. The board must report every frame (its state, or the typed error the frame
//! met), agree with the host replay bit for bit as in the main job, and find the target again
//! after every fault.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use anyhow::{Result, bail, ensure};
use camgeom::target::TargetState;
use camgeom_fw_app::recorded::{Fault, FaultPlan, FaultSpan};
use camgeom_fw_app::report::FrameRecord;

/// Frames a target may take to come back after a fault ends before the job fails.
pub const MAX_REACQUIRE: u32 = 10;

/// The plan the fault job runs on the 150-frame box sequence: every kind of fault, each after
/// the target has been tracked again for a while, and a long outage at the end.
pub fn plan() -> Result<FaultPlan> {
    let span = |first, frames, fault, param| FaultSpan {
        first,
        frames,
        fault,
        param,
    };
    Ok(FaultPlan::new(&[
        span(20, 3, Fault::Black, 0),
        span(35, 2, Fault::White, 0),
        span(50, 2, Fault::Noise, 0x5eed),
        span(62, 2, Fault::Repeat, 0),
        span(72, 1, Fault::Drop, 3),
        span(82, 1, Fault::Torn, 0),
        span(92, 1, Fault::WrongSize, 0),
        span(102, 1, Fault::ReadError, 0),
        span(112, 10, Fault::Black, 0),
    ])?)
}

fn good(r: &FrameRecord) -> bool {
    r.error.is_none() && r.state == TargetState::Tracking
}

/// One row of the fault table.
pub struct Row {
    span: FaultSpan,
    /// Frames from the fault's first to the first tracking frame after it, not tracking.
    lost: u32,
    /// Frames after the fault's last until tracking again.
    reacquire: u32,
    /// The errors the faulty frames reported, by name.
    errors: Vec<&'static str>,
    /// The states the faulty frames ended in.
    states: Vec<&'static str>,
}

/// Checks the records of a fault run against `plan` and returns the fault table: every
/// delivered frame reported, every fault survived, the target found again within
/// [`MAX_REACQUIRE`] frames of every fault's end.
pub fn check(
    plan: &FaultPlan,
    records: &BTreeMap<u32, FrameRecord>,
    count: usize,
) -> Result<Vec<Row>> {
    ensure!(
        records.keys().copied().eq(0..count as u32),
        "the board did not report every frame: {} records for {count} frames",
        records.len()
    );
    let mut rows = Vec::new();
    for s in plan.spans() {
        let end = s.first + s.frames;
        let Some(back) = (end..count as u32).find(|k| records.get(k).is_some_and(good)) else {
            bail!(
                "after the {} frames {}..{end}, the target was never found again",
                s.fault.name(),
                s.first
            );
        };
        let reacquire = back - end;
        ensure!(
            reacquire <= MAX_REACQUIRE,
            "after the {} frames {}..{end}, the target took {reacquire} frames to come back",
            s.fault.name(),
            s.first
        );
        let hit: Vec<&FrameRecord> = (s.first..end).filter_map(|k| records.get(&k)).collect();
        let lost = (s.first..back)
            .filter(|k| !records.get(k).is_some_and(good))
            .count() as u32;
        let mut errors: Vec<&'static str> = hit
            .iter()
            .filter_map(|r| r.error.map(|e| e.name()))
            .collect();
        errors.dedup();
        let mut states: Vec<&'static str> = hit
            .iter()
            .filter(|r| r.error.is_none())
            .map(|r| r.state.name())
            .collect();
        states.dedup();
        rows.push(Row {
            span: *s,
            lost,
            reacquire,
            errors,
            states,
        });
    }
    Ok(rows)
}

/// The fault table in Markdown.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| fault | delivered frames | reported | frames not tracking | frames to re-acquire after it |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        let what = match r.span.fault {
            Fault::Drop => format!("drop ({} recorded frames skipped)", r.span.param),
            f => f.name().replace('_', " "),
        };
        let mut reported: Vec<String> = r.states.iter().map(|s| s.to_string()).collect();
        reported.extend(r.errors.iter().map(|e| format!("error `{e}`")));
        let _ = writeln!(
            s,
            "| {what} | {}..{} | {} | {} | {} |",
            r.span.first,
            r.span.first + r.span.frames - 1,
            reported.join(", "),
            r.lost,
            r.reacquire
        );
    }
    s
}
