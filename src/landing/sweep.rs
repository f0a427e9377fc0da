//! Lawnmower (boustrophedon) sweep generator for the landing-pad search.
//!
//! Job: given the nominal goal (the sweep's centre), the sweep's size and line spacing, where the drone
//! is now, and the arena with a safety margin, produce the waypoint list of a boustrophedon pattern:
//! parallel lines flown alternately in opposite directions, joined by short turns. The drone flies
//! straight from waypoint to waypoint at constant absolute height while the pad detector
//! ([`crate::landing::pad`]) watches the downward range.
//!
//! Layout choices (and why):
//! * **Lines sit at the centres of equal strips.** The extent across the lines, `w`, is cut into
//!   `n = ⌈w/spacing⌉` strips of width `w/n ≤ spacing`, and a line runs down the middle of each. Every
//!   point of the area is then within `spacing/2` of a line, with one line fewer than a pattern that puts
//!   lines on both borders (5 instead of 6 lines for 1 m at 0.2 m), and no time spent flying the border,
//!   where only half a pad could be.
//! * **Line axis.** [`SweepAxis::Auto`] (default) runs the lines along the longer side of the (clipped)
//!   area, which needs fewer lines and so fewer turns; on a square it runs them along arena x.
//! * **Crosshatch** (default on): after the first pass, a second pass with lines along the other axis,
//!   starting at the corner where the first pass ended. The pad detector measures a pad's centre
//!   accurately only *along* the lines that cross it (the midpoint of the entry and exit edges); across the
//!   lines it knows no better than the line spacing. Crossing the pad in both directions pins both
//!   coordinates. A mission can stop the sweep as soon as the detector locks.
//! * **Start corner.** The first waypoint is whichever of the pattern's four corners is nearest the drone,
//!   so no time is wasted flying to the far side first.
//! * **Clipping.** The area is intersected with the arena shrunk by the margin *before* the lines are laid
//!   out, so the lines keep their spacing and every waypoint is at least `margin` inside the arena.
//!
//! Non-goals: obstacle avoidance along the sweep (the planner and [`crate::nav::avoidance`] handle that),
//! heights and timing (the sweep is 2-D), and rotated patterns (lines are axis-aligned).
//!
//! Units and frames: metres, arena frame (origin at the arena's lower-left corner, x right, y up). The
//! arena spans `[0, width] × [0, height]`.
//!
//! Memory: `8·N` bytes of waypoints plus ~50 bytes (568 bytes for the default `N`); `N` is a const generic (default
//! [`DEFAULT_SWEEP_CAPACITY`]). Complexity: O(lines) to build, O(1) per waypoint access.

use heapless::Vec;

/// Default waypoint capacity (512 bytes): a 1 × 1 m crosshatch fits down to 1/16 m = 0.0625 m spacing
/// (2 passes × 16 lines × 2 waypoints = 64); at 0.05 m it would need 80.
pub const DEFAULT_SWEEP_CAPACITY: usize = 64;

/// An area narrower than this in either direction (after clipping) is degenerate, metres.
const MIN_EXTENT_M: f32 = 1e-3;

/// Slack, in lines, when counting lines, so that e.g. 1.0/0.2 = 5.0000005 in f32 gives 5 lines, not 6.
const LINE_COUNT_SLACK: f32 = 1e-4;

/// Along which arena axis the sweep's (first pass) lines run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SweepAxis {
    /// Along the longer side of the clipped area (fewer turns); along x on a square.
    #[default]
    Auto,
    /// Lines parallel to arena x (spaced along y).
    AlongX,
    /// Lines parallel to arena y (spaced along x).
    AlongY,
}

/// Size and pattern of a sweep. [`Default`]: 1.0 × 1.0 m, 0.2 m spacing, auto axis, crosshatch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweepConfig {
    /// Extent along arena x, metres. Default 1.0 m (the seed's).
    pub size_x_m: f32,
    /// Extent along arena y, metres. Default 1.0 m (the seed's).
    pub size_y_m: f32,
    /// Maximum distance between adjacent lines, metres. Default 0.2 m (seed range 0.2–0.3 m): less than
    /// the 0.3 m pad, so at least one line of each pass crosses a pad lying inside the area. With 0.15 m
    /// (< pad/2) at least two do, which lets the pad detector cross-check crossings.
    pub spacing_m: f32,
    /// Axis of the first pass's lines. Default [`SweepAxis::Auto`].
    pub axis: SweepAxis,
    /// Whether to append a second pass along the other axis. Default `true` (see the module docs).
    pub crosshatch: bool,
}

impl Default for SweepConfig {
    fn default() -> Self {
        Self {
            size_x_m: 1.0,
            size_y_m: 1.0,
            spacing_m: 0.2,
            axis: SweepAxis::Auto,
            crosshatch: true,
        }
    }
}

/// The arena `[0, width] × [0, height]` and the margin waypoints keep from its walls, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArenaBounds {
    /// Arena extent along x, metres.
    pub width_m: f32,
    /// Arena extent along y, metres.
    pub height_m: f32,
    /// Minimum distance from every waypoint to the arena's walls, metres.
    pub margin_m: f32,
}

