//! The error type of the host-side loaders: every error names the file (and line when known)
//! and says what is wrong, in one line.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong while reading an input file.
#[derive(Debug)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The file could not be read.
    Io(std::io::Error),
    /// The text does not follow the file format (bad YAML/XML/JSON/TOML/CSV syntax, a value that
    /// is not a number where one is required, ...).
    Syntax(String),
    /// A required key is absent.
    MissingKey(String),
    /// A matrix or list has the wrong size or shape.
    Shape(String),
    /// The file is well formed but describes something camgeom does not model (an unknown file
    /// extension, the rational or thin-prism distortion model, ...).
    Unsupported(String),
    /// camgeom rejected the values (for example [`camgeom::Error::InvalidIntrinsics`] for a zero
    /// focal length).
    Camera(camgeom::Error),
}

/// An input error: which file, where in it (when known) and what is wrong.
#[derive(Debug)]
pub struct Error {
    path: PathBuf,
    line: Option<usize>,
    kind: ErrorKind,
}

/// Result with the host [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, kind: ErrorKind) -> Self {
        Self {
            path: path.into(),
            line: None,
            kind,
        }
    }

    /// An error about line `line` (1-based) of `path`.
    pub fn at_line(path: impl Into<PathBuf>, line: usize, kind: ErrorKind) -> Self {
        Self {
            path: path.into(),
            line: Some(line),
            kind,
        }
    }

    /// The file the error is about (`-` for standard input).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The 1-based line, when the error is tied to one.
    pub fn line(&self) -> Option<usize> {
        self.line
    }

    /// What is wrong.
    pub fn kind(&self) -> &ErrorKind {
        &self.kind
    }

    /// The camgeom error behind this one, if camgeom rejected the values.
    pub fn camera_error(&self) -> Option<camgeom::Error> {
        match self.kind {
            ErrorKind::Camera(e) => Some(e),
            _ => None,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        f.write_str(": ")?;
        match &self.kind {
            ErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            ErrorKind::Syntax(m) => write!(f, "{m}"),
            ErrorKind::MissingKey(k) => write!(f, "missing key `{k}`"),
            ErrorKind::Shape(m) => write!(f, "{m}"),
            ErrorKind::Unsupported(m) => write!(f, "unsupported: {m}"),
            ErrorKind::Camera(e) => write!(f, "camgeom rejected the values: {e} ({e:?})"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            ErrorKind::Io(e) => Some(e),
            ErrorKind::Camera(e) => Some(e),
            _ => None,
        }
    }
}

/// The snake-case name of a camgeom error, as the CLI prints it in its `status` column
/// ([`camgeom::Error::name`]): `BehindCamera` → `behind_camera`.
pub fn status_name(e: &camgeom::Error) -> String {
    e.name().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_names_are_snake_case() {
        assert_eq!(status_name(&camgeom::Error::BehindCamera), "behind_camera");
        assert_eq!(status_name(&camgeom::Error::NonFinite), "non_finite");
        assert_eq!(
            status_name(&camgeom::Error::NoConvergence),
            "no_convergence"
        );
        assert_eq!(
            status_name(&camgeom::Error::InvalidParameter("lk.win")),
            "invalid_parameter"
        );
    }
}
