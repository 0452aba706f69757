//! The dense matrix an `opencv-matrix` node or a plain-text matrix file holds.

use nalgebra::Matrix3;

/// A dense matrix read from an `opencv-matrix` node (row-major, channels interleaved, as OpenCV
/// stores it).
#[derive(Debug, Clone, PartialEq)]
pub struct Matrix {
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Channels per element (`dt: 3d` has 3; usually 1).
    pub channels: usize,
    /// The element type code (`d`, `f`, `i`, `u`, ...), without the channel count.
    pub dt: char,
    /// `rows * cols * channels` values, row-major.
    pub data: Vec<f64>,
}

impl Matrix {
    /// Element `(r, c)` of a single-channel matrix.
    pub fn get(&self, r: usize, c: usize) -> Option<f64> {
        if r < self.rows && c < self.cols && self.channels == 1 {
            self.data.get(r * self.cols + c).copied()
        } else {
            None
        }
    }

    /// Row `r` (all its columns and channels).
    pub fn row(&self, r: usize) -> Option<&[f64]> {
        let w = self.cols * self.channels;
        self.data.get(r * w..(r + 1) * w)
    }

    /// The matrix as an nalgebra 3x3, when it is a single-channel 3x3.
    pub fn to_matrix3(&self) -> Option<Matrix3<f64>> {
        if self.rows == 3 && self.cols == 3 && self.channels == 1 {
            Some(Matrix3::from_row_slice(&self.data))
        } else {
            None
        }
    }

    /// `true` for a single-channel row or column vector.
    pub fn is_vector(&self) -> bool {
        self.channels == 1 && (self.rows == 1 || self.cols == 1)
    }
}
