//! Host files over semihosting, and the emulated board's virtual camera.
//!
//! QEMU runs with `-semihosting-config enable=on,target=native`: the ARM semihosting calls
//! `SYS_OPEN`, `SYS_READ`, `SYS_WRITE`, `SYS_SEEK`, `SYS_FLEN` and `SYS_CLOSE` reach the host's
//! file system, relative to QEMU's working directory (`cargo xtask run` starts QEMU in the run
//! directory it prepared: `target/camgeom-run/<size>/`).

use camgeom::image::ImageMut;
use camgeom_fw_app::FrameSource;
use cortex_m_semihosting::{nr, syscall};

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

/// An open host file.
pub struct HostFile {
    fd: usize,
}

/// Longest file name (without the NUL the call needs).
const NAME_MAX: usize = 63;

impl HostFile {
    fn open(name: &str, mode: usize) -> Result<Self, HostError> {
        let mut buf = [0u8; NAME_MAX + 1];
        let bytes = name.as_bytes();
        buf.get_mut(..bytes.len())
            .ok_or(HostError::Name)?
            .copy_from_slice(bytes);
        // SAFETY: SYS_OPEN reads `len` bytes of the NUL-terminated name, which outlives the call.
        let fd = unsafe { syscall!(OPEN, buf.as_ptr(), mode, bytes.len()) };
        if fd as isize == -1 {
            return Err(HostError::Open);
        }
        Ok(Self { fd })
    }

    /// Opens `name` for reading (binary).
    pub fn open_read(name: &str) -> Result<Self, HostError> {
        Self::open(name, nr::open::R_BINARY)
    }

    /// Creates or truncates `name` for writing (binary).
    pub fn create(name: &str) -> Result<Self, HostError> {
        Self::open(name, nr::open::W_TRUNC_BINARY)
    }

    /// Fills `buf` from the current position.
    pub fn read_exact(&mut self, buf: &mut [u8]) -> Result<(), HostError> {
        // SAFETY: SYS_READ writes at most `buf.len()` bytes into `buf`.
        let left = unsafe { syscall!(READ, self.fd, buf.as_mut_ptr(), buf.len()) };
        // The call returns the number of bytes *not* read.
        if left == 0 {
            Ok(())
        } else {
            Err(HostError::Read)
        }
    }

    /// Writes all of `buf`.
    pub fn write_all(&mut self, buf: &[u8]) -> Result<(), HostError> {
        // SAFETY: SYS_WRITE reads `buf.len()` bytes from `buf`.
        let left = unsafe { syscall!(WRITE, self.fd, buf.as_ptr(), buf.len()) };
        if left == 0 {
            Ok(())
        } else {
            Err(HostError::Write)
        }
    }

    /// Moves to byte `pos` from the start.
    pub fn seek(&mut self, pos: usize) -> Result<(), HostError> {
        // SAFETY: no memory is passed.
        let r = unsafe { syscall!(SEEK, self.fd, pos) };
        if r == 0 { Ok(()) } else { Err(HostError::Seek) }
    }

    /// The file's length in bytes.
    pub fn file_len(&self) -> Result<usize, HostError> {
        // SAFETY: no memory is passed.
        let r = unsafe { syscall!(FLEN, self.fd) };
        if r as isize == -1 {
            Err(HostError::Seek)
        } else {
            Ok(r)
        }
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: no memory is passed; a failed close leaves nothing to do.
        unsafe {
            syscall!(CLOSE, self.fd);
        }
    }
}

/// The virtual camera: frames of a recorded sequence, raw `width x height` grayscale bytes one
/// after the other in one host file, delivered every `stride`-th frame up to `count` frames.
pub struct RecordedCamera {
    file: HostFile,
    width: usize,
    height: usize,
    stride: usize,
    count: usize,
    next: usize,
}

impl RecordedCamera {
    /// Opens `name`; `count` is capped to the frames the file holds.
    pub fn open(
        name: &str,
        width: usize,
        height: usize,
        stride: usize,
        count: usize,
    ) -> Result<Self, HostError> {
        let file = HostFile::open_read(name)?;
        let frame = (width * height).max(1);
        let stride = stride.max(1);
        let held = file.file_len()? / frame;
        Ok(Self {
            file,
            width,
            height,
            stride,
            count: count.min(held.div_ceil(stride)),
            next: 0,
        })
    }

    /// Frames this source delivers in all.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The recorded frame number of the `i`-th delivered frame.
    pub fn recorded_index(&self, i: usize) -> usize {
        i * self.stride
    }
}

impl FrameSource for RecordedCamera {
    type Error = HostError;

    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, HostError> {
        if self.next >= self.count {
            return Ok(false);
        }
        if (frame.width(), frame.height()) != (self.width, self.height) {
            return Err(HostError::Read);
        }
        let frame_len = self.width * self.height;
        if self.stride > 1 {
            self.file.seek(self.recorded_index(self.next) * frame_len)?;
        }
        for y in 0..self.height {
            let row = frame.row_mut(y).ok_or(HostError::Read)?;
            let row = row.get_mut(..self.width).ok_or(HostError::Read)?;
            self.file.read_exact(row)?;
        }
        self.next += 1;
        Ok(true)
    }
}
