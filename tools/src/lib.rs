//! The host side of cfnav, grouped like the firmware's `src/`: the planner replay (`nav`), the simulator
//! and its command line (`sim`), the mission trigger (`mission`) and the map download (`map`) over the host's radio link (`radio`), and
//! the firmware image build (`firmware`). The `cfnav` binary (`src/main.rs`) is a thin command-line front
//! end over these modules; benches and tests use them too.

pub mod firmware;
pub mod map;
pub mod mission;
pub mod nav;
pub mod pil;
pub mod radio;
pub mod sim;
