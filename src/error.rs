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
    /// A parameter is outside its documented range.
    InvalidParameter,
    /// Image geometry that cannot be used: a zero or too large size, a stride shorter than the
    /// width, a buffer too short for the geometry, or images whose sizes must match and do not.
    InvalidImage,
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
            Error::InvalidParameter => "parameter out of range",
            Error::InvalidImage => "invalid image geometry",
        })
    }
}

impl core::error::Error for Error {}

/// Result with camgeom's [`Error`].
pub type Result<T> = core::result::Result<T, Error>;
