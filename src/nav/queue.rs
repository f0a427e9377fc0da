//! An indexed 4-ary min-heap over grid cells: the open list `U` of D* Lite.
//!
//! Job: hold at most `CAP` cells, each with a priority [`Key`] and one `u16` payload (D* Lite keeps the
//! cell's `rhs` there, see [`crate::nav::dstar`]), and support insert, change-key (up or down), removal of any
//! cell and membership tests. `heapless::BinaryHeap` cannot change or remove an arbitrary element, which
//! D* Lite's `UpdateVertex` needs, hence this module.
//!
//! Non-goals: stability among equal keys, growth beyond `CAP` (a full queue is reported, never grown).
//!
//! Sifts move a hole instead of swapping (one entry write per level) and compare keys as one packed
//! integer; the heap is 4-ary (see `ARITY`).
//!
//! Memory: `2·CELLS` bytes for the position index plus `10·CAP` bytes for the entries (struct of arrays,
//! so no padding): 7200 cells and 1024 entries take 24 640 B.
//!
//! Complexity: `contains`/`payload`/`top` O(1); `push`, `update`, `remove`, `pop` O(log CAP); `clear` and
//! `rekey` O(len).
//!
//! The position index stores `slot + 1`, so an all-zero queue is a valid empty one (it can live in
//! zero-initialised or `NOLOAD` memory once cleared).

/// Children per heap node. A 4-ary heap is half as deep as a binary one: D* Lite pushes several cells per
/// expansion and pops one, and with deepest-first ties a pushed cell often rises to the top, so the
/// shallower sift-up outweighs the extra comparisons of sift-down.
const ARITY: usize = 4;

/// A D* Lite priority: compared lexicographically, `k1` first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Key {
    /// `min(g, rhs) + h(start, s) + km`.
    pub k1: u32,
    /// `min(g, rhs)`.
    pub k2: u16,
}

impl Key {
    /// A key larger than any real one (what an empty queue's top compares as).
    pub const MAX: Key = Key {
        k1: u32::MAX,
        k2: u16::MAX,
    };
}

/// The queue already holds `CAP` cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueueFull;

/// See the module documentation.
#[derive(Clone)]
pub struct IndexedQueue<const CELLS: usize, const CAP: usize> {
    /// `slot + 1` of each cell in the heap, 0 when the cell is not queued.
    position: [u16; CELLS],
    k1: [u32; CAP],
    k2: [u16; CAP],
    cell: [u16; CAP],
    payload: [u16; CAP],
    len: usize,
    high_water: usize,
}

impl<const CELLS: usize, const CAP: usize> Default for IndexedQueue<CELLS, CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CELLS: usize, const CAP: usize> IndexedQueue<CELLS, CAP> {
    // Cell ids and `slot + 1` are stored as u16.
    const FITS: () = assert!(CELLS <= u16::MAX as usize && CAP < u16::MAX as usize && CAP > 0);

