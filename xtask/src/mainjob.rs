//! `cargo xtask run`: the emulated board's main job, and the host-vs-board check.
//!
//! 1. The projection checks (`camgeom-fw-projection`) run first: small and quick.
//! 2. For each frame size (320x240, and 160x120 unless only the first is asked for): the
//!    bundled sequence `host-tests/data/sequences/box/*.png` is turned into raw grayscale
//!    frames (`frames.raw`; 160x120 is OpenCV's `pyrDown` of each frame, camgeom's bit-exact
//!    one) and a run description (`run.bin`: the camera from `box-camera.yml`, the lid corners
//!    from `box-top.csv`, both scaled to the frame size) in `target/camgeom-run/<size>/`.
//! 3. The firmware runs on QEMU in that directory: it reads both over semihosting, logs every
//!    frame and writes overlay frames back (`overlay-NNNN.raw`, turned into PNGs here along
//!    with a contact sheet `overlays.png`).
//! 4. The same `camgeom-fw-app` pipeline, compiled for the host (this crate depends on it),
//!    replays the same bytes. Every frame must agree: state and counts exactly, the checksum of
//!    the Q16.16 track positions bit for bit (issue #8's determinism check), the overlays
//!    byte for byte, and the f32 pose within [`POSE_TOLERANCE`].
//! 5. The per-stage cost table is printed in Markdown (BENCHMARKS.md takes it verbatim).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail, ensure};
use camgeom::image::{ImageMut, ImageView};
use camgeom::pyramid::pyr_down;
use camgeom_fw_app::pipeline::{FrameReport, NoClock, Pipeline};
use camgeom_fw_app::run::{CANDIDATES, LEVELS, RunSpec, TRACKS, WIN};
use camgeom_fw_app::{FrameSource, pipeline_type};

use crate::firmware::{build_and_run_projection, build_bin, run_on_qemu_in, size_report};
use crate::util::root;

/// The lid of the box (OpenCV's real-time pose tutorial mesh, `host-tests/data/README.md`).
const LID_M: [f32; 2] = [0.258, 0.189];
/// Every this many frames an overlay is written back (plus the last).
const OVERLAY_EVERY: u32 = 15;
/// Relative tolerance on the pose (translation and rotation vector, each component against
/// the vector's norm). Both builds do IEEE-754 binary32 arithmetic with round-to-nearest and
/// the same maths library: camgeom without `std` calls `libm` (Rust code, the same on both;
/// its square root is the correctly rounded instruction on each) and LLVM contracts no
/// `a * b + c` into a fused multiply-add without being asked. What differs is the code
/// generator (x86-64 SSE vs Armv7E-M FPv5, instruction selection and order of independent
/// operations) and debug assertions (on in the host build). So the poses are expected to be
/// bit-identical; the tolerance, 1e-5 (about 80 ulp), only keeps a future compiler that
/// contracts or reassociates from failing the run, while any real divergence (a different
/// inlier set moves the pose by 1e-3 or more) still fails it.
const POSE_TOLERANCE: f32 = 1e-5;

/// One frame size of the run.
#[derive(Clone, Copy)]
pub struct Size {
    pub width: u32,
    pub height: u32,
    /// The firmware binary for this size.
    pub bin: &'static str,
}

pub const FULL: Size = Size {
    width: 320,
    height: 240,
    bin: "camgeom-fw-emulated",
};
pub const HALF: Size = Size {
    width: 160,
    height: 120,
    bin: "camgeom-fw-qqvga",
};

/// What `cargo xtask run` (or CI) runs.
pub struct Options {
    pub sizes: Vec<Size>,
    /// Every `stride`-th recorded frame.
    pub stride: u32,
}

impl Options {
    /// `cargo xtask run`: every frame, both sizes.
    pub fn full() -> Self {
        Self {
            sizes: vec![FULL, HALF],
            stride: 1,
        }
    }
}

fn sequence_dir() -> PathBuf {
    root().join("host-tests/data/sequences")
}

/// The run directory of a size.
pub fn run_dir(size: Size) -> PathBuf {
    root()
        .join("target/camgeom-run")
        .join(format!("{}x{}", size.width, size.height))
}

fn read_png(path: &Path) -> Result<(u32, u32, Vec<u8>)> {
    let file = fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size().context("PNG too large")?];
    let info = reader.next_frame(&mut buf)?;
    ensure!(
        info.color_type == png::ColorType::Grayscale && info.bit_depth == png::BitDepth::Eight,
        "{}: expected 8-bit grayscale",
        path.display()
    );
    buf.truncate(info.buffer_size());
    Ok((info.width, info.height, buf))
}

