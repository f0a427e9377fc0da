//! Map-relative localization: the horizontal Multi-ranger beams measured against the occupancy map the
//! drone has already built, as scalar position fixes for the EKF.
//!
//! Why: flow-only position is a random walk (≈ 1 cm/√s, 10–25 cm over a mission in simulation). The
//! arena's walls and the obstacles the map already holds do not move, so a beam that reaches one of them
//! measures the drone's distance to it. The wall anchors (`wall_hold`) do this only while hovering and only
//! square to the axes; here every sweep in flight is used, at any heading, against the map.
//!
//! Job, in two halves that run on different sides of the firmware:
//! * [`cast_fixes`] (the navigator's side, thread mode, where the map lives): for each horizontal beam,
//!   an exact grid walk ([`ray_cast`]) from the estimated position along the beam's estimated direction to
//!   the first *confirmed* obstacle cell or the arena's wall, and from it a [`MapFix`]: the surface's
//!   normal `n` (pointing away from the drone), the measured and the expected distance to the surface
//!   along `n`, and the std of the difference. It runs *before* the same sweep is written into the map,
//!   against the map as it was, so a beam never sees the cell it is about to write.
//! * [`Estimator::on_map_fixes`](super::Estimator::on_map_fixes) (the stabilizer's side): each fix is a
//!   scalar measurement `d_n = c − p·n` (Jacobian `−n` on x, y), gated at `map_fix_gate_sigma`.
//!
//! Surfaces. *The arena's walls* are known exactly (the mission's `arena_m`: planes x = 0, x = X, y = 0,
//! y = Y, those of them `mission.walls` names); a mapped cell within half a cell of a wall is that wall's
//! own trace and is skipped, so the ray reaches the exact wall. An open side is no surface: a ray that
//! reaches it gives no fix (whatever the beam met lies outside the map), and the cells along it count
//! as any other. *An obstacle's surface* is a [`Landmark`]: the ray cast finds its first
//! confirmed cell and the face the ray entered by (x or y); a cell is used only if one of its two
//! neighbours along that face is occupied too (a straight piece of surface, not the corner of a box or a
//! thin cylinder, whose faces the grid cannot tell), and a face's last cell (one such neighbour, not both)
//! only for a reading within [`FACE_END_MAX_DIFFERENCE_M`] of the plane: the map smears a surface's end,
//! and a cylinder's flank looks straight for a few cells, so a beam there may have passed the end or met
//! the curve behind the plane. The first [`LANDMARK_SETTLE`] beams that end at such
//! a face place its plane (the mean of where they ended: estimated position + measured distance along the
//! normal; no fix meanwhile), and from then on the plane is frozen and every beam that reaches a confirmed
//! cell within 1.5 cells of it is a fix against it, once the beams have met the face over at least
//! [`LANDMARK_MIN_EXTENT_CELLS`] cells along it (a box's face, not a cylinder's flank).
//!
//! Landmarks along a corridor (measured in simulation). A drone flying along a wall at
//! 0.45 m/s passes a 5 cm row per sweep, and its heading swings while it looks ahead, so a side beam meets
//! each row of the face about once per pass, in scattered rows. Three rules let such a face become one
//! landmark: one hit from an earlier sweep locates a surface ([`CONFIRMED_LOG_ODDS`]); a beam joins a
//! landmark up to [`LANDMARK_GAP_CELLS`] beyond its extent; a new landmark replaces an unsettled one
//! before a settled one, so the faces found on the way out still hold on the way back. Without them, a
//! corridor can give its side beams no settled landmark for 20 s and the estimate drifts across it
//! (22.6 cm against 15.5 cm with them in one stressed world); over 2 000 stressed worlds the missions whose
//! estimate ever erred by more than 10 cm fell from 84 to 51. The extent rule keeps a cylinder's flank,
//! which the looser rules would otherwise settle, from pulling the estimate along as the beam slides
//! over the curve (24 cm of error without it, 5 cm with it, in one stressed world).
//!
//! Why landmarks rather than the cells themselves (measured in simulation): with the plane through
//! the first confirmed cell's centre, the fixes ratcheted. The first confirmed cell along a ray is the
//! nearest of the cells the noisy hits straddle, so its centre is biased towards the drone; the fix then
//! moves the estimate away from the surface, the next hits (written from the moved estimate) confirm a
//! cell nearer still, and so on: on the default world (noise seed 14) the estimate crept 21 cm behind the
//! truth in 10 s of flight towards a wall. A frozen, unquantised plane cannot follow the map.
//!
//! Rules against a self-reinforcing loop (the map is written in the estimated frame, so a map and an
//! estimate could drift together): a cell only *locates* a surface, the plane comes from the measured
//! ends of several beams and then stays frozen; the caller casts before it writes the sweep, so a cell
//! counts only from a return of an earlier sweep ([`CONFIRMED_LOG_ODDS`]); the arena's walls, which no drift can
//! move, win over a cell that lies within half a cell of them. Outliers (a person, an unmapped box in front
//! of a mapped wall, a ranger outlier): the measured range must lie within [`PRE_GATE_M`] of the expected
//! one, then the estimator's 3σ gate decides; a beam more than 1.5 cells short of the surface cast whose
//! end lies beside a cell the map holds (not that surface's) met that object and gives no fix
//! ([`ends_beside_mapped`]: every sweep of an object reads the same shortfall, which the estimator's jump
//! rule would take for a confirmed drift). Beams at more than [`MAX_INCIDENCE_RAD`] to the surface's
//! normal are not used (a grazing beam's range depends on where along the surface it lands).
//!
//! Heading. A beam's distance along a wall's normal depends on the heading it was computed with:
//! `measured = r·n·u(ψ)`, so a heading error δ (true minus estimated, counter-clockwise) makes it short by
//! `δ·r·n·u⊥` ([`MapFix::yaw_lever_m`], `u⊥` the beam turned by +90°). Against the arena's exact walls
//! each fix therefore carries its Jacobian on the heading too, and the EKF splits the residual between
//! position and heading by their covariances. Two beams 90° apart on one wall (the drone flying at
//! 35°–55° to it; walls are used up to [`MAX_WALL_INCIDENCE_RAD`], a flat plane has no grazing doubt)
//! have levers of opposite sign: their disagreement is the heading alone, whatever the position. One beam
//! over consecutive sweeps as the drone moves does the same through the filter's position–heading
//! covariance (the flow's displacement is rotated by the heading error). Rules: only the exact walls
//! steer the heading, never a landmark (its plane was placed with the estimated heading of its time, so
//! a heading error would be frozen into it: the self-reinforcing loop); the position gate sees the
//! heading's variance; a fix that would turn the heading by more than `map_fix_max_yaw_step_rad` (0.02
//! rad) is rejected. Measured (`host-tests/tests/flight/heading.rs`, default world, a 6 mrad/s gyro bias
//! appearing after the at-rest calibration, 3° placement error): the late yaw error stays at 2.0–3.3°
//! (a lag: there is no gyro-bias state) and the position at 3.1–3.9 cm, against 6.2–10.8° and 12–66 cm
//! without.
//!
//! Non-goals: a gyro-bias state (the heading error is corrected, not its rate), mapping (the mission owns
//! the map), loop closure.
//!
//! Units and frames: metres, radians, arena frame (origin at the arena's lower-left corner). Memory: a
//! [`MapFixes`] is 4 × 20 bytes plus tags; [`Landmarks`] (the navigator keeps one per flight) 48 × 16
//! bytes. Cost: at most
//! [`MAX_RANGE_M`] / cell × 2 + 2 cell visits per beam (≈ 102 at 5 cm: a grid walk visits at most one cell
//! per x or y boundary crossed), four beams per sweep; a new landmark scans the 48 slots for one to
//! replace; then up to four scalar EKF updates.

