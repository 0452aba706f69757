//! The emulated board's main job: the `camgeom-fw-app` pipeline over a recorded sequence.
//!
//! Reads the run description (`run.bin`), the frames (`frames.raw`) and, for the fault job, a
//! fault plan (`faults.bin`) from the host over semihosting ([`crate::semihost`]), runs
//! the pipeline on every frame ([`drive`], the loop the host replay runs too) and writes what it
//! found back as binary records ([`camgeom_fw_app::report`]: one per frame with state, counts,
//! track checksum, poses, outline and per-stage cost in instructions, then a summary with the
//! pipeline's RAM and the stack high-water mark) to `report.bin`. Every `overlay_every`-th
//! overlay goes back as `overlay-NNNN.raw`. The defmt log says the same for people (one line a
//! frame at `debug`, the summary at `info`); `cargo xtask run` reads only the records.

use camgeom::image::ImageView;
use camgeom::target::{Acquire, GivenCorners, TargetState};
use camgeom_fw_app::calibrate_mode::{Buffers, Status, calibrate_mode};
use camgeom_fw_app::calibration::CalibError;
use camgeom_fw_app::command::{Ack, AckStatus, COMMAND_LEN, Command, Mode};
use camgeom_fw_app::drive;
use camgeom_fw_app::frame_chunk::send_frame;
use camgeom_fw_app::link::{Deframer, max_frame_len};
use camgeom_fw_app::pipeline::{AppError, Clock, FrameLoop};
use camgeom_fw_app::recorded::{CameraError, FAULT_PLAN_LEN, FaultPlan, RecordedCamera};
use camgeom_fw_app::report::{FrameRecord, SummaryRecord};
use camgeom_fw_app::run::{Acquisition, RUN_SPEC_LEN, RunSpec};
use camgeom_fw_app::settings::Settings;

use crate::flash::{FLASH_FILE, FlashModel};
use crate::semihost::{HostError, HostFile, HostFrames};
use crate::{board, cost};

/// Pyramid levels, KLT window, corner candidates and tracks of the main job (shared with the
/// host replay).
pub use camgeom_fw_app::run::{CANDIDATES, LEVELS, TRACKS, WIN};

/// The file the records go to, in QEMU's working directory.
pub const REPORT_FILE: &str = "report.bin";

/// The commands the board receives at boot: the host's side of the link, framed as on a
/// UART ([`camgeom_fw_app::link`]); read over semihosting, as QEMU 7's file serial ports
/// carry only what the board sends.
pub const COMMANDS_FILE: &str = "commands.bin";

/// Where the records go besides [`REPORT_FILE`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// Only to [`REPORT_FILE`].
    Off,
    /// Also as the framed record stream ([`camgeom_fw_app::link`]) over UART0
    /// ([`crate::uart`]; Arm `mps2-an500` and `mps2-an385` only).
    Uart0,
}

/// What else a job does with each frame's record: the tag job sends MAVLink
/// ([`crate::uart::MavlinkLink`]); `()` does nothing, and costs nothing in the binaries that
/// pass it.
pub trait RecordSink {
    /// Frame `r`'s record, of a target of `size` (metres).
    fn record(&mut self, r: &FrameRecord, size: [f32; 2]);
    /// The run is over: log what was sent.
    fn finish(&self);
}

impl RecordSink for () {
    fn record(&mut self, _: &FrameRecord, _: [f32; 2]) {}
    fn finish(&self) {}
}

/// Microseconds since boot: SysTick counts instructions, one a virtual nanosecond under
/// QEMU's `-icount shift=0`.
pub fn now_us() -> u64 {
    SysTickClock.now() / 1000
}

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

fn fail_app(what: &str, e: AppError<CameraError<HostError>>) -> ! {
    match e {
        AppError::Core(c) => defmt::error!("{=str}: {}", what, c),
        other => defmt::error!("{=str}: {=str}", what, other.name()),
    }
    board::exit_failure()
}

/// The fault plan in `faults.bin`, or none when there is no such file (the main job).
fn read_faults() -> FaultPlan {
    let mut bytes = [0u8; FAULT_PLAN_LEN];
    match HostFile::open_read("faults.bin") {
        Err(_) => FaultPlan::none(),
        Ok(mut f) => match f.read_exact(&mut bytes).map(|()| FaultPlan::parse(&bytes)) {
            Ok(Ok(plan)) => plan,
            Ok(Err(e)) => {
                defmt::error!("faults.bin: {}", e);
                board::exit_failure()
            }
            Err(e) => fail_host("faults.bin", e),
        },
    }
}

