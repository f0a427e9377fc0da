//! The occupancy grid: log-odds evidence from the horizontal laser rangers, the *occupied* decision with
//! hysteresis, and the inflated *blocked* layer that the planner reads through [`Traversability`].
//!
//! # Job
//!
//! * Fold range beams into per-cell log-odds ([`OccupancyGrid::integrate_beam`]): every cell the beam
//!   crosses gets a *miss*, the cell the beam ends in gets a *hit* (unless the reading was a max-range "no
//!   return"). The traversal is an exact Amanatides–Woo grid walk, so every cell the segment crosses is
//!   updated exactly once, however short or steep the beam.
//! * Decide *occupied* from the log-odds with hysteresis (thresholds in [`GridConfig`]).
//! * Maintain *blocked* = "an occupied cell or the arena wall lies within the inflation radius", so the
//!   planner can treat the drone as a point. The arena walls are occupied cells just outside the grid (row
//!   −1, row `h`, column −1, column `w`). The layer is kept up to date incrementally: an occupancy flip
//!   only revisits the disc of cells around it.
//! * Report every cell whose blocked state flipped through [`ChangedCells`], which is what the
//!   incremental planner (D* Lite) consumes.
//!
//! Non-goals: planning (see `crate::nav::dstar`), the sensor model beyond fixed log-odds increments (no range
//! noise model, no beam width, no decay over time), heights (the map is 2-D), and knowing where the
//! drone is (the caller passes beams already transformed into the arena frame).
//!
//! # Units and frames
//!
//! Beam endpoints and disc centres are arena-frame metres (origin at the arena's lower-left corner, see
//! [`crate::nav::map`]). Cells are [`CELL_SIZE_M`] squares addressed by [`Cell`]; the metres ↔ cell transform is
//! exactly [`GridShape::cell_at`]. Inflation radii are in whole cells and Euclidean: cell `q` inflates
//! cell `p` when `dx² + dy² ≤ r²`. Log-odds are small integers; one unit is roughly 0.25 nat (see
//! [`GridConfig`]).
//!
//! # Memory
//!
//! Exactly one byte per cell plus 12 bytes of scalars (shape 4, config 6, radius 1, open sides 1):
//! `size_of::<OccupancyGrid<CELLS>>() == CELLS + 12` for even `CELLS` (7 212 bytes for the 120 × 60 seed
//! arena, 8 204 bytes for the 128 × 64 large arena). Each cell byte is
//!
//! ```text
//!   bit   7        6          5 … 0
//!       blocked  occupied   log-odds, 6-bit two's complement (−32 … 31)
//! ```
//!
//! The *occupied* bit is state, not a function of the log-odds: with hysteresis a cell whose log-odds lie
//! between the two thresholds is occupied or free depending on its history, so it needs its own bit. That
//! leaves six bits of log-odds, which is plenty for the increments used (a hit is +8, the clamp range is
//! −8 … 24 by default). No second per-cell array and no per-cell counter exist; un-inflating therefore
//! re-scans neighbourhoods instead of decrementing counts (see *Complexity*).
//!
//! # Complexity (`r` = inflation radius in cells, `L` = beam length in cells)
//!
//! | operation | time |
//! |---|---|
//! | [`OccupancyGrid::reset`] | O(cells) |
//! | [`OccupancyGrid::integrate_beam`] | O(L) + O(r²) if the end cell becomes occupied + O(r⁴) per cell that becomes free |
//! | [`OccupancyGrid::set_occupied`] | O(r²) |
//! | [`OccupancyGrid::mark_free_disc`] | O(cells in the disc) + O(r⁴) per cell that becomes free |
//! | queries ([`OccupancyGrid::is_blocked`], …) | O(1) |
//!
//! The O(r⁴) term is the worst case of un-inflating: each of the ≈ πr² cells around a freed cell that is
//! still blocked scans its own ≈ πr² disc for another occupied cell, stopping at the first one found. The
//! radius is capped at [`MAX_INFLATION_RADIUS_CELLS`] to bound it.
//!
//! # Change reporting
//!
//! Update methods *append* to the caller's [`ChangedCells`] (they never clear it). Within one call every
//! cell whose blocked state differs after the call from before it is appended exactly once, and no other
//! cell is: each call is ordered so that a cell can only flip in one direction (a beam applies its hit
//! before its misses, and only a hit can make a cell occupied). [`OccupancyGrid::reset`] reports nothing;
//! the planner must start over after it.

use crate::nav::map::{CELL_SIZE_M, Cell, GridShape, Traversability};

/// Largest inflation radius the grid accepts, in cells (0.8 m). Larger radii are clamped to it, so that the
/// O(r⁴) un-inflation cost stays bounded on the MCU.
pub const MAX_INFLATION_RADIUS_CELLS: u8 = 16;

/// The largest log-odds of a *contested* cell (see [`OccupancyGrid::is_doubtful_region`]): below one clean
/// hit (+8 with the default [`GridConfig`]), so a hit and a miss (5), a miss and a hit (5) or a hit and two
/// misses (2).
pub const CONTESTED_MAX_LOG_ODDS: i8 = 7;

