//! The tag job: the second main job on the Cortex-M7, the AR loop on an AprilTag.
//!
//! The rendered tag sequence (`host-tests/data/sequences/tag/`: 160 frames at 320x240 of a
//! printed tag36h11, id 42, 8 cm, moving in front of a photo, with motion blur, noise, an
//! exposure drop, an occlusion, and the tag leaving the view and coming back; exact poses in
//! `truth.csv`) goes through `camgeom-fw-tag`: the tag detector acquires the target
//! (`camgeom::apriltag::TagTarget`) and tracks it by detecting it where it must be (the
//! predicted quad's edges refined and decoded, else a detection in the region around it); a
//! full detection runs when that fails, after a loss and every [`REACQUIRE_EVERY`] frames as a
//! guard. The host replays it bit for bit as the box job; the poses are compared with the
//! truth, and one summary line (`tag job: ...`, [`summary`]) gives the figures checks read.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, ensure};
use camgeom::camera::Lens;
use camgeom::nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use camgeom::target::{Stage, TargetState};
use camgeom_fw_app::costs::{Cost, STAGES};
use camgeom_fw_app::recorded::FaultPlan;
use camgeom_fw_app::report::FrameRecord;
use camgeom_fw_app::run::{Acquisition, RunSpec};
use camgeom_host::images::load_gray;
use camgeom_host::load_camera;
use camgeom_host::points::format_csv;

use super::{compare, emulate, live, replay, stream};
use crate::firmware::{build_bin_for, size_of};
use crate::jobs::{M7, Size};
use crate::util::root;

/// The tag's black square (the sequence's README: 8 cm).
const TAG_SIZE_M: f32 = 0.08;
/// The sequence's tag.
const TAG_ID: u16 = 42;
/// While tracking, a full detection runs every this many frames as a guard (the tracking by
/// detection confirms the tag's code on every frame, so the guard is rare).
pub const REACQUIRE_EVERY: u32 = 30;

pub const SIZE: Size = Size {
    width: 320,
    height: 240,
    bin: "camgeom-fw-tag",
};

fn sequence() -> PathBuf {
    camgeom_host::data_dir().join("sequences/tag")
}