use crate::types::MultiRangerSample;

/// Beams longer than this give no fix, m (the ranger's noise grows with the range; the walk is bounded
/// by it).
pub const MAX_RANGE_M: f32 = 2.5;
/// Beams shorter than this give no fix, m (something at the drone).
pub const MIN_RANGE_M: f32 = 0.1;
/// A cell locates a surface at or above this log-odds: one clean hit (+8) of an earlier sweep, or more
/// hits net of misses (−3 each). (Two hits, 16, left a face flown past once without landmarks: each row
/// of it is met about once per pass; see the module docs, "Landmarks along a corridor".)
pub const CONFIRMED_LOG_ODDS: i8 = 8;
/// A beam more than this off the surface's normal gives no fix, rad (40°): for an obstacle's face, whose
/// grid cells say little about where along it a grazing beam lands.
pub const MAX_INCIDENCE_RAD: f32 = 0.70;
/// The same for the arena's exact walls, rad (55°): a flat plane has no such doubt, and beams up to 55°
/// let two beams 90° apart see one wall at once when the drone flies at 35°–55° to it (the heading
/// correction, see the module docs).
pub const MAX_WALL_INCIDENCE_RAD: f32 = 0.96;
/// A measured range further than this from the expected one is something else (an unmapped object in
/// front, an outlier), m.
pub const PRE_GATE_M: f32 = 0.3;
/// A beam that ends at the last cell of a face (one neighbour along it occupied, not both) gives a fix only
/// if it differs from the expected distance by at most this, m. The map smears a surface's end by a cell
/// or so, and a curved surface (a cylinder) looks straight for a few cells, so a beam there may pass the
/// end or meet the curve far behind the plane: a 14 cm cylinder's flank, taken for its widest face, read
/// 6–9 cm long for three sweeps running in a stressed simulation and pulled the estimate 5 cm off.
pub const FACE_END_MAX_DIFFERENCE_M: f32 = 0.04;
/// Ranger noise of the fix: this floor plus [`RANGER_STD_RELATIVE`] × range, m (the VL53L1x: a few mm plus
/// ≈ 1 % of the range; doubled for surfaces that are not quite flat).
pub const RANGER_STD_FLOOR_M: f32 = 0.005;
/// Ranger noise per metre of range.
pub const RANGER_STD_RELATIVE: f32 = 0.02;