/// Smallest log-odds a cell byte can hold.
pub const LOG_ODDS_MIN: i8 = -32;
/// Largest log-odds a cell byte can hold.
pub const LOG_ODDS_MAX: i8 = 31;

/// Beam endpoints farther than this from the arena origin (in cells, ≈ 3.3 km) are rejected as corrupt. It
/// covers the widest grid a [`GridShape`] can describe; beyond it `f32` resolves less than 1/128 cell.
const MAX_BEAM_COORD_CELLS: f32 = 65_536.0;
/// Cells before a beam's hit, in its row or column, that the beam does not see free unless the map
/// already shows a face across it there ([`OccupancyGrid::integrate_beam`]): 0.4 m, about where a beam 2°
/// off a face's plane leaves the face's cell row.
pub const GRAZE_CELLS: i32 = 8;

const BLOCKED: u8 = 0x80;
const OCCUPIED: u8 = 0x40;
const LOG_ODDS_MASK: u8 = 0x3F;

/// Sign-extends the 6-bit log-odds field of a cell byte.
#[inline]
fn decode_log_odds(byte: u8) -> i8 {
    // Shift the field to the top of an i8 and arithmetic-shift it back down to replicate the sign bit.
    (((byte & LOG_ODDS_MASK) << 2) as i8) >> 2
}

/// Packs log-odds (already within `LOG_ODDS_MIN ..= LOG_ODDS_MAX`) into the 6-bit field.
#[inline]
fn encode_log_odds(log_odds: i8) -> u8 {
    (log_odds as u8) & LOG_ODDS_MASK
}

/// Log-odds parameters of the grid.
///
/// Log-odds are integers in units of roughly 0.25 nat. The defaults are tuned for a time-of-flight laser
/// ranger, whose false positives are rare but whose beams graze obstacle corners:
///
/// * a single hit on an unknown cell makes it occupied (0 + 8 ≥ 6): a laser return is strong evidence,
///   and a late obstacle costs more than a spurious one;
/// * three misses clear a single false hit (8 → 5 → 2 → −1 ≤ 0), so a glitch disappears after the next
///   few sweeps;
/// * a cell seen free before needs two hits (−3 + 8 = 5 < 6), and a confirmed obstacle (three hits,
///   saturated at 24) needs eight misses to clear, so grazing beams do not erase real walls;
/// * the lower clamp (−8) keeps a long-free cell able to turn occupied after two hits.
///
/// [`OccupancyGrid::reset_with`] sanitises a config by clamping so that `LOG_ODDS_MIN ≤ min_log_odds ≤ 0 <
/// occupied_threshold ≤ max_log_odds ≤ LOG_ODDS_MAX` and `min_log_odds ≤ free_threshold <
/// occupied_threshold`; the sanitised config is what [`OccupancyGrid::config`] returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridConfig {
    /// Added to a cell's log-odds when a beam ends in it with a return. Default 8.
    pub hit_increment: u8,
    /// Subtracted from a cell's log-odds when a beam passes through it. Default 3.
    pub miss_decrement: u8,
    /// Lower clamp of the log-odds; also the value [`OccupancyGrid::mark_free_disc`] sets. Default −8.
    pub min_log_odds: i8,
    /// Upper clamp of the log-odds; also the value [`OccupancyGrid::set_occupied`] sets. Default 24.
    pub max_log_odds: i8,
    /// A free cell becomes occupied when its log-odds reach at least this. Default 6.
    pub occupied_threshold: i8,
    /// An occupied cell becomes free when its log-odds fall to this or below. Default 0.
    pub free_threshold: i8,
}

impl GridConfig {
    /// The documented defaults (see the type's documentation), usable in `const` contexts.
    pub const DEFAULT: Self = Self {
        hit_increment: 8,
        miss_decrement: 3,
        min_log_odds: -8,
        max_log_odds: 24,
        occupied_threshold: 6,
        free_threshold: 0,
    };

    /// The config with every bound forced into the representable, self-consistent range: `min ≤ 0 <
    /// occupied_threshold ≤ max` keeps an unknown cell (log-odds 0, as `reset` leaves it) inside the clamp
    /// range and not occupied, and `free_threshold < occupied_threshold` keeps the hysteresis from flapping.
    fn sanitized(self) -> Self {
        let min_log_odds = self.min_log_odds.clamp(LOG_ODDS_MIN, 0);
        let max_log_odds = self.max_log_odds.clamp(1, LOG_ODDS_MAX);
        let occupied_threshold = self.occupied_threshold.clamp(1, max_log_odds);
        let free_threshold = self.free_threshold.clamp(min_log_odds, occupied_threshold - 1);
        Self {
            min_log_odds,
            max_log_odds,
            occupied_threshold,
            free_threshold,
            ..self
        }
    }
}

impl Default for GridConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Cells whose blocked state flipped, collected for the incremental planner.
///
/// Holds at most `N` cells. When more changes arrive, they are dropped and [`ChangedCells::overflowed`]
/// becomes true: the caller must then replan from scratch instead of feeding the list to the planner.
/// See the module documentation for the at-most-once guarantee within one update call.
#[derive(Clone, Debug)]
pub struct ChangedCells<const N: usize> {
    cells: heapless::Vec<Cell, N>,
    overflowed: bool,
}

