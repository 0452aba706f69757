//! Host files over semihosting, and the recorded frames of the emulated board's camera.
//!
//! QEMU runs with `-semihosting-config enable=on,target=native`: the semihosting calls
//! `SYS_OPEN`, `SYS_READ`, `SYS_WRITE`, `SYS_SEEK`, `SYS_FLEN` and `SYS_CLOSE` (the same on Arm
//! and RISC-V; made by the `semihosting` crate) reach the host's file system, relative to QEMU's
//! working directory (`cargo xtask run` starts QEMU in the run
//! directory it prepared: `target/camgeom-run/<size>/`).

use core::ffi::CStr;

use camgeom::image::ImageMut;
use camgeom_fw_app::recorded::RecordedFrames;
use semihosting::io::{Read as _, Seek as _, SeekFrom, Write as _};

/// A semihosting call failed (the host returned -1, or moved fewer bytes than asked).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum HostError {
    /// `SYS_OPEN` of the named file failed.
    Open,
    /// A read returned fewer bytes than asked.
    Read,
    /// A write did not take every byte.
    Write,
    /// `SYS_SEEK` or `SYS_FLEN` failed.
    Seek,
    /// The file name does not fit the name buffer.
    Name,
}

/// An open host file (closed when dropped).
pub struct HostFile(semihosting::fs::File);

/// Longest file name (without the NUL the call needs).
const NAME_MAX: usize = 63;

impl HostFile {
    fn open(name: &str, create: bool) -> Result<Self, HostError> {
        let mut buf = [0u8; NAME_MAX + 1];
        buf.get_mut(..name.len())
            .ok_or(HostError::Name)?
            .copy_from_slice(name.as_bytes());
        let path = CStr::from_bytes_until_nul(&buf).map_err(|_| HostError::Name)?;
        let file = if create {
            semihosting::fs::File::create(path)
        } else {
            semihosting::fs::File::open(path)
        };
        file.map(Self).map_err(|_| HostError::Open)
    }

    /// Opens `name` for reading (binary).
    pub fn open_read(name: &str) -> Result<Self, HostError> {
        Self::open(name, false)
    }

    /// Creates or truncates `name` for writing (binary).
    pub fn create(name: &str) -> Result<Self, HostError> {
        Self::open(name, true)
    }

    /// Fills `buf` from the current position.
    pub fn read_exact(&mut self, buf: &mut [u8]) -> Result<(), HostError> {
        self.0.read_exact(buf).map_err(|_| HostError::Read)
    }

    /// Writes all of `buf`.
    pub fn write_all(&mut self, buf: &[u8]) -> Result<(), HostError> {
        self.0.write_all(buf).map_err(|_| HostError::Write)
    }

    /// Moves to byte `pos` from the start.
    pub fn seek(&mut self, pos: usize) -> Result<(), HostError> {
        self.0
            .seek(SeekFrom::Start(pos as u64))
            .map(|_| ())
            .map_err(|_| HostError::Seek)
    }

    /// The file's length in bytes.
    pub fn file_len(&self) -> Result<usize, HostError> {
        let len = self.0.metadata().map_err(|_| HostError::Seek)?.len();
        usize::try_from(len).map_err(|_| HostError::Seek)
    }
}

/// A recording in a host file: raw `width x height` grayscale frames one after the other, read
/// over semihosting (random access, for [`camgeom_fw_app::recorded::RecordedCamera`]).
pub struct HostFrames {
    file: HostFile,
    width: usize,
    height: usize,
    len: usize,
}

impl HostFrames {
    /// Opens `name` for frames of `width x height`.
    pub fn open(name: &str, width: usize, height: usize) -> Result<Self, HostError> {
        let file = HostFile::open_read(name)?;
        let len = file.file_len()? / (width * height).max(1);
        Ok(Self {
            file,
            width,
            height,
            len,
        })
    }
}

/// What [`RecordedFrames::failing_read`] opens: a name no run directory holds, so the host
/// refuses the call.
const MISSING: &str = "no-such-frame.raw";

impl RecordedFrames for HostFrames {
    type Error = HostError;

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn len(&self) -> usize {
        self.len
    }

    fn read_rows(
        &mut self,
        index: usize,
        rows: core::ops::Range<usize>,
        frame: &mut ImageMut<'_, u8>,
    ) -> Result<(), HostError> {
        let w = self.width;
        self.file.seek((index * self.height + rows.start) * w)?;
        for y in rows {
            let row = frame.row_mut(y).ok_or(HostError::Read)?;
            self.file
                .read_exact(row.get_mut(..w).ok_or(HostError::Read)?)?;
        }
        Ok(())
    }

    fn failing_read(&mut self) -> HostError {
        match HostFile::open_read(MISSING) {
            Err(e) => e,
            // Someone made the file: still a frame that did not arrive.
            Ok(_) => HostError::Read,
        }
    }
}