impl ArenaBounds {
    /// An arena of `width_m × height_m` with `margin_m` kept from the walls.
    pub const fn new(width_m: f32, height_m: f32, margin_m: f32) -> Self {
        Self {
            width_m,
            height_m,
            margin_m,
        }
    }
}

/// Why a sweep could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SweepError {
    /// An input is NaN or infinite.
    NonFinite,
    /// The line spacing is zero or negative.
    NonPositiveSpacing,
    /// The sweep size is zero or negative, or the arena's size or margin is invalid.
    InvalidSize,
    /// The sweep area does not overlap the arena shrunk by the margin.
    OutsideArena,
    /// The pattern needs more waypoints than the capacity `N`.
    TooManyWaypoints {
        /// Waypoints the pattern needs (`usize::MAX` when the line count alone exceeds the capacity).
        needed: usize,
        /// The sweep's capacity `N`.
        capacity: usize,
    },
}

/// An axis-aligned rectangle, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Left edge (smallest x).
    pub min_x: f32,
    /// Bottom edge (smallest y).
    pub min_y: f32,
    /// Right edge (largest x).
    pub max_x: f32,
    /// Top edge (largest y).
    pub max_y: f32,
}

impl Rect {
    /// Whether a point lies inside or on the border (with `eps` slack).
    pub fn contains(&self, x: f32, y: f32, eps: f32) -> bool {
        x >= self.min_x - eps && x <= self.max_x + eps && y >= self.min_y - eps && y <= self.max_y + eps
    }
}

/// One boustrophedon pass, before its waypoints are written.
struct Pass {
    /// Lines run along x (true) or y (false).
    along_x: bool,
    /// Number of lines.
    lines: usize,
}

/// A boustrophedon sweep: a fixed-capacity list of arena-frame waypoints, flown in order.
#[derive(Clone, Debug)]
pub struct LawnmowerSweep<const N: usize = DEFAULT_SWEEP_CAPACITY> {
    waypoints: Vec<(f32, f32), N>,
    area: Rect,
    first_pass_along_x: bool,
    lines_per_pass: [usize; 2],
    line_spacing: [f32; 2],
}

impl<const N: usize> LawnmowerSweep<N> {
    /// Builds the sweep centred on `center` (the nominal goal), starting at the pattern corner nearest
    /// `drone` (the drone's current position).
    pub fn new(
        center: (f32, f32),
        drone: (f32, f32),
        config: &SweepConfig,
        arena: &ArenaBounds,
    ) -> Result<Self, SweepError> {
        let inputs = [
            center.0,
            center.1,
            drone.0,
            drone.1,
            config.size_x_m,
            config.size_y_m,
            config.spacing_m,
            arena.width_m,
            arena.height_m,
            arena.margin_m,
        ];
        if inputs.iter().any(|v| !v.is_finite()) {
            return Err(SweepError::NonFinite);
        }
        if config.spacing_m <= 0.0 {
            return Err(SweepError::NonPositiveSpacing);
        }
        if config.size_x_m <= 0.0 || config.size_y_m <= 0.0 || arena.margin_m < 0.0 {
            return Err(SweepError::InvalidSize);
        }
        if arena.width_m <= 2.0 * arena.margin_m || arena.height_m <= 2.0 * arena.margin_m {
            return Err(SweepError::InvalidSize);
        }

        // Clip the requested area to the arena shrunk by the margin.
        let area = Rect {
            min_x: (center.0 - 0.5 * config.size_x_m).max(arena.margin_m),
            max_x: (center.0 + 0.5 * config.size_x_m).min(arena.width_m - arena.margin_m),
            min_y: (center.1 - 0.5 * config.size_y_m).max(arena.margin_m),
            max_y: (center.1 + 0.5 * config.size_y_m).min(arena.height_m - arena.margin_m),
        };
        let (ext_x, ext_y) = (area.max_x - area.min_x, area.max_y - area.min_y);
        if !(ext_x >= MIN_EXTENT_M && ext_y >= MIN_EXTENT_M) {
            return Err(SweepError::OutsideArena);
        }

        // Fewer turns: lines along the longer side; along x on a tie.
        let first_along_x = match config.axis {
            SweepAxis::AlongX => true,
            SweepAxis::AlongY => false,
            SweepAxis::Auto => ext_x >= ext_y,
        };
        let line_count = |across: f32| -> Result<usize, SweepError> {
            let n = libm::ceilf(across / config.spacing_m - LINE_COUNT_SLACK).max(1.0);
            // Reject before the cast: a tiny spacing could give a count no usize (or capacity) holds.
            if n > N as f32 {
                return Err(SweepError::TooManyWaypoints {
                    needed: usize::MAX,
                    capacity: N,
                });
            }
            Ok(n as usize)
        };
        let first = Pass {
            along_x: first_along_x,
            lines: line_count(if first_along_x { ext_y } else { ext_x })?,
        };
        let second = if config.crosshatch {
            Some(Pass {
                along_x: !first_along_x,
                lines: line_count(if first_along_x { ext_x } else { ext_y })?,
            })
        } else {
            None
        };
        let needed = 2 * first.lines + second.as_ref().map_or(0, |p| 2 * p.lines);
        if needed > N {
            return Err(SweepError::TooManyWaypoints { needed, capacity: N });
        }

        let mut sweep = Self {
            waypoints: Vec::new(),
            area,
            first_pass_along_x: first_along_x,
            lines_per_pass: [first.lines, second.as_ref().map_or(0, |p| p.lines)],
            line_spacing: [0.0; 2],
        };
        let first_spacing = sweep.write_pass(&first, drone)?;
        let mut second_spacing = 0.0;
        if let Some(second) = second {
            // Start the second pass at its corner nearest to where the first pass ended.
            let end = sweep.waypoints.last().copied().unwrap_or(drone);
            second_spacing = sweep.write_pass(&second, end)?;
        }
        sweep.line_spacing = [first_spacing, second_spacing];
        Ok(sweep)
    }

