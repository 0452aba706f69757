//! The main job's firmware binaries, one per frame size (what `run` runs and `size` measures).

/// One frame size of the main job and the firmware binary built for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    /// Frame width (pixels).
    pub width: u32,
    /// Frame height (pixels).
    pub height: u32,
    /// The firmware binary for this size.
    pub bin: &'static str,
}

impl Size {
    /// `WxH`.
    pub fn name(&self) -> String {
        format!("{}x{}", self.width, self.height)
    }
}

/// 320x240: the main job proper.
pub const FULL: Size = Size {
    width: 320,
    height: 240,
    bin: "camgeom-fw-emulated",
};

/// 160x120: the same pipeline on the sequence downscaled by `pyrDown`.
pub const HALF: Size = Size {
    width: 160,
    height: 120,
    bin: "camgeom-fw-qqvga",
};
