//! Points and lines of the projective plane.
