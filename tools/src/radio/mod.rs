//! The radio on the host: a CRTP-over-UDP link for crazyflie-lib (what `cfnav mission start` speaks to the
//! simulator's `--serve` and to a drone's radio bridge) and the on-disk cache of parameter and log TOCs.

pub mod connect;
pub mod toc_cache;
pub mod udp_link;