/// What a ray reached.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Distance from the origin to where the ray enters the surface's cell (or meets the wall), m.
    pub distance_m: f32,
    /// The axis the surface is square to: 0 = a face of constant x, 1 = constant y.
    pub axis: usize,
    /// The surface's normal along `axis`, pointing away from the origin: +1 or −1.
    pub sign: f32,
    /// The surface plane's coordinate along `axis`, m (a cell's centre, or the wall).
    pub plane_m: f32,
    /// The arena's wall (exact) rather than a mapped cell (quantised).
    pub wall: bool,
    /// The cell the ray entered (column, row); for the wall, the last cell before it.
    pub cell: (i32, i32),
}

/// The grid a ray walks: `width × height` cells of `cell_m`, covering `[0, width·cell) × [0, height·cell)`,
/// inside an arena whose sides are the planes x = 0, x = `arena_m.0`, y = 0, y = `arena_m.1`, each a wall
/// only if `walls` has its bit (`crate::mission::WALL_SOUTH` …).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayGrid {
    /// Columns.
    pub width: i32,
    /// Rows.
    pub height: i32,
    /// Cell edge, m.
    pub cell_m: f32,
    /// The arena's size, m.
    pub arena_m: (f32, f32),
    /// Which sides are walls (`mission.walls`: south 1, east 2, north 4, west 8). An open side measures
    /// nothing: a ray that reaches it ends there without a hit, and the cells along it are ordinary cells
    /// (no wall's trace to skip).
    pub walls: u8,
}