fn prepare(dir: &Path) -> Result<RunSpec> {
    fs::create_dir_all(dir)?;
    let seq = sequence();
    let mut names: Vec<PathBuf> = fs::read_dir(&seq)
        .with_context(|| format!("cannot read {}", seq.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    let mut raw = Vec::new();
    for n in &names {
        let img = load_gray(n)?;
        ensure!(
            (img.width, img.height) == (320, 240),
            "{}: not 320x240",
            n.display()
        );
        raw.extend_from_slice(&img.data);
    }
    fs::write(dir.join("frames.raw"), &raw)?;
    let cam = load_camera(seq.join("camera.yml"))?.camera_f32();
    let k = &cam.intrinsics;
    let Lens::BrownConrady(d) = cam.lens else {
        anyhow::bail!("{}: the board takes a Brown-Conrady camera", seq.display());
    };
    let spec = RunSpec {
        width: 320,
        height: 240,
        frames: names.len() as u32,
        stride: 1,
        overlay_every: 16,
        intrinsics: [k.fx(), k.fy(), k.cx(), k.cy()],
        distortion: d.to_opencv(),
        target_size: [TAG_SIZE_M; 2],
        corners: [[0.0; 2]; 4],
        acquisition: Acquisition::Tag {
            family: 0,
            id: TAG_ID,
        },
        reacquire_every: REACQUIRE_EVERY,
        forward_backward: false,
    };
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    Ok(spec)
}

/// A pose as the truth gives it: `R` and `t` (`X_cam = R X_tag + t`, AprilTag's tag frame).
type TruePose = (Matrix3<f64>, Vector3<f64>);

/// The columns of `truth.csv` the job reads (the file has more: the tag's corners, ...).
#[derive(serde::Deserialize)]
struct TruthRow {
    frame: u32,
    r11: f64,
    r12: f64,
    r13: f64,
    r21: f64,
    r22: f64,
    r23: f64,
    r31: f64,
    r32: f64,
    r33: f64,
    tx: f64,
    ty: f64,
    tz: f64,
}

/// Per frame of the truth, its pose.
fn truth() -> Result<BTreeMap<u32, TruePose>> {
    let path = sequence().join("truth.csv");
    let mut reader =
        csv::Reader::from_path(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut out = BTreeMap::new();
    for row in reader.deserialize() {
        let r: TruthRow = row.with_context(|| format!("{}: bad row", path.display()))?;
        let m = Matrix3::new(
            r.r11, r.r12, r.r13, r.r21, r.r22, r.r23, r.r31, r.r32, r.r33,
        );
        out.insert(r.frame, (m, Vector3::new(r.tx, r.ty, r.tz)));
    }
    Ok(out)
}

/// Rotation (degrees) and translation (mm) errors of the tracked poses against the truth: the
/// target's frame is the tag's with its origin at the tag's top-left outer corner, so
/// `t_tag = t + R (s/2, s/2, 0)`.
fn pose_errors(records: &BTreeMap<u32, FrameRecord>) -> Result<BTreeMap<u32, (f64, f64)>> {
    let truth = truth()?;
    let mut out = BTreeMap::new();
    for (k, r) in records {
        let (Some((best, _)), Some((rt, tt))) = (r.pose, truth.get(k)) else {
            continue;
        };
        let rv = Vector3::new(best.r[0], best.r[1], best.r[2]).cast::<f64>();
        let rot = Rotation3::new(rv);
        let half = f64::from(TAG_SIZE_M) / 2.0;
        let t = Vector3::new(best.t[0], best.t[1], best.t[2]).cast::<f64>()
            + rot * Vector3::new(half, half, 0.0);
        let qt = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*rt));
        let dr = (UnitQuaternion::from_rotation_matrix(&rot) * qt.inverse())
            .angle()
            .to_degrees();
        out.insert(*k, (dr, (t - tt).norm() * 1e3));
    }
    Ok(out)
}

/// The columns of `frames.csv`.
const FRAMES_COLUMNS: [&str; 15] = [
    "frame",
    "state",
    "acquired",
    "partial",
    "tracked",
    "inliers",
    "features",
    "acquire",
    "flow",
    "homography",
    "pose",
    "redetect",
    "total",
    "rotation_deg",
    "translation_mm",
];

/// One row a frame: what the board did and cost, and its pose error against the truth
/// (`frames.csv` beside the run, for plots and for finding the frames worth a look).
fn write_frames_csv(
    path: &Path,
    frames: &BTreeMap<u32, FrameRecord>,
    errors: &BTreeMap<u32, (f64, f64)>,
) -> Result<()> {
    let rows = frames.iter().map(|(k, r)| {
        let c = &r.costs;
        let (dr, dt) = errors
            .get(k)
            .map_or((String::new(), String::new()), |(a, b)| {
                (format!("{a:.4}"), format!("{b:.3}"))
            });
        let counts = [
            u32::from(r.acquired),
            u32::from(r.partial),
            u32::from(r.tracked),
            u32::from(r.inliers),
            u32::from(r.features),
            c[Cost::Step(Stage::Acquire)],
            c[Cost::Step(Stage::Flow)],
            c[Cost::Step(Stage::Homography)],
            c[Cost::Step(Stage::Pose)],
            c[Cost::Step(Stage::Redetect)],
            c.total,
        ];
        [k.to_string(), format!("{:?}", r.state)]
            .into_iter()
            .chain(counts.map(|n| n.to_string()))
            .chain([dr, dt])
    });
    let s = format_csv(&FRAMES_COLUMNS, rows);
    fs::write(path, s).with_context(|| format!("cannot write {}", path.display()))
}

/// The line `cargo xtask run` prints for the tag job (checks read it): frames with a pose,
/// rotation error median / p95 / max, mean and worst instructions a frame (the loop's total),
/// and the mean and worst cost of a full detection (the acquisition stage of the frames that
/// ran only a full detection: those after a frame without the target).
fn summary(frames: &BTreeMap<u32, FrameRecord>, errors: &BTreeMap<u32, (f64, f64)>) -> String {
    let mut dr: Vec<f64> = errors.values().map(|e| e.0).collect();
    let totals: Vec<u64> = frames.values().map(|r| u64::from(r.costs.total)).collect();
    let n = totals.len().max(1) as f64;
    let mean = totals.iter().sum::<u64>() as f64 / n;
    let worst = totals.iter().copied().max().unwrap_or(0);
    let mut prev = TargetState::Uninitialised;
    let mut full = Vec::new();
    for r in frames.values() {
        if prev != TargetState::Tracking {
            full.push(u64::from(r.costs[Cost::Step(Stage::Acquire)]));
        }
        prev = r.state;
    }
    let fm = full.iter().sum::<u64>() as f64 / full.len().max(1) as f64;
    let fw = full.iter().copied().max().unwrap_or(0);
    format!(
        "tag job: {} of {} frames with a pose; rotation error {:.3}/{:.3}/{:.3} deg; {:.2} M instructions a frame (worst {:.2} M); full detection {:.2} M (worst {:.2} M)",
        dr.len(),
        frames.len(),
        quantile(&mut dr, 0.5),
        quantile(&mut dr, 0.95),
        quantile(&mut dr, 1.0),
        mean / 1e6,
        worst as f64 / 1e6,
        fm / 1e6,
        fw as f64 / 1e6
    )
}

fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(((v.len().max(1) - 1) as f64 * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// `cargo xtask run`'s tag job on the reference board; returns its Markdown tables.
pub fn run(stride: u32) -> Result<String> {
    let dir = root().join("target/camgeom-run/tag");
    let spec = prepare(&dir)?;
    let raw = fs::read(dir.join("frames.raw"))?;
    let host = replay::replay_size(SIZE, &spec, &FaultPlan::none(), &raw)?;
    let elf = build_bin_for(M7, SIZE.bin, &[])?;
    let (flash, ram, _) = size_of(M7, &elf)?;
    // UART0 live to the monitors through the link harness, which saves it as serial.bin.
    let _ = fs::remove_file(dir.join("serial.bin"));
    let harness = live::Harness::start(dir.join("serial.bin"))?;
    let board = emulate::run_board_with(M7, &elf, &dir, Some(harness.addr()), SIZE, stride)?;
    let live = harness.finish()?;
    let verdict = compare::compare(&board.frames, &host.0, &board.overlays, &host.1)?;
    let link = stream::check(&dir, &board.log, spec.target_size, &live)?;
    let frames = &board.frames;
    ensure!(
        frames.values().all(|r| r.error.is_none()),
        "the tag job reported an error on a frame"
    );
    // The tag leaves the view (frames 104..130) and comes back: it must be found again.
    let back = frames
        .values()
        .filter(|r| r.index > 130 && r.state == TargetState::Tracking)
        .count();
    ensure!(
        back >= 20,
        "the tag was not found again after leaving the view ({back} frames)"
    );
    let errors = pose_errors(frames)?;
    write_frames_csv(&dir.join("frames.csv"), frames, &errors)?;
    let (mut dr, mut dt): (Vec<f64>, Vec<f64>) = errors.values().copied().unzip();
    println!(
        "tag job {} 320x240: {verdict}; {} of {} frames with a pose",
        M7.name,
        dr.len(),
        frames.len()
    );
    println!("{}", summary(frames, &errors));
    let partial: Vec<String> = frames
        .values()
        .filter(|r| r.partial && r.state == TargetState::Tracking)
        .map(|r| r.index.to_string())
        .collect();
    println!(
        "tag job: {} of the frames with a pose from a partly seen tag ({})",
        partial.len(),
        partial.join(" ")
    );
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| frames | stage | {} |\n|---|---|{}",
        STAGES[1..].join(" | "),
        "---|".repeat(STAGES.len() - 1)
    );
    // Frame kinds: found by a full detection (acquired), found where it must be (4 corners
    // tracked) wholly or partly seen, tracked by KLT (other tracked frames), lost.
    let kind = |r: &FrameRecord| match (r.acquired, r.state, r.tracked) {
        (true, _, _) => 0,
        (false, TargetState::Tracking, 4) if r.features == 0 && !r.partial => 1,
        (false, TargetState::Tracking, 4) if r.features == 0 => 2,
        (false, TargetState::Tracking, _) => 3,
        _ => 4,
    };
    for (name, k) in [
        ("full detection", 0),
        ("tracked by detection", 1),
        ("tracked by detection, partly seen", 2),
        ("tracked by KLT", 3),
        ("lost (full detection)", 4),
    ] {
        let rows: Vec<&FrameRecord> = frames.values().filter(|r| kind(r) == k).collect();
        if rows.is_empty() {
            continue;
        }
        let n = rows.len().max(1) as u64;
        let cells: Vec<String> = (1..STAGES.len())
            .map(|k| {
                let c: Vec<u64> = rows
                    .iter()
                    .map(|r| u64::from(r.costs.to_array()[k]))
                    .collect();
                let mean = c.iter().sum::<u64>() / n;
                let worst = c.iter().copied().max().unwrap_or(0);
                format!("{:.2}M / {:.2}M", mean as f64 / 1e6, worst as f64 / 1e6)
            })
            .collect();
        let _ = writeln!(
            s,
            "| {name} ({}) | mean / worst | {} |",
            rows.len(),
            cells.join(" | ")
        );
    }
    let _ = writeln!(
        s,
        "\n| poses (of {} frames) | rotation error, median / p95 / max | translation error, median / p95 / max | static RAM | flash | stack |\n|---|---|---|---|---|---|\n| {} | {:.3}° / {:.3}° / {:.3}° | {:.2} / {:.2} / {:.2} mm | {ram} B | {flash} B | {} B |",
        frames.len(),
        dr.len(),
        quantile(&mut dr, 0.5),
        quantile(&mut dr, 0.95),
        quantile(&mut dr, 1.0),
        quantile(&mut dt, 0.5),
        quantile(&mut dt, 0.95),
        quantile(&mut dt, 1.0),
        board.summary.stack_used
    );
    let _ = write!(s, "\n{link}");
    Ok(s)
}
