//! camgeom's on-board application, shared by every board crate.
//!
//! A board supplies frames through [`FrameSource`] (a camera, or a recorded sequence read
//! from the host on the emulator); everything downstream of the frame is the same code on
//! every board.
#![no_std]

pub mod source;

pub use source::FrameSource;