/// Walks the ray from `origin` (m) along the unit vector `dir` for at most `max_m` and returns the first
/// cell for which `confirmed(column, row)` holds (the cell containing the origin excluded), or the arena's
/// wall if the ray meets it first, or `None` (also when the ray leaves the arena through an open side). Amanatides–Woo: every cell the ray crosses is visited once, in
/// order, at most `2·max_m/cell + 2` of them. Cells outside `grid` are never asked. Non-finite input, an
/// origin outside the arena or a zero direction give `None`.
pub fn ray_cast(
    grid: &RayGrid,
    origin: (f32, f32),
    dir: (f32, f32),
    max_m: f32,
    confirmed: impl Fn(i32, i32) -> bool,
) -> Option<RayHit> {
    let (ox, oy) = origin;
    let (ux, uy) = dir;
    let (ax, ay) = grid.arena_m;
    let s = grid.cell_m;
    let finite = [ox, oy, ux, uy, ax, ay, s, max_m].iter().all(|v| v.is_finite());
    if !finite || s <= 0.0 || max_m <= 0.0 || ux * ux + uy * uy < 0.25 {
        return None;
    }
    if !(ox > 0.0 && oy > 0.0 && ox < ax && oy < ay) {
        return None;
    }
    // The wall the ray meets first.
    let along = |o: f32, u: f32, far: f32| -> f32 {
        if u > 1e-9 {
            (far - o) / u
        } else if u < -1e-9 {
            -o / u
        } else {
            f32::INFINITY
        }
    };
    let (twx, twy) = (along(ox, ux, ax), along(oy, uy, ay));
    let (t_wall, wall_axis) = if twx <= twy { (twx, 0) } else { (twy, 1) };
    let has = |axis: usize, positive: bool| grid.walls & crate::mission::wall_bit(axis, positive) != 0;
    // The side the ray leaves through is open: nothing stands there to measure.
    let wall_there = has(wall_axis, if wall_axis == 0 { ux > 0.0 } else { uy > 0.0 });
    let wall_hit = |cell: (i32, i32)| {
        let (u, far) = if wall_axis == 0 { (ux, ax) } else { (uy, ay) };
        RayHit {
            distance_m: t_wall,
            axis: wall_axis,
            sign: if u > 0.0 { 1.0 } else { -1.0 },
            plane_m: if u > 0.0 { far } else { 0.0 },
            wall: true,
            cell,
        }
    };

    let mut cx = libm::floorf(ox / s) as i32;
    let mut cy = libm::floorf(oy / s) as i32;
    let step_x: i32 = if ux > 0.0 { 1 } else { -1 };
    let step_y: i32 = if uy > 0.0 { 1 } else { -1 };
    let next_boundary = |c: i32, step: i32, o: f32, u: f32| -> f32 {
        if u.abs() <= 1e-9 {
            return f32::INFINITY;
        }
        let b = if step > 0 { (c + 1) as f32 * s } else { c as f32 * s };
        ((b - o) / u).max(0.0)
    };
    let mut t_max_x = next_boundary(cx, step_x, ox, ux);
    let mut t_max_y = next_boundary(cy, step_y, oy, uy);
    let dt_x = if ux.abs() > 1e-9 { s / ux.abs() } else { f32::INFINITY };
    let dt_y = if uy.abs() > 1e-9 { s / uy.abs() } else { f32::INFINITY };
    let limit = max_m.min(t_wall);
    let max_steps = (2.0 * max_m / s) as u32 + 2;
    for _ in 0..max_steps {
        // Step into the next cell.
        let (t_enter, axis) = if t_max_x <= t_max_y {
            let t = t_max_x;
            cx += step_x;
            t_max_x += dt_x;
            (t, 0)
        } else {
            let t = t_max_y;
            cy += step_y;
            t_max_y += dt_y;
            (t, 1)
        };
        if t_enter >= limit {
            break;
        }
        if cx < 0 || cy < 0 || cx >= grid.width || cy >= grid.height {
            // Out of the grid: at the wall when the grid ends there (the walk's summed steps may land a
            // rounding error short of `t_wall`); otherwise (a grid smaller than the arena) nothing is known.
            let at_wall = t_enter >= t_wall - 0.5 * s && t_wall <= max_m && wall_there;
            return at_wall.then(|| wall_hit((cx, cy)));
        }
        // A cell within half a cell of a wall is that wall's own trace: the exact wall replaces it.
        let (lo_x, lo_y) = (cx as f32 * s, cy as f32 * s);
        let trace = (lo_x <= 0.5 * s && has(0, false))
            || (lo_y <= 0.5 * s && has(1, false))
            || (lo_x + s >= ax - 0.5 * s && has(0, true))
            || (lo_y + s >= ay - 0.5 * s && has(1, true));
        if trace || !confirmed(cx, cy) {
            continue;
        }
        let (lo, u) = if axis == 0 { (lo_x, ux) } else { (lo_y, uy) };
        return Some(RayHit {
            distance_m: t_enter,
            axis,
            sign: if u > 0.0 { 1.0 } else { -1.0 },
            plane_m: lo + 0.5 * s,
            wall: false,
            cell: (cx, cy),
        });
    }
    (t_wall <= max_m && wall_there).then(|| wall_hit((cx, cy)))
}

