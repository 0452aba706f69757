//! The arithmetics camgeom computes in, and the one way to choose between them: a type
//! parameter.
//!
//! - `f32`: floating point, for cores with an FPU (Cortex-M4F/M7/M33, hosts).
//! - [`Fixed`]: integers only (Q16.16 coordinates, [`Q16`]; integer sums and thresholds), for
//!   cores without an FPU (Cortex-M0+/M3, RISC-V IMAC), where `f32` is a software library.
//!
//! Every algorithm with an integer path takes the arithmetic as a type, never as a run-time
//! flag or a second function: the other path is compiled out, and a board names its choice
//! once, in the type it puts in a `static`. What each needs of it is a trait:
//!
//! | algorithm | parameter | trait |
//! |---|---|---|
//! | pyramidal Lucas-Kanade ([`crate::klt::calc_flow`], [`crate::klt::Tracker`]) | `A` | [`FlowArith`] |
//! | the AR loop's pose ([`crate::target::PlanarTarget`]) | `A` | [`PoseArith`] |
//! | the perspective warp ([`crate::warp::warp_perspective_into`]) | `A` | [`Arithmetic`] |
//!
//! [`crate::fixed`] holds the integer projective transfer the integer paths share
//! ([`crate::fixed::FixedProjective`]).
//!
//! ```
//! use camgeom::arith::{Arithmetic, Fixed};
//!
//! fn path<A: Arithmetic>() -> &'static str {
//!     A::NAME
//! }
//! assert_eq!((path::<f32>(), path::<Fixed>()), ("f32", "fixed"));
//! ```

pub use crate::fixed::Q16;
pub use crate::klt::{Fixed, FlowArith};
pub use crate::target::PoseArith;

/// An arithmetic (sealed: `f32` and [`Fixed`]).
pub trait Arithmetic: Copy + Default + sealed::Sealed + 'static {
    /// Integer-only ([`Fixed`]) rather than `f32`.
    const INTEGER: bool;
    /// Its name in tables and command lines: `f32` or `fixed`.
    const NAME: &'static str;
}

impl Arithmetic for f32 {
    const INTEGER: bool = false;
    const NAME: &'static str = "f32";
}

impl Arithmetic for Fixed {
    const INTEGER: bool = true;
    const NAME: &'static str = "fixed";
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for super::Fixed {}
}
