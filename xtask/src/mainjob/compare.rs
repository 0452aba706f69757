//! The host-vs-board check: every frame's record and every overlay must agree.

use std::collections::BTreeMap;

use anyhow::{Result, bail};
use camgeom_fw_app::report::{FrameRecord, PoseRecord};

use super::emulate::Overlays;

/// Relative tolerance on the poses (translation and rotation vector, each component against
/// the vector's norm). Both builds do IEEE-754 binary32 arithmetic with round-to-nearest and
/// the same maths library: camgeom without `std` calls `libm` (Rust code, the same on both;
/// its square root is the correctly rounded instruction on each) and LLVM contracts no
/// `a * b + c` into a fused multiply-add without being asked. What differs is the code
/// generator (x86-64 SSE vs Armv7E-M FPv5, instruction selection and order of independent
/// operations) and debug assertions (on in the host build). So the poses are expected to be
/// bit-identical; the tolerance, 1e-5 (about 80 ulp), only keeps a future compiler that
/// contracts or reassociates from failing the run, while any real divergence (a different
/// inlier set moves the pose by 1e-3 or more) still fails it.
pub const POSE_TOLERANCE: f32 = 1e-5;

/// The largest relative difference of two poses, per component against the vector's norm.
fn pose_gap(a: &PoseRecord, b: &PoseRecord) -> f32 {
    let rel = |x: &[f32; 3], y: &[f32; 3]| {
        let n = x.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-6);
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs() / n)
            .fold(0.0f32, f32::max)
    };
    rel(&a.t, &b.t).max(rel(&a.r, &b.r))
}

fn bits(p: &PoseRecord) -> [u32; 7] {
    p.to_array().map(f32::to_bits)
}

/// What both sides must report identically: state, flags, counts, checksum, error.
fn counts(r: &FrameRecord) -> impl PartialEq + std::fmt::Debug {
    (
        r.state,
        r.acquired,
        r.partial,
        r.error.map(|e| e.name()),
        [r.tracked, r.inliers, r.added, r.features],
    )
}

/// Compares the board's records and overlays with the host replay's; returns a one-line
/// verdict, or every disagreement (the first 20) as the error.
pub fn compare(
    board: &BTreeMap<u32, FrameRecord>,
    host: &BTreeMap<u32, FrameRecord>,
    board_overlays: &Overlays,
    host_overlays: &Overlays,
) -> Result<String> {
    let mut problems = Vec::new();
    if board.len() != host.len() {
        problems.push(format!(
            "the board reported {} frames, the host ran {}",
            board.len(),
            host.len()
        ));
    }
    let (mut worst, mut bit_identical, mut poses) = (0.0f32, 0usize, 0usize);
    for (i, h) in host {
        let Some(b) = board.get(i) else {
            problems.push(format!("frame {i}: not in the board's report"));
            continue;
        };
        if counts(b) != counts(h) {
            problems.push(format!(
                "frame {i}: board {:?}, host {:?} (state, acquired, partial, error, tracked/inliers/added/features)",
                counts(b),
                counts(h)
            ));
        }
        if b.checksum != h.checksum {
            problems.push(format!(
                "frame {i}: Q16.16 track checksum board {:#010x}, host {:#010x}",
                b.checksum, h.checksum
            ));
        }
        if b.outline.is_some() != h.outline.is_some() {
            problems.push(format!("frame {i}: an outline on one side only"));
        }
        match (&b.pose, &h.pose) {
            (Some(p), Some(q)) => {
                for (x, y) in [(&p.0, &q.0), (&p.1, &q.1)] {
                    poses += 1;
                    let g = pose_gap(x, y);
                    worst = worst.max(g);
                    bit_identical += usize::from(bits(x) == bits(y));
                    if g > POSE_TOLERANCE {
                        problems.push(format!(
                            "frame {i}: pose differs by {g:e} (relative): board {x:?}, host {y:?}"
                        ));
                    }
                }
            }
            (None, None) => {}
            _ => problems.push(format!("frame {i}: a pose on one side only")),
        }
    }
    if board_overlays.keys().ne(host_overlays.keys()) {
        problems.push(format!(
            "overlays: the board wrote frames {:?}, the host drew {:?}",
            board_overlays.keys().collect::<Vec<_>>(),
            host_overlays.keys().collect::<Vec<_>>()
        ));
    }
    for (i, b) in board_overlays {
        if host_overlays.get(i).is_some_and(|h| h != b) {
            problems.push(format!(
                "overlay {i}: the board's picture differs from the host's"
            ));
        }
    }
    if !problems.is_empty() {
        let shown: Vec<_> = problems.iter().take(20).cloned().collect();
        bail!(
            "host and board disagree ({} problems):\n  {}",
            problems.len(),
            shown.join("\n  ")
        );
    }
    Ok(format!(
        "host replay agrees with the board on all {} frames: states and counts equal, Q16.16 \
         track checksums bit-identical, {bit_identical} of {poses} poses (best and alternative) \
         bit-identical and all within {POSE_TOLERANCE:e} relative (worst {worst:e}), {} overlays \
         byte-identical",
        host.len(),
        board_overlays.len()
    ))
}
