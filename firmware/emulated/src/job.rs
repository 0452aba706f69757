//! The emulated board's main job: the `camgeom-fw-app` pipeline over a recorded sequence.
//!
//! Reads the run description (`run.bin`) and the frames (`frames.raw`) from the host over
//! semihosting ([`crate::semihost`]), runs [`Pipeline`] on every frame, logs each frame's
//! state, counts, track checksum, pose and per-stage cost (instructions, SysTick under QEMU
//! `-icount`), saves every `overlay_every`-th overlay back to the host as
//! `overlay-NNNN.raw`, and ends with the cost table (mean and worst per stage), the RAM of the
//! pipeline and the stack high-water mark. `cargo xtask run` parses these lines: keep their
//! wording in step with `xtask/src/mainjob.rs`.

use camgeom::image::ImageView;
use camgeom::target::TargetState;
use camgeom_fw_app::pipeline::{AppError, Clock, FrameReport, Pipeline, StageCosts};
use camgeom_fw_app::run::{RUN_SPEC_LEN, RunSpec};

use crate::semihost::{HostError, HostFile, RecordedCamera};
use crate::{board, cost};

/// Pyramid levels, KLT window, corner candidates and tracks of the main job (shared with the
/// host replay).
pub use camgeom_fw_app::run::{CANDIDATES, LEVELS, TRACKS, WIN};

/// SysTick, in instructions (QEMU `-icount`) or cycles (hardware).
struct SysTickClock;

impl Clock for SysTickClock {
    fn now(&mut self) -> u64 {
        cost::now().saturating_mul(u64::from(cost::per_tick()))
    }
}

fn fail_host(what: &str, e: HostError) -> ! {
    defmt::error!("{=str}: host file error {}", what, e);
    board::exit_failure()
}

fn fail_app(what: &str, e: AppError<HostError>) -> ! {
    match e {
        AppError::Source(h) => defmt::error!("{=str}: frame source: {}", what, h),
        AppError::NoFrame => defmt::error!("{=str}: the sequence has no frame", what),
        AppError::Geometry => {
            defmt::error!("{=str}: the run does not fit the pipeline's buffers", what)
        }
        AppError::NotStarted => defmt::error!("{=str}: not started", what),
        AppError::Core(c) => defmt::error!("{=str}: {}", what, c),
    }
    board::exit_failure()
}

/// Mean and worst per stage over the frames.
#[derive(Default)]
struct Totals {
    frames: u32,
    sum: [u64; 8],
    worst: [u32; 8],
    tracking: u32,
}

impl Totals {
    fn add(&mut self, r: &FrameReport) {
        self.frames += 1;
        self.tracking += u32::from(r.state == TargetState::Tracking);
        for ((s, w), (_, c)) in self
            .sum
            .iter_mut()
            .zip(self.worst.iter_mut())
            .zip(r.costs.named())
        {
            *s += u64::from(c);
            *w = (*w).max(c);
        }
    }
}

fn log_frame(recorded: usize, r: &FrameReport) {
    defmt::info!(
        "frame {=u32} (recorded {=usize}): {} tracked {=usize} inliers {=usize} added {=usize} features {=usize} q16 {=u32:#010x}",
        r.index,
        recorded,
        r.state,
        r.tracked,
        r.inliers,
        r.added,
        r.features,
        r.checksum
    );
    if let Some(p) = r.pose {
        let t = p.pose.translation();
        let v = p.pose.rotation_vector();
        defmt::info!(
            "pose {=u32}: t {=f32} {=f32} {=f32} r {=f32} {=f32} {=f32} rms {=f32}",
            r.index,
            t.x,
            t.y,
            t.z,
            v.x,
            v.y,
            v.z,
            p.rms_px
        );
    }
    let c = r.costs;
    defmt::info!(
        "cost {=u32}: capture {=u32} pyramid {=u32} flow {=u32} homography {=u32} pose {=u32} redetect {=u32} draw {=u32} total {=u32}",
        r.index,
        c.capture,
        c.pyramid,
        c.flow,
        c.homography,
        c.pose,
        c.redetect,
        c.draw,
        c.total
    );
}

/// Writes `overlay-NNNN.raw` (4-digit recorded frame number).
fn save_overlay(recorded: usize, img: &ImageView<'_, u8>) -> Result<(), HostError> {
    let mut name = *b"overlay-0000.raw";
    let mut n = recorded;
    for d in name.get_mut(8..12).into_iter().flatten().rev() {
        *d = b'0' + (n % 10) as u8;
        n /= 10;
    }
    let name = core::str::from_utf8(&name).unwrap_or("overlay.raw");
    let mut f = HostFile::create(name)?;
    for row in img.rows() {
        f.write_all(row.get(..img.width()).unwrap_or(row))?;
    }
    Ok(())
}