fn log_frame(r: &FrameRecord) {
    match r.error {
        Some(e) => defmt::debug!(
            "frame {=u32}: error {=str} ({=str})",
            r.index,
            e.name(),
            r.state.name()
        ),
        None => defmt::debug!(
            "frame {=u32}: {=str} tracked {=u16} inliers {=u16} added {=u16} features {=u16} q16 {=u32:#010x} total {=u32}",
            r.index,
            r.state.name(),
            r.tracked,
            r.inliers,
            r.added,
            r.features,
            r.checksum,
            r.costs.total
        ),
    }
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

fn read_spec() -> RunSpec {
    let mut bytes = [0u8; RUN_SPEC_LEN];
    if let Err(e) = HostFile::open_read("run.bin").and_then(|mut f| f.read_exact(&mut bytes)) {
        fail_host("run.bin", e)
    }
    match RunSpec::parse(&bytes) {
        Ok(s) => s,
        Err(e) => {
            defmt::error!("run.bin: {}", e);
            board::exit_failure()
        }
    }
}

/// Runs the main job on `app` (a `static`) for `W x H` frames, the target found by what
/// `acquisition` makes of the run description (`None`: this firmware cannot acquire the
/// run's target, a failed run), the records also streamed as `stream` says; exits the
/// emulator. A firmware that has no calibrate mode: [`run_with_calibrate`] is one that has.
pub fn run<A: Acquire>(
    app: &mut impl FrameLoop,
    width: usize,
    height: usize,
    stream: Stream,
    sink: impl RecordSink,
    acquisition: impl FnOnce(&RunSpec) -> Option<A>,
) -> ! {
    // `false`: the calibrate mode's code (the chessboard detector and the calibrator, 80 KB
    // of flash) is not in this firmware at all.
    run_job::<A, false>(app, width, height, stream, sink, acquisition, None)
}

/// [`run`] with the calibrate mode's buffers (`calibrate`; a firmware that [`run`]s answers
/// `mode calibrate` as unsupported). In calibrate mode (commanded, or stored) the board
/// runs [`calibrate_mode`] over the frames instead of the tracking: progress, result and
/// verdict on the record stream, a good camera saved to the flash with the mode back to the
/// run's tracking mode; then it exits.
pub fn run_with_calibrate<A: Acquire>(
    app: &mut impl FrameLoop,
    width: usize,
    height: usize,
    stream: Stream,
    sink: impl RecordSink,
    acquisition: impl FnOnce(&RunSpec) -> Option<A>,
    calibrate: Buffers<'_>,
) -> ! {
    run_job::<A, true>(
        app,
        width,
        height,
        stream,
        sink,
        acquisition,
        Some(calibrate),
    )
}

/// [`run`] (`CALIBRATES` false) or [`run_with_calibrate`].
fn run_job<A: Acquire, const CALIBRATES: bool>(
    app: &mut impl FrameLoop,
    width: usize,
    height: usize,
    stream: Stream,
    mut sink: impl RecordSink,
    acquisition: impl FnOnce(&RunSpec) -> Option<A>,
    calibrate: Option<Buffers<'_>>,
) -> ! {
    cost::start();
    let run = read_spec();
    let mut flash = match FlashModel::boot() {
        Some(Ok(f)) => f,
        Some(Err(e)) => fail_host(FLASH_FILE, e),
        None => {
            defmt::error!("the flash is already in use");
            board::exit_failure()
        }
    };
    let mut link = Link::open(stream);
    let settings = settings(&run, &mut flash, &mut link, CALIBRATES);
    if CALIBRATES && let (Mode::Calibrate, Some(buffers)) = (settings.mode, calibrate) {
        calibrate_boot(app, &run, &settings, buffers, &mut flash, &mut link)
    }
    // In stream-frames mode each frame's pixels go before its record, after the settings the
    // host draws the overlay with.
    let streaming = settings.mode == Mode::StreamFrames;
    let settings_record = settings.encode();
    let Some(spec) = run.with_settings(&settings) else {
        defmt::error!(
            "this firmware tracks; the settings say {=str}",
            settings.mode.name()
        );
        board::exit_failure()
    };
    let cfg = match spec.app_config() {
        Ok(c) => c,
        Err(e) => {
            defmt::error!("run.bin: {}", e);
            board::exit_failure()
        }
    };
    if (cfg.width, cfg.height) != (width, height) {
        defmt::error!(
            "run.bin is for {=usize}x{=usize}, this firmware for {=usize}x{=usize}",
            cfg.width,
            cfg.height,
            width,
            height
        );
        board::exit_failure()
    }
    let stride = spec.stride.max(1) as usize;
    let plan = read_faults();
    let frames = match HostFrames::open("frames.raw", width, height) {
        Ok(f) => f,
        Err(e) => fail_host("frames.raw", e),
    };
    let mut camera = RecordedCamera::new(frames, stride, spec.frames as usize, plan);
    let mut report = match HostFile::create(REPORT_FILE) {
        Ok(f) => f,
        Err(e) => fail_host(REPORT_FILE, e),
    };
    defmt::info!(
        "main job: {=usize}x{=usize}, {=usize} frames (stride {=usize}, {=usize} fault spans), {=usize} pyramid levels, KLT {=usize}x{=usize} Q16.16, {=usize} tracks; pipeline RAM {=usize} bytes (const sizes)",
        width,
        height,
        camera.count(),
        stride,
        plan.spans().count(),
        LEVELS,
        WIN,
        WIN,
        TRACKS,
        app.bytes()
    );
    let mut clock = SysTickClock;
    let overlay_every = spec.overlay_every as usize;
    let count = camera.count();
    let mut overlay_error = None;
    let mut saved = 0u32;
    let mut overlay = |index: u32, img: &ImageView<'_, u8>| {
        let i = index as usize;
        if overlay_every > 0 && (i.is_multiple_of(overlay_every) || i + 1 == count) {
            match save_overlay(i * stride, img) {
                Ok(()) => saved += 1,
                Err(e) => overlay_error = Some(e),
            }
        }
    };
    let mut summary = SummaryRecord::default();
    let mut record = |r: &FrameRecord, pixels: Option<&ImageView<'_, u8>>| {
        log_frame(r);
        if let (true, Some(img)) = (streaming, pixels) {
            link.send_pixels(&settings_record);
            if let Err(e) = send_frame(r.index, img, |chunk| link.send_pixels(chunk)) {
                defmt::error!("frame {=u32}: {}", r.index, e);
                board::exit_failure()
            }
        }
        summary.frames += 1;
        summary.tracking += u32::from(r.state == TargetState::Tracking && r.error.is_none());
        let bytes = r.encode();
        if let Err(e) = report.write_all(&bytes) {
            fail_host(REPORT_FILE, e)
        }
        link.send(&bytes);
        sink.record(r, spec.target_size);
    };
    let Some(mut acquire) = acquisition(&spec) else {
        defmt::error!("run.bin asks for a target this firmware cannot acquire");
        board::exit_failure()
    };
    if let Err(e) = drive(
        app,
        &cfg,
        &mut camera,
        &mut acquire,
        &mut clock,
        &mut record,
        &mut overlay,
    ) {
        fail_app("finish", e)
    }
    if let Some(e) = overlay_error {
        fail_host("overlay", e)
    }
    let (stack, stack_size) = board::stack_usage();
    summary.pipeline_ram = app.bytes() as u32;
    summary.stack_used = stack;
    summary.stack_size = stack_size;
    summary.overlays = saved;
    let bytes = summary.encode();
    if let Err(e) = report.write_all(&bytes) {
        fail_host(REPORT_FILE, e)
    }
    link.send(&bytes);
    link.log();
    sink.finish();
    defmt::info!(
        "main job: {=u32} frames, {=u32} tracking, pipeline RAM {=u32} bytes, stack {=u32} of {=u32} bytes, {=u32} overlays",
        summary.frames,
        summary.tracking,
        summary.pipeline_ram,
        stack,
        stack_size,
        saved
    );
    board::exit_success()
}

