//! Landing: finding an elevated pad from the downward range and flying the lines that find it.
//!
//! Holds the pad detector (range steps → edges → crossings → centre with a confidence, [`pad`]) and the
//! lawnmower line generator for the coarse search ([`sweep`]), and the gate that allows a descent only over
//! the pad's interior, or clear of it ([`gate`]).
//!
//! May depend on: [`crate::types`] and [`crate::math`] only (a sweep's lines are clipped to an arena
//! rectangle it is given). It does not decide when to search or land, nor avoid obstacles on the way: that
//! is [`crate::mission`].
//! Memory: a detector holds a fixed ring of edges (const generic), a sweep a few floats.

pub mod gate;
pub mod pad;
pub mod sweep;