/// One beam's fix: the distance to a surface measured along its normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapFix {
    /// The surface's unit normal, pointing away from the drone (arena frame).
    pub normal: [f32; 2],
    /// The measured distance from the drone to the surface along `normal`: range × cos(incidence), m.
    pub measured_m: f32,
    /// The same distance expected from the estimated position when the beam was cast, m.
    pub expected_m: f32,
    /// The std of `measured_m − expected_m` (ranger and, for a landmark, its plane's), m.
    pub std_m: f32,
    /// The heading's lever on the fix, m/rad: `range · n·u⊥`, with `u⊥` the beam's arena direction turned
    /// by +90°. `measured_m` (computed with the estimated heading) comes out short by this much per radian
    /// the true heading lies counter-clockwise of the estimate, so the EKF's Jacobian on the heading error
    /// is `−yaw_lever_m`. Set only
    /// against the arena's exact walls (0 for a landmark, whose plane was placed with the estimated
    /// heading of its time and must not steer the heading: see the module docs, "Heading").
    pub yaw_lever_m: f32,
}

/// The fixes of one Multi-ranger sweep, in the order of [`MultiRangerSample::horizontal`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MapFixes {
    /// One per horizontal beam.
    pub fixes: [Option<MapFix>; 4],
}

impl MapFixes {
    /// Whether no beam gave a fix.
    pub fn is_empty(&self) -> bool {
        self.fixes.iter().all(Option::is_none)
    }
}

/// A straight piece of an obstacle's surface, frozen in the arena frame the first few times a beam sees it
/// (see the module documentation, "Landmarks").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Landmark {
    /// The axis the surface is square to: 0 = a face of constant x, 1 = constant y.
    pub axis: u8,
    /// The side it was seen from: the normal pointing away from the drone, +1 or −1 along `axis`.
    pub sign: i8,
    /// The surface's coordinate along `axis`, m: the mean of where the first [`LANDMARK_SETTLE`] beams
    /// ended (estimated position + measured distance along the normal).
    pub plane_m: f32,
    /// The cells along the face it covers (first and last index across `axis`).
    pub along: (i16, i16),
    /// Beams averaged into `plane_m` (at most [`LANDMARK_SETTLE`]; fixes only from then on).
    pub seen: u8,
}

/// A landmark gives fixes once this many beams have placed it.
pub const LANDMARK_SETTLE: u8 = 5;
/// Landmarks kept; when full, a new one replaces the oldest unsettled one, or the oldest if all have
/// settled.
pub const MAX_LANDMARKS: usize = 48;
/// A confirmed cell belongs to a landmark whose plane lies within this many cells of the cell's centre.
const LANDMARK_MATCH_CELLS: f32 = 1.5;
/// ... and whose extent along the face reaches within this many cells of it (a side beam of a drone
/// passing a face, its heading swinging, meets scattered rows of it).
pub const LANDMARK_GAP_CELLS: i16 = 6;
/// A settled landmark gives fixes only once beams have met it over this many cells along the face
/// (30 cm): a cylinder's flank (radius up to 0.15 m) also looks straight for a few cells.
pub const LANDMARK_MIN_EXTENT_CELLS: i16 = 6;
/// The std of a settled landmark's plane relative to the ranger noise of one fix, m.
const LANDMARK_STD_M: f32 = 0.005;

/// The landmarks of one flight (fixed memory, [`MAX_LANDMARKS`] entries).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Landmarks {
    items: [Option<Landmark>; MAX_LANDMARKS],
    next: usize,
}

impl Default for Landmarks {
    fn default() -> Self {
        Self::new()
    }
}

impl Landmarks {
    /// None.
    pub const fn new() -> Self {
        Self {
            items: [None; MAX_LANDMARKS],
            next: 0,
        }
    }

    /// Forget them all (a new flight).
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// The landmarks held.
    pub fn iter(&self) -> impl Iterator<Item = &Landmark> {
        self.items.iter().flatten()
    }

