//! Fixed-point paths.
