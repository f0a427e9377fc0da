//! `cfnav plan MAP`: replays the firmware's D* Lite on a text map (docs/formats.md, map format).
//!
//! The drone starts at `S` believing every `o` free; each loop it senses (every `o` within Chebyshev
//! distance R becomes known), tells the planner which cells changed, replans incrementally, and moves one
//! cell along its path. The loop ends at the goal or when the planner reports that no path exists.

use std::fmt;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use cfnav::nav::dstar::{DStarLite, PlanStatus, move_cost};
use cfnav::nav::map::{Cell, GridShape, Traversability};
use clap::Args;
use serde::Serialize;

/// Largest map the replay accepts: the planner's costs are proven to fit `u16` up to this many cells,
/// which covers the largest arena the firmware maps (128 × 64).
pub const MAX_MAP_CELLS: usize = 128 * 64;
const QUEUE: usize = 8192;
type ReplayPlanner = DStarLite<MAX_MAP_CELLS, QUEUE>;

/// Arguments of `cfnav plan`.
#[derive(Args, Debug)]
pub struct PlanArgs {
    /// The map file (docs/formats.md (map format): `.` free, `#` known obstacle, `o` hidden obstacle, `S`, `G`).
    pub map: PathBuf,
    /// Sensing radius in cells (Chebyshev distance), at least 1.
    #[arg(long, default_value_t = 2)]
    pub sense_radius: u16,
    /// Write the JSON report to this file (`-` for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// A parsed replay map.
#[derive(Clone, Debug)]
pub struct ReplayMap {
    pub width: u16,
    pub height: u16,
    /// What the world really holds.
    truth: Vec<bool>,
    /// What the drone believes (starts with only the `#` cells).
    belief: Vec<bool>,
    pub start: Cell,
    pub goal: Cell,
}

/// A map file problem: which line, what was expected.
#[derive(Debug)]
pub struct MapError {
    pub line: usize,
    pub message: String,
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.message)
        } else {
            write!(f, "line {}: {}", self.line, self.message)
        }
    }
}

impl ReplayMap {
    /// Parse the text of a map file.
    pub fn parse(text: &str) -> Result<Self, MapError> {
        let err = |line: usize, message: String| MapError { line, message };
        let mut rows: Vec<(usize, &str)> = Vec::new();
        for (n, raw) in text.lines().enumerate() {
            let line = raw.strip_suffix('\r').unwrap_or(raw);
            if line.starts_with(';') || line.trim().is_empty() {
                continue;
            }
            if let Some((_, first)) = rows.first()
                && first.chars().count() != line.chars().count()
            {
                return Err(err(
                    n + 1,
                    format!(
                        "row is {} cells wide, expected {} like the first row",
                        line.chars().count(),
                        first.chars().count()
                    ),
                ));
            }
            rows.push((n + 1, line));
        }
        let Some((_, first)) = rows.first() else {
            return Err(err(0, "the map has no rows (expected lines of . # o S G)".into()));
        };
        let width = first.chars().count();
        let height = rows.len();
        if width * height > MAX_MAP_CELLS || width > usize::from(u16::MAX) || height > usize::from(u16::MAX) {
            return Err(err(
                0,
                format!(
                    "the map is {width} × {height} = {} cells; the planner holds at most {MAX_MAP_CELLS} (e.g. 128 × 64)",
                    width * height
                ),
            ));
        }
        let (w, h) = (width as u16, height as u16);
        let mut truth = vec![false; width * height];
        let mut belief = vec![false; width * height];
        let (mut start, mut goal) = (None, None);
        for (r, (line_no, line)) in rows.iter().enumerate() {
            let y = (height - 1 - r) as u16;
            for (x, ch) in line.chars().enumerate() {
                let i = usize::from(y) * width + x;
                let cell = Cell::new(x as u16, y);
                match ch {
                    '.' => {}
                    '#' => {
                        truth[i] = true;
                        belief[i] = true;
                    }
                    'o' => truth[i] = true,
                    'S' if start.is_some() => {
                        return Err(err(*line_no, "a second start `S`; expected exactly one".into()));
                    }
                    'G' if goal.is_some() => {
                        return Err(err(*line_no, "a second goal `G`; expected exactly one".into()));
                    }
                    'S' => start = Some(cell),
                    'G' => goal = Some(cell),
                    other => {
                        return Err(err(
                            *line_no,
                            format!(
                                "unexpected character {other:?} in column {}; expected one of . # o S G",
                                x + 1
                            ),
                        ));
                    }
                }
            }
        }
        let start = start.ok_or_else(|| err(0, "no start `S` in the map".into()))?;
        let goal = goal.ok_or_else(|| err(0, "no goal `G` in the map".into()))?;
        Ok(Self {
            width: w,
            height: h,
            truth,
            belief,
            start,
            goal,
        })
    }

