//! What the `camgeom` subcommands share: argument groups ([`args`]), the correspondence
//! input of `homography`, `twoview` and `sfm` ([`matches`](mod@matches)), frame folders
//! ([`frames`]) and output files ([`files`]). A subcommand's module takes these from here,
//! never from another subcommand.

pub mod args;
pub mod files;
pub mod frames;
pub mod matches;
