//! The host replay: the same `camgeom-fw-app` pipeline, compiled for the host, on the same
//! bytes as the board.

use std::collections::BTreeMap;

use anyhow::{Result, anyhow, bail};
use camgeom::image::{ImageMut, ImageView};
use camgeom::target::GivenCorners;
use camgeom_fw_app::pipeline::{NoClock, Pipeline};
use camgeom_fw_app::report::FrameRecord;
use camgeom_fw_app::run::{CANDIDATES, LEVELS, RunSpec, TRACKS, WIN};
use camgeom_fw_app::{FrameSource, pipeline_type};

use super::emulate::Overlays;
use crate::jobs::Size;

/// The host's virtual camera: the same `frames.raw`, the same stride.
struct HostCamera<'a> {
    raw: &'a [u8],
    width: usize,
    height: usize,
    stride: usize,
    count: usize,
    next: usize,
}

impl FrameSource for HostCamera<'_> {
    type Error = String;

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, String> {
        if self.next >= self.count {
            return Ok(false);
        }
        let len = self.width * self.height;
        let start = self.next * self.stride * len;
        let src = self
            .raw
            .get(start..start + len)
            .ok_or_else(|| "frames.raw too short".to_string())?;
        for (y, row) in src.chunks_exact(self.width).enumerate() {
            let dst = frame.row_mut(y).ok_or("frame too small")?;
            dst.get_mut(..self.width)
                .ok_or("frame too narrow")?
                .copy_from_slice(row);
        }
        self.next += 1;
        Ok(true)
    }
}

/// Every frame's record and the overlays the board would write.
pub type Replay = (BTreeMap<u32, FrameRecord>, Overlays);

fn replay<
    const F: usize,
    const P: usize,
    const S: usize,
    const C: usize,
    const K: usize,
    const N: usize,
>(
    app: &mut Pipeline<F, P, S, C, K, N>,
    spec: &RunSpec,
    raw: &[u8],
) -> Result<Replay> {
    let cfg = spec.app_config().map_err(|e| anyhow!("run.bin: {e}"))?;
    let (w, h) = (cfg.width, cfg.height);
    let stride = spec.stride.max(1) as usize;
    let held = raw.len() / (w * h);
    let count = (spec.frames as usize).min(held.div_ceil(stride));
    let mut cam = HostCamera {
        raw,
        width: w,
        height: h,
        stride,
        count,
        next: 0,
    };
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
    let mut acquire = GivenCorners::new(spec.start_corners());
    let first = app
        .start(&cfg, &mut cam, &mut acquire, &mut NoClock)
        .map_err(|e| anyhow!("host start: {}", e.name()))?;
    out.insert(0, FrameRecord::of(&first));
    while let Some(r) = app
        .step(&cfg, &mut cam, &mut acquire, &mut NoClock, &mut keep)
        .map_err(|e| anyhow!("host step: {}", e.name()))?
    {
        out.insert(r.index, FrameRecord::of(&r));
    }
    app.finish::<String>(&cfg, &mut keep)
        .map_err(|e| anyhow!("host finish: {}", e.name()))?;
    Ok((out, overlays))
}

/// Replays the run of `size` described by `spec` on `raw` (the bytes of `frames.raw`).
pub fn replay_size(size: Size, spec: &RunSpec, raw: &[u8]) -> Result<Replay> {
    // The pipeline is a few hundred KB: build it on the heap.
    match (size.width, size.height) {
        (320, 240) => {
            let mut app: Box<pipeline_type!(320, 240, LEVELS, WIN, CANDIDATES, TRACKS)> =
                Box::default();
            replay(&mut app, spec, raw)
        }
        (160, 120) => {
            let mut app: Box<pipeline_type!(160, 120, LEVELS, WIN, CANDIDATES, TRACKS)> =
                Box::default();
            replay(&mut app, spec, raw)
        }
        (w, h) => bail!("no host pipeline for {w}x{h}"),
    }
}
