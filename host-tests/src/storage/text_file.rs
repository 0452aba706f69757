//! Reading a text file: standard input, the byte-order mark, CRLF; its extension.

use std::path::Path;

use crate::error::{Error, ErrorKind, Result};

/// The lower-case extension of `path` (`""` when none).
pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

pub(crate) fn ext_display(ext: &str) -> String {
    if ext.is_empty() {
        "(no extension)".to_string()
    } else {
        format!(".{ext}")
    }
}

/// Reads a UTF-8 text file (`-` reads standard input), dropping a byte-order mark and turning
/// CRLF into LF.
pub fn read_text(path: &Path) -> Result<String> {
    let raw = if path.as_os_str() == "-" {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut std::io::stdin(), &mut s)
            .map(|_| s)
            .map_err(|e| Error::new(path, ErrorKind::Io(e)))?
    } else {
        std::fs::read_to_string(path).map_err(|e| Error::new(path, ErrorKind::Io(e)))?
    };
    let s = raw.strip_prefix('\u{feff}').unwrap_or(&raw);
    Ok(if s.contains('\r') {
        s.replace("\r\n", "\n")
    } else {
        s.to_string()
    })
}