/// The board's settings: those stored in the flash, else the run's own; then the commands in
/// [`COMMANDS_FILE`] applied in order, each answered on the record stream
/// ([`camgeom_fw_app::command`]), a save stored in the flash and persisted.
fn settings(run: &RunSpec, flash: &mut FlashModel, link: &mut Link, calibrates: bool) -> Settings {
    let mut settings = match flash.settings() {
        Some(s) => {
            defmt::info!("settings: loaded from flash: {}", s);
            s
        }
        None => run.settings(),
    };
    let Ok(mut file) = HostFile::open_read(COMMANDS_FILE) else {
        return settings;
    };
    let len = match file.file_len() {
        Ok(n) => n,
        Err(e) => fail_host(COMMANDS_FILE, e),
    };
    // The bytes as a UART delivers them: a few at a time, into the receiver.
    let mut rx = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
    let mut chunk = [0u8; 64];
    let mut at = 0;
    while at < len {
        let n = (len - at).min(chunk.len());
        let got = chunk.get_mut(..n).unwrap_or(&mut []);
        if let Err(e) = file.read_exact(got) {
            fail_host(COMMANDS_FILE, e)
        }
        at += n;
        let mut input: &[u8] = got;
        while let Some(frame) = rx.push(&mut input) {
            let (kind, status) = match Command::decode(frame.record) {
                Err(e) => {
                    defmt::warn!("command {=u16}: {}", frame.seq, e);
                    (0, AckStatus::Invalid)
                }
                Ok(c) => (
                    c.kind(),
                    command(c, &mut settings, run, flash, link.streams(), calibrates),
                ),
            };
            defmt::info!(
                "command {=u16}: kind {=u32}, {=str}",
                frame.seq,
                kind,
                status.name()
            );
            link.send(
                &Ack {
                    seq: frame.seq,
                    kind,
                    status,
                }
                .encode(),
            );
        }
    }
    let st = rx.stats();
    defmt::info!(
        "commands: {=u32} frames, {=u32} damaged, {=u32} lost; flash {=u32} erases, {=u32} words written",
        st.frames,
        st.damaged,
        st.lost,
        flash.erases,
        flash.writes
    );
    settings
}

