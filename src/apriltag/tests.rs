//! Unit tests of the detector.

#[test]
fn workspace_sizes() {
    use super::*;
    std::println!(
        "Workspace320x240 {} B, Workspace640x480 {} B",
        Workspace320x240::BYTES,
        Workspace640x480::BYTES
    );
}
