//! The link fault harness: the emulated board's UART0 (QEMU `-serial tcp:127.0.0.1:PORT`, a
//! client of this harness) carried live to `camgeom monitor`'s code over real localhost
//! sockets, once clean and once through each damaged link.
//!
//! The harness listens before QEMU starts. For each stream (the clean one and each [`Fault`])
//! a thread runs the monitor as `camgeom monitor --tcp ADDR --json --idle S` does
//! ([`camgeom_host::monitor::open_tcp`] and [`camgeom_host::monitor::monitor_link`]) against a
//! listener of the harness. As the board's bytes arrive, the harness keeps them (written to
//! `serial.bin` at the end) and writes each stream's bytes to its monitor: the clean ones as
//! they are, the others through their fault, applied byte by byte with a seeded generator, so
//! that what each monitor reads does not depend on how TCP cut the stream. When QEMU closes
//! UART0 (it exits), the harness closes every monitor's socket and collects what each printed.
//!
//! Nothing can hang: every accept waits at most [`ACCEPT`], a board that sends nothing for
//! [`IDLE`] ends the run, writes to a monitor time out, and each monitor stops after
//! [`IDLE`] without a byte or at the QEMU run's own time limit (which the checks then report:
//! a monitor must end because its board closed).

use std::fs;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::path::PathBuf;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use camgeom::rng::Pcg32;
use camgeom_host::monitor::{LiveLimits, monitor_link, open_tcp};

/// How long the harness waits for a connection (QEMU's, a monitor's).
const ACCEPT: Duration = Duration::from_secs(60);
/// A board or monitor silent this long has stalled.
const IDLE: Duration = Duration::from_secs(30);
/// Longest a whole run may take (QEMU's own limit is `XTASK_QEMU_TIMEOUT`, 120 s by default).
const RUN: Duration = Duration::from_secs(600);

/// One way a link damages a stream.
#[derive(Clone, Copy)]
pub enum Fault {
    /// One bit flipped in this many bytes.
    Flip(u32),
    /// One byte dropped in this many.
    Drop(u32),
    /// One byte sent twice in this many.
    Repeat(u32),
    /// A burst of 16 random bytes in this many.
    Burst(u32),
}

/// The faults of the table, in its order; the `i`-th draws from `Pcg32::new(0x5eed + i)`.
pub const FAULTS: [Fault; 7] = [
    Fault::Flip(1000),
    Fault::Flip(100),
    Fault::Drop(1000),
    Fault::Drop(100),
    Fault::Repeat(1000),
    Fault::Repeat(100),
    Fault::Burst(2000),
];

impl Fault {
    /// The table's name of the fault.
    pub fn name(self) -> String {
        match self {
            Fault::Flip(n) => format!("bit flipped, 1 byte in {n}"),
            Fault::Drop(n) => format!("byte dropped, 1 in {n}"),
            Fault::Repeat(n) => format!("byte repeated, 1 in {n}"),
            Fault::Burst(n) => format!("16-byte burst of noise, 1 in {n} bytes"),
        }
    }

    /// Byte `b` through the faulty link into `out`; returns the bytes it touched.
    fn apply(self, b: u8, rng: &mut Pcg32, out: &mut Vec<u8>) -> usize {
        match self {
            Fault::Flip(n) if rng.below(n) == 0 => {
                out.push(b ^ (1 << rng.below(8)));
                1
            }
            Fault::Drop(n) if rng.below(n) == 0 => 1,
            Fault::Repeat(n) if rng.below(n) == 0 => {
                out.extend([b, b]);
                1
            }
            Fault::Burst(n) if rng.below(n) == 0 => {
                out.push(b);
                out.extend((0..16).map(|_| rng.below(256) as u8));
                16
            }
            _ => {
                out.push(b);
                0
            }
        }
    }
}

/// What one monitor saw.
pub struct Monitored {
    /// The stream's fault, `None` for the clean one.
    pub fault: Option<Fault>,
    /// Bytes the fault touched.
    pub touched: usize,
    /// What the monitor printed (`--json`: one object a line), its last line the link's
    /// counts.
    pub output: String,
    /// It stopped at a limit, not because the board closed the stream.
    pub timed_out: bool,
}

/// What came over the link.
pub struct LiveRun {
    /// The board's bytes (also in `serial.bin`).
    pub bytes: Vec<u8>,
    /// The clean stream's monitor, then one a fault of [`FAULTS`].
    pub monitors: Vec<Monitored>,
}

/// A harness listening for QEMU.
pub struct Harness {
    addr: SocketAddr,
    thread: JoinHandle<Result<LiveRun>>,
}

