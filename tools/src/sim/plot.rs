//! Plots of a run: one figure of the arena seen from above (x right, y up, equal scales, 1 m grid) with the
//! true obstacles and pads, the map the drone believed at the end, the planned paths, the flown track and the
//! estimate, the pad locks and the landings, under a title with the outcome.
//!
//! `.svg` or `.png`, chosen by the file name. The SVG writes its text (title, legend, axis labels) as SVG
//! `<text>`, which needs no font file. The bitmap backend cannot draw text without a font backend (plotters'
//! `ttf` or `ab_glyph` features, which need system fonts or a shipped font file), so the PNG writes its text
//! with a small built-in 5 × 7 pixel font (capitals, digits and some punctuation).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::runner::RunResult;
use cfnav_sim::world::{ALL_WALLS, WALL_EAST, WALL_NORTH, WALL_SOUTH, WALL_WEST, World};

/// Width of the figure, px.
const WIDTH: u32 = 1600;
/// Left margin (y tick labels), px.
const LEFT: i32 = 60;
/// Right margin, px.
const RIGHT: i32 = 40;
/// Top margin (title lines and the y axis caption), px.
const TOP: i32 = 136;
/// Tallest the arena may be drawn, px.
const MAX_PLOT_HEIGHT: f32 = 1000.0;
/// Space under the arena for the x tick labels and caption, px.
const AXIS_SPACE: i32 = 70;
/// Legend layout, px.
const LEGEND_COLUMNS: usize = 4;
const LEGEND_ROW: i32 = 34;
const SWATCH: i32 = 40;

const GRID: RGBColor = RGBColor(220, 220, 220);
const WALL: RGBColor = RGBColor(30, 30, 30);
const OBSTACLE: RGBColor = RGBColor(150, 150, 150);
/// A floor patch the flow sensor reads poorly.
const POOR_FLOOR: RGBColor = RGBColor(236, 226, 200);
/// A walker's path and its starting point.
const MOVER: RGBColor = RGBColor(170, 60, 160);
const OBSTACLE_EDGE: RGBColor = RGBColor(80, 80, 80);
const LOW_OBSTACLE: RGBColor = RGBColor(210, 210, 210);
const LOW_OBSTACLE_EDGE: RGBColor = RGBColor(150, 150, 150);
const HOME: RGBColor = RGBColor(0, 150, 40);
const GOAL: RGBColor = RGBColor(0, 90, 220);
const OTHER_PAD: RGBColor = RGBColor(110, 110, 110);
const OCCUPIED: RGBAColor = RGBAColor(170, 0, 0, 0.55);
const BLOCKED: RGBAColor = RGBAColor(255, 70, 70, 0.2);
const PLAN_OLD: RGBAColor = RGBAColor(120, 60, 190, 0.15);
const PLAN_LAST: RGBColor = RGBColor(110, 40, 180);
const OUTBOUND: RGBColor = RGBColor(235, 120, 0);
const RETURN: RGBColor = RGBColor(0, 150, 150);
const HOVER: RGBColor = RGBColor(210, 0, 170);
const ESTIMATE: RGBColor = RGBColor(40, 40, 40);
const MARK: RGBColor = RGBColor(0, 0, 0);

/// Draw one run to `path`: an SVG (`.svg`) or a PNG (`.png`, 1600 px wide).
pub fn draw(world: &World, result: &RunResult, path: &Path) -> Result<(), String> {
    draw_labelled(world, result, path, None)
}

/// Title lines and what is known of the world, for a figure that is not a simulator run (`cfnav map`).
pub struct Labels {
    /// First line.
    pub title: String,
    /// The two lines under it.
    pub subtitle: [String; 2],
    /// Whether `world` is the real one (obstacles, pads, nominal start and goal); otherwise only its
    /// arena's size is drawn and the legend leaves the rest out.
    pub world_known: bool,
}

/// [`draw`] with other title lines (and, without a known world, no obstacles, pads or nominal marks).
pub fn draw_labelled(world: &World, result: &RunResult, path: &Path, labels: Option<&Labels>) -> Result<(), String> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let mut figure = Figure::new(world, result);
    if let Some(l) = labels {
        figure.title = l.title.clone();
        figure.subtitle = l.subtitle.clone();
        figure.nominal = l.world_known;
        if !l.world_known {
            figure.legend.retain(|(swatch, label)| {
                !matches!(swatch, Swatch::Start | Swatch::Goal | Swatch::Outline(_)) && !label.starts_with("obstacle")
            });
        }
    }
    let size = (WIDTH, figure.height);
    let fail = |e: String| format!("{}: cannot draw the plot: {e}", path.display());
    match ext.as_deref() {
        Some("svg") => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            figure.render(&root, world, result, TextKind::Svg).map_err(fail)?;
            root.present().map_err(|e| fail(e.to_string()))
        }
        Some("png") => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            figure.render(&root, world, result, TextKind::Pixel).map_err(fail)?;
            root.present().map_err(|e| fail(e.to_string()))
        }
        _ => Err(format!(
            "{}: cannot plot to this file; expected a name ending in .svg or .png",
            path.display()
        )),
    }
}