impl<const N: usize> ChangedCells<N> {
    /// An empty list.
    pub const fn new() -> Self {
        Self {
            cells: heapless::Vec::new(),
            overflowed: false,
        }
    }

    /// Forgets all cells and the overflow flag.
    pub fn clear(&mut self) {
        self.cells.clear();
        self.overflowed = false;
    }

    /// Appends a cell, or records the overflow when the list is full.
    pub fn push(&mut self, cell: Cell) {
        if self.cells.push(cell).is_err() {
            self.overflowed = true;
        }
    }

    /// The cells recorded so far, in the order they changed.
    pub fn as_slice(&self) -> &[Cell] {
        self.cells.as_slice()
    }

    /// Number of cells recorded.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no cell is recorded.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// Whether changes were dropped because more than `N` happened since the last [`ChangedCells::clear`].
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }
}

impl<const N: usize> Default for ChangedCells<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// Occupancy grid of at most `CELLS` cells with an inflated blocked layer. See the module documentation.
#[derive(Clone)]
pub struct OccupancyGrid<const CELLS: usize> {
    /// One byte per cell, row-major (`GridShape::index`); only the first `shape.cells()` are used.
    cells: [u8; CELLS],
    shape: GridShape,
    config: GridConfig,
    inflation_radius: u8,
    /// The arena's open sides (low nibble, `mission.walls` bits) and the geofence in cells (high nibble):
    /// within that many cells of an open side a cell is blocked, as within the inflation radius of a wall.
    border: u8,
}

// The byte count promised in the module documentation.
const _: () = assert!(
    core::mem::size_of::<OccupancyGrid<{ crate::nav::map::ARENA_CELLS }>>() == crate::nav::map::ARENA_CELLS + 12
);

impl<const CELLS: usize> OccupancyGrid<CELLS> {
    /// An empty 0 × 0 grid (every cell is outside, hence blocked) with the default config; call
    /// [`OccupancyGrid::reset`] before use. `const`, so the grid can live in a `static`.
    pub const fn new() -> Self {
        Self {
            cells: [0; CELLS],
            shape: GridShape { width: 0, height: 0 },
            config: GridConfig::DEFAULT,
            inflation_radius: 0,
            border: 0,
        }
    }

    /// From the next reset, the sides in `open_sides` (`mission.walls` bits: south 1, east 2, north 4,
    /// west 8) are no walls: the cells within `fence_cells` (at most 15; at least the inflation radius
    /// applies) of such a side are blocked instead, a geofence the planner does not cross. Cells outside
    /// the grid stay blocked either way.
    pub fn set_open_sides(&mut self, open_sides: u8, fence_cells: u8) {
        self.border = (open_sides & 0x0F) | (fence_cells.min(15) << 4);
    }

    /// The open sides set by [`Self::set_open_sides`] (`mission.walls` bits).
    pub fn open_sides(&self) -> u8 {
        self.border & 0x0F
    }

    /// Clears the grid to `shape` with every cell unknown (log-odds 0, not occupied), keeping the current
    /// [`GridConfig`], and blocks the cells within `inflation_radius_cells` of the arena walls.
    ///
    /// The radius is clamped to [`MAX_INFLATION_RADIUS_CELLS`]. Returns `false`, and leaves an empty 0 × 0
    /// grid, when `shape` holds more than `CELLS` cells. Reports no changes: replan from scratch after it.
    pub fn reset(&mut self, shape: GridShape, inflation_radius_cells: u8) -> bool {
        self.reset_with(shape, inflation_radius_cells, self.config)
    }

    /// [`OccupancyGrid::reset`] with new log-odds parameters (sanitised, see [`GridConfig`]).
    pub fn reset_with(&mut self, shape: GridShape, inflation_radius_cells: u8, config: GridConfig) -> bool {
        self.config = config.sanitized();
        self.inflation_radius = inflation_radius_cells.min(MAX_INFLATION_RADIUS_CELLS);
        // In place: a `[0; CELLS]` temporary could cost CELLS bytes of stack in unoptimised builds.
        self.cells.fill(0);
        let fits = shape.cells() <= CELLS;
        self.shape = if fits { shape } else { GridShape { width: 0, height: 0 } };
        for y in 0..i32::from(self.shape.height) {
            for x in 0..i32::from(self.shape.width) {
                if self.wall_within_radius(x, y)
                    && let Some(byte) = self.byte_mut(x, y)
                {
                    *byte |= BLOCKED;
                }
            }
        }
        fits
    }

    /// The grid's size in cells.
    pub fn shape(&self) -> GridShape {
        self.shape
    }

    /// The (sanitised) log-odds parameters in use.
    pub fn config(&self) -> GridConfig {
        self.config
    }

    /// The inflation radius in use, cells (after clamping).
    pub fn inflation_radius_cells(&self) -> u8 {
        self.inflation_radius
    }