    /// Whether the world holds an obstacle at `c` (`#` or `o`).
    pub fn is_obstacle(&self, c: Cell) -> bool {
        self.truth.get(self.index(c)).copied().unwrap_or(true)
    }

    /// Whether the drone currently believes `c` blocked (before the replay: only the `#` cells).
    pub fn is_believed_blocked(&self, c: Cell) -> bool {
        self.belief.get(self.index(c)).copied().unwrap_or(true)
    }

    fn index(&self, c: Cell) -> usize {
        usize::from(c.y) * usize::from(self.width) + usize::from(c.x)
    }

    /// Reveal every hidden obstacle within `radius` of `at`; returns the cells that changed.
    fn sense(&mut self, at: Cell, radius: u16) -> Vec<Cell> {
        let mut changed = Vec::new();
        let (x0, x1) = (
            at.x.saturating_sub(radius),
            at.x.saturating_add(radius).min(self.width - 1),
        );
        let (y0, y1) = (
            at.y.saturating_sub(radius),
            at.y.saturating_add(radius).min(self.height - 1),
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                let c = Cell::new(x, y);
                let i = self.index(c);
                if self.belief[i] != self.truth[i] {
                    self.belief[i] = self.truth[i];
                    changed.push(c);
                }
            }
        }
        changed
    }
}

/// The drone's belief, as the planner reads it.
struct Belief<'a>(&'a ReplayMap);

impl Traversability for Belief<'_> {
    fn shape(&self) -> GridShape {
        GridShape {
            width: self.0.width,
            height: self.0.height,
        }
    }

    fn is_blocked(&self, x: i32, y: i32) -> bool {
        if x < 0 || y < 0 || x >= i32::from(self.0.width) || y >= i32::from(self.0.height) {
            return true;
        }
        self.0.belief[y as usize * usize::from(self.0.width) + x as usize]
    }
}

/// One sense + replan.
#[derive(Serialize, Debug, Clone)]
pub struct Step {
    pub x: u16,
    pub y: u16,
    pub cost: Option<u32>,
    pub expanded: u32,
    pub changed: usize,
    pub us: f64,
    /// The cells whose occupancy changed before this replan (for benchmarks that replay the sequence).
    #[serde(skip)]
    pub changed_cells: Vec<Cell>,
}

/// The replay report (docs/formats.md, map format), with a few extra fields.
#[derive(Serialize, Debug)]
pub struct Report {
    pub status: &'static str,
    pub width: u16,
    pub height: u16,
    pub steps: Vec<Step>,
    pub moves: u32,
    pub path_cost: u32,
    pub start: [u16; 2],
    pub goal: [u16; 2],
    pub sense_radius: u16,
    pub total_expanded: u64,
    pub max_open_list: usize,
}