    /// Appends one pass starting at its corner nearest `from`; returns the actual line spacing.
    fn write_pass(&mut self, pass: &Pass, from: (f32, f32)) -> Result<f32, SweepError> {
        let a = self.area;
        // (along-axis range, across-axis range) in this pass's own coordinates.
        let (along, across) = if pass.along_x {
            ((a.min_x, a.max_x), (a.min_y, a.max_y))
        } else {
            ((a.min_y, a.max_y), (a.min_x, a.max_x))
        };
        let n = pass.lines;
        let strip = (across.1 - across.0) / n as f32;
        let line_at = |k: usize| across.0 + (k as f32 + 0.5) * strip;
        let to_xy = |u: f32, v: f32| if pass.along_x { (u, v) } else { (v, u) };

        // Four candidate starts: first or last line, from either end. The nearest one wins; the
        // comparison order makes ties deterministic.
        let mut best = (false, false, f32::INFINITY);
        for reverse_lines in [false, true] {
            for start_at_max in [false, true] {
                let v = line_at(if reverse_lines { n - 1 } else { 0 });
                let u = if start_at_max { along.1 } else { along.0 };
                let (x, y) = to_xy(u, v);
                let d = libm::hypotf(x - from.0, y - from.1);
                if d < best.2 {
                    best = (reverse_lines, start_at_max, d);
                }
            }
        }
        let (reverse_lines, mut at_max, _) = best;
        for k in 0..n {
            let v = line_at(if reverse_lines { n - 1 - k } else { k });
            let (u0, u1) = if at_max { (along.1, along.0) } else { (along.0, along.1) };
            for u in [u0, u1] {
                let needed = self.waypoints.len() + 1;
                self.waypoints
                    .push(to_xy(u, v))
                    .map_err(|_| SweepError::TooManyWaypoints { needed, capacity: N })?;
            }
            at_max = !at_max;
        }
        Ok(strip)
    }

    /// Number of waypoints.
    pub fn len(&self) -> usize {
        self.waypoints.len()
    }

    /// Whether there are no waypoints (never true for a successfully built sweep).
    pub fn is_empty(&self) -> bool {
        self.waypoints.is_empty()
    }

    /// Waypoint `i` (arena frame, metres), or `None` past the end.
    pub fn waypoint(&self, i: usize) -> Option<(f32, f32)> {
        self.waypoints.get(i).copied()
    }

    /// All waypoints in flight order.
    pub fn waypoints(&self) -> &[(f32, f32)] {
        &self.waypoints
    }

    /// Iterates over the waypoints in flight order.
    pub fn iter(&self) -> impl Iterator<Item = (f32, f32)> + '_ {
        self.waypoints.iter().copied()
    }

    /// The area actually swept: the requested area clipped to the arena minus the margin.
    pub fn area(&self) -> Rect {
        self.area
    }

    /// Whether the first pass's lines run along arena x.
    pub fn first_pass_along_x(&self) -> bool {
        self.first_pass_along_x
    }

    /// Lines in the first and second pass (0 without crosshatch).
    pub fn lines_per_pass(&self) -> [usize; 2] {
        self.lines_per_pass
    }

    /// Actual distance between adjacent lines in the first and second pass (≤ the configured spacing).
    pub fn line_spacing(&self) -> [f32; 2] {
        self.line_spacing
    }

    /// Number of waypoints of the first pass (the second pass, if any, follows them).
    pub fn first_pass_len(&self) -> usize {
        let [first, _] = self.lines_per_pass;
        2 * first
    }
}

impl<'a, const N: usize> IntoIterator for &'a LawnmowerSweep<N> {
    type Item = &'a (f32, f32);
    type IntoIter = core::slice::Iter<'a, (f32, f32)>;

    fn into_iter(self) -> Self::IntoIter {
        self.waypoints.iter()
    }
}