    /// Changes the inflation radius and rebuilds the blocked layer from the occupied cells and the walls,
    /// keeping all evidence. Every cell whose blocked state flips is reported (a large change overflows
    /// `changed`, which tells the planner to start afresh). O(cells · r²): about 0.4 M cell visits for the
    /// seed arena at 4 cells, so it belongs to a rare event (a no-path fallback), not to every tick.
    pub fn set_inflation_radius<const N: usize>(&mut self, inflation_radius_cells: u8, changed: &mut ChangedCells<N>) {
        let r = inflation_radius_cells.min(MAX_INFLATION_RADIUS_CELLS);
        if r == self.inflation_radius {
            return;
        }
        self.inflation_radius = r;
        let (w, h) = (i32::from(self.shape.width), i32::from(self.shape.height));
        for y in 0..h {
            for x in 0..w {
                let blocked = self.wall_within_radius(x, y)
                    || Disc::new(self.shape, x, y, r).any(|(qx, qy)| self.occupied_at(qx, qy));
                if let Some(byte) = self.byte_mut(x, y)
                    && (*byte & BLOCKED != 0) != blocked
                {
                    *byte ^= BLOCKED;
                    changed.push(Cell::new(x as u16, y as u16));
                }
            }
        }
    }

    /// Whether a cell is occupied (after hysteresis). Cells outside the grid are not.
    pub fn is_occupied(&self, cell: Cell) -> bool {
        self.byte(i32::from(cell.x), i32::from(cell.y))
            .is_some_and(|b| b & OCCUPIED != 0)
    }

    /// Whether the planner may not enter a cell: an occupied cell or the wall lies within the inflation
    /// radius. Cells outside the grid are blocked.
    pub fn is_blocked(&self, cell: Cell) -> bool {
        self.blocked_at(i32::from(cell.x), i32::from(cell.y))
    }

    /// A cell's log-odds (0 = unknown, positive = evidence of an obstacle). 0 outside the grid.
    pub fn log_odds(&self, cell: Cell) -> i8 {
        self.log_odds_at(i32::from(cell.x), i32::from(cell.y))
    }

    /// Whether no evidence lies in a cell: log-odds 0 and not occupied (never crossed nor hit by a beam, or
    /// its hits and misses cancelled exactly). Cells outside the grid are not unknown (they are the wall).
    pub fn is_unknown(&self, cell: Cell) -> bool {
        self.byte(i32::from(cell.x), i32::from(cell.y))
            .is_some_and(|b| b & OCCUPIED == 0 && decode_log_odds(b) == 0)
    }

    /// Whether a cell is unknown and at least `min_neighbours` of its eight neighbours are unknown,
    /// occupied or outside the grid (the wall): the inside or the rim of a region no beam has looked
    /// into, which may hide an obstacle, as opposed to the one-cell gaps four beams leave between their
    /// traces in open space (an unknown cell in such a gap has at most two unknown neighbours along it,
    /// plus the diagonal ones where two gaps meet). O(1).
    pub fn is_unobserved_region(&self, cell: Cell, min_neighbours: u8) -> bool {
        self.is_region_of(cell, min_neighbours, |b| b & OCCUPIED == 0 && decode_log_odds(b) == 0)
    }

    /// [`Self::is_unobserved_region`] with a stricter idea of "seen": a cell counts as seen free only at
    /// log-odds `free_max` or below, so a cell holding a hit below the occupied threshold (with
    /// `free_max` −1), or also one that one grazing beam or one outlier crossed (with −6, two misses),
    /// still belongs to the region. To [`Self::is_unobserved_region`] any cell with evidence is seen.
    /// O(1).
    pub fn is_weakly_observed_region(&self, cell: Cell, min_neighbours: u8, free_max: i8) -> bool {
        self.is_region_of(cell, min_neighbours, |b| {
            b & OCCUPIED == 0 && decode_log_odds(b) > free_max
        })
    }

