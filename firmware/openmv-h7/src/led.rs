//! The OpenMV Cam H7's RGB LED as the tracker's state: blue while searching (no target yet),
//! green while tracking, red when the target is lost (the pipeline then looks for it again on
//! every frame: the detector for a tag, the last outline and then the given corners for the
//! card).
//!
//! Pins, from the OpenMV firmware's MicroPython board description
//! (`ports/stm32/boards/OPENMV4/mpconfigboard.h` in openmv/micropython): red PC0, green PC1,
//! blue PC2, each **active low** (the pin sinks the LED's current).

use camgeom::target::TargetState;
use embassy_stm32::Peri;
use embassy_stm32::gpio::{Level, Output, Pin, Speed};

/// The RGB LED.
pub struct Led<'d> {
    red: Output<'d>,
    green: Output<'d>,
    blue: Output<'d>,
}

impl<'d> Led<'d> {
    /// The LED on `red` (PC0), `green` (PC1) and `blue` (PC2), off.
    pub fn new(
        red: Peri<'d, impl Pin>,
        green: Peri<'d, impl Pin>,
        blue: Peri<'d, impl Pin>,
    ) -> Self {
        // High = off (active low).
        Self {
            red: Output::new(red, Level::High, Speed::Low),
            green: Output::new(green, Level::High, Speed::Low),
            blue: Output::new(blue, Level::High, Speed::Low),
        }
    }

    /// Shows `state`: blue for [`TargetState::Uninitialised`] (searching), green for
    /// [`TargetState::Tracking`], red for [`TargetState::Lost`].
    pub fn show(&mut self, state: TargetState) {
        let (r, g, b) = match state {
            TargetState::Uninitialised => (false, false, true),
            TargetState::Tracking => (false, true, false),
            TargetState::Lost => (true, false, false),
        };
        let on = |lit: bool| if lit { Level::Low } else { Level::High };
        self.red.set_level(on(r));
        self.green.set_level(on(g));
        self.blue.set_level(on(b));
    }
}