/// How the text is written.
#[derive(Clone, Copy, PartialEq)]
enum TextKind {
    /// SVG `<text>`.
    Svg,
    /// Rectangles of the built-in pixel font.
    Pixel,
}

/// Text sizes.
#[derive(Clone, Copy)]
enum Size {
    Title,
    Normal,
}

/// The mission phase a track point belongs to (its colour).
#[derive(Clone, Copy, PartialEq)]
enum Phase {
    Outbound,
    Return,
    Hover,
}

impl Phase {
    /// The phase of a `mission.state` code; `None` for idle and the final states (they keep the previous one).
    fn of(state: u8) -> Option<Phase> {
        match state {
            1..=15 => Some(Phase::Outbound),
            20..=24 => Some(Phase::Return),
            30 | 40 => Some(Phase::Hover),
            _ => None,
        }
    }

    fn color(self) -> RGBColor {
        match self {
            Phase::Outbound => OUTBOUND,
            Phase::Return => RETURN,
            Phase::Hover => HOVER,
        }
    }
}

/// A legend's sample.
#[derive(Clone, Copy)]
enum Swatch {
    Fill(RGBAColor, RGBAColor),
    Outline(RGBColor),
    Line(RGBAColor, u32),
    Dashed(RGBColor, u32),
    Start,
    Goal,
    Cross,
    Ring,
}

/// The figure's layout and legend, known before a backend is opened.
struct Figure {
    /// Figure height, px.
    height: u32,
    /// Arena size drawn, m.
    arena: (f32, f32),
    /// Pixels per metre.
    scale: f32,
    /// Pixel position of the arena's (0, 0) corner.
    origin: (i32, i32),
    /// Top of the legend, px.
    legend_top: i32,
    legend: Vec<(Swatch, String)>,
    title: String,
    subtitle: [String; 2],
    /// Draw the nominal start and goal.
    nominal: bool,
}

impl Figure {
    fn new(world: &World, result: &RunResult) -> Figure {
        let side = |v: f32| if v.is_finite() && v > 0.0 { v } else { 1.0 };
        let arena = (side(world.arena.size[0]), side(world.arena.size[1]));
        let plot_width = (WIDTH as i32 - LEFT - RIGHT) as f32;
        let scale = (plot_width / arena.0).min(MAX_PLOT_HEIGHT / arena.1);
        let drawn = ((arena.0 * scale).round() as i32, (arena.1 * scale).round() as i32);
        let x0 = LEFT + (plot_width as i32 - drawn.0) / 2;
        let origin = (x0, TOP + drawn.1);
        let legend = legend(world, result);
        let legend_top = origin.1 + AXIS_SPACE;
        let rows = legend.len().div_ceil(LEGEND_COLUMNS) as i32;
        let height = (legend_top + rows * LEGEND_ROW + 16) as u32;
        let (title, subtitle) = titles(world, result);
        Figure {
            height,
            arena,
            scale,
            origin,
            legend_top,
            legend,
            title,
            subtitle,
            nominal: true,
        }
    }

    /// Pixel position of an arena point.
    fn px(&self, x: f32, y: f32) -> (i32, i32) {
        (
            self.origin.0 + (x * self.scale).round() as i32,
            self.origin.1 - (y * self.scale).round() as i32,
        )
    }