    /// The landmark the beam's surface belongs to, creating or settling it with this beam's end
    /// (`end_m`, the estimated position plus the measured distance along the normal). Returns the plane to
    /// measure against once the landmark has settled (before this beam was added).
    fn observe(
        &mut self,
        axis: usize,
        sign: f32,
        cell_center_m: f32,
        along: i16,
        end_m: f32,
        cell_m: f32,
    ) -> Option<f32> {
        let sign_i: i8 = if sign > 0.0 { 1 } else { -1 };
        let found = self.items.iter_mut().flatten().find(|l| {
            usize::from(l.axis) == axis
                && l.sign == sign_i
                && (l.plane_m - cell_center_m).abs() <= LANDMARK_MATCH_CELLS * cell_m
                && along >= l.along.0 - LANDMARK_GAP_CELLS
                && along <= l.along.1 + LANDMARK_GAP_CELLS
        });
        match found {
            Some(l) => {
                l.along = (l.along.0.min(along), l.along.1.max(along));
                if l.seen >= LANDMARK_SETTLE {
                    return (l.along.1 - l.along.0 + 1 >= LANDMARK_MIN_EXTENT_CELLS).then_some(l.plane_m);
                }
                l.seen += 1;
                l.plane_m += (end_m - l.plane_m) / f32::from(l.seen);
                None
            }
            None => {
                // Replace an unsettled landmark before a settled one (the faces found on the way out
                // still hold on the way back).
                let slot = (0..MAX_LANDMARKS)
                    .map(|k| (self.next + k) % MAX_LANDMARKS)
                    .find(|&i| self.items[i].is_none_or(|l| l.seen < LANDMARK_SETTLE))
                    .unwrap_or(self.next);
                self.next = slot;
                self.items[self.next] = Some(Landmark {
                    axis: axis as u8,
                    sign: sign_i,
                    plane_m: end_m,
                    along: (along, along),
                    seen: 1,
                });
                self.next = (self.next + 1) % MAX_LANDMARKS;
                None
            }
        }
    }
}

/// A beam shorter than the surface cast by more than this many cells is checked for having met something
/// else the map already holds ([`ends_beside_mapped`]): as far as the cells of the surface itself reach
/// (a landmark's beams end within [`LANDMARK_MATCH_CELLS`] of its plane).
const SHORT_BEAM_CELLS: f32 = 1.5;
/// How far around a short beam's end ([`ends_beside_mapped`]) an occupied cell is looked for, cells.
const BESIDE_END_CELLS: i32 = 2;

/// Whether the beam along `u` from `position_m` that read `range_m`, short of the surface `hit` the cast
/// found, ended within [`BESIDE_END_CELLS`] of a cell the map holds as `occupied` that is not part of that
/// surface (further than [`SHORT_BEAM_CELLS`] from its plane). Then the beam met an object the map already
/// knows but the ray slipped past: the curve of a cylinder, or a box in front of a wall whose first sweep
/// wrote one hit beside this ray. Every later sweep of such an object reads the same shortfall, so the
/// estimator's jump rule (a jump needs a second sweep's word) would take it for a real drift: three beams
/// that meet a 0.3 m cylinder 0.23 m in front of a wall can make the estimate jump 19 cm and stay off for
/// the rest of the leg. A real drift
/// towards a surface leaves the beam's end in the free cells before it, unless the map has absorbed the
/// drift already (then the cast stops at those cells and this rule does not apply). At most 25 cell
/// look-ups.
fn ends_beside_mapped(
    grid: &RayGrid,
    position_m: [f32; 2],
    u: [f32; 2],
    range_m: f32,
    hit: &RayHit,
    occupied: &impl Fn(i32, i32) -> bool,
) -> bool {
    let end = [position_m[0] + range_m * u[0], position_m[1] + range_m * u[1]];
    if !(end[0].is_finite() && end[1].is_finite()) {
        return false;
    }
    let (cx, cy) = (
        libm::floorf(end[0] / grid.cell_m) as i32,
        libm::floorf(end[1] / grid.cell_m) as i32,
    );
    for dy in -BESIDE_END_CELLS..=BESIDE_END_CELLS {
        for dx in -BESIDE_END_CELLS..=BESIDE_END_CELLS {
            let (x, y) = (cx + dx, cy + dy);
            if !(0..grid.width).contains(&x) || !(0..grid.height).contains(&y) {
                continue;
            }
            let centre = [(x as f32 + 0.5) * grid.cell_m, (y as f32 + 0.5) * grid.cell_m];
            if (centre[hit.axis] - hit.plane_m).abs() <= SHORT_BEAM_CELLS * grid.cell_m {
                // The surface's own cells (a wall's trace, a landmark's face).
                continue;
            }
            if occupied(x, y) {
                return true;
            }
        }
    }
    false
}

