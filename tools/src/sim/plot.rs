//! (being written) Plots of a run.
use std::path::Path;

use super::runner::RunResult;
use super::world::World;

/// Draw a run (being written).
pub fn draw(_world: &World, _result: &RunResult, path: &Path) -> Result<(), String> {
    Err(format!("{}: plotting is being written", path.display()))
}