    fn render<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        world: &World,
        result: &RunResult,
        text: TextKind,
    ) -> Result<(), String> {
        let p = Painter { root, text };
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (aw, ah) = self.arena;

        // The 1 m grid and its labels.
        for i in 0..=(aw.floor() as i32) {
            let x = i as f32;
            p.path(vec![self.px(x, 0.0), self.px(x, ah)], GRID.stroke_width(1))?;
            let (px, py) = self.px(x, 0.0);
            p.text(&i.to_string(), (px, py + 10), Size::Normal, HPos::Center, MARK)?;
        }
        for j in 0..=(ah.floor() as i32) {
            let y = j as f32;
            p.path(vec![self.px(0.0, y), self.px(aw, y)], GRID.stroke_width(1))?;
            let (px, py) = self.px(0.0, y);
            p.text(&j.to_string(), (px - 12, py - 7), Size::Normal, HPos::Right, MARK)?;
        }
        let (cx, cy) = self.px(aw / 2.0, 0.0);
        p.text("x (m)", (cx, cy + 38), Size::Normal, HPos::Center, MARK)?;
        let (tx, ty) = self.px(0.0, ah);
        p.text("y (m)", (tx, ty - 28), Size::Normal, HPos::Left, MARK)?;

        // Poor floor patches (the flow sensor reads them poorly), under everything else.
        for f in &world.floor {
            p.rect(
                self.px(f.min[0], f.max[1]),
                self.px(f.max[0], f.min[1]),
                POOR_FLOOR.filled(),
            )?;
        }

        // True obstacles (lower than the cruise height in a lighter grey: the drone may fly over them).
        let low = |h: f32| h <= world.mission.height;
        for b in &world.boxes {
            let (fill, edge) = if low(b.height) {
                (LOW_OBSTACLE, LOW_OBSTACLE_EDGE)
            } else {
                (OBSTACLE, OBSTACLE_EDGE)
            };
            if b.yaw_deg == 0.0 {
                p.rect(self.px(b.min[0], b.max[1]), self.px(b.max[0], b.min[1]), fill.filled())?;
                p.outline(&self.rect_corners(b.min, b.max), edge.stroke_width(1))?;
            } else {
                let corners: Vec<(i32, i32)> = b.corners().iter().map(|c| self.px(c[0], c[1])).collect();
                root.draw(&Polygon::new(corners.clone(), fill.filled()))
                    .map_err(|e| e.to_string())?;
                p.outline(&corners, edge.stroke_width(1))?;
            }
        }
        for q in &world.polygons {
            let (fill, edge) = if low(q.height) {
                (LOW_OBSTACLE, LOW_OBSTACLE_EDGE)
            } else {
                (OBSTACLE, OBSTACLE_EDGE)
            };
            let corners: Vec<(i32, i32)> = q.points.iter().map(|c| self.px(c[0], c[1])).collect();
            root.draw(&Polygon::new(corners.clone(), fill.filled()))
                .map_err(|e| e.to_string())?;
            p.outline(&corners, edge.stroke_width(1))?;
        }
        // Walkers: their path, and where each starts.
        for m in &world.movers {
            p.path(
                m.path.iter().map(|c| self.px(c[0], c[1])).collect(),
                MOVER.stroke_width(2),
            )?;
            p.outline(&self.circle(m.path[0], m.radius), MOVER.stroke_width(2))?;
        }
        for c in &world.cylinders {
            let (fill, edge) = if low(c.height) {
                (LOW_OBSTACLE, LOW_OBSTACLE_EDGE)
            } else {
                (OBSTACLE, OBSTACLE_EDGE)
            };
            let ring = self.circle(c.center, c.radius);
            root.draw(&Polygon::new(ring.clone(), fill.filled()))
                .map_err(|e| e.to_string())?;
            p.outline(&ring, edge.stroke_width(1))?;
        }

        // The believed map: the inflated (blocked) layer, then the occupied cells.
        if let Some((w, h, blocked, occupied)) = &result.believed {
            let (w, h) = (usize::from(*w), usize::from(*h));
            let only_blocked: Vec<bool> = (0..w * h)
                .map(|i| blocked.get(i) == Some(&true) && occupied.get(i) != Some(&true))
                .collect();
            self.cells(&p, w, h, &only_blocked, BLOCKED)?;
            self.cells(&p, w, h, occupied, OCCUPIED)?;
        }

        // Pads and the arena's walls.
        let goal = world.goal_pad_index();
        for (i, pad) in world.pads.iter().enumerate() {
            let color = match i {
                0 => HOME,
                i if i == goal => GOAL,
                _ => OTHER_PAD,
            };
            if pad.yaw_deg == 0.0 {
                let half = [pad.size[0] / 2.0, pad.size[1] / 2.0];
                let lo = [pad.center[0] - half[0], pad.center[1] - half[1]];
                let hi = [pad.center[0] + half[0], pad.center[1] + half[1]];
                p.frame(self.px(lo[0], hi[1]), self.px(hi[0], lo[1]), color, 3)?;
            } else {
                let corners: Vec<(i32, i32)> = pad.corners().iter().map(|c| self.px(c[0], c[1])).collect();
                p.outline(&corners, color.stroke_width(3))?;
            }
        }
        if world.arena.walls == ALL_WALLS {
            p.frame(self.px(0.0, ah), self.px(aw, 0.0), WALL, 3)?;
        } else {
            // Walls where they exist; an open side dashed thin.
            for (bit, a, b) in [
                (WALL_SOUTH, (0.0, 0.0), (aw, 0.0)),
                (WALL_EAST, (aw, 0.0), (aw, ah)),
                (WALL_NORTH, (0.0, ah), (aw, ah)),
                (WALL_WEST, (0.0, 0.0), (0.0, ah)),
            ] {
                let line = vec![self.px(a.0, a.1), self.px(b.0, b.1)];
                if world.arena.has_wall(bit) {
                    p.path(line, WALL.stroke_width(3))?;
                } else {
                    for dash in dashes(&line, 8.0, 6.0) {
                        p.path(dash, WALL.stroke_width(1))?;
                    }
                }
            }
        }

        // Planned paths: every snapshot thin and light, the last one thick.
        let n = result.paths.len();
        for (k, plan) in result.paths.iter().enumerate() {
            let points = dedup(plan.iter().map(|&(x, y)| self.px(x, y)));
            if k + 1 == n {
                p.path(points, PLAN_LAST.stroke_width(3))?;
            } else {
                p.path(points, PLAN_OLD.stroke_width(1))?;
            }
        }

        // The estimate (dashed), then the flown track coloured by phase.
        let estimate: Vec<(i32, i32)> = dedup(result.trace.iter().map(|t| self.px(t.estimate[0], t.estimate[1])));
        for dash in dashes(&estimate, 9.0, 6.0) {
            p.path(dash, ESTIMATE.stroke_width(2))?;
        }
        for (phase, points) in self.track(result) {
            p.path(points, phase.color().stroke_width(3))?;
        }

        // Markers: the nominal start and goal, the pad locks, the landings.
        if self.nominal {
            let s = self.px(world.mission.start[0], world.mission.start[1]);
            p.marker(Swatch::Start, s)?;
            let g = self.px(world.mission.goal[0], world.mission.goal[1]);
            p.marker(Swatch::Goal, g)?;
        }
        for &(x, y) in &result.pad_locks {
            p.marker(Swatch::Cross, self.px(x, y))?;
        }
        for [x, y] in landing_points(result) {
            p.marker(Swatch::Ring, self.px(x, y))?;
        }

        // Title and legend.
        p.text(&self.title, (LEFT, 14), Size::Title, HPos::Left, MARK)?;
        for (k, line) in self.subtitle.iter().enumerate() {
            p.text(line, (LEFT, 52 + 26 * k as i32), Size::Normal, HPos::Left, MARK)?;
        }
        let column = (WIDTH as i32 - 2 * LEFT) / LEGEND_COLUMNS as i32;
        for (k, (swatch, label)) in self.legend.iter().enumerate() {
            let x = LEFT + (k % LEGEND_COLUMNS) as i32 * column;
            let y = self.legend_top + (k / LEGEND_COLUMNS) as i32 * LEGEND_ROW + LEGEND_ROW / 2;
            p.swatch(*swatch, (x, y))?;
            p.text(label, (x + SWATCH + 12, y - 7), Size::Normal, HPos::Left, MARK)?;
        }
        Ok(())
    }

    /// Closed outline of an axis-aligned rectangle, in px.
    fn rect_corners(&self, lo: [f32; 2], hi: [f32; 2]) -> Vec<(i32, i32)> {
        vec![
            self.px(lo[0], lo[1]),
            self.px(hi[0], lo[1]),
            self.px(hi[0], hi[1]),
            self.px(lo[0], hi[1]),
        ]
    }

    /// A circle as a polygon, in px.
    fn circle(&self, c: [f32; 2], r: f32) -> Vec<(i32, i32)> {
        const N: usize = 48;
        (0..N)
            .map(|k| {
                let a = k as f32 * std::f32::consts::TAU / N as f32;
                self.px(c[0] + r * a.cos(), c[1] + r * a.sin())
            })
            .collect()
    }

    /// Fill the cells of a row-major grid of 5 cm cells (row 0 at y = 0) that are set, a row's run at a time.
    fn cells<DB: DrawingBackend>(
        &self,
        p: &Painter<'_, DB>,
        w: usize,
        h: usize,
        set: &[bool],
        color: RGBAColor,
    ) -> Result<(), String> {
        let cell = cfnav::nav::map::CELL_SIZE_M;
        for row in 0..h {
            let mut col = 0;
            while col < w {
                if set.get(row * w + col) != Some(&true) {
                    col += 1;
                    continue;
                }
                let start = col;
                while col < w && set.get(row * w + col) == Some(&true) {
                    col += 1;
                }
                let top_left = self.px(start as f32 * cell, (row + 1) as f32 * cell);
                let bottom_right = self.px(col as f32 * cell, row as f32 * cell);
                p.rect(top_left, bottom_right, color.filled())?;
            }
        }
        Ok(())
    }

    /// The truth track split where the mission phase changes, each piece sharing its first point with the
    /// previous piece's last.
    fn track(&self, result: &RunResult) -> Vec<(Phase, Vec<(i32, i32)>)> {
        let mut pieces: Vec<(Phase, Vec<(i32, i32)>)> = Vec::new();
        let mut phase = Phase::Outbound;
        let mut points: Vec<(i32, i32)> = Vec::new();
        for t in &result.trace {
            let q = self.px(t.truth[0], t.truth[1]);
            let next = Phase::of(t.state).unwrap_or(phase);
            if next != phase {
                points.push(q);
                pieces.push((phase, std::mem::take(&mut points)));
                phase = next;
            }
            if points.last() != Some(&q) {
                points.push(q);
            }
        }
        pieces.push((phase, points));
        pieces.retain(|(_, v)| v.len() >= 2);
        pieces
    }
}

