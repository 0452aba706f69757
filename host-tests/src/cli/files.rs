//! The output files of the subcommands, their write errors being output errors (exit status
//! 1, see `CLI.md`).

use std::path::Path;

use crate::error::{Error, ErrorKind, Result};

/// Writes an output file of a subcommand.
pub fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| Error::new(path, ErrorKind::Write(e)))
}

/// Creates an output directory of a subcommand (and its parents).
pub fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| Error::new(path, ErrorKind::Write(e)))
}