    /// [`Self::is_weakly_observed_region`] where misses next to contested evidence count for less: a cell
    /// with log-odds in `contested_free_max + 1 ..= free_max` (one net miss, with the defaults −6 and −1)
    /// still counts as unseen when one of its eight neighbours is *contested*, i.e. holds log-odds 1 ..=
    /// [`CONTESTED_MAX_LOG_ODDS`] (a hit and a miss, or less than one clean hit). Such a mix is what a wall's
    /// end or a box's corner leaves: beams grazing the part of a cell the surface does not fill mark it free
    /// as often as beams ending on the surface mark it hit. O(1): reads only cells of the 5 × 5 block around
    /// `cell` (at most 81 reads; one for a cell plainly seen free or occupied).
    pub fn is_doubtful_region(&self, cell: Cell, min_neighbours: u8, free_max: i8, contested_free_max: i8) -> bool {
        let contested_next_to = |x: i32, y: i32| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    (dx, dy) != (0, 0)
                        && self
                            .byte(x + dx, y + dy)
                            .is_some_and(|b| (1..=CONTESTED_MAX_LOG_ODDS).contains(&decode_log_odds(b)))
                })
            })
        };
        self.is_region_at(cell, min_neighbours, |x, y, b| {
            let lo = decode_log_odds(b);
            b & OCCUPIED == 0 && (lo > free_max || (lo > contested_free_max && contested_next_to(x, y)))
        })
    }

    /// Whether `cell`'s byte is `unseen` and at least `min_neighbours` of its eight neighbours are unseen,
    /// occupied or outside the grid (the region tests above, with their idea of "unseen").
    fn is_region_of(&self, cell: Cell, min_neighbours: u8, unseen: impl Fn(u8) -> bool) -> bool {
        self.is_region_at(cell, min_neighbours, |_, _, b| unseen(b))
    }

    /// [`Self::is_region_of`] with an idea of "unseen" that may also look at the cell's position (`x`, `y`,
    /// then its byte). The centre is tested first: a seen cell costs one read.
    fn is_region_at(&self, cell: Cell, min_neighbours: u8, unseen: impl Fn(i32, i32, u8) -> bool) -> bool {
        let (x, y) = (i32::from(cell.x), i32::from(cell.y));
        if !self.byte(x, y).is_some_and(|b| unseen(x, y, b)) {
            return false;
        }
        let mut count = 0u8;
        for dy in -1..=1 {
            for dx in -1..=1 {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                let (nx, ny) = (x + dx, y + dy);
                let not_free = self.byte(nx, ny).is_none_or(|b| b & OCCUPIED != 0 || unseen(nx, ny, b));
                count += u8::from(not_free);
            }
        }
        count >= min_neighbours
    }

    /// Folds one range reading into the grid. `from` is the sensor position, `to` the point the beam
    /// reached, both arena-frame metres.
    ///
    /// Every grid cell the segment crosses gets a miss, except the cell containing `to`, which gets a hit
    /// when `hit` is true (a return) and a miss like the others when `hit` is false (a max-range or
    /// no-return reading, which therefore marks nothing occupied). With a return, the [`GRAZE_CELLS`]
    /// cells before the hit in its row (a beam nearer the x axis) or column get their miss only down to
    /// log-odds 0 (a hit there is taken back, but the cell is not seen free by this beam): a beam
    /// nearly parallel to a face, a few millimetres off it, crosses the cells of the face's own row (which
    /// the face fills only partly or, with a millimetre of estimate error, wholly) and ends on that face
    /// far along. Marked free, those cells would hide a box's end from the tests of unseen space (an 11 cm
    /// slab seen end-on, beams grazing both long faces, leaves its middle row alone unseen, which reads as
    /// a gap between beam traces). A return whose end
    /// cell's two neighbours across the beam already hold evidence (log-odds > 0) comes from a face across
    /// the beam, a wall seen head-on, and the row before it is missed like the rest (without that
    /// exception every beam square to a wall left 0.4 m in front of it unseen, and the corner world of
    /// `sim::pads`, noise seed 2, locked onto its pad 12 cm off the centre). The part of the segment
    /// outside the grid is ignored; if `to` lies outside, no cell gets a hit (the return came from beyond the map). A cell
    /// the segment only touches at a corner or along an edge may or may not be updated (measure zero); when
    /// the segment passes exactly through a corner the walk steps along x first. Non-finite endpoints, or
    /// endpoints farther than ≈ 3.3 km from the origin, make the call a no-op.
    pub fn integrate_beam<const N: usize>(
        &mut self,
        from: (f32, f32),
        to: (f32, f32),
        hit: bool,
        changed: &mut ChangedCells<N>,
    ) {
        let Some(walk) = BeamWalk::new(self.shape, from, to) else {
            return;
        };
        let hit_cell = if hit { walk.end_in_grid } else { None };
        let along_x = libm::fabsf(to.0 - from.0) >= libm::fabsf(to.1 - from.1);
        // A return from a face across the beam (both of the hit cell's neighbours across the beam already
        // hold evidence: a wall seen head-on) says the row before it is free; only a return from a face
        // the map does not yet show across the beam may be a graze along it.
        let graze_end = hit_cell.filter(|&(hx, hy)| {
            let across = if along_x {
                [(hx, hy - 1), (hx, hy + 1)]
            } else {
                [(hx - 1, hy), (hx + 1, hy)]
            };
            !across.iter().all(|&(x, y)| self.log_odds_at(x, y) > 0)
        });
        // The hit goes first: it is the only update in this call that can make a cell occupied, so doing it
        // before the misses means every cell's blocked state flips at most once per call.
        if let Some((x, y)) = hit_cell {
            self.add_log_odds(x, y, i16::from(self.config.hit_increment), changed);
        }
        let miss = -i16::from(self.config.miss_decrement);
        for (x, y) in walk {
            if Some((x, y)) == hit_cell {
                continue;
            }
            let grazed = graze_end.is_some_and(|(hx, hy)| {
                if along_x {
                    y == hy && (x - hx).abs() <= GRAZE_CELLS
                } else {
                    x == hx && (y - hy).abs() <= GRAZE_CELLS
                }
            });
            if grazed {
                // Evidence of an obstacle there is still taken back (it moved, or was an outlier's), but
                // not beyond "no evidence".
                let held = self.log_odds_at(x, y);
                if held > 0 {
                    self.add_log_odds(x, y, miss.max(-i16::from(held)), changed);
                }
            } else {
                self.add_log_odds(x, y, miss, changed);
            }
        }
    }

    /// Declares the disc around `center` (arena-frame metres) free, e.g. the drone's own footprint: every
    /// cell whose centre lies within `radius_m` of `center`, plus the cell containing `center`, is set to
    /// the minimum log-odds (and so becomes free). A negative radius clears only the centre cell;
    /// non-finite input makes the call a no-op.
    pub fn mark_free_disc<const N: usize>(&mut self, center: (f32, f32), radius_m: f32, changed: &mut ChangedCells<N>) {
        let (cx, cy) = center;
        if !(cx.is_finite() && cy.is_finite()) || radius_m.is_nan() {
            return;
        }
        let min = self.config.min_log_odds;
        if let Some(cell) = self.shape.cell_at(cx, cy) {
            self.set_log_odds(i32::from(cell.x), i32::from(cell.y), min, changed);
        }
        if radius_m < 0.0 {
            return;
        }
        // Candidate cells: the bounding box of the disc, clipped to the grid. `as i32` saturates on the
        // huge values an infinite radius produces, and the clamp then keeps the loop within the grid.
        let w = i32::from(self.shape.width);
        let h = i32::from(self.shape.height);
        let x0 = (libm::floorf((cx - radius_m) / CELL_SIZE_M) as i32).max(0);
        let x1 = (libm::floorf((cx + radius_m) / CELL_SIZE_M) as i32).min(w - 1);
        let y0 = (libm::floorf((cy - radius_m) / CELL_SIZE_M) as i32).max(0);
        let y1 = (libm::floorf((cy + radius_m) / CELL_SIZE_M) as i32).min(h - 1);
        let r2 = radius_m * radius_m;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = ((x as f32 + 0.5) * CELL_SIZE_M, (y as f32 + 0.5) * CELL_SIZE_M);
                let (ex, ey) = (px - cx, py - cy);
                if ex * ex + ey * ey <= r2 {
                    self.set_log_odds(x, y, min, changed);
                }
            }
        }
    }

    /// Forces a known obstacle: the cell gets the maximum log-odds and becomes occupied. Cells outside
    /// the grid are ignored.
    pub fn set_occupied<const N: usize>(&mut self, cell: Cell, changed: &mut ChangedCells<N>) {
        let (x, y) = (i32::from(cell.x), i32::from(cell.y));
        let max = encode_log_odds(self.config.max_log_odds);
        let Some(byte) = self.byte_mut(x, y) else {
            return;
        };
        let was_occupied = *byte & OCCUPIED != 0;
        *byte = (*byte & BLOCKED) | OCCUPIED | max;
        if !was_occupied {
            self.inflate(x, y, changed);
        }
    }

    // ----- internals -----

    /// [`Self::log_odds`] at signed coordinates (0 outside the grid).
    fn log_odds_at(&self, x: i32, y: i32) -> i8 {
        self.byte(x, y).map_or(0, decode_log_odds)
    }

    /// Row-major index of signed coordinates, `None` outside the grid.
    #[inline]
    fn index(&self, x: i32, y: i32) -> Option<usize> {
        self.shape
            .contains(x, y)
            .then(|| y as usize * usize::from(self.shape.width) + x as usize)
    }

    #[inline]
    fn byte(&self, x: i32, y: i32) -> Option<u8> {
        self.index(x, y).and_then(|i| self.cells.get(i).copied())
    }

    #[inline]
    fn byte_mut(&mut self, x: i32, y: i32) -> Option<&mut u8> {
        self.index(x, y).and_then(|i| self.cells.get_mut(i))
    }

    #[inline]
    fn blocked_at(&self, x: i32, y: i32) -> bool {
        self.byte(x, y).is_none_or(|b| b & BLOCKED != 0)
    }

    #[inline]
    fn occupied_at(&self, x: i32, y: i32) -> bool {
        self.byte(x, y).is_some_and(|b| b & OCCUPIED != 0)
    }

    /// Whether a wall cell (row −1, row h, column −1 or column w) lies within the inflation radius of an
    /// in-grid cell, or an open side within the geofence ([`Self::set_open_sides`]). The nearest wall
    /// cell is straight across the nearest edge, so the Euclidean test reduces to the distance to that
    /// edge; corner wall cells are never nearer.
    #[inline]
    fn wall_within_radius(&self, x: i32, y: i32) -> bool {
        let r = i32::from(self.inflation_radius);
        let fence = r.max(i32::from(self.border >> 4));
        let reach = |bit: u8| if self.border & bit != 0 { fence } else { r };
        // `mission.walls` bits: south 1, east 2, north 4, west 8.
        x < reach(8)
            || y < reach(1)
            || i32::from(self.shape.width) - x <= reach(2)
            || i32::from(self.shape.height) - y <= reach(4)
    }

    /// Adds `delta` to a cell's log-odds (clamped) and applies the hysteresis.
    fn add_log_odds<const N: usize>(&mut self, x: i32, y: i32, delta: i16, changed: &mut ChangedCells<N>) {
        let Some(byte) = self.byte(x, y) else {
            return;
        };
        let sum = i16::from(decode_log_odds(byte)) + delta;
        // The clamp bounds are i8, so the clamped sum fits an i8.
        let value = sum.clamp(i16::from(self.config.min_log_odds), i16::from(self.config.max_log_odds)) as i8;
        self.set_log_odds(x, y, value, changed);
    }

    /// Stores a cell's log-odds, re-decides occupancy with hysteresis and, if it flipped, updates the
    /// blocked layer around the cell.
    fn set_log_odds<const N: usize>(&mut self, x: i32, y: i32, value: i8, changed: &mut ChangedCells<N>) {
        let (occupied_threshold, free_threshold) = (self.config.occupied_threshold, self.config.free_threshold);
        let Some(byte) = self.byte_mut(x, y) else {
            return;
        };
        let was_occupied = *byte & OCCUPIED != 0;
        let occupied = if was_occupied {
            value > free_threshold
        } else {
            value >= occupied_threshold
        };
        *byte = (*byte & BLOCKED) | if occupied { OCCUPIED } else { 0 } | encode_log_odds(value);
        match (was_occupied, occupied) {
            (false, true) => self.inflate(x, y, changed),
            (true, false) => self.deflate(x, y, changed),
            _ => {}
        }
    }

    /// `(x, y)` became occupied: block every cell of its disc that is not blocked yet.
    fn inflate<const N: usize>(&mut self, x: i32, y: i32, changed: &mut ChangedCells<N>) {
        for (px, py) in Disc::new(self.shape, x, y, self.inflation_radius) {
            if let Some(byte) = self.byte_mut(px, py)
                && *byte & BLOCKED == 0
            {
                *byte |= BLOCKED;
                changed.push(Cell::new(px as u16, py as u16));
            }
        }
    }

    /// `(x, y)` became free: unblock every cell of its disc that no other occupied cell or wall still
    /// blocks. Only cells within the radius of `(x, y)` can have depended on it.
    fn deflate<const N: usize>(&mut self, x: i32, y: i32, changed: &mut ChangedCells<N>) {
        let r = self.inflation_radius;
        for (px, py) in Disc::new(self.shape, x, y, r) {
            if !self.blocked_at(px, py) || self.wall_within_radius(px, py) {
                continue;
            }
            // The disc is symmetric, so "an occupied cell within r of p" is "an occupied cell in p's disc".
            if Disc::new(self.shape, px, py, r).any(|(qx, qy)| self.occupied_at(qx, qy)) {
                continue;
            }
            if let Some(byte) = self.byte_mut(px, py) {
                *byte &= !BLOCKED;
                changed.push(Cell::new(px as u16, py as u16));
            }
        }
    }
}