/// Where the drone came down: the truth where the trace first shows `OnGoalPad` (15), and its last point.
fn landing_points(result: &RunResult) -> Vec<[f32; 2]> {
    let first_goal = result.trace.iter().find(|t| t.state == 15);
    first_goal
        .into_iter()
        .chain(result.trace.last())
        .map(|t| [t.truth[0], t.truth[1]])
        .collect()
}

/// The title (world, seed, outcome, mission time) and the line of figures under it.
fn titles(world: &World, result: &RunResult) -> (String, [String; 2]) {
    let r = &result.report;
    let outcome = match r.reason {
        Some(reason) => format!("{} ({reason})", r.outcome),
        None => r.outcome.to_string(),
    };
    let time = r
        .mission_time_s
        .map_or_else(|| "-".to_string(), |t| format!("{t:.1} s"));
    let title = format!(
        "cfnav sim: world \"{}\", seed {}: {outcome}, mission time {time}",
        r.world, r.seed
    );
    let goal = world.goal_pad_index();
    let landings: Vec<String> = r
        .landings
        .iter()
        .map(|l| {
            let pad = match l.pad {
                i if i == goal => "goal".to_string(),
                0 => "home".to_string(),
                i => format!("pad {i}"),
            };
            let off = if l.on_pad { "" } else { " off pad" };
            format!("{pad} {:.3} m{off}", l.error_m)
        })
        .collect();
    let landings = if landings.is_empty() {
        "none".to_string()
    } else {
        landings.join(", ")
    };
    let clearance = r
        .min_clearance_m
        .map_or_else(|| "-".to_string(), |c| format!("{c:.2} m"));
    let subtitle = [
        format!(
            "landing errors: {landings};  collisions {}, min clearance {clearance}",
            r.collisions
        ),
        format!(
            "flown {:.1} m, replans {};  estimate error max {:.2} m, rms {:.2} m (horizontal, airborne)",
            r.distance_m, r.replans, r.max_estimate_error_m, r.rms_estimate_error_m
        ),
    ];
    (title, subtitle)
}

