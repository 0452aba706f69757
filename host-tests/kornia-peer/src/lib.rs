//! Nothing here: the crate is its bench, `benches/kornia.rs` (see `Cargo.toml`).
