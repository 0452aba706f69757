//! `camgeom monitor`: the host end of a board's record stream, from a saved stream file or a
//! TCP socket (an emulated board's UART: QEMU `-serial tcp:...`); the decoding and printing are
//! [`camgeom_host::monitor`].

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;

use camgeom_host::monitor::monitor;
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["replay", "tcp"])))]
pub struct MonitorArgs {
    /// A saved record stream (an emulated board's `serial.bin`, or bytes captured from a real
    /// board's port).
    #[arg(long, value_name = "FILE")]
    replay: Option<PathBuf>,
    /// Connect to a board's stream at HOST:PORT (an emulated board started with QEMU
    /// `-serial tcp:HOST:PORT,server`) and read until it closes.
    #[arg(long, value_name = "HOST:PORT")]
    tcp: Option<String>,
    /// One JSON object a frame record (and one for the summary, one for the link counts)
    /// instead of a table.
    #[arg(long)]
    json: bool,
    /// Also write every frame record as a CSV row to this file.
    #[arg(long, value_name = "LOG.csv")]
    csv: Option<PathBuf>,
}

/// `camgeom monitor`: decodes the stream, printing as it goes; returns the link's counts.
pub fn run(a: &MonitorArgs) -> Result<String> {
    let (name, mut input): (String, Box<dyn Read>) = match (&a.replay, &a.tcp) {
        (Some(p), _) => (
            p.display().to_string(),
            Box::new(File::open(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?),
        ),
        (None, Some(addr)) => (
            addr.clone(),
            Box::new(
                TcpStream::connect(addr)
                    .map_err(|e| Error::new(addr.as_str(), ErrorKind::Io(e)))?,
            ),
        ),
        (None, None) => return Err(Error::usage("give --replay FILE or --tcp HOST:PORT")),
    };
    let mut csv = match &a.csv {
        Some(p) => Some((
            p.as_path(),
            BufWriter::new(File::create(p).map_err(|e| Error::new(p, ErrorKind::Io(e)))?),
        )),
        None => None,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let last = monitor(
        &mut input,
        &name,
        a.json,
        &mut out,
        csv.as_mut().map(|(p, w)| (*p, w as &mut dyn Write)),
    )?;
    if let Some((p, mut w)) = csv {
        w.flush().map_err(|e| Error::new(p, ErrorKind::Io(e)))?;
    }
    Ok(last + "\n")
}
