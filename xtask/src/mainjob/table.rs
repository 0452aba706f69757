//! The main job's per-stage cost table, in Markdown (BENCHMARKS.md takes it verbatim).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use camgeom::target::TargetState;
use camgeom_fw_app::costs::STAGES;
use camgeom_fw_app::report::{FrameRecord, SummaryRecord};

use crate::jobs::{Board, M7, Size};

/// One row of the table: a board's run at a frame size.
pub struct Row {
    pub board: Board,
    pub size: Size,
    pub frames: usize,
    pub tracking: usize,
    /// Mean and worst per stage over the frames after the first, in [`STAGES`] order.
    pub mean: [u64; STAGES.len()],
    pub worst: [u32; STAGES.len()],
    pub flash: u64,
    pub ram: u64,
    pub pipeline_ram: u64,
    pub stack: u64,
}

impl Row {
    /// The row of a board run's records (`flash` and `ram` from its ELF).
    pub fn new(
        board: Board,
        size: Size,
        frames: &BTreeMap<u32, FrameRecord>,
        summary: &SummaryRecord,
        flash: u64,
        ram: u64,
    ) -> Self {
        // Frame 0 only acquires the target: the table is over the tracked frames after it.
        let stepped: Vec<&FrameRecord> = frames.values().filter(|r| r.index > 0).collect();
        let n = stepped.len().max(1) as u64;
        let mut mean = [0u64; STAGES.len()];
        let mut worst = [0u32; STAGES.len()];
        for r in &stepped {
            for (k, c) in r.costs.to_array().into_iter().enumerate() {
                mean[k] += u64::from(c);
                worst[k] = worst[k].max(c);
            }
        }
        for m in &mut mean {
            *m /= n;
        }
        Self {
            board,
            size,
            frames: frames.len(),
            tracking: frames
                .values()
                .filter(|r| r.state == TargetState::Tracking)
                .count(),
            mean,
            worst,
            flash,
            ram,
            pipeline_ram: u64::from(summary.pipeline_ram),
            stack: u64::from(summary.stack_used),
        }
    }

    /// Mean and worst of one stage.
    pub fn stage(&self, name: &str) -> (u64, u32) {
        let k = STAGES.iter().position(|s| *s == name).unwrap_or(0);
        (self.mean[k], self.worst[k])
    }

    /// Mean instructions a frame, every stage but the capture.
    pub fn mean_total(&self) -> u64 {
        self.stage("total").0
    }
}

pub fn m(v: u64) -> String {
    format!("{:.2}M", v as f64 / 1e6)
}

/// The tables in Markdown: the per-stage costs of every board and size (with each board's
/// ratio to the Cortex-M7 at the same size), then memory.
pub fn table(rows: &[Row], stride: u32) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Instructions per frame (QEMU `-icount shift=0`; SysTick on Arm, ±40; `minstret` on \
         RISC-V, exact), mean / worst over the frames after the first{}:\n",
        if stride > 1 {
            format!(" (every {stride}th recorded frame)")
        } else {
            String::new()
        }
    );
    let shown = [
        "pyramid",
        "acquire",
        "flow",
        "homography",
        "pose",
        "redetect",
        "draw",
        "total",
    ];
    let _ = writeln!(
        s,
        "| board (core) | frame | frames (tracking) | {} | total / M7 |",
        shown.join(" | ")
    );
    let _ = writeln!(s, "|---|---|---|{}---|", "---|".repeat(shown.len()));
    for r in rows {
        let cells: Vec<String> = shown
            .iter()
            .map(|name| {
                let (mean, worst) = r.stage(name);
                format!("{} / {}", m(mean), m(u64::from(worst)))
            })
            .collect();
        let reference = rows
            .iter()
            .find(|x| x.board == M7 && x.size == r.size)
            .map(Row::mean_total);
        let ratio = reference.map_or("-".to_string(), |m7| {
            format!("{:.2}x", r.mean_total() as f64 / m7.max(1) as f64)
        });
        let _ = writeln!(
            s,
            "| {} ({}) | {} | {} ({}) | {} | {ratio} |",
            r.board.name,
            r.board.core,
            r.size.name(),
            r.frames,
            r.tracking,
            cells.join(" | ")
        );
    }
    let _ = writeln!(
        s,
        "\n| board (memory capped to) | frame | flash | static RAM (of which the pipeline) | stack high-water | est. fps on the M7 at 480 MHz |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for r in rows {
        let fps = if r.board == M7 {
            format!("{:.1}", 480e6 / r.mean_total().max(1) as f64)
        } else {
            "-".to_string()
        };
        let _ = writeln!(
            s,
            "| {} ({}) | {} | {} B | {} B ({} B) | {} B | {fps} |",
            r.board.name,
            r.board.class,
            r.size.name(),
            r.flash,
            r.ram,
            r.pipeline_ram,
            r.stack
        );
    }
    s
}
