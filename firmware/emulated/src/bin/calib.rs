//! The emulated board calibrates its camera: the bundled chessboard views, downscaled to
//! 320x240 by `cargo xtask run`, arrive as frames over semihosting; the board detects the board
//! in each, keeps the views in fixed RAM and solves for K, distortion and RMS
//! ([`camgeom_fw_app::calibration::calibrate`], the code the host replay runs), writing one
//! record a frame and the result to `calib-report.bin`. When `calib.bin` describes a ChArUco
//! board, the same for ChArUco views seen in part
//! ([`camgeom_fw_app::charuco_calibration::calibrate_charuco`]: the ArUco detector in
//! [`Workspace320x240`], the corners interpolated and refined, `Calibrator::add_points`).
#![no_std]
#![no_main]

use camgeom::apriltag::{Detector, DetectorConfig, Workspace320x240};
use camgeom::charuco::CharucoParams;
use camgeom_fw_app::calibration::{
    BoardCalibrator, BoardDetector, CalibError, CalibRecord, CalibSpec, SPEC_LEN, SpecBoard,
    calibrate, scratch_len,
};
use camgeom_fw_app::charuco_calibration::{
    CHARUCO_CORNERS, CHARUCO_RECORD_LEN, CharucoCalibrator, CharucoDetection, MARKERS, board_of,
    calibrate_charuco, charuco_calibrator,
};
use camgeom_fw_app::pipeline::Clock;
use camgeom_fw_app::recorded::{CameraError, FaultPlan, RecordedCamera};
use camgeom_fw_emulated::semihost::{HostError, HostFile, HostFrames};
use camgeom_fw_emulated::{board, cost, entry};
use static_cell::{ConstStaticCell, StaticCell};

const W: usize = 320;
const H: usize = 240;

static FRAME: ConstStaticCell<[u8; W * H]> = ConstStaticCell::new([0; W * H]);
static DETECTOR: ConstStaticCell<BoardDetector> = ConstStaticCell::new(BoardDetector::new());
static SCRATCH: ConstStaticCell<[i32; scratch_len(W)]> = ConstStaticCell::new([0; scratch_len(W)]);
static CALIBRATOR: StaticCell<BoardCalibrator> = StaticCell::new();
static WORKSPACE: ConstStaticCell<Workspace320x240> = ConstStaticCell::new(Workspace320x240::new());
static CHARUCO_CALIBRATOR: StaticCell<CharucoCalibrator> = StaticCell::new();

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

#[entry]
fn main() -> ! {
    cost::start();
    let mut bytes = [0u8; SPEC_LEN];
    if let Err(e) = HostFile::open_read("calib.bin").and_then(|mut f| f.read_exact(&mut bytes)) {
        fail_host("calib.bin", e)
    }
    let spec = match CalibSpec::parse(&bytes) {
        Ok(s) if (s.width as usize, s.height as usize) == (W, H) => s,
        Ok(_) => {
            defmt::error!("calib.bin is not for 320x240");
            board::exit_failure()
        }
        Err(e) => {
            defmt::error!("calib.bin: {}", e);
            board::exit_failure()
        }
    };
    let frames = match HostFrames::open("frames.raw", W, H) {
        Ok(f) => f,
        Err(e) => fail_host("frames.raw", e),
    };
    let mut camera = RecordedCamera::new(frames, 1, spec.frames as usize, FaultPlan::none());
    let mut report = match HostFile::create("calib-report.bin") {
        Ok(f) => f,
        Err(e) => fail_host("calib-report.bin", e),
    };
    if spec.board != SpecBoard::Chessboard {
        charuco(&spec, &mut camera, &mut report)
    }
    let calibrator = match BoardCalibrator::new(
        camgeom::chessboard::BoardSize::new(spec.cols as usize, spec.rows as usize).unwrap_or_else(
            |e| {
                defmt::error!("board: {}", e);
                board::exit_failure()
            },
        ),
        spec.square,
        W,
        H,
    ) {
        Ok(c) => CALIBRATOR.init(c),
        Err(e) => {
            defmt::error!("calibrator: {}", e);
            board::exit_failure()
        }
    };
    let mut found = 0u32;
    let result = calibrate(
        &spec,
        &mut camera,
        FRAME.take(),
        DETECTOR.take(),
        SCRATCH.take(),
        calibrator,
        &mut SysTickClock,
        &mut |v| {
            found += u32::from(v.corners.is_some());
            if let Err(e) = report.write_all(&v.encode()) {
                fail_host("calib-report.bin", e)
            }
        },
    );
    let mut result = checked(result);
    result.stack = board::stack_usage().0;
    if let Err(e) = report.write_all(&result.encode()) {
        fail_host("calib-report.bin", e)
    }
    let [fx, fy, cx, cy] = result.intrinsics;
    defmt::info!(
        "calibration: board found in {=u32} of {=u32} frames, {=u32} views used; fx {=f32} fy {=f32} cx {=f32} cy {=f32}, RMS {=f32} px; solve {=u32} instructions, stack {=u32} bytes, calibrator {=usize} bytes",
        found,
        spec.frames,
        result.views_used,
        fx,
        fy,
        cx,
        cy,
        result.rms_px,
        result.cost,
        result.stack,
        BoardCalibrator::BYTES
    );
    board::exit_success()
}

