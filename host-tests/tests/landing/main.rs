//! Landing (src/landing): the pad detector, the lawnmower sweep and the descent gate.

mod gate;
mod pad;
mod sweep;