/// The fixes of one sweep (`sample`) from the estimated position `position_m` and heading `yaw_rad`,
/// against the arena's walls and the `landmarks` found at the confirmed cells of the map as it is *before*
/// this sweep is written (see the module docs); beams that place a new landmark give no fix.
/// `confirmed(column, row)` says whether a cell holds a confirmed obstacle
/// (log-odds ≥ [`CONFIRMED_LOG_ODDS`]); `occupied` whether it is occupied at all (the straight-surface
/// check). Non-finite input gives no fix.
pub fn cast_fixes(
    grid: &RayGrid,
    sample: &MultiRangerSample,
    position_m: [f32; 2],
    yaw_rad: f32,
    landmarks: &mut Landmarks,
    confirmed: impl Fn(i32, i32) -> bool,
    occupied: impl Fn(i32, i32) -> bool,
) -> MapFixes {
    let mut out = MapFixes::default();
    if !(yaw_rad.is_finite() && position_m.iter().all(|p| p.is_finite())) {
        return out;
    }
    let (sn, cs) = (libm::sinf(yaw_rad), libm::cosf(yaw_rad));
    let min_cos = libm::cosf(MAX_INCIDENCE_RAD);
    let min_cos_wall = libm::cosf(MAX_WALL_INCIDENCE_RAD);
    for (beam, range) in sample.horizontal().into_iter().enumerate() {
        let Some(r) = range.filter(|r| r.is_finite() && (MIN_RANGE_M..=MAX_RANGE_M).contains(r)) else {
            continue;
        };
        let (bx, by) = MultiRangerSample::HORIZONTAL_BEAMS_BODY[beam];
        let u = [cs * bx - sn * by, sn * bx + cs * by];
        // Cast a little beyond the reading: a surface the noise put just past it is still the one seen.
        let reach = (r + PRE_GATE_M).min(MAX_RANGE_M + PRE_GATE_M);
        let Some(hit) = ray_cast(grid, (position_m[0], position_m[1]), (u[0], u[1]), reach, &confirmed) else {
            continue;
        };
        let cos_inc = hit.sign * u[hit.axis];
        if cos_inc.is_nan() || cos_inc < if hit.wall { min_cos_wall } else { min_cos } {
            continue;
        }
        // A straight piece of surface: a neighbour along the face is occupied too; both, inside the face.
        let mut face_interior = true;
        if !hit.wall {
            let (x, y) = hit.cell;
            let (before, after) = if hit.axis == 0 {
                (occupied(x, y - 1), occupied(x, y + 1))
            } else {
                (occupied(x - 1, y), occupied(x + 1, y))
            };
            if !(before || after) {
                continue;
            }
            face_interior = before && after;
        }
        let mut normal = [0.0; 2];
        normal[hit.axis] = hit.sign;
        let measured = r * cos_inc;
        let plane_m = if hit.wall {
            hit.plane_m
        } else {
            let (x, y) = hit.cell;
            let along = if hit.axis == 0 { y } else { x } as i16;
            let end_m = position_m[hit.axis] + hit.sign * measured;
            if (end_m - hit.plane_m).abs() > LANDMARK_MATCH_CELLS * grid.cell_m {
                // The beam did not end at this cell (something else, or an outlier).
                continue;
            }
            let Some(plane) = landmarks.observe(hit.axis, hit.sign, hit.plane_m, along, end_m, grid.cell_m) else {
                continue;
            };
            plane
        };
        let expected = hit.sign * (plane_m - position_m[hit.axis]);
        if expected - measured > SHORT_BEAM_CELLS * grid.cell_m
            && ends_beside_mapped(grid, position_m, u, r, &hit, &occupied)
        {
            continue;
        }
        let difference = (measured - expected).abs();
        if difference.is_nan() || difference > PRE_GATE_M {
            continue;
        }
        if !face_interior && difference > FACE_END_MAX_DIFFERENCE_M {
            continue;
        }
        let ranger_std = (RANGER_STD_FLOOR_M + RANGER_STD_RELATIVE * r) * cos_inc;
        let plane_std = if hit.wall { 0.0 } else { LANDMARK_STD_M };
        let std_m = libm::sqrtf(ranger_std * ranger_std + plane_std * plane_std);
        // n·u⊥ with u⊥ = (−u_y, u_x); only the wall's own axis of n is non-zero.
        let u_perp = [-u[1], u[0]];
        let yaw_lever_m = if hit.wall { r * hit.sign * u_perp[hit.axis] } else { 0.0 };
        out.fixes[beam] = Some(MapFix {
            normal,
            measured_m: measured,
            expected_m: expected,
            std_m,
            yaw_lever_m,
        });
    }
    out
}