/// The result, or the failure logged and the run ended.
fn checked(result: Result<CalibRecord, CalibError<CameraError<HostError>>>) -> CalibRecord {
    match result {
        Ok(r) => r,
        Err(CalibError::Source(CameraError::Read(e))) => fail_host("frames.raw", e),
        Err(CalibError::Source(CameraError::WrongSize)) => {
            defmt::error!("frames.raw: a frame of the wrong size");
            board::exit_failure()
        }
        Err(CalibError::Core(e)) => {
            defmt::error!("calibration: {}", e);
            board::exit_failure()
        }
    }
}

/// The ChArUco run: every frame's markers and corners, the views of enough corners kept, the
/// solve; the records to `report`, the summary line, and the run ends. Never inlined: its
/// locals stay out of `main`'s frame, so the chessboard run's stack is its own.
#[inline(never)]
fn charuco(spec: &CalibSpec, camera: &mut RecordedCamera<HostFrames>, report: &mut HostFile) -> ! {
    let fail = |what: &str, e: camgeom::Error| -> ! {
        defmt::error!("{=str}: {}", what, e);
        board::exit_failure()
    };
    let board = board_of(spec).unwrap_or_else(|e| fail("ChArUco board", e));
    let detector = Detector::new(DetectorConfig::default(), &[board.dictionary()])
        .unwrap_or_else(|e| fail("ArUco detector", e));
    let calibrator = match charuco_calibrator(&board, W, H) {
        Ok(c) => CHARUCO_CALIBRATOR.init(c),
        Err(e) => fail("calibrator", e),
    };
    let params = CharucoParams::default();
    let mut ws = WORKSPACE.take().as_mut_view();
    let mut detection = CharucoDetection {
        board: &board,
        detector: &detector,
        workspace: &mut ws,
        params: &params,
    };
    let (mut found, mut corners, mut worst) = (0u32, 0u32, 0u32);
    let result = calibrate_charuco(
        spec,
        camera,
        FRAME.take(),
        &mut detection,
        calibrator,
        &mut SysTickClock,
        &mut |v| {
            found += u32::from(!v.corners.is_empty());
            corners += v.corners.len() as u32;
            worst = worst.max(v.cost);
            if let Err(e) = report.write_all(&v.encode()) {
                fail_host("calib-report.bin", e)
            }
        },
    );
    let mut result = checked(result);
    result.stack = board::stack_usage().0;
    if let Err(e) = report.write_all(&result.encode_n::<CHARUCO_RECORD_LEN>()) {
        fail_host("calib-report.bin", e)
    }
    let [fx, fy, cx, cy] = result.intrinsics;
    defmt::info!(
        "charuco calibration: corners found in {=u32} of {=u32} frames ({=u32} corners), {=u32} views used; fx {=f32} fy {=f32} cx {=f32} cy {=f32}, RMS {=f32} px; worst detection {=u32}, solve {=u32} instructions, stack {=u32} bytes; RAM of the ChArUco path: marker workspace {=usize} bytes, calibrator {=usize} bytes, a frame's corners {=usize} and markers {=usize} bytes (stack), the frame {=usize} bytes",
        found,
        spec.frames,
        corners,
        result.views_used,
        fx,
        fy,
        cx,
        cy,
        result.rms_px,
        worst,
        result.cost,
        result.stack,
        Workspace320x240::BYTES,
        CharucoCalibrator::BYTES,
        core::mem::size_of::<[camgeom::charuco::CharucoCorner; CHARUCO_CORNERS]>(),
        core::mem::size_of::<camgeom::heapless::Vec<camgeom::apriltag::Detection, MARKERS>>(),
        W * H
    );
    board::exit_success()
}
