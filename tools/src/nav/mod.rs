//! Navigation on the host: `cfnav plan`, the planner replay of a `.map` file against the firmware's own
//! D* Lite (what the host tests compare with the Dijkstra oracle and the benches time).

pub mod replay;
