//! The one error type of camgeom.

use core::fmt;

/// Why a camgeom operation could not produce a trustworthy result.
///
/// Every fallible public function returns this instead of panicking, returning NaN or returning
/// a silently wrong answer. New variants may be added as capabilities grow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// An input held NaN or an infinity.
    NonFinite,
    /// Intrinsics that do not describe a camera: focal length not strictly positive, a `K`
    /// whose last row is not `[0 0 1]`, or a singular `K`.
    InvalidIntrinsics,
    /// The point lies on or behind the camera's principal plane (`z <= 0` in the camera frame),
    /// so it has no image.
    BehindCamera,
    /// A homogeneous point with `w ~ 0` (an ideal point) where a finite point was required.
    AtInfinity,
    /// The configuration is degenerate: coincident points, identical lines, collinear samples.
    Degenerate,
    /// An iterative method reached its iteration cap without meeting its tolerance.
    NoConvergence,
    /// A value does not fit the fixed-point format.
    Overflow,
    /// Slices that must have matching lengths do not.
    LengthMismatch,
    /// Fewer inputs than the method needs.
    TooFewPoints,
    /// A parameter is outside its documented range. Names it as the configuration spells it
    /// (`"lk.win"`, `"threshold"`, `"levels"`, ...).
    InvalidParameter(&'static str),
    /// A caller-provided buffer is shorter than the `const fn` that sizes it asks for. Names
    /// the buffer (`"scratch"`, `"out"`, ...).
    BufferTooSmall(&'static str),
    /// Image geometry that cannot be used: a zero or too large size, a stride shorter than the
    /// width, a buffer too short for the geometry, or images whose sizes must match and do not.
    InvalidImage,
}

impl Error {
    /// The error's kind in snake case (`non_finite`, `invalid_parameter`, ...): stable across
    /// releases, for command-line tools, logs and board reports to name errors by.
    ///
    /// ```
    /// use camgeom::Error;
    /// use camgeom::camera::Intrinsics;
    ///
    /// let err = Intrinsics::new(-500.0f32, 500.0, 320.0, 240.0).unwrap_err();
    /// assert_eq!(err.name(), "invalid_intrinsics");
    /// // The subject is left out of the name (it is in `subject` and the message).
    /// let e = Error::BufferTooSmall("scratch");
    /// assert_eq!((e.name(), e.subject()), ("buffer_too_small", Some("scratch")));
    /// assert_eq!(e.to_string(), "buffer too small: scratch");
    /// // Every kind has its own snake-case name.
    /// for (i, a) in Error::ALL.iter().enumerate() {
    ///     assert!(a.name().bytes().all(|b| b.is_ascii_lowercase() || b == b'_'));
    ///     assert!(Error::ALL[..i].iter().all(|b| b.name() != a.name()));
    /// }
    /// ```
    pub const fn name(&self) -> &'static str {
        match self {
            Error::NonFinite => "non_finite",
            Error::InvalidIntrinsics => "invalid_intrinsics",
            Error::BehindCamera => "behind_camera",
            Error::AtInfinity => "at_infinity",
            Error::Degenerate => "degenerate",
            Error::NoConvergence => "no_convergence",
            Error::Overflow => "overflow",
            Error::LengthMismatch => "length_mismatch",
            Error::TooFewPoints => "too_few_points",
            Error::InvalidParameter(_) => "invalid_parameter",
            Error::BufferTooSmall(_) => "buffer_too_small",
            Error::InvalidImage => "invalid_image",
        }
    }

    /// The parameter or buffer the error is about, for [`Error::InvalidParameter`] and
    /// [`Error::BufferTooSmall`].
    pub const fn subject(&self) -> Option<&'static str> {
        match self {
            Error::InvalidParameter(p) | Error::BufferTooSmall(p) => Some(p),
            _ => None,
        }
    }

    /// Every kind, in declaration order (with a placeholder subject), for tables and tests.
    pub const ALL: [Error; 12] = [
        Error::NonFinite,
        Error::InvalidIntrinsics,
        Error::BehindCamera,
        Error::AtInfinity,
        Error::Degenerate,
        Error::NoConvergence,
        Error::Overflow,
        Error::LengthMismatch,
        Error::TooFewPoints,
        Error::InvalidParameter("parameter"),
        Error::BufferTooSmall("buffer"),
        Error::InvalidImage,
    ];
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Error::NonFinite => "input is NaN or infinite",
            Error::InvalidIntrinsics => "intrinsics do not describe a camera",
            Error::BehindCamera => "point is on or behind the camera plane",
            Error::AtInfinity => "point is at infinity",
            Error::Degenerate => "degenerate configuration",
            Error::NoConvergence => "iteration did not converge within its bound",
            Error::Overflow => "value out of fixed-point range",
            Error::LengthMismatch => "slice lengths do not match",
            Error::TooFewPoints => "too few points",
            Error::InvalidParameter(p) => return write!(f, "parameter out of range: {p}"),
            Error::BufferTooSmall(b) => return write!(f, "buffer too small: {b}"),
            Error::InvalidImage => "invalid image geometry",
        })
    }
}

impl core::error::Error for Error {}

/// Result with camgeom's [`Error`].
pub type Result<T> = core::result::Result<T, Error>;
