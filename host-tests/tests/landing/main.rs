//! Landing (src/landing): the pad detector and the lawnmower sweep.

mod pad;
mod sweep;