/// The legend's entries, for what the figure shows.
fn legend(world: &World, result: &RunResult) -> Vec<(Swatch, String)> {
    let mut v = vec![(
        Swatch::Fill(OBSTACLE.to_rgba(), OBSTACLE_EDGE.to_rgba()),
        "obstacle".to_string(),
    )];
    let mut low = world
        .boxes
        .iter()
        .map(|b| b.height)
        .chain(world.cylinders.iter().map(|c| c.height))
        .chain(world.polygons.iter().map(|q| q.height));
    if low.any(|h| h <= world.mission.height) {
        v.push((
            Swatch::Fill(LOW_OBSTACLE.to_rgba(), LOW_OBSTACLE_EDGE.to_rgba()),
            "obstacle below cruise".into(),
        ));
    }
    if !world.floor.is_empty() {
        v.push((
            Swatch::Fill(POOR_FLOOR.to_rgba(), POOR_FLOOR.to_rgba()),
            "poor floor".into(),
        ));
    }
    if !world.movers.is_empty() {
        v.push((Swatch::Outline(MOVER), "walker (start, path)".into()));
    }
    v.push((Swatch::Outline(HOME), "home pad".into()));
    v.push((Swatch::Outline(GOAL), "goal pad".into()));
    if world.pads.len() > 2 {
        v.push((Swatch::Outline(OTHER_PAD), "other pad".into()));
    }
    v.push((Swatch::Start, "nominal start".into()));
    v.push((Swatch::Goal, "nominal goal".into()));
    if result.believed.is_some() {
        v.push((Swatch::Fill(OCCUPIED, OCCUPIED), "drone's map: occupied".into()));
        v.push((Swatch::Fill(BLOCKED, BLOCKED), "drone's map: inflated".into()));
    }
    if !result.paths.is_empty() {
        v.push((
            Swatch::Line(RGBAColor(PLAN_OLD.0, PLAN_OLD.1, PLAN_OLD.2, 0.5), 2),
            "planned paths".into(),
        ));
        v.push((Swatch::Line(PLAN_LAST.to_rgba(), 3), "last planned path".into()));
    }
    let phases: Vec<Phase> = result.trace.iter().filter_map(|t| Phase::of(t.state)).collect();
    if !result.trace.is_empty() {
        v.push((Swatch::Line(OUTBOUND.to_rgba(), 3), "flown, outbound".into()));
    }
    if phases.contains(&Phase::Return) {
        v.push((Swatch::Line(RETURN.to_rgba(), 3), "flown, return".into()));
    }
    if phases.contains(&Phase::Hover) {
        v.push((Swatch::Line(HOVER.to_rgba(), 3), "flown, hover / emergency".into()));
    }
    if !result.trace.is_empty() {
        v.push((Swatch::Dashed(ESTIMATE, 2), "position estimate".into()));
    }
    if !result.pad_locks.is_empty() {
        v.push((Swatch::Cross, "pad lock".into()));
    }
    if !result.trace.is_empty() {
        v.push((Swatch::Ring, "landing".into()));
    }
    v
}

/// Drop consecutive repeated pixels.
fn dedup(points: impl Iterator<Item = (i32, i32)>) -> Vec<(i32, i32)> {
    let mut v: Vec<(i32, i32)> = Vec::new();
    for q in points {
        if v.last() != Some(&q) {
            v.push(q);
        }
    }
    v
}