impl<const CELLS: usize> Default for OccupancyGrid<CELLS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CELLS: usize> Traversability for OccupancyGrid<CELLS> {
    fn shape(&self) -> GridShape {
        self.shape
    }

    fn is_blocked(&self, x: i32, y: i32) -> bool {
        self.blocked_at(x, y)
    }
}

/// The cells `(x, y)` of the grid with `(x − cx)² + (y − cy)² ≤ r²`, row by row.
struct Disc {
    cx: i32,
    cy: i32,
    r: i32,
    width: i32,
    /// Current row and the last row to visit.
    y: i32,
    y_end: i32,
    /// Next column of the current row and its last column.
    x: i32,
    x_end: i32,
}

impl Disc {
    fn new(shape: GridShape, cx: i32, cy: i32, r: u8) -> Self {
        let r = i32::from(r);
        let mut disc = Self {
            cx,
            cy,
            r,
            width: i32::from(shape.width),
            y: (cy - r).max(0),
            y_end: (cy + r).min(i32::from(shape.height) - 1),
            x: 0,
            x_end: -1,
        };
        disc.start_row();
        disc
    }

    /// Sets the column range of row `self.y`: the half-width is ⌊√(r² − dy²)⌋.
    fn start_row(&mut self) {
        let dy = self.y - self.cy;
        let rest = self.r * self.r - dy * dy;
        let mut half = 0;
        // r ≤ MAX_INFLATION_RADIUS_CELLS, so this loop is short; it avoids floats and their rounding.
        while (half + 1) * (half + 1) <= rest {
            half += 1;
        }
        self.x = (self.cx - half).max(0);
        self.x_end = (self.cx + half).min(self.width - 1);
    }
}

