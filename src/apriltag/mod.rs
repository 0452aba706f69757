//! AprilTag detection and tag pose in fixed memory (AprilTag 3's pipeline, Olson 2011, Wang and
//! Olson 2016, Krogius et al. 2019, re-designed for caller buffers and bounded work).
//!
//! Stages, per frame (details in the submodules):
//!
//! 1. optional decimation (point sampling, as AprilTag's integer `quad_decimate`);
//! 2. adaptive threshold on 4x4 tiles with the 3x3 tile dilation ([`segment`]);
//! 3. connected components by union-find over provisional labels, white 8-connected, black
//!    4-connected, in caller buffers ([`segment`]);
//! 4. boundary points between black and white components, clustered per component pair
//!    ([`segment`], [`quad`]);
//! 5. a quad per cluster: points sorted by angle, line-fit error maxima as corner candidates,
//!    the best 4-way split, line intersections ([`quad`]);
//! 6. edge refinement along the edge normals in the full frame, then decoding against planar
//!    black/white intensity models, with up to 3 bits corrected by a chunk-indexed code table
//!    ([`decode`], [`family`]);
//! 7. duplicates (overlapping detections of one id) reduced to the best.
//!
//! [`Detector`] holds the validated [`DetectorConfig`] and families; [`Workspace`] the memory
//! (a board's `static`), which the detector takes as a [`WorkspaceView`];
//! [`Detector::detect`] returns the [`Detection`]s in a `heapless::Vec`; [`tag_pose`] gives the
//! metric pose; [`Detector::find_target`] the four corners of one tag in a planar target's
//! corner order, and [`TagTarget`] makes that the AR loop's acquisition step
//! ([`crate::target::PlanarTarget::step`]), which also tracks the tag by detecting it where it
//! must be: [`Detector::refine_target`] (the edge refinement and decoding from a predicted
//! quad), [`Detector::find_target_near`] (the whole pipeline in the region around it) and
//! [`Detector::refine_partial`] (a tag partly hidden or cut by the frame's edge: robust edge
//! fits and the seen cells confirming the id, flagged as partly seen).
//! [`board_pose`] gives one pose from every visible tag of a [`TagBoard`] ([`board`]).
//!
//! **Memory** (the [`Workspace`] table): no byte per pixel is stored. At 320x240 and
//! decimation 1, [`Workspace320x240`] is 119 KB (AprilTag 3 allocates 8 bytes a pixel for its
//! union-find alone, 614 KB, plus a thresholded copy, a cluster hash of `0.2 w h` buckets and
//! the clusters); at 640x480, [`Workspace640x480`] is 271 KB, or [`Workspace320x240`] at
//! decimation 2. Stack: a few KB (the quad fit's tables of 12 candidates, the radix counts).
//! The code tables are in flash ([`families`]).
//!
//! **Work** per frame is bounded by the capacities: `3 + batches` passes over the (decimated)
//! pixels (threshold, labelling, counting, one per point batch; the last three cost `O(runs)`
//! beyond reading the row), at most `3/4 CLUSTERS` clusters, `max_batches · POINTS` boundary
//! points, `max_quads` quads decoded, each cluster's fit linear in its points (radix sort,
//! sliding sums) plus `k²` line fits and `C(k, 4)` splits of its `k ≤ max_nmaxima` corner
//! candidates, each quad's refinement and decoding a constant. Instruction counts per
//! frame, against AprilTag 3's: BENCHMARKS.md, "AprilTag".
//!
//! Coordinates are camgeom's: pixel `(i, j)` is centred at `(i, j)` (OpenCV's convention);
//! AprilTag's are these plus [`APRILTAG_PIXEL_OFFSET`].
//!
//! **ArUco** (OpenCV's `ArucoDetector::detectMarkers`): OpenCV's predefined dictionaries
//! ([`families::DICT_4X4_50`] .. [`families::DICT_ARUCO_MIP_36H12`], OpenCV's ids) are
//! families of [`Kind::Aruco`] decoded by the same pipeline: the quad of the marker's black
//! border against its white quiet zone, the payload read as an AprilTag's, the border cells
//! checked and the bits corrected with OpenCV's rules
//! ([`DetectorConfig::max_erroneous_bits_in_border_rate`],
//! [`DetectorConfig::error_correction_rate`]), the corners in OpenCV's order by
//! [`Detection::aruco_corners`]. A marker needs a white quiet zone around its black border
//! (the printed page's margin; one cell is plenty): without one, on a dark background, the
//! border joins the background, no quad is found and the marker is not detected (OpenCV's
//! detector needs the same contrast for its contour).
//!
//! ```
//! use camgeom::apriltag::{families, Detection, Detector, DetectorConfig, Workspace320x240};
//! use camgeom::image::ImageView;
//!
//! // A 320x240 frame with tag36h11 id 7 drawn 8 pixels a cell (the family's own cells).
//! let mut px = vec![200u8; 320 * 240];
//! for y in -1..9 {
//!     for x in -1..9 {
//!         let white = families::TAG36H11.cell(7, x, y).unwrap();
//!         for dy in 0..8 {
//!             for dx in 0..8 {
//!                 let (u, v) = ((120 + 8 * x + dx) as usize, (80 + 8 * y + dy) as usize);
//!                 px[v * 320 + u] = if white { 230 } else { 20 };
//!             }
//!         }
//!     }
//! }
//! let frame = ImageView::packed(&px, 320, 240)?;
//! let detector = Detector::new(DetectorConfig::default(), &[&families::TAG36H11])?;
//! let mut ws = Box::new(Workspace320x240::new());
//! let tags: heapless::Vec<Detection, 8> = detector.detect(&frame, &mut ws.as_mut_view())?;
//! assert_eq!(tags.len(), 1);
//! assert_eq!(tags[0].id, 7);
//! // Corner 3 is the top-left of the border's outer edge, pixels 120..184 (edges at -0.5).
//! let tl = tags[0].corners[3];
//! assert!((tl.x - 119.5).abs() < 0.5 && (tl.y - 79.5).abs() < 0.5);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod acquire;
pub mod board;
pub mod decode;
mod detector;
pub mod families;
pub mod family;
mod geom;
pub mod label;
mod pose;
pub mod quad;
mod robust_edges;
pub mod segment;
mod track;
mod visible_code;
mod workspace;

/// What [`Detector::detect_into`] tells as each [`Stage`] ends (`StageProbe<Stage>`).
pub use crate::probe::StageProbe;
pub use acquire::{TagTarget, TrackCounts};
pub use board::{
    BoardBuffers, BoardConfig, BoardPose, BoardTag, GridBoard, TagBoard, board_pose, grid_tags,
};
pub use detector::{
    APRILTAG_PIXEL_OFFSET, CORNER_TAG_COORDS, Detection, Detector, DetectorConfig, MAX_FAMILIES,
    Stage,
};
pub use family::{Decoded, Family, Kind, LayoutBit, rotate90};
pub use label::Label;
pub use pose::tag_pose;
pub use segment::MAX_SIDE;
pub use track::{PartialDetection, PartialRefusal, PartialView};
pub use workspace::{
    Stats, Workspace, Workspace320x240, Workspace640x480, WorkspaceView, sort_len, tiles_len,
};

#[cfg(test)]
mod tests;