/// Carries out one command ([`Settings::carry_out`]): this firmware tracks, so a mode that
/// does not is refused (calibrate, unless it `calibrates`), and so is streaming frames
/// without a record stream (`streams`); a save is stored in the flash and persisted.
fn command(
    c: Command,
    settings: &mut Settings,
    run: &RunSpec,
    flash: &mut FlashModel,
    streams: bool,
    calibrates: bool,
) -> AckStatus {
    let fits = |s: &Settings| match run.with_settings(s) {
        Some(_) if streams || s.mode != Mode::StreamFrames => Ok(()),
        None if calibrates && s.mode == Mode::Calibrate => Ok(()),
        _ => Err(AckStatus::Unsupported),
    };
    settings.carry_out(&c, fits, |s| save(s, flash))
}

/// Stores `s` in the flash and persists it.
fn save(s: &Settings, flash: &mut FlashModel) -> Result<(), camgeom_fw_app::settings::SaveError> {
    s.save(flash, 0).inspect_err(|e| {
        defmt::error!("settings: not saved: {}", e);
    })?;
    if let Err(e) = flash.persist() {
        fail_host(FLASH_FILE, e)
    }
    Ok(())
}

/// The calibrate mode over `frames.raw` (the run's frame count at most): every record on the
/// stream, a good camera saved; logs the verdict (`calibrate mode: ...`) and the settings in
/// force after it, and exits.
fn calibrate_boot(
    app: &mut impl FrameLoop,
    run: &RunSpec,
    settings: &Settings,
    buffers: Buffers<'_>,
    flash: &mut FlashModel,
    link: &mut Link,
) -> ! {
    let (width, height) = (run.width as usize, run.height as usize);
    // The frames go into one of the pipeline's frame buffers: it does not track meanwhile.
    let Some(mut frame) = app.lend_frame(width, height) else {
        defmt::error!("run.bin's frames do not fit this firmware's buffers");
        board::exit_failure()
    };
    let frames = match HostFrames::open("frames.raw", width, height) {
        Ok(f) => f,
        Err(e) => fail_host("frames.raw", e),
    };
    let mut camera = RecordedCamera::new(frames, 1, run.frames as usize, FaultPlan::none());
    let back = run.settings().mode;
    let outcome = calibrate_mode(
        settings,
        back,
        &mut camera,
        &mut frame,
        buffers,
        &mut SysTickClock,
        &mut |record| link.send(record),
        |s| save(s, flash),
    );
    let o = match outcome {
        Ok(o) => o,
        Err(CalibError::Source(CameraError::Read(e))) => fail_host("frames.raw", e),
        Err(CalibError::Source(CameraError::WrongSize)) => {
            defmt::error!("frames.raw: a frame of the wrong size");
            board::exit_failure()
        }
        Err(CalibError::Core(e)) => {
            defmt::error!("calibrate mode: {}", e);
            board::exit_failure()
        }
    };
    // The settings in force from now on, as the host sees them.
    link.send(&o.settings.encode());
    let v = o.verdict;
    let [fx, fy, cx, cy] = o.settings.intrinsics;
    let (stack, stack_size) = board::stack_usage();
    link.log();
    defmt::info!(
        "calibrate mode: {=str} after {=u32} frames, {=u32} of {=u32} views (reason {=u32:#x}); camera fx {=f32} fy {=f32} cx {=f32} cy {=f32}; stack {=u32} of {=u32} bytes",
        v.status.name(),
        v.frame,
        v.views,
        v.needed,
        v.reason,
        fx,
        fy,
        cx,
        cy,
        stack,
        stack_size
    );
    if v.status == Status::Calibrated {
        defmt::info!("settings: calibrated camera saved to flash: {}", o.settings);
    }
    board::exit_success()
}