impl Iterator for Disc {
    type Item = (i32, i32);

    fn next(&mut self) -> Option<(i32, i32)> {
        while self.y <= self.y_end {
            if self.x <= self.x_end {
                let cell = (self.x, self.y);
                self.x += 1;
                return Some(cell);
            }
            self.y += 1;
            if self.y <= self.y_end {
                self.start_row();
            }
        }
        None
    }
}

/// Amanatides–Woo walk over the grid cells a segment crosses, after clipping it to the grid.
///
/// Coordinates are in cell units (metres / [`CELL_SIZE_M`], the same division [`GridShape::cell_at`] does,
/// so the end cell agrees with it). The walk goes from the start cell to the end cell in exactly
/// `|Δcolumn| + |Δrow|` unit steps; at each step it moves across whichever cell edge (vertical or
/// horizontal) the segment reaches first. The crossing parameters are recomputed from the entry point at
/// every step rather than accumulated, so rounding does not build up along long beams; the comparison is
/// cross-multiplied to avoid dividing by a zero direction component.
struct BeamWalk {
    /// Current cell.
    x: i32,
    y: i32,
    step_x: i32,
    step_y: i32,
    /// Steps still to take along each axis.
    left_x: u32,
    left_y: u32,
    /// Point where the segment enters the grid (its start if that is inside).
    origin_x: f32,
    origin_y: f32,
    /// Absolute direction components of the segment.
    abs_dx: f32,
    abs_dy: f32,
    /// Whether the start cell has been yielded.
    started: bool,
    /// The cell containing the segment's end, if that is inside the grid (per `GridShape::cell_at`).
    end_in_grid: Option<(i32, i32)>,
}

