//! Grid geometry shared by the mapper and the planner: cells, the arena-frame ↔ cell transform, the
//! compile-time capacity of the arena, and the [`Traversability`] trait through which the planner reads the
//! inflated "blocked" layer.
//!
//! Non-goals: storage of occupancy (see [`crate::nav::grid`]) and search (see [`crate::nav::dstar`]).
//!
//! Cells are 5 cm squares. Cell `(x, y)` covers `[x·s, (x+1)·s) × [y·s, (y+1)·s)` in the arena frame, with
//! `s` = [`CELL_SIZE_M`]; `y` counts rows from the bottom (the arena's y = 0 edge).
//!
//! ```text
//!   y ▲   row h-1  ┌──┬──┬──┐
//!     │            │  │  │  │   index = y · width + x
//!     │   row 0    ├──┼──┼──┤
//!     │            │0 │1 │2 │
//!     └────────────┴──┴──┴──┴─▶ x
//! ```

/// Edge length of a grid cell, metres.
pub const CELL_SIZE_M: f32 = 0.05;

/// Widest arena the firmware maps, in cells (6.4 m).
pub const MAX_WIDTH_CELLS: u16 = 128;
/// Deepest arena the firmware maps, in cells (3.2 m).
pub const MAX_HEIGHT_CELLS: u16 = 64;

/// Cell capacity of the grid and planner the firmware is built with.
///
/// The default is the seed arena, 6 × 3 m = 120 × 60 cells, which keeps grid + planner within 48 KiB.
/// The `large-arena` feature raises it to 128 × 64 cells (6.4 × 3.2 m) at the cost of about 5 KiB more.
#[cfg(not(feature = "large-arena"))]
pub const ARENA_CELLS: usize = 120 * 60;
/// Cell capacity of the grid and planner the firmware is built with (6.4 × 3.2 m).
#[cfg(feature = "large-arena")]
pub const ARENA_CELLS: usize = 128 * 64;

/// A grid cell: column `x` and row `y` counted from the arena's lower-left corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Cell {
    /// Column, 0 at the arena's x = 0 edge.
    pub x: u16,
    /// Row, 0 at the arena's y = 0 edge.
    pub y: u16,
}

impl Cell {
    /// The cell at column `x`, row `y`.
    pub const fn new(x: u16, y: u16) -> Self {
        Self { x, y }
    }

    /// Chebyshev (king-move) distance between two cells.
    pub fn chebyshev(self, other: Cell) -> u16 {
        self.x.abs_diff(other.x).max(self.y.abs_diff(other.y))
    }
}

/// Width and height of a grid in cells; the transform between the arena frame and cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridShape {
    /// Columns.
    pub width: u16,
    /// Rows.
    pub height: u16,
}

impl GridShape {
    /// A shape of `width × height` cells, if it is non-empty and holds at most `capacity` cells.
    pub fn new(width: u16, height: u16, capacity: usize) -> Option<Self> {
        let cells = usize::from(width) * usize::from(height);
        (width > 0 && height > 0 && cells <= capacity && cells <= usize::from(u16::MAX))
            .then_some(Self { width, height })
    }

    /// The shape that covers an arena of `size_x_m × size_y_m` metres (rounded to whole cells), if it
    /// holds at most `capacity` cells.
    pub fn for_arena(size_x_m: f32, size_y_m: f32, capacity: usize) -> Option<Self> {
        if !(size_x_m.is_finite() && size_y_m.is_finite()) || size_x_m <= 0.0 || size_y_m <= 0.0 {
            return None;
        }
        let w = libm::roundf(size_x_m / CELL_SIZE_M);
        let h = libm::roundf(size_y_m / CELL_SIZE_M);
        if w < 1.0 || h < 1.0 || w > f32::from(u16::MAX) || h > f32::from(u16::MAX) {
            return None;
        }
        Self::new(w as u16, h as u16, capacity)
    }

    /// Number of cells.
    pub fn cells(self) -> usize {
        usize::from(self.width) * usize::from(self.height)
    }

    /// Whether signed coordinates name a cell of this grid.
    #[inline]
    pub fn contains(self, x: i32, y: i32) -> bool {
        x >= 0 && y >= 0 && x < i32::from(self.width) && y < i32::from(self.height)
    }

    /// Row-major index of a cell (the caller guarantees it is inside).
    #[inline]
    pub fn index(self, cell: Cell) -> usize {
        usize::from(cell.y) * usize::from(self.width) + usize::from(cell.x)
    }

    /// The cell of a row-major index (a 0-wide shape maps everything to column 0 rather than dividing by 0).
    #[inline]
    pub fn cell(self, index: usize) -> Cell {
        let w = usize::from(self.width.max(1));
        Cell::new((index % w) as u16, (index / w) as u16)
    }

    /// The cell containing an arena-frame point, or `None` outside the grid (or for NaN).
    pub fn cell_at(self, x_m: f32, y_m: f32) -> Option<Cell> {
        let cx = libm::floorf(x_m / CELL_SIZE_M);
        let cy = libm::floorf(y_m / CELL_SIZE_M);
        if !(cx.is_finite() && cy.is_finite()) || cx < 0.0 || cy < 0.0 {
            return None;
        }
        if cx >= f32::from(self.width) || cy >= f32::from(self.height) {
            return None;
        }
        Some(Cell::new(cx as u16, cy as u16))
    }

    /// The arena-frame centre of a cell, metres.
    pub fn center_of(self, cell: Cell) -> (f32, f32) {
        (
            (f32::from(cell.x) + 0.5) * CELL_SIZE_M,
            (f32::from(cell.y) + 0.5) * CELL_SIZE_M,
        )
    }
}

/// The planner's view of a map: which cells may not be entered.
///
/// Implemented by [`crate::nav::grid::OccupancyGrid`] (its inflated layer) and by test and replay maps.
pub trait Traversability {
    /// The grid's size.
    fn shape(&self) -> GridShape;
    /// Whether the cell at signed coordinates may not be entered. Cells outside the grid are blocked.
    fn is_blocked(&self, x: i32, y: i32) -> bool;
}
