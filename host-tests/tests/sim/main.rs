//! The simulator (tools/src/sim): world files, physics and sensor models, and whole missions flown in it.

mod collide;
mod commander;
mod latency;
mod link_loss;
mod mission;
mod modes;
mod pads;
mod physics;
mod ranger_loss;
mod rooms;
mod sequences;
mod stress;
mod world;

use cfnav::mission::MissionState;
use cfnav_sim::report::Landing;
use cfnav_sim::world::{BODY_RADIUS_M, World};
use cfnav_tools::sim::runner::{RunOptions, run};

/// Whether `landing` (on or beside `world.pads[pad]`) came down on that pad within 6 cm of its centre, or
/// on the floor with the body wholly clear of the pad (farther from its centre than half its diagonal and
/// `world` under the `[sensors]` and `[disturbances]` of the stress file at `path` (relative to the
/// repository root, e.g. `worlds/stress.toml`), overlaid on its own.
pub fn with_stress(mut world: World, path: &str) -> World {
    let file = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path);
    let stress = cfnav_sim::stress::Stress::load(file).unwrap_or_else(|e| panic!("{e}"));
    world.stress = world.stress.overlaid(&stress);
    world
}

/// the body's radius): never across its rim.
pub fn on_pad_centre_or_clear_of_it(world: &World, pad: usize, landing: &Landing) -> bool {
    let Some(p) = world.pads.get(pad) else {
        return false;
    };
    let clear = p.size[0].hypot(p.size[1]) / 2.0 + BODY_RADIUS_M;
    landing.pad == pad && ((landing.on_pad && landing.error_m < 0.06) || (!landing.on_pad && landing.error_m > clear))
}

/// When the default world's mission (its own noise seed, trigger at 1 s, nothing injected) first enters
/// `state`, s. Tests place their faults by the mission's phases read from this run, not at fixed times, so a
/// change that moves the timeline keeps testing the same phases.
pub fn default_world_enters(state: MissionState) -> f64 {
    static TIMELINE: std::sync::OnceLock<Vec<(u8, f64)>> = std::sync::OnceLock::new();
    let timeline = TIMELINE.get_or_init(|| {
        let world = World::default_world();
        let mut options = RunOptions::for_world(&world);
        options.record = true;
        let r = run(&world, &options).expect("runs");
        assert_eq!(r.report.outcome, "completed", "the reference run: {:?}", r.report);
        let mut seen: Vec<(u8, f64)> = Vec::new();
        for p in &r.trace {
            if !seen.iter().any(|(s, _)| *s == p.state) {
                seen.push((p.state, p.t_s));
            }
        }
        seen
    });
    timeline
        .iter()
        .find(|(s, _)| *s == state.code())
        .map(|(_, t)| *t)
        .unwrap_or_else(|| panic!("the reference run never entered {state:?}: {timeline:?}"))
}
