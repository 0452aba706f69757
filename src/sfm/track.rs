//! What the pipeline and the bundle adjustment read: one scene point's pixels in the views.

use nalgebra::Point2;

/// The observations of one scene point in the three views (`None`: not seen), raw pixels.
pub type Track<T = f32> = [Option<Point2<T>>; 3];