pub fn write_png(path: &Path, width: u32, height: u32, data: &[u8]) -> Result<()> {
    let file =
        fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), width, height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(data)?;
    Ok(())
}

/// `fx fy cx cy` of `box-camera.yml` (no distortion: it states zeros).
fn box_camera() -> Result<[f32; 4]> {
    let path = sequence_dir().join("box-camera.yml");
    let text = fs::read_to_string(&path)?;
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("data:") && l.contains('['))
        .context("box-camera.yml: no camera_matrix data")?;
    let inner = line
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .context("box-camera.yml: bad data row")?
        .0;
    let v: Vec<f32> = inner
        .split(',')
        .map(|s| s.trim().trim_end_matches('.').parse::<f32>())
        .collect::<Result<_, _>>()
        .context("box-camera.yml: bad number")?;
    ensure!(v.len() == 9, "box-camera.yml: camera_matrix is not 3x3");
    Ok([v[0], v[4], v[2], v[5]])
}

/// The lid corners of `box-top.csv`.
fn box_corners() -> Result<[[f32; 2]; 4]> {
    let text = fs::read_to_string(sequence_dir().join("box-top.csv"))?;
    let rows: Vec<[f32; 2]> = text
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let (x, y) = l.split_once(',').context("box-top.csv: bad row")?;
            Ok([x.trim().parse()?, y.trim().parse()?])
        })
        .collect::<Result<_>>()?;
    rows.try_into()
        .map_err(|_| anyhow::anyhow!("box-top.csv: expected 4 corners"))
}

/// Writes `frames.raw` and `run.bin` for `size` (all recorded frames; the stride is in
/// `run.bin`). Returns the run description.
fn prepare(size: Size, opts: &Options, dir: &Path) -> Result<RunSpec> {
    fs::create_dir_all(dir)?;
    let seq = sequence_dir().join("box");
    let mut names: Vec<PathBuf> = fs::read_dir(&seq)
        .with_context(|| format!("cannot read {}", seq.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    names.sort();
    ensure!(!names.is_empty(), "no frames in {}", seq.display());
    let (w, h) = (size.width as usize, size.height as usize);
    let mut raw = Vec::with_capacity(names.len() * w * h);
    for name in &names {
        let (fw, fh, px) = read_png(name)?;
        ensure!(
            (fw, fh) == (320, 240),
            "{}: expected 320x240, got {fw}x{fh}",
            name.display()
        );
        if (fw, fh) == (size.width, size.height) {
            raw.extend_from_slice(&px);
        } else {
            ensure!(
                camgeom::pyramid::down_size(320, 240) == (w, h),
                "only 320x240 and its pyrDown are prepared"
            );
            let src = ImageView::packed(&px, 320, 240).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let mut out = vec![0u8; w * h];
            let mut dst = ImageMut::packed(&mut out, w, h).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            pyr_down(&src, &mut dst).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            raw.extend_from_slice(&out);
        }
    }
    fs::write(dir.join("frames.raw"), &raw)?;
    // pyrDown's output pixel x samples input 2x: positions and intrinsics halve.
    let scale = size.width as f32 / 320.0;
    let [fx, fy, cx, cy] = box_camera()?;
    let spec = RunSpec {
        width: size.width,
        height: size.height,
        frames: names.len() as u32,
        stride: opts.stride,
        overlay_every: OVERLAY_EVERY,
        intrinsics: [fx * scale, fy * scale, cx * scale, cy * scale],
        distortion: [0.0; 5],
        target_size: LID_M,
        corners: box_corners()?.map(|[x, y]| [x * scale, y * scale]),
    };
    fs::write(dir.join("run.bin"), spec.to_bytes())?;
    // Stale overlays from an earlier run must not be mistaken for this one's.
    for e in fs::read_dir(dir)?.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        if n.starts_with("overlay-") {
            fs::remove_file(e.path())?;
        }
    }
    Ok(spec)
}

/// One frame as the board logged it.
#[derive(Debug, Default, Clone, PartialEq)]
struct Logged {
    state: String,
    tracked: usize,
    inliers: usize,
    added: usize,
    features: usize,
    checksum: u32,
    /// `t` then the rotation vector, then the rms.
    pose: Option<[f32; 7]>,
    /// capture pyramid flow homography pose redetect draw total.
    costs: [u32; 8],
}

const STAGES: [&str; 8] = [
    "capture",
    "pyramid",
    "flow",
    "homography",
    "pose",
    "redetect",
    "draw",
    "total",
];

fn words(s: &str) -> Vec<&str> {
    s.split(|c: char| c.is_whitespace() || c == ':' || c == '(' || c == ')')
        .filter(|w| !w.is_empty())
        .collect()
}

/// The value after `key` in `w`.
fn after<'a>(w: &[&'a str], key: &str) -> Result<&'a str> {
    w.iter()
        .position(|x| *x == key)
        .and_then(|i| w.get(i + 1))
        .copied()
        .with_context(|| format!("log line without `{key}`"))
}