/// The dashes of a polyline in px: `on` px drawn, `off` px left out, repeating along its length.
fn dashes(points: &[(i32, i32)], on: f32, off: f32) -> Vec<Vec<(i32, i32)>> {
    let mut out = Vec::new();
    let mut current: Vec<(i32, i32)> = Vec::new();
    let mut drawing = true;
    let mut left = on;
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let (ax, ay) = (a.0 as f32, a.1 as f32);
        let (dx, dy) = (b.0 as f32 - ax, b.1 as f32 - ay);
        let length = dx.hypot(dy);
        let mut at = 0.0;
        if drawing && current.is_empty() {
            current.push(a);
        }
        while length - at > left {
            at += left;
            let q = (
                (ax + dx * at / length).round() as i32,
                (ay + dy * at / length).round() as i32,
            );
            if drawing {
                current.push(q);
                out.push(std::mem::take(&mut current));
            } else {
                current.push(q);
            }
            drawing = !drawing;
            left = if drawing { on } else { off };
        }
        left -= length - at;
        if drawing {
            current.push(b);
        }
    }
    if drawing && current.len() >= 2 {
        out.push(current);
    }
    out
}

/// Draws on a backend, text included.
struct Painter<'a, DB: DrawingBackend> {
    root: &'a DrawingArea<DB, Shift>,
    text: TextKind,
}

impl<DB: DrawingBackend> Painter<'_, DB> {
    fn path(&self, points: Vec<(i32, i32)>, style: ShapeStyle) -> Result<(), String> {
        if points.len() < 2 {
            return Ok(());
        }
        self.root
            .draw(&PathElement::new(points, style))
            .map_err(|e| e.to_string())
    }

    /// A closed outline, 1 px wide (the bitmap backend cannot close a wider path: its polygon cancels where
    /// the path runs over itself, so wide frames are drawn by [`Painter::frame`]).
    fn outline(&self, corners: &[(i32, i32)], style: ShapeStyle) -> Result<(), String> {
        let mut v = corners.to_vec();
        v.extend(corners.first());
        self.path(v, style)
    }

    /// A rectangle's frame `w` px wide centred on its edges, as four filled bars.
    fn frame(&self, a: (i32, i32), b: (i32, i32), color: RGBColor, w: i32) -> Result<(), String> {
        let (x0, x1, y0, y1) = (a.0.min(b.0), a.0.max(b.0), a.1.min(b.1), a.1.max(b.1));
        let (h0, h1) = (w / 2, w - w / 2);
        let style = color.filled();
        self.rect((x0 - h0, y0 - h0), (x1 + h1, y0 + h1), style)?;
        self.rect((x0 - h0, y1 - h0), (x1 + h1, y1 + h1), style)?;
        self.rect((x0 - h0, y0 - h0), (x0 + h1, y1 + h1), style)?;
        self.rect((x1 - h0, y0 - h0), (x1 + h1, y1 + h1), style)
    }

    fn rect(&self, a: (i32, i32), b: (i32, i32), style: ShapeStyle) -> Result<(), String> {
        self.root
            .draw(&Rectangle::new([a, b], style))
            .map_err(|e| e.to_string())
    }

    fn polygon(&self, points: Vec<(i32, i32)>, fill: RGBColor) -> Result<(), String> {
        self.root
            .draw(&Polygon::new(points.clone(), fill.filled()))
            .map_err(|e| e.to_string())?;
        self.outline(&points, MARK.stroke_width(1))
    }

    fn marker(&self, kind: Swatch, (x, y): (i32, i32)) -> Result<(), String> {
        match kind {
            Swatch::Start => self.polygon(vec![(x, y - 12), (x + 11, y + 8), (x - 11, y + 8)], HOME),
            Swatch::Goal => self.polygon(vec![(x, y - 12), (x + 10, y), (x, y + 12), (x - 10, y)], GOAL),
            Swatch::Cross => {
                let s = 8;
                self.path(vec![(x - s, y - s), (x + s, y + s)], MARK.stroke_width(3))?;
                self.path(vec![(x - s, y + s), (x + s, y - s)], MARK.stroke_width(3))
            }
            Swatch::Ring => self
                .root
                .draw(&Circle::new((x, y), 13, MARK.stroke_width(3)))
                .map_err(|e| e.to_string()),
            _ => Ok(()),
        }
    }

    /// A legend sample centred vertically on `y`, starting at `x`.
    fn swatch(&self, kind: Swatch, (x, y): (i32, i32)) -> Result<(), String> {
        match kind {
            Swatch::Fill(fill, edge) => {
                self.rect((x, y - 10), (x + SWATCH, y + 10), fill.filled())?;
                self.outline(
                    &[(x, y - 10), (x + SWATCH, y - 10), (x + SWATCH, y + 10), (x, y + 10)],
                    edge.into(),
                )
            }
            Swatch::Outline(color) => self.frame((x + 4, y - 10), (x + SWATCH - 4, y + 10), color, 3),
            Swatch::Line(color, w) => self.path(vec![(x, y), (x + SWATCH, y)], color.stroke_width(w)),
            Swatch::Dashed(color, w) => {
                for dash in dashes(&[(x, y), (x + SWATCH, y)], 9.0, 6.0) {
                    self.path(dash, color.stroke_width(w))?;
                }
                Ok(())
            }
            marker => self.marker(marker, (x + SWATCH / 2, y)),
        }
    }

    /// Text with its top at `y`, anchored at `x` as `h` says.
    fn text(&self, s: &str, (x, y): (i32, i32), size: Size, h: HPos, color: RGBColor) -> Result<(), String> {
        match self.text {
            TextKind::Svg => {
                let px = match size {
                    Size::Title => 32.0,
                    Size::Normal => 22.0,
                };
                let style = ("sans-serif", px).into_font().color(&color).pos(Pos::new(h, VPos::Top));
                self.root
                    .draw(&Text::new(s.to_string(), (x, y), style))
                    .map_err(|e| e.to_string())
            }
            TextKind::Pixel => {
                // A title too long for the figure at 3 px a dot is written at 2.
                let fits = |dot: i32| s.chars().count() as i32 * 6 * dot <= WIDTH as i32 - 2 * LEFT;
                let dot = match size {
                    Size::Title if fits(3) => 3,
                    _ => 2,
                };
                self.pixel_text(s, (x, y), dot, h, color)
            }
        }
    }

    /// Text in the built-in 5 × 7 font, each font pixel `dot` px square, 1 dot between letters.
    fn pixel_text(&self, s: &str, (x, y): (i32, i32), dot: i32, h: HPos, color: RGBColor) -> Result<(), String> {
        let n = s.chars().count() as i32;
        let width = (n * 6 - 1).max(0) * dot;
        let x0 = match h {
            HPos::Left => x,
            HPos::Center => x - width / 2,
            HPos::Right => x - width,
        };
        for (i, c) in s.chars().enumerate() {
            let gx = x0 + i as i32 * 6 * dot;
            for (r, row) in glyph(c).split('|').enumerate() {
                let gy = y + r as i32 * dot;
                let bits = row.as_bytes();
                let mut col = 0;
                while col < bits.len() {
                    if bits[col] != b'#' {
                        col += 1;
                        continue;
                    }
                    let start = col;
                    while col < bits.len() && bits[col] == b'#' {
                        col += 1;
                    }
                    let a = (gx + start as i32 * dot, gy);
                    let b = (gx + col as i32 * dot, gy + dot);
                    self.rect(a, b, color.filled())?;
                }
            }
        }
        Ok(())
    }
}