impl BeamWalk {
    fn new(shape: GridShape, from: (f32, f32), to: (f32, f32)) -> Option<Self> {
        let (w, h) = (f32::from(shape.width), f32::from(shape.height));
        let (ax, ay) = (from.0 / CELL_SIZE_M, from.1 / CELL_SIZE_M);
        let (bx, by) = (to.0 / CELL_SIZE_M, to.1 / CELL_SIZE_M);
        let sane = |v: f32| v.is_finite() && libm::fabsf(v) <= MAX_BEAM_COORD_CELLS;
        if !(sane(ax) && sane(ay) && sane(bx) && sane(by)) || shape.cells() == 0 {
            return None;
        }
        let (dx, dy) = (bx - ax, by - ay);
        // The cell a point lies in, `GridShape::cell_at`'s rule (half-open cells; the far edges are out).
        let cell_of = |px: f32, py: f32| {
            let (cx, cy) = (libm::floorf(px), libm::floorf(py));
            (cx >= 0.0 && cy >= 0.0 && cx < w && cy < h).then_some((cx as i32, cy as i32))
        };
        let start_in_grid = cell_of(ax, ay);
        let end_in_grid = cell_of(bx, by);

        // Liang–Barsky: clip the parameter range [0, 1] to the closed box [0, w] × [0, h].
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for (p, q) in [(-dx, ax), (dx, w - ax), (-dy, ay), (dy, h - ay)] {
            if p == 0.0 {
                // Parallel to this edge: entirely outside or entirely on the inner side.
                if q < 0.0 {
                    return None;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        // Reject a segment that misses the grid or only touches its border at one point. One with an endpoint
        // inside is always kept, even if rounding made the clipped range empty (an end a hair inside the
        // border): the walk below only needs the start and end cells, both clamped into the grid.
        if start_in_grid.is_none() && end_in_grid.is_none() && t0 >= t1 {
            return None;
        }

        let clamp_cell = |px: f32, py: f32| {
            let cx = (libm::floorf(px) as i32).clamp(0, i32::from(shape.width) - 1);
            let cy = (libm::floorf(py) as i32).clamp(0, i32::from(shape.height) - 1);
            (cx, cy)
        };
        let (origin_x, origin_y) = if start_in_grid.is_some() {
            (ax, ay)
        } else {
            (ax + t0 * dx, ay + t0 * dy)
        };
        // A point on the border may floor to the row/column just past it (x = w); the clamp picks the
        // border cell the segment actually runs along.
        let (sx, sy) = start_in_grid.unwrap_or_else(|| clamp_cell(origin_x, origin_y));
        let (ex, ey) = end_in_grid.unwrap_or_else(|| clamp_cell(ax + t1 * dx, ay + t1 * dy));
        Some(Self {
            x: sx,
            y: sy,
            step_x: (ex - sx).signum(),
            step_y: (ey - sy).signum(),
            left_x: ex.abs_diff(sx),
            left_y: ey.abs_diff(sy),
            origin_x,
            origin_y,
            abs_dx: libm::fabsf(dx),
            abs_dy: libm::fabsf(dy),
            started: false,
            end_in_grid,
        })
    }
}

impl Iterator for BeamWalk {
    type Item = (i32, i32);

    fn next(&mut self) -> Option<(i32, i32)> {
        if !self.started {
            self.started = true;
            return Some((self.x, self.y));
        }
        let step_along_x = match (self.left_x, self.left_y) {
            (0, 0) => return None,
            (_, 0) => true,
            (0, _) => false,
            _ => {
                // Distance (along each axis) from the entry point to the next vertical / horizontal cell
                // edge in the direction of travel. The segment reaches the vertical edge first when
                // gap_x / |dx| < gap_y / |dy|; cross-multiplied to stay finite when a component is 0.
                let gap_x = if self.step_x > 0 {
                    (self.x + 1) as f32 - self.origin_x
                } else {
                    self.origin_x - self.x as f32
                };
                let gap_y = if self.step_y > 0 {
                    (self.y + 1) as f32 - self.origin_y
                } else {
                    self.origin_y - self.y as f32
                };
                gap_x * self.abs_dy <= gap_y * self.abs_dx
            }
        };
        if step_along_x {
            self.x += self.step_x;
            self.left_x -= 1;
        } else {
            self.y += self.step_y;
            self.left_y -= 1;
        }
        Some((self.x, self.y))
    }
}
