//! The error type of the host side, the loaders' and the `camgeom` CLI's: every error names the
//! file (and line) when there is one and says what is wrong, in one line.

use std::fmt;
use std::path::{Path, PathBuf};

/// What went wrong.
#[derive(Debug)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The file could not be read.
    Io(std::io::Error),
    /// An output (a file, a directory, standard output) could not be written.
    Write(std::io::Error),
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
    /// A command-line usage error: an option's value out of range, or options that do not go
    /// together.
    Usage(String),
    /// The input is well formed but does not determine a result (structure from motion that
    /// registers fewer than two views, ...): the message says why.
    Undetermined(String),
    /// A camgeom operation on the input failed: `context` says which and on what (for example
    /// `"pts.csv: find_homography failed on 3 correspondences"`).
    Camgeom {
        /// What was being done.
        context: String,
        /// The error camgeom returned.
        error: camgeom::Error,
    },
}

/// An error: which file, where in it (when known) and what is wrong.
#[derive(Debug)]
pub struct Error {
    path: Option<PathBuf>,
    line: Option<usize>,
    kind: ErrorKind,
}

/// Result with the host [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, kind: ErrorKind) -> Self {
        Self {
            path: Some(path.into()),
            line: None,
            kind,
        }
    }

    /// An error about line `line` (1-based) of `path`.
    pub fn at_line(path: impl Into<PathBuf>, line: usize, kind: ErrorKind) -> Self {
        Self {
            path: Some(path.into()),
            line: Some(line),
            kind,
        }
    }

    /// No result determined ([`ErrorKind::Undetermined`]), about no file.
    pub fn undetermined(message: impl Into<String>) -> Self {
        Self {
            path: None,
            line: None,
            kind: ErrorKind::Undetermined(message.into()),
        }
    }

    /// A command-line usage error ([`ErrorKind::Usage`]), about no file.
    pub fn usage(message: impl Into<String>) -> Self {
        Self {
            path: None,
            line: None,
            kind: ErrorKind::Usage(message.into()),
        }
    }

    /// A failed camgeom operation ([`ErrorKind::Camgeom`]); `context` names the operation and
    /// its input.
    pub fn camgeom(context: impl Into<String>, error: camgeom::Error) -> Self {
        Self {
            path: None,
            line: None,
            kind: ErrorKind::Camgeom {
                context: context.into(),
                error,
            },
        }
    }

    /// The file the error is about (`-` for standard input), if any.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The 1-based line, when the error is tied to one.
    pub fn line(&self) -> Option<usize> {
        self.line
    }

    /// What is wrong.
    pub fn kind(&self) -> &ErrorKind {
        &self.kind
    }

    /// The camgeom error behind this one, if camgeom rejected the values or an operation.
    pub fn camgeom_error(&self) -> Option<camgeom::Error> {
        match self.kind {
            ErrorKind::Camera(e) | ErrorKind::Camgeom { error: e, .. } => Some(e),
            _ => None,
        }
    }
}

/// How the host names a camgeom error in a message: its stable name, then what it means with
/// the parameter or buffer it is about (`invalid_parameter (parameter out of range: threshold)`).
pub fn describe(e: &camgeom::Error) -> String {
    format!("{} ({e})", e.name())
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(path) = &self.path {
            write!(f, "{}", path.display())?;
            if let Some(line) = self.line {
                write!(f, ":{line}")?;
            }
            f.write_str(": ")?;
        }
        match &self.kind {
            ErrorKind::Io(e) => write!(f, "cannot read: {e}"),
            ErrorKind::Write(e) => write!(f, "cannot write: {e}"),
            ErrorKind::Syntax(m)
            | ErrorKind::Shape(m)
            | ErrorKind::Usage(m)
            | ErrorKind::Undetermined(m) => f.write_str(m),
            ErrorKind::MissingKey(k) => write!(f, "missing key `{k}`"),
            ErrorKind::Unsupported(m) => write!(f, "unsupported: {m}"),
            ErrorKind::Camera(e) => write!(f, "camgeom rejected the values: {}", describe(e)),
            ErrorKind::Camgeom { context, error } => write!(f, "{context}: {}", describe(error)),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            ErrorKind::Io(e) | ErrorKind::Write(e) => Some(e),
            ErrorKind::Camera(e) | ErrorKind::Camgeom { error: e, .. } => Some(e),
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

    #[test]
    fn messages_name_the_file_and_the_camgeom_error() {
        let e = Error::at_line(
            "k.yml",
            5,
            ErrorKind::Camera(camgeom::Error::InvalidIntrinsics),
        );
        assert_eq!(
            e.to_string(),
            "k.yml:5: camgeom rejected the values: invalid_intrinsics (intrinsics do not \
             describe a camera)"
        );
        assert_eq!(e.camgeom_error(), Some(camgeom::Error::InvalidIntrinsics));
        // The parameter a camgeom error is about is part of the message.
        let e = Error::camgeom(
            "m.csv: find_homography failed on 9 correspondences",
            camgeom::Error::InvalidParameter("threshold"),
        );
        assert_eq!(
            e.to_string(),
            "m.csv: find_homography failed on 9 correspondences: invalid_parameter (parameter \
             out of range: threshold)"
        );
        assert_eq!(e.path(), None);
        assert_eq!(
            Error::usage("--win must be 3..=63").to_string(),
            "--win must be 3..=63"
        );
    }
}