/// Parses the board's `frame N`, `pose N` and `cost N` lines.
fn parse_log(messages: &[String]) -> Result<BTreeMap<u32, Logged>> {
    let mut frames: BTreeMap<u32, Logged> = BTreeMap::new();
    for m in messages {
        let w = words(m);
        let (Some(kind), Some(index)) = (w.first(), w.get(1)) else {
            continue;
        };
        let Ok(index) = index.parse::<u32>() else {
            continue;
        };
        match *kind {
            "frame" => {
                let f = frames.entry(index).or_default();
                f.state = w.get(4).copied().unwrap_or("").to_string();
                f.tracked = after(&w, "tracked")?.parse()?;
                f.inliers = after(&w, "inliers")?.parse()?;
                f.added = after(&w, "added")?.parse()?;
                f.features = after(&w, "features")?.parse()?;
                let q = after(&w, "q16")?;
                f.checksum = u32::from_str_radix(q.trim_start_matches("0x"), 16)?;
            }
            "pose" => {
                let t = w.iter().position(|x| *x == "t").context("pose line")?;
                let v: Vec<f32> = w
                    .iter()
                    .skip(t)
                    .filter_map(|x| x.parse::<f32>().ok())
                    .collect();
                ensure!(v.len() == 7, "pose line: {m}");
                let mut p = [0f32; 7];
                p.copy_from_slice(&v);
                frames.entry(index).or_default().pose = Some(p);
            }
            "cost" => {
                let f = frames.entry(index).or_default();
                for (c, name) in f.costs.iter_mut().zip(STAGES) {
                    *c = after(&w, name)?.parse()?;
                }
            }
            _ => {}
        }
    }
    Ok(frames)
}

fn logged_from(r: &FrameReport) -> Logged {
    Logged {
        state: format!("{:?}", r.state),
        tracked: r.tracked,
        inliers: r.inliers,
        added: r.added,
        features: r.features,
        checksum: r.checksum,
        pose: r.pose.map(|p| {
            let t = p.pose.translation();
            let v = p.pose.rotation_vector();
            [t.x, t.y, t.z, v.x, v.y, v.z, p.rms_px]
        }),
        costs: [0; 8],
    }
}

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

/// The host replay: the pipeline over `frames.raw`; every frame's report and the overlays
/// (by delivered frame number).
type Replay = (BTreeMap<u32, Logged>, BTreeMap<u32, Vec<u8>>);

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
    let cfg = spec.app_config().map_err(|e| anyhow::anyhow!("{e:?}"))?;
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
    let first = app
        .start(&cfg, &mut cam, &spec.start_corners(), &mut NoClock)
        .map_err(|e| anyhow::anyhow!("host start: {e:?}"))?;
    out.insert(0, logged_from(&first));
    while let Some(r) = app
        .step(&cfg, &mut cam, &mut NoClock, &mut keep)
        .map_err(|e| anyhow::anyhow!("host step: {e:?}"))?
    {
        out.insert(r.index, logged_from(&r));
    }
    app.finish::<String>(&cfg, &mut keep)
        .map_err(|e| anyhow::anyhow!("host finish: {e:?}"))?;
    Ok((out, overlays))
}

fn replay_size(size: Size, spec: &RunSpec, raw: &[u8]) -> Result<Replay> {
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

/// The largest relative pose difference, per component against the vector's norm.
fn pose_gap(a: &[f32; 7], b: &[f32; 7]) -> f32 {
    let rel = |x: &[f32], y: &[f32]| {
        let n = x.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-6);
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs() / n)
            .fold(0.0f32, f32::max)
    };
    rel(&a[0..3], &b[0..3]).max(rel(&a[3..6], &b[3..6]))
}