impl Harness {
    /// Listens on a free localhost port and starts the monitors; the board's stream will be
    /// saved as `serial`.
    pub fn start(serial: PathBuf) -> Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0").context("cannot listen on localhost")?;
        let addr = listener.local_addr()?;
        let mut monitors = Vec::new();
        for fault in std::iter::once(None).chain(FAULTS.map(Some)) {
            monitors.push(MonitorLink::start(fault)?);
        }
        let thread = thread::spawn(move || carry(&listener, monitors, &serial));
        Ok(Self { addr, thread })
    }

    /// Where QEMU connects UART0.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Waits for the board to close its stream and for every monitor to end.
    pub fn finish(self) -> Result<LiveRun> {
        self.thread
            .join()
            .map_err(|_| anyhow!("the link harness panicked"))?
    }
}

/// A monitor thread and the harness's end of its socket.
struct MonitorLink {
    fault: Option<Fault>,
    listener: TcpListener,
    thread: JoinHandle<Result<(String, bool)>>,
}

impl MonitorLink {
    /// A listener, and a thread running the monitor's code against it.
    fn start(fault: Option<Fault>) -> Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let addr = listener.local_addr()?.to_string();
        let thread = thread::spawn(move || {
            let limits = LiveLimits {
                deadline: Some(Instant::now() + RUN),
                idle: Some(IDLE),
            };
            let mut live = open_tcp(&addr, &[], limits).map_err(|e| anyhow!("{e}"))?;
            let mut out = Vec::new();
            let seen = monitor_link(&mut live, &addr, true, &mut out, None, None)
                .map_err(|e| anyhow!("{e}"))?;
            let text = String::from_utf8(out)? + &seen.last + "\n";
            Ok((text, live.timed_out()))
        });
        Ok(Self {
            fault,
            listener,
            thread,
        })
    }
}

/// Accepts one connection on `l` within [`ACCEPT`].
fn accept(l: &TcpListener, what: &str) -> Result<TcpStream> {
    l.set_nonblocking(true)?;
    let start = Instant::now();
    loop {
        match l.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false)?;
                return Ok(s);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if start.elapsed() > ACCEPT {
                    bail!("{what} did not connect within {} s", ACCEPT.as_secs());
                }
                thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(e.into()),
        }
    }
}

/// One stream to a monitor: its socket, its fault's generator and what it touched.
struct Out {
    socket: TcpStream,
    fault: Option<(Fault, Pcg32)>,
    touched: usize,
    buf: Vec<u8>,
}

/// The harness's thread: accepts the monitors and the board, carries the board's bytes to
/// every monitor until the board closes, then collects the monitors.
fn carry(
    board: &TcpListener,
    monitors: Vec<MonitorLink>,
    serial: &std::path::Path,
) -> Result<LiveRun> {
    let mut outs = Vec::new();
    let mut i = 0u64;
    for m in &monitors {
        let socket = accept(&m.listener, "a monitor")?;
        socket.set_write_timeout(Some(IDLE))?;
        let fault = m.fault.map(|f| {
            let rng = Pcg32::new(0x5eed + i);
            i += 1;
            (f, rng)
        });
        outs.push(Out {
            socket,
            fault,
            touched: 0,
            buf: Vec::new(),
        });
    }
    let mut uart = accept(board, "QEMU's UART0")?;
    uart.set_read_timeout(Some(IDLE))?;
    let mut bytes = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        let n = uart
            .read(&mut chunk)
            .context("the board's UART0 stalled or failed")?;
        if n == 0 {
            break;
        }
        let got = &chunk[..n];
        bytes.extend_from_slice(got);
        for o in &mut outs {
            o.buf.clear();
            match &mut o.fault {
                None => o.buf.extend_from_slice(got),
                Some((f, rng)) => {
                    for &b in got {
                        o.touched += f.apply(b, rng, &mut o.buf);
                    }
                }
            }
            o.socket
                .write_all(&o.buf)
                .context("a monitor stopped reading")?;
        }
    }
    fs::write(serial, &bytes).with_context(|| format!("cannot write {}", serial.display()))?;
    for o in &outs {
        o.socket.shutdown(Shutdown::Write)?;
    }
    let mut done = Vec::new();
    for (m, o) in monitors.into_iter().zip(outs) {
        let (output, timed_out) = m
            .thread
            .join()
            .map_err(|_| anyhow!("a monitor panicked"))??;
        done.push(Monitored {
            fault: m.fault,
            touched: o.touched,
            output,
            timed_out,
        });
    }
    Ok(LiveRun {
        bytes,
        monitors: done,
    })
}