/// Runs the main job on `app` (a `static`) for `W x H` frames; exits the emulator.
pub fn run<
    const F: usize,
    const P: usize,
    const S: usize,
    const C: usize,
    const K: usize,
    const N: usize,
>(
    app: &mut Pipeline<F, P, S, C, K, N>,
    width: usize,
    height: usize,
) -> ! {
    cost::start();
    let mut spec_bytes = [0u8; RUN_SPEC_LEN];
    if let Err(e) = HostFile::open_read("run.bin").and_then(|mut f| f.read_exact(&mut spec_bytes)) {
        fail_host("run.bin", e)
    }
    let spec = match RunSpec::parse(&spec_bytes) {
        Ok(s) => s,
        Err(e) => {
            defmt::error!("run.bin: {}", e);
            board::exit_failure()
        }
    };
    let cfg = match spec.app_config() {
        Ok(c) => c,
        Err(e) => {
            defmt::error!("run.bin: {}", e);
            board::exit_failure()
        }
    };
    if (cfg.width, cfg.height) != (width, height) || cfg.target.lk.win != WIN {
        defmt::error!(
            "run.bin is for {=usize}x{=usize}, this firmware for {=usize}x{=usize} (window {=usize})",
            cfg.width,
            cfg.height,
            width,
            height,
            WIN
        );
        board::exit_failure()
    }
    let stride = spec.stride.max(1) as usize;
    let mut camera =
        match RecordedCamera::open("frames.raw", width, height, stride, spec.frames as usize) {
            Ok(c) => c,
            Err(e) => fail_host("frames.raw", e),
        };
    defmt::info!(
        "main job: {=usize}x{=usize}, {=usize} frames (stride {=usize}), {=usize} pyramid levels, KLT {=usize}x{=usize} Q16.16, {=usize} tracks; pipeline RAM {=usize} bytes (const sizes)",
        width,
        height,
        camera.count(),
        stride,
        LEVELS,
        WIN,
        WIN,
        N,
        Pipeline::<F, P, S, C, K, N>::RAM
    );
    let mut clock = SysTickClock;
    let overlay_every = spec.overlay_every as usize;
    let count = camera.count();
    let mut overlay_error = None;
    let mut saved = 0u32;
    let mut overlay = |index: u32, img: &ImageView<'_, u8>| {
        let i = index as usize;
        if overlay_every > 0 && (i.is_multiple_of(overlay_every) || i + 1 == count) {
            let recorded = i * stride;
            match save_overlay(recorded, img) {
                Ok(()) => saved += 1,
                Err(e) => overlay_error = Some(e),
            }
        }
    };
    let mut totals = Totals::default();
    let start = match app.start(&cfg, &mut camera, &spec.start_corners(), &mut clock) {
        Ok(r) => r,
        Err(e) => fail_app("start", e),
    };
    log_frame(0, &start);
    loop {
        match app.step(&cfg, &mut camera, &mut clock, &mut overlay) {
            Ok(Some(r)) => {
                log_frame(camera.recorded_index(r.index as usize), &r);
                totals.add(&r);
            }
            Ok(None) => break,
            Err(e) => fail_app("step", e),
        }
    }
    if let Err(e) = app.finish::<HostError>(&cfg, &mut overlay) {
        fail_app("finish", e)
    }
    if let Some(e) = overlay_error {
        fail_host("overlay", e)
    }

    let n = u64::from(totals.frames.max(1));
    defmt::info!(
        "cost per frame over {=u32} frames (instructions, +-{=u32}; mean, worst):",
        totals.frames,
        cost::per_tick()
    );
    for ((name, _), (sum, worst)) in StageCosts::default()
        .named()
        .iter()
        .zip(totals.sum.iter().zip(totals.worst.iter()))
    {
        defmt::info!(
            "  stage {=str}: mean {=u64} worst {=u32}",
            name,
            sum / n,
            *worst
        );
    }
    let (stack, stack_size) = board::stack_usage();
    defmt::info!("stack: {=u32} bytes used of {=u32}", stack, stack_size);
    defmt::info!("overlays saved: {=u32}", saved);
    defmt::info!(
        "main job: {=u32} frames, {=u32} tracking, pipeline RAM {=usize} bytes, stack {=u32} bytes",
        totals.frames + 1,
        totals.tracking,
        Pipeline::<F, P, S, C, K, N>::RAM,
        stack
    );
    board::exit_success()
}