/// The acquisition of the box job: the corners the run gives (no tag detector in this
/// firmware).
pub fn given_corners(spec: &RunSpec) -> Option<GivenCorners> {
    match spec.acquisition {
        Acquisition::Corners => Some(GivenCorners::new(spec.start_corners())),
        Acquisition::Tag { .. } => None,
    }
}

/// The record stream of a run, with what it cost (the frames' pixels and the settings sent
/// with them counted apart).
struct Link {
    #[cfg(target_arch = "arm")]
    uart: Option<crate::uart::RecordLink>,
    frames: u32,
    bytes: u32,
    instructions: u64,
    pixel_frames: u32,
    pixel_bytes: u32,
}

impl Link {
    fn open(stream: Stream) -> Self {
        #[cfg(target_arch = "arm")]
        let uart = (stream != Stream::Off).then(crate::uart::RecordLink::open);
        #[cfg(not(target_arch = "arm"))]
        if stream != Stream::Off {
            defmt::error!("this board has no record stream");
            board::exit_failure()
        }
        Self {
            #[cfg(target_arch = "arm")]
            uart,
            frames: 0,
            bytes: 0,
            instructions: 0,
            pixel_frames: 0,
            pixel_bytes: 0,
        }
    }

    /// Whether the records go out on a link.
    fn streams(&self) -> bool {
        #[cfg(target_arch = "arm")]
        return self.uart.is_some();
        #[cfg(not(target_arch = "arm"))]
        false
    }

    /// Sends `record` (a frame's chunk of pixels, or the settings before them) as the next
    /// frame, counted apart from the reports.
    fn send_pixels(&mut self, record: &[u8]) {
        #[cfg(target_arch = "arm")]
        if let Some(uart) = &mut self.uart {
            match uart.send(record) {
                Ok(n) => {
                    self.pixel_frames += 1;
                    self.pixel_bytes += n as u32;
                }
                Err(e) => {
                    defmt::error!("record stream: {}", e);
                    board::exit_failure()
                }
            }
        }
        #[cfg(not(target_arch = "arm"))]
        let _ = record;
    }

    /// Sends `record` as the next frame (a failure ends the run: the host checks the stream).
    fn send(&mut self, record: &[u8]) {
        #[cfg(target_arch = "arm")]
        if let Some(uart) = &mut self.uart {
            let mut clock = SysTickClock;
            let start = clock.now();
            match uart.send(record) {
                Ok(n) => {
                    self.frames += 1;
                    self.bytes += n as u32;
                    self.instructions += clock.now().saturating_sub(start);
                }
                Err(e) => {
                    defmt::error!("record stream: {}", e);
                    board::exit_failure()
                }
            }
        }
        #[cfg(not(target_arch = "arm"))]
        let _ = record;
    }

    fn log(&self) {
        if self.frames > 0 {
            defmt::info!(
                "record stream: {=u32} frames, {=u32} bytes over UART0, {=u64} instructions a frame to frame and send",
                self.frames,
                self.bytes,
                self.instructions / u64::from(self.frames)
            );
        }
        if self.pixel_frames > 0 {
            defmt::info!(
                "frames streamed: {=u32} link frames of pixels and settings, {=u32} bytes over UART0",
                self.pixel_frames,
                self.pixel_bytes
            );
        }
    }
}
