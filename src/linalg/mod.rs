//! Small dense linear algebra for fixed-size systems, without allocation.
//!
//! - [`svd_jacobi`]: one-sided Jacobi SVD `A = U Σ Vᵀ` of an `R x C` static matrix (`R ≥ C`),
//!   bounded sweeps, singular values sorted descending;
//! - [`StreamingQr`]: the `R` of `A = Q R` for a tall `A` absorbed row by row, so that
//!   `AᵀA = RᵀR` without forming `AᵀA` (whose condition number is `cond(A)²`).
//!
//! - [`lm`]: a bounded Levenberg-Marquardt driver on top of the streaming QR.
//!
//! Together they give least-squares null vectors of arbitrarily many equations in constant
//! memory: push the rows into a [`StreamingQr`], then take [`Svd::null_vector`] of `R`. That is
//! how [`crate::homography`] solves the DLT.
//!
//! ```
//! use camgeom::linalg::{StreamingQr, svd_jacobi};
//! use camgeom::nalgebra::{Matrix2, Vector3};
//!
//! // AᵀA = [25 20; 20 25] has eigenvalues 45 and 5: the singular values are √45 and √5.
//! let a = Matrix2::new(3.0f64, 0.0, 4.0, 5.0);
//! let svd = svd_jacobi(&a)?;
//! assert!((svd.singular_values[0] - 45f64.sqrt()).abs() < 1e-12);
//! assert!((svd.singular_values[1] - 5f64.sqrt()).abs() < 1e-12);
//! assert!((svd.recompose() - a).amax() < 1e-12);
//! // The line 2x - y + 3 = 0 from 100 of its points, one row (x, y, 1) at a time.
//! let mut qr = StreamingQr::<f64, 3>::new();
//! for i in 0..100 {
//!     let x = f64::from(i) * 0.37 - 9.0;
//!     qr.push_row(&[x, 2.0 * x + 3.0, 1.0])?;
//! }
//! let (l, residual) = qr.null_vector()?;
//! let truth = Vector3::new(2.0, -1.0, 3.0).normalize();
//! assert!(residual < 1e-10 && (l - truth).amax().min((l + truth).amax()) < 1e-12);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod cholesky;
mod eigen;
mod elementary;
pub mod lm;
mod nullspace;
mod qr;
mod reduction;
mod rotation;
mod svd;

pub(crate) use cholesky::cholesky_solve;
pub(crate) use eigen::{null_vector, real_eigenvalues};
pub(crate) use elementary::{column, hypot, swap_rows};
pub(crate) use nullspace::null_space;
pub use qr::StreamingQr;
pub(crate) use reduction::Reduced;
pub use rotation::closest_rotation;
pub(crate) use rotation::rotation_step;
pub use svd::{MAX_SWEEPS, Svd, svd_jacobi};
