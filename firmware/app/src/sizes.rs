//! The pipeline storage of the main job's geometries, each spelled once.
//!
//! A [`Pipeline`]'s buffer lengths are `const fn`s of its geometry: frame size, pyramid
//! levels ([`LEVELS`]), KLT window ([`WIN`]), detector candidates ([`CANDIDATES`]) and tracks
//! ([`TRACKS`]). A board puts one of these types in a `static`; code that runs it takes a
//! [`FrameLoop`](crate::pipeline::FrameLoop) and never names the sizes. A new geometry is
//! one more alias here.

use crate::pipeline::{
    Pipeline, corner_scratch_len, flow_scratch_len, frame_len, kept_flow_scratch_len, pyramid_len,
};
use crate::run::{CANDIDATES, LEVELS, TRACKS, WIN};

/// The 320x240 (QVGA) pipeline of the main job.
pub type Qvga = Pipeline<
    { frame_len(320, 240) },
    { pyramid_len(320, 240, LEVELS) },
    { flow_scratch_len(WIN) },
    { corner_scratch_len(320) },
    CANDIDATES,
    TRACKS,
>;

/// The 320x240 pipeline whose flow scratch also keeps the forward-backward check's templates
/// for the next frame ([`kept_flow_scratch_len`]: the same results, less work with the check
/// on, much more RAM).
pub type QvgaKept = Pipeline<
    { frame_len(320, 240) },
    { pyramid_len(320, 240, LEVELS) },
    { kept_flow_scratch_len(WIN, LEVELS - 1, TRACKS) },
    { corner_scratch_len(320) },
    CANDIDATES,
    TRACKS,
>;

/// The 160x120 (QQVGA) pipeline of the main job.
pub type Qqvga = Pipeline<
    { frame_len(160, 120) },
    { pyramid_len(160, 120, LEVELS) },
    { flow_scratch_len(WIN) },
    { corner_scratch_len(160) },
    CANDIDATES,
    TRACKS,
>;