    /// An empty queue.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::FITS;
        Self {
            position: [0; CELLS],
            k1: [0; CAP],
            k2: [0; CAP],
            cell: [0; CAP],
            payload: [0; CAP],
            len: 0,
            high_water: 0,
        }
    }

    /// Number of queued cells.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no cell is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The largest number of cells queued at once since the last [`IndexedQueue::reset_high_water`].
    pub fn high_water(&self) -> usize {
        self.high_water
    }

    /// Restart the high-water mark at the current length.
    pub fn reset_high_water(&mut self) {
        self.high_water = self.len;
    }

    /// Empty the queue (O(len)): only the queued cells' positions are touched.
    pub fn clear(&mut self) {
        for slot in 0..self.len {
            let c = usize::from(self.cell[slot]);
            if let Some(p) = self.position.get_mut(c) {
                *p = 0;
            }
        }
        self.len = 0;
    }

    /// Forget everything, including stale position entries (O(CELLS)); needed once for memory that was
    /// never initialised through [`IndexedQueue::new`].
    pub fn wipe(&mut self) {
        self.position.fill(0);
        self.len = 0;
        self.high_water = 0;
    }

    /// The heap slot of a cell, if queued.
    #[inline]
    fn slot_of(&self, cell: usize) -> Option<usize> {
        match self.position.get(cell) {
            Some(&p) if p != 0 => Some(usize::from(p) - 1),
            _ => None,
        }
    }

    /// Whether `cell` is queued.
    #[inline]
    pub fn contains(&self, cell: usize) -> bool {
        self.slot_of(cell).is_some()
    }

    /// The payload of a queued cell.
    #[inline]
    pub fn payload(&self, cell: usize) -> Option<u16> {
        self.slot_of(cell).map(|s| self.payload[s])
    }

    /// The cell with the smallest key, and that key.
    #[inline]
    pub fn top(&self) -> Option<(usize, Key)> {
        (self.len > 0).then(|| (usize::from(self.cell[0]), self.key(0)))
    }

    /// The smallest key, or [`Key::MAX`] when empty.
    #[inline]
    pub fn top_key(&self) -> Key {
        if self.len > 0 { self.key(0) } else { Key::MAX }
    }

    /// Insert a cell that is not queued yet. A cell that is already queued gets its key and payload
    /// replaced instead; a cell id outside `CELLS` is ignored.
    pub fn push(&mut self, cell: usize, key: Key, payload: u16) -> Result<(), QueueFull> {
        let Some(&p) = self.position.get(cell) else {
            return Ok(());
        };
        if p != 0 {
            self.set(usize::from(p) - 1, key, payload);
            return Ok(());
        }
        if self.len >= CAP {
            return Err(QueueFull);
        }
        let slot = self.len;
        self.len += 1;
        self.high_water = self.high_water.max(self.len);
        self.write(slot, cell as u16, key, payload);
        self.sift_up(slot);
        Ok(())
    }

    /// Change the key and payload of a queued cell (does nothing for a cell that is not queued).
    pub fn update(&mut self, cell: usize, key: Key, payload: u16) {
        if let Some(slot) = self.slot_of(cell) {
            self.set(slot, key, payload);
        }
    }

    /// Give the entry at `slot` a new key and payload and restore the heap order.
    fn set(&mut self, slot: usize, key: Key, payload: u16) {
        let old = self.key(slot);
        self.k1[slot] = key.k1;
        self.k2[slot] = key.k2;
        self.payload[slot] = payload;
        if key < old {
            self.sift_up(slot);
        } else {
            self.sift_down(slot);
        }
    }

    /// Remove a cell if queued; returns its payload.
    pub fn remove(&mut self, cell: usize) -> Option<u16> {
        let slot = self.slot_of(cell)?;
        let payload = self.payload[slot];
        self.position[cell] = 0;
        self.len -= 1;
        let last = self.len;
        if slot != last {
            let moved_key = self.key(last);
            self.write(slot, self.cell[last], moved_key, self.payload[last]);
            // The moved entry may belong above or below the hole.
            let parent_bigger = slot > 0 && self.key((slot - 1) / ARITY) > moved_key;
            if parent_bigger {
                self.sift_up(slot);
            } else {
                self.sift_down(slot);
            }
        }
        Some(payload)
    }

    /// Remove and return the cell with the smallest key.
    pub fn pop(&mut self) -> Option<(usize, Key, u16)> {
        let (cell, key) = self.top()?;
        let payload = self.remove(cell)?;
        Some((cell, key, payload))
    }

    /// Recompute every key with `key_of(cell, payload)` and restore the heap order (O(len)).
    pub fn rekey(&mut self, mut key_of: impl FnMut(usize, u16) -> Key) {
        for slot in 0..self.len {
            let k = key_of(usize::from(self.cell[slot]), self.payload[slot]);
            self.k1[slot] = k.k1;
            self.k2[slot] = k.k2;
        }
        for slot in (0..self.len.div_ceil(ARITY)).rev() {
            self.sift_down(slot);
        }
    }

    /// Visit every queued cell with its key and payload, in heap order (for checks and plots).
    pub fn for_each(&self, mut visit: impl FnMut(usize, Key, u16)) {
        for slot in 0..self.len {
            visit(usize::from(self.cell[slot]), self.key(slot), self.payload[slot]);
        }
    }

    /// The key at `slot` as one integer with the same order: one comparison, no branch on `k1` equality, in
    /// the sift loops. `k1` fills the high word, so on a 32-bit core the register pair is the key itself
    /// (`k1 << 16` costs shifts there: +7 % instructions on a replan, measured under QEMU).
    #[inline(always)]
    fn rank(&self, slot: usize) -> u64 {
        (u64::from(self.k1[slot]) << 32) | u64::from(self.k2[slot])
    }

    #[inline]
    fn key(&self, slot: usize) -> Key {
        Key {
            k1: self.k1[slot],
            k2: self.k2[slot],
        }
    }

    #[inline]
    fn write(&mut self, slot: usize, cell: u16, key: Key, payload: u16) {
        self.cell[slot] = cell;
        self.k1[slot] = key.k1;
        self.k2[slot] = key.k2;
        self.payload[slot] = payload;
        self.position[usize::from(cell)] = (slot + 1) as u16;
    }

    /// Move the entry at `from` to `to` (the hole), keeping `position` in step.
    #[inline]
    fn move_entry(&mut self, from: usize, to: usize) {
        let cell = self.cell[from];
        self.cell[to] = cell;
        self.k1[to] = self.k1[from];
        self.k2[to] = self.k2[from];
        self.payload[to] = self.payload[from];
        self.position[usize::from(cell)] = (to + 1) as u16;
    }

    /// Restore the heap order above `slot`: the entry there moves up past every larger parent, which move
    /// down into the hole it leaves (one write per level instead of a swap).
    fn sift_up(&mut self, mut slot: usize) {
        let key = self.key(slot);
        let rank = self.rank(slot);
        let (cell, payload) = (self.cell[slot], self.payload[slot]);
        while slot > 0 {
            let parent = (slot - 1) / ARITY;
            if self.rank(parent) <= rank {
                break;
            }
            self.move_entry(parent, slot);
            slot = parent;
        }
        self.write(slot, cell, key, payload);
    }

    /// Restore the heap order below `slot`: the smallest child moves up into the hole.
    fn sift_down(&mut self, mut slot: usize) {
        let key = self.key(slot);
        let rank = self.rank(slot);
        let (cell, payload) = (self.cell[slot], self.payload[slot]);
        loop {
            let first = ARITY * slot + 1;
            if first >= self.len {
                break;
            }
            let end = (first + ARITY).min(self.len);
            let mut child = first;
            let mut child_rank = self.rank(first);
            for c in first + 1..end {
                let r = self.rank(c);
                if r < child_rank {
                    child = c;
                    child_rank = r;
                }
            }
            if rank <= child_rank {
                break;
            }
            self.move_entry(child, slot);
            slot = child;
        }
        self.write(slot, cell, key, payload);
    }
}
