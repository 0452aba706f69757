//! The host replay: the same `camgeom-fw-app` pipeline, compiled for the host, on the same
//! bytes as the board.

use std::collections::BTreeMap;

use anyhow::{Result, anyhow, bail};
use camgeom::apriltag::{Detector, DetectorConfig, TagTarget, Workspace320x240};
use camgeom::image::ImageView;
use camgeom::target::{Acquire, GivenCorners};
use camgeom_fw_app::drive;
use camgeom_fw_app::pipeline::{FrameLoop, NoClock};
use camgeom_fw_app::recorded::{FaultPlan, RecordedCamera, SliceFrames};
use camgeom_fw_app::report::FrameRecord;
use camgeom_fw_app::run::{Acquisition, RunSpec, TAG_FAMILIES};
use camgeom_fw_app::sizes::{Qqvga, Qvga};

use super::emulate::Overlays;
use crate::jobs::Size;

/// Every frame's record and the overlays the board would write.
pub type Replay = (BTreeMap<u32, FrameRecord>, Overlays);

fn replay(
    app: &mut impl FrameLoop,
    spec: &RunSpec,
    plan: &FaultPlan,
    raw: &[u8],
) -> Result<Replay> {
    let cfg = spec.app_config().map_err(|e| anyhow!("run.bin: {e}"))?;
    let (w, h) = (cfg.width, cfg.height);
    let mut camera = RecordedCamera::new(
        SliceFrames::new(raw, w, h),
        spec.stride.max(1) as usize,
        spec.frames as usize,
        *plan,
    );
    let count = camera.count();
    let mut out = BTreeMap::new();
    let mut overlays = BTreeMap::new();
    let every = spec.overlay_every as usize;
    let mut keep = |i: u32, img: &ImageView<'_, u8>| {
        let i = i as usize;
        if every > 0 && (i.is_multiple_of(every) || i + 1 == count) {
            let mut v = Vec::with_capacity(w * h);
            for r in img.rows() {
                v.extend_from_slice(&r[..w]);
            }
            overlays.insert(i as u32, v);
        }
    };
    let mut record = |r: &FrameRecord, _: Option<&ImageView<'_, u8>>| {
        out.insert(r.index, *r);
    };
    // The acquisition the board makes of the same run description (job::given_corners, the
    // tag binary's TagTarget), on the host.
    let mut given;
    let (detector, mut workspace, mut tag);
    let acquire: &mut dyn Acquire = match spec.acquisition {
        Acquisition::Corners => {
            given = GivenCorners::new(spec.start_corners());
            &mut given
        }
        Acquisition::Tag { family, id } => {
            let family = *TAG_FAMILIES
                .get(usize::from(family))
                .ok_or_else(|| anyhow!("run.bin: no such tag family"))?;
            // The tag binary's detector (decimation 2 for its full detections).
            let cfg = DetectorConfig {
                decimate: 2,
                ..DetectorConfig::default()
            };
            detector = Detector::new(cfg, &[family])?;
            workspace = Box::new(Workspace320x240::new());
            tag = TagTarget::new(&detector, workspace.as_mut_view(), family, id);
            &mut tag
        }
    };
    drive(
        app,
        &cfg,
        &mut camera,
        acquire,
        &mut NoClock,
        &mut record,
        &mut keep,
    )
    .map_err(|e| anyhow!("host replay: {}", e.name()))?;
    Ok((out, overlays))
}

/// Replays the run of `size` described by `spec` and `plan` on `raw` (the bytes of
/// `frames.raw`).
pub fn replay_size(size: Size, spec: &RunSpec, plan: &FaultPlan, raw: &[u8]) -> Result<Replay> {
    // The pipeline is a few hundred KB: build it on the heap.
    match (size.width, size.height) {
        (320, 240) => {
            let mut app: Box<Qvga> = Box::default();
            replay(&mut *app, spec, plan, raw)
        }
        (160, 120) => {
            let mut app: Box<Qqvga> = Box::default();
            replay(&mut *app, spec, plan, raw)
        }
        (w, h) => bail!("no host pipeline for {w}x{h}"),
    }
}
