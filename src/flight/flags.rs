//! One definition of the bit flags the flight modules report each tick, for logs and tests.
//!
//! Job: a `u16` of flags with `contains` and `set`. The meaning of each bit belongs to the module that sets
//! it: `Flags<K>` is a different type for each owner `K` ([`ControlFlags`](super::control::ControlFlags),
//! [`SupervisorFlags`](super::supervisor::SupervisorFlags)), and each owner declares its bits as associated
//! constants on its own `Flags<K>`, so one module's flag cannot be tested on the other's output.
//! Non-goals: names or printing of single bits. Memory: two bytes.

use core::fmt;
use core::marker::PhantomData;

/// A set of bit flags owned by the module `K`; see the module documentation.
pub struct Flags<K>(pub u16, PhantomData<K>);

impl<K> Flags<K> {
    /// The flags with exactly these bits set.
    pub const fn from_bits(bits: u16) -> Self {
        Self(bits, PhantomData)
    }

    /// Whether `flag` (one of the owner's constants) is set.
    pub fn contains(self, flag: u16) -> bool {
        self.0 & flag != 0
    }

    /// Sets `flag` when `on`; never clears a bit (a tick's flags only accumulate).
    pub(crate) fn set(&mut self, flag: u16, on: bool) {
        if on {
            self.0 |= flag;
        }
    }
}

// Written out rather than derived: a derive would ask the marker `K` for the same traits.
impl<K> Clone for Flags<K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<K> Copy for Flags<K> {}

impl<K> Default for Flags<K> {
    fn default() -> Self {
        Self::from_bits(0)
    }
}

impl<K> PartialEq for Flags<K> {
    fn eq(&self, other: &Self) -> bool {
        self.0 == other.0
    }
}

impl<K> Eq for Flags<K> {}

impl<K> fmt::Debug for Flags<K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Flags({:#06x})", self.0)
    }
}