/// Replay the planner on a parsed map.
pub fn replay(mut map: ReplayMap, radius: u16) -> anyhow::Result<Report> {
    let mut planner: Box<ReplayPlanner> = Box::new(DStarLite::new());
    let shape = GridShape {
        width: map.width,
        height: map.height,
    };
    planner
        .reset(shape, map.start, map.goal)
        .map_err(|e| anyhow::anyhow!("planner refused the map: {e:?}"))?;
    let mut here = map.start;
    let (mut steps, mut moves, mut path_cost) = (Vec::new(), 0u32, 0u32);
    let status = loop {
        let changed = map.sense(here, radius);
        let t0 = Instant::now();
        planner.set_start(here).map_err(|e| anyhow::anyhow!("planner: {e:?}"))?;
        planner
            .cells_changed(&Belief(&map), &changed)
            .map_err(|e| anyhow::anyhow!("planner: {e:?}"))?;
        let result = planner
            .compute(&Belief(&map), u32::MAX)
            .map_err(|e| anyhow::anyhow!("planner: {e:?}"))?;
        let us = t0.elapsed().as_secs_f64() * 1e6;
        let cost = match result {
            PlanStatus::Found { cost } => Some(cost),
            PlanStatus::NoPath => None,
            PlanStatus::Incomplete => anyhow::bail!("planner stopped with an unlimited budget"),
        };
        steps.push(Step {
            x: here.x,
            y: here.y,
            cost,
            expanded: planner.expansions(),
            changed: changed.len(),
            us,
            changed_cells: changed,
        });
        if cost.is_none() {
            break "no_path";
        }
        if here == map.goal {
            break "reached";
        }
        let belief = Belief(&map);
        let next = planner
            .next_cell(&belief, here)
            .context("planner has a cost but no next cell")?;
        let (dx, dy) = (
            i32::from(next.x) - i32::from(here.x),
            i32::from(next.y) - i32::from(here.y),
        );
        let step_cost = move_cost(&belief, i32::from(here.x), i32::from(here.y), dx, dy)
            .context("planner chose an illegal move")?;
        path_cost += u32::from(step_cost);
        moves += 1;
        here = next;
        anyhow::ensure!(
            moves as usize <= 4 * usize::from(map.width) * usize::from(map.height),
            "the replay did not terminate"
        );
    };
    Ok(Report {
        status,
        width: map.width,
        height: map.height,
        total_expanded: steps.iter().map(|s| u64::from(s.expanded)).sum(),
        steps,
        moves,
        path_cost,
        start: [map.start.x, map.start.y],
        goal: [map.goal.x, map.goal.y],
        sense_radius: radius,
        max_open_list: planner.queue_high_water(),
    })
}

fn load(path: &Path) -> Result<ReplayMap, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    ReplayMap::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// `cfnav plan`.
pub fn run(args: &PlanArgs) -> ExitCode {
    if args.sense_radius == 0 {
        eprintln!("error: --sense-radius must be at least 1 (the drone must see the cell it moves into)");
        return ExitCode::from(2);
    }
    let map = match load(&args.map) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let report = match replay(map, args.sense_radius) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {}: {e:#}", args.map.display());
            return ExitCode::from(2);
        }
    };
    if let Some(out) = &args.json {
        let text = match serde_json::to_string_pretty(&report) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("error: cannot encode the report: {e}");
                return ExitCode::from(2);
            }
        };
        if out.as_os_str() == "-" {
            println!("{text}");
        } else if let Err(e) = std::fs::write(out, text + "\n") {
            eprintln!("error: {}: cannot write: {e}", out.display());
            return ExitCode::from(2);
        }
    }
    if args.json.as_deref().is_none_or(|p| p.as_os_str() != "-") {
        let first = report.steps.first();
        let replans = report.steps.len().saturating_sub(1);
        let replan_us: Vec<f64> = report
            .steps
            .iter()
            .skip(1)
            .filter(|s| s.changed > 0)
            .map(|s| s.us)
            .collect();
        println!(
            "{}: {} ({}×{}), {} moves, path cost {}, first plan {} expansions in {:.0} µs, {} replans ({} after changes, mean {:.0} µs), {} expansions in all",
            args.map.display(),
            report.status,
            report.width,
            report.height,
            report.moves,
            report.path_cost,
            first.map_or(0, |s| s.expanded),
            first.map_or(0.0, |s| s.us),
            replans,
            replan_us.len(),
            if replan_us.is_empty() {
                0.0
            } else {
                replan_us.iter().sum::<f64>() / replan_us.len() as f64
            },
            report.total_expanded,
        );
    }
    ExitCode::from(if report.status == "reached" { 0 } else { 1 })
}