/// Compares the board's log with the host replay; returns a one-line verdict.
fn compare(
    board: &BTreeMap<u32, Logged>,
    host: &BTreeMap<u32, Logged>,
    board_overlays: &BTreeMap<u32, Vec<u8>>,
    host_overlays: &BTreeMap<u32, Vec<u8>>,
) -> Result<String> {
    let mut problems = Vec::new();
    if board.len() != host.len() {
        problems.push(format!(
            "the board logged {} frames, the host ran {}",
            board.len(),
            host.len()
        ));
    }
    let (mut worst, mut bit_identical) = (0.0f32, 0usize);
    for (i, h) in host {
        let Some(b) = board.get(i) else {
            problems.push(format!("frame {i}: not in the board's log"));
            continue;
        };
        let counts = |l: &Logged| (l.state.clone(), l.tracked, l.inliers, l.added, l.features);
        if counts(b) != counts(h) {
            problems.push(format!(
                "frame {i}: board {:?}, host {:?} (state, tracked, inliers, added, features)",
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
        match (&b.pose, &h.pose) {
            (Some(p), Some(q)) => {
                let g = pose_gap(p, q);
                worst = worst.max(g);
                bit_identical +=
                    usize::from(p.iter().zip(q).all(|(x, y)| x.to_bits() == y.to_bits()));
                if g > POSE_TOLERANCE {
                    problems.push(format!(
                        "frame {i}: pose differs by {g:e} (relative): board {p:?}, host {q:?}"
                    ));
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
    let poses = host.values().filter(|l| l.pose.is_some()).count();
    Ok(format!(
        "host replay agrees with the board on all {} frames: states and counts equal, Q16.16 \
         track checksums bit-identical (issue #8 determinism), {bit_identical} of {poses} poses \
         bit-identical and all within {POSE_TOLERANCE:e} relative (worst {worst:e}), {} overlays \
         byte-identical",
        host.len(),
        board_overlays.len()
    ))
}

/// Reads the board's overlays, writes them as PNGs and a contact sheet; returns the overlays
/// (by delivered frame number) and the PNG paths.
fn collect_overlays(dir: &Path, size: Size, stride: u32) -> Result<(Overlays, Vec<PathBuf>)> {
    let (w, h) = (size.width as usize, size.height as usize);
    let mut out = BTreeMap::new();
    let mut pngs = Vec::new();
    let mut entries: Vec<PathBuf> = fs::read_dir(dir)?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("overlay-"))
                && p.extension().is_some_and(|e| e == "raw")
        })
        .collect();
    entries.sort();
    for p in entries {
        let data = fs::read(&p)?;
        ensure!(data.len() == w * h, "{}: {} bytes", p.display(), data.len());
        let stem = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let recorded: u32 = stem.trim_start_matches("overlay-").parse()?;
        let png = p.with_extension("png");
        write_png(&png, size.width, size.height, &data)?;
        pngs.push(png);
        out.insert(recorded / stride.max(1), data);
    }
    // Contact sheet: 5 columns, 2 px gaps.
    if !out.is_empty() {
        let cols = out.len().min(5);
        let rows = out.len().div_ceil(cols);
        let (sw, sh) = (cols * (w + 2) - 2, rows * (h + 2) - 2);
        let mut sheet = vec![0u8; sw * sh];
        for (k, img) in out.values().enumerate() {
            let (cx, cy) = ((k % cols) * (w + 2), (k / cols) * (h + 2));
            for y in 0..h {
                let d = (cy + y) * sw + cx;
                sheet[d..d + w].copy_from_slice(&img[y * w..(y + 1) * w]);
            }
        }
        let path = dir.join("overlays.png");
        write_png(&path, sw as u32, sh as u32, &sheet)?;
        pngs.push(path);
    }
    Ok((out, pngs))
}

/// Overlay frames by frame number.
type Overlays = BTreeMap<u32, Vec<u8>>;

/// One row of the cost table.
pub struct Row {
    size: Size,
    frames: usize,
    tracking: usize,
    mean: [u64; 8],
    worst: [u32; 8],
    flash: u64,
    ram: u64,
    pipeline_ram: u64,
    stack: u64,
}

fn number_after(messages: &[String], start: &str, key: &str) -> Option<u64> {
    let m = messages.iter().find(|m| m.starts_with(start))?;
    let w = words(m);
    after(&w, key).ok()?.parse().ok()
}

fn run_size(size: Size, opts: &Options) -> Result<Row> {
    let dir = run_dir(size);
    let t = Instant::now();
    let spec = prepare(size, opts, &dir)?;
    println!(
        "main job {}x{}: input prepared in {} ({:.1} s)",
        size.width,
        size.height,
        dir.strip_prefix(root()).unwrap_or(&dir).display(),
        t.elapsed().as_secs_f64()
    );
    let elf = build_bin(size.bin, &[])?;
    let (flash, ram) = size_report(&elf)?;
    let t = Instant::now();
    let show = |m: &str| !(m.starts_with("cost ") || m.starts_with("pose "));
    let (_, messages) = run_on_qemu_in(&elf, Some(&dir), "main job: ", " frames, ", &show)?;
    let qemu_secs = t.elapsed().as_secs_f64();
    let board = parse_log(&messages)?;
    let (board_overlays, pngs) = collect_overlays(&dir, size, spec.stride)?;

    let t = Instant::now();
    let raw = fs::read(dir.join("frames.raw"))?;
    let (host, host_overlays) = replay_size(size, &spec, &raw)?;
    let host_secs = t.elapsed().as_secs_f64();
    let verdict = compare(&board, &host, &board_overlays, &host_overlays)?;
    println!("main job {}x{}: {verdict}", size.width, size.height);
    println!(
        "main job {}x{}: QEMU {qemu_secs:.1} s, host replay {host_secs:.1} s; overlays: {}",
        size.width,
        size.height,
        pngs.iter()
            .map(|p| p.strip_prefix(root()).unwrap_or(p).display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );

    // Frame 0 starts the target (detection only): the table is over the stepped frames.
    let stepped: Vec<&Logged> = board
        .iter()
        .filter(|(i, _)| **i > 0)
        .map(|(_, l)| l)
        .collect();
    let n = stepped.len().max(1) as u64;
    let mut mean = [0u64; 8];
    let mut worst = [0u32; 8];
    for l in &stepped {
        for k in 0..8 {
            mean[k] += u64::from(l.costs[k]);
            worst[k] = worst[k].max(l.costs[k]);
        }
    }
    for m in &mut mean {
        *m /= n;
    }
    Ok(Row {
        size,
        frames: board.len(),
        tracking: board.values().filter(|l| l.state == "Tracking").count(),
        mean,
        worst,
        flash,
        ram,
        pipeline_ram: number_after(&messages, "main job: ", "RAM").unwrap_or(0),
        stack: number_after(&messages, "stack", "stack").unwrap_or(0),
    })
}

fn m(v: u64) -> String {
    format!("{:.2}M", v as f64 / 1e6)
}

/// The cost table in Markdown.
fn table(rows: &[Row], stride: u32) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Instructions per frame (QEMU `-icount shift=0`, SysTick, +-40), mean / worst over the \
         stepped frames{}:\n",
        if stride > 1 {
            format!(" (every {stride}th recorded frame)")
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        s,
        "| frame | frames (tracking) | pyramid | flow | homography | pose | redetect | draw | total | est. fps at 480 MHz |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let cell = |k: usize| format!("{} / {}", m(r.mean[k]), m(u64::from(r.worst[k])));
        let fps = 480e6 / r.mean[7].max(1) as f64;
        let _ = writeln!(
            s,
            "| {}x{} | {} ({}) | {} | {} | {} | {} | {} | {} | {} | {:.1} |",
            r.size.width,
            r.size.height,
            r.frames,
            r.tracking,
            cell(1),
            cell(2),
            cell(3),
            cell(4),
            cell(5),
            cell(6),
            cell(7),
            fps
        );
    }
    let _ = writeln!(
        s,
        "\n| frame | flash | static RAM (of which the pipeline, from its const sizes) | stack high-water |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    for r in rows {
        let _ = writeln!(
            s,
            "| {}x{} | {} B | {} B ({} B) | {} B |",
            r.size.width, r.size.height, r.flash, r.ram, r.pipeline_ram, r.stack
        );
    }
    s
}

/// `cargo xtask run`.
pub fn run(opts: &Options) -> Result<()> {
    let summary = build_and_run_projection()?;
    println!("projection checks: {summary}");
    let mut rows = Vec::new();
    for &size in &opts.sizes {
        let row = run_size(size, opts)?;
        ensure!(
            row.ram >= row.pipeline_ram,
            "static RAM {} B is less than the pipeline's {} B: the buffers are not in statics",
            row.ram,
            row.pipeline_ram
        );
        rows.push(row);
    }
    println!(
        "\n---- main job cost table (Markdown; fps = 480e6 / mean total, assuming about one \
         instruction per cycle: an estimate) ----\n{}",
        table(&rows, opts.stride)
    );
    let measured: Vec<(&str, u64, u64)> =
        rows.iter().map(|r| (r.size.bin, r.flash, r.ram)).collect();
    crate::size::compare(&measured)?;
    Ok(())
}
