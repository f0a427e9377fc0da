//! Independent oracles for the planner tests: a plain std map and a textbook Dijkstra written from the
//! movement rules of docs/formats.md (map format), sharing no code with `cfnav::nav::dstar`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use cfnav::nav::map::{Cell, GridShape, Traversability};

/// A heap-allocated blocked/free map of any size.
#[derive(Clone, Debug)]
pub struct VecMap {
    pub width: u16,
    pub height: u16,
    pub blocked: Vec<bool>,
}

impl VecMap {
    pub fn new(width: u16, height: u16) -> Self {
        Self {
            width,
            height,
            blocked: vec![false; usize::from(width) * usize::from(height)],
        }
    }

    pub fn index(&self, c: Cell) -> usize {
        usize::from(c.y) * usize::from(self.width) + usize::from(c.x)
    }

    pub fn get(&self, c: Cell) -> bool {
        self.blocked[self.index(c)]
    }

    pub fn set(&mut self, c: Cell, blocked: bool) {
        let i = self.index(c);
        self.blocked[i] = blocked;
    }

    pub fn cells(&self) -> impl Iterator<Item = Cell> + '_ {
        (0..self.height).flat_map(move |y| (0..self.width).map(move |x| Cell::new(x, y)))
    }
}

impl Traversability for VecMap {
    fn shape(&self) -> GridShape {
        GridShape {
            width: self.width,
            height: self.height,
        }
    }

    fn is_blocked(&self, x: i32, y: i32) -> bool {
        if x < 0 || y < 0 || x >= i32::from(self.width) || y >= i32::from(self.height) {
            return true;
        }
        self.blocked[y as usize * usize::from(self.width) + x as usize]
    }
}

fn free(map: &VecMap, x: i32, y: i32) -> bool {
    x >= 0
        && y >= 0
        && x < i32::from(map.width)
        && y < i32::from(map.height)
        && !map.blocked[y as usize * usize::from(map.width) + x as usize]
}

/// The legal moves out of a cell with their costs: 10 straight, 14 diagonal, never into a blocked cell,
/// never a diagonal past a blocked cell.
pub fn moves(map: &VecMap, c: Cell) -> Vec<(Cell, u32)> {
    let (x, y) = (i32::from(c.x), i32::from(c.y));
    let mut out = Vec::with_capacity(8);
    for dy in -1..=1 {
        for dx in -1..=1 {
            if dx == 0 && dy == 0 {
                continue;
            }
            if !free(map, x + dx, y + dy) {
                continue;
            }
            let diagonal = dx != 0 && dy != 0;
            if diagonal && !(free(map, x + dx, y) && free(map, x, y + dy)) {
                continue;
            }
            out.push((
                Cell::new((x + dx) as u16, (y + dy) as u16),
                if diagonal { 14 } else { 10 },
            ));
        }
    }
    out
}

/// Cheapest cost from `from` to `to`, `None` when unreachable.
pub fn dijkstra(map: &VecMap, from: Cell, to: Cell) -> Option<u32> {
    if from == to {
        return Some(0);
    }
    let mut dist = vec![u32::MAX; map.blocked.len()];
    let mut heap = BinaryHeap::new();
    dist[map.index(from)] = 0;
    heap.push(Reverse((0u32, from.x, from.y)));
    while let Some(Reverse((d, x, y))) = heap.pop() {
        let c = Cell::new(x, y);
        if d > dist[map.index(c)] {
            continue;
        }
        if c == to {
            return Some(d);
        }
        for (n, w) in moves(map, c) {
            let nd = d + w;
            let i = map.index(n);
            if nd < dist[i] {
                dist[i] = nd;
                heap.push(Reverse((nd, n.x, n.y)));
            }
        }
    }
    None
}

/// The cost of a cell path if every step is a legal move, else `None`.
pub fn path_cost(map: &VecMap, path: &[Cell]) -> Option<u32> {
    let mut total = 0;
    for w in path.windows(2) {
        let (_, c) = moves(map, w[0]).into_iter().find(|(n, _)| *n == w[1])?;
        total += c;
    }
    Some(total)
}

/// Parse a map drawn with `#` (blocked) and `.` (free), first line = highest row.
pub fn parse(rows: &[&str]) -> VecMap {
    let height = rows.len() as u16;
    let width = rows[0].len() as u16;
    let mut map = VecMap::new(width, height);
    for (r, line) in rows.iter().enumerate() {
        let y = height - 1 - r as u16;
        for (x, ch) in line.chars().enumerate() {
            map.set(Cell::new(x as u16, y), ch == '#');
        }
    }
    map
}