/// A character of the built-in pixel font: seven rows of five columns, `#` set, rows split by `|`. Lower
/// case is drawn in capitals; characters it lacks as `?`.
fn glyph(c: char) -> &'static str {
    match c.to_ascii_uppercase() {
        'A' => " ### |#   #|#   #|#####|#   #|#   #|#   #",
        'B' => "#### |#   #|#   #|#### |#   #|#   #|#### ",
        'C' => " ### |#   #|#    |#    |#    |#   #| ### ",
        'D' => "#### |#   #|#   #|#   #|#   #|#   #|#### ",
        'E' => "#####|#    |#    |#### |#    |#    |#####",
        'F' => "#####|#    |#    |#### |#    |#    |#    ",
        'G' => " ### |#   #|#    |# ###|#   #|#   #| ####",
        'H' => "#   #|#   #|#   #|#####|#   #|#   #|#   #",
        'I' => " ### |  #  |  #  |  #  |  #  |  #  | ### ",
        'J' => "  ###|   # |   # |   # |   # |#  # | ##  ",
        'K' => "#   #|#  # |# #  |##   |# #  |#  # |#   #",
        'L' => "#    |#    |#    |#    |#    |#    |#####",
        'M' => "#   #|## ##|# # #|# # #|#   #|#   #|#   #",
        'N' => "#   #|#   #|##  #|# # #|#  ##|#   #|#   #",
        'O' => " ### |#   #|#   #|#   #|#   #|#   #| ### ",
        'P' => "#### |#   #|#   #|#### |#    |#    |#    ",
        'Q' => " ### |#   #|#   #|#   #|# # #|#  # | ## #",
        'R' => "#### |#   #|#   #|#### |# #  |#  # |#   #",
        'S' => " ####|#    |#    | ### |    #|    #|#### ",
        'T' => "#####|  #  |  #  |  #  |  #  |  #  |  #  ",
        'U' => "#   #|#   #|#   #|#   #|#   #|#   #| ### ",
        'V' => "#   #|#   #|#   #|#   #|#   #| # # |  #  ",
        'W' => "#   #|#   #|#   #|# # #|# # #|# # #| # # ",
        'X' => "#   #|#   #| # # |  #  | # # |#   #|#   #",
        'Y' => "#   #|#   #| # # |  #  |  #  |  #  |  #  ",
        'Z' => "#####|    #|   # |  #  | #   |#    |#####",
        '0' => " ### |#   #|#  ##|# # #|##  #|#   #| ### ",
        '1' => "  #  | ##  |  #  |  #  |  #  |  #  | ### ",
        '2' => " ### |#   #|    #|   # |  #  | #   |#####",
        '3' => "#####|   # |  #  |   # |    #|#   #| ### ",
        '4' => "   # |  ## | # # |#  # |#####|   # |   # ",
        '5' => "#####|#    |#### |    #|    #|#   #| ### ",
        '6' => "  ## | #   |#    |#### |#   #|#   #| ### ",
        '7' => "#####|    #|   # |  #  | #   | #   | #   ",
        '8' => " ### |#   #|#   #| ### |#   #|#   #| ### ",
        '9' => " ### |#   #|#   #| ####|    #|   # | ##  ",
        ' ' => "",
        '.' => "|||||##   |##   ",
        ',' => "||||##   | #   |#    ",
        ':' => "|##   |##   ||##   |##   |",
        ';' => "|##   |##   ||##   | #   |#    ",
        '/' => "|    #|   # |  #  | #   |#    |",
        '-' => "|||#####|||",
        '+' => "|  #  |  #  |#####|  #  |  #  |",
        '(' => "   # |  #  | #   | #   | #   |  #  |   # ",
        ')' => " #   |  #  |   # |   # |   # |  #  | #   ",
        '=' => "||#####||#####||",
        '%' => "##   |##  #|   # |  #  | #   |#  ##|   ##",
        '_' => "||||||#####",
        '"' => " # # | # # | # # ||||",
        '\'' => "  #  |  #  | #   ||||",
        '!' => "  #  |  #  |  #  |  #  |  #  ||  #  ",
        '>' => "#    | #   |  #  |   # |  #  | #   |#    ",
        '<' => "    #|   # |  #  | #   |  #  |   # |    #",
        '\u{b7}' => "|||  #  |||",
        '\u{2013}' | '\u{2014}' | '\u{2212}' => "|||#####|||",
        '\u{d7}' => "||#   #| # # |  #  | # # |#   #",
        _ => " ### |#   #|    #|   # |  #  ||  #  ",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::runner::{RunOptions, run};

    #[test]
    fn draws_the_default_world_as_svg_and_png() {
        let w = World::default_world();
        let result = run(
            &w,
            &RunOptions {
                record: true,
                ..RunOptions::for_world(&w)
            },
        )
        .expect("the run");
        let dir = std::env::temp_dir().join(format!("cfnav-plot-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temp dir");

        let svg = dir.join("run.svg");
        draw(&w, &result, &svg).expect("the SVG");
        let text = std::fs::read_to_string(&svg).expect("the SVG file");
        assert!(text.len() > 10_000, "SVG of {} bytes", text.len());
        let start = text.trim_start();
        assert!(start.starts_with("<svg") || start.starts_with("<?xml"));
        assert!(text.contains("<path") || text.contains("<polyline"));
        assert!(text.contains("<text") && text.contains(result.report.outcome));
        assert!(text.trim_end().ends_with("</svg>"));

        let png = dir.join("run.png");
        draw(&w, &result, &png).expect("the PNG");
        let bytes = std::fs::read(&png).expect("the PNG file");
        assert!(bytes.len() > 10_000, "PNG of {} bytes", bytes.len());
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"));

        let err = draw(&w, &result, &dir.join("run.jpg")).expect_err("a bad extension");
        assert!(
            err.contains("run.jpg") && err.contains(".svg") && err.contains(".png"),
            "{err}"
        );
        let err = draw(&w, &result, &dir.join("run")).expect_err("no extension");
        assert!(err.contains(".svg"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn draws_an_empty_run() {
        let w = World::default_world();
        let mut result = run(
            &w,
            &RunOptions {
                time_limit_s: 0.0,
                ..RunOptions::for_world(&w)
            },
        )
        .expect("the run");
        result.trace.clear();
        result.paths.clear();
        result.paths.push(Vec::new());
        result.believed = None;
        result.pad_locks.clear();
        let dir = std::env::temp_dir().join(format!("cfnav-plot-empty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temp dir");
        draw(&w, &result, &dir.join("empty.svg")).expect("the SVG");
        draw(&w, &result, &dir.join("empty.PNG")).expect("the PNG");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn every_glyph_has_seven_rows_of_at_most_five_columns() {
        for c in (' '..='~').chain(['\u{b7}', '\u{2014}', '\u{d7}']) {
            let g = glyph(c);
            let rows: Vec<&str> = g.split('|').collect();
            assert!(g.is_empty() || rows.len() == 7, "{c:?}: {} rows", rows.len());
            assert!(rows.iter().all(|r| r.len() <= 5), "{c:?}");
        }
    }
}
