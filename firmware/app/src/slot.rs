//! [`Slot`]: an `Option` for state that lives in a zero-initialised `static`.

use camgeom::heapless::Vec;

/// Holds at most one `T`, like `Option<T>`, but its empty value is a zero length and
/// uninitialised storage.
///
/// That matters for a `static`: the linker puts it in `.bss` (zeroed at start-up, no flash)
/// only when every initialised byte of its `const` value is zero. An `Option<T>` whose `T`
/// has a niche (a `bool`, an enum) spells `None` as a nonzero byte inside `T`, which moves the
/// whole static, frame buffers and all, into `.data`: a flash image of the same size that
/// start-up copies into RAM (226 KB of 340 KB flash for the 320x240 pipeline).
pub struct Slot<T>(Vec<T, 1>);

impl<T> Slot<T> {
    /// Empty.
    pub const fn empty() -> Self {
        Self(Vec::new())
    }

    /// Puts `v` in, dropping what was there.
    pub fn set(&mut self, v: T) {
        self.0.clear();
        // Cannot fail: the vector was just emptied and holds one element.
        let _ = self.0.push(v);
    }

    /// The value, if any.
    pub fn get(&self) -> Option<&T> {
        self.0.first()
    }

    /// The value, if any, mutably.
    pub fn get_mut(&mut self) -> Option<&mut T> {
        self.0.first_mut()
    }

    /// Takes the value out, leaving the slot empty.
    pub fn take(&mut self) -> Option<T> {
        self.0.pop()
    }
}

impl<T> Default for Slot<T> {
    fn default() -> Self {
        Self::empty()
    }
}
