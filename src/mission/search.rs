//! The pad search: the coarse lawnmower around the nominal goal, then refinement lines across and along the
//! first crossing until the detector locks, every line clipped to keep its clearance from mapped obstacles
//! and the arena walls, and bounded by what the horizontal beams read now (the map in the estimate frame
//! can miss a thin cylinder or a face it confirmed late), slowing before regions no beam has looked into
//! and turning the nearest beam onto them (the heading is otherwise held: a line may run diagonally to all
//! four beams).
//! The rules are in the [mission's documentation](super).

use super::landing::{MAX_REFUSALS, Touchdown};
use super::navigate::{SEARCH_UNOBSERVED_APPROACH_GAIN, SEARCH_UNOBSERVED_MIN_SPEED_M_S};
use super::{Leg, Mission, Phase, Search};
use crate::landing::gate::Target;
use crate::landing::pad::EdgeKind;
use crate::landing::sweep::{ArenaBounds, LawnmowerSweep, SweepAxis};
use crate::nav::map::{CELL_SIZE_M, Cell};
use crate::types::{MultiRangerSample, Setpoint, StateEstimate};

/// Search lines stop this far from mapped obstacles and arena walls, m: the drone's radius (0.06 m), the
/// estimate's drift over a search (≈ 5 cm) and tracking overshoot at a line's end.
const SEARCH_CLEARANCE_M: f32 = 0.18;
/// Along a search line the drone steers for the point this far ahead of its projection onto the line, m
/// (pure pursuit: an offset from the line decays over about this much travel).
const LINE_LOOKAHEAD_M: f32 = 0.2;
/// Closer than this to the line, the drone flies straight at the line's end, m.
const LINE_STRAIGHT_M: f32 = 0.02;
/// A drone this close to a coarse line, between its ends, flies on along it rather than back to its start, m.
const ON_LINE_TOLERANCE_M: f32 = 0.1;
/// Mapped cells lying wholly within this of the arena's boundary are the wall's own returns, m (two cells:
/// the wall's cell and the next one in, where the estimate's few centimetres of drift put some returns).
const WALL_CELLS_M: f32 = 0.1;
/// Two crossings, one each way, lock when the detector's confidence (its shape term: the edges lie at one
/// distance from the centre, as on a square pad) is at least this.
const TWO_CROSSING_LOCK_CONFIDENCE: f32 = 0.8;
/// How far [`Mission::clearance`] looks, m.
const CLEARANCE_HORIZON_M: f32 = 0.3;
/// Sampling step along a search line for the clearance check, m.
const CLEARANCE_STEP_M: f32 = 0.025;
const REFINE_LINES: u8 = 3;
/// A line end reached this far short of its waypoint was cut short by the clearance, m (the end is
/// reached within 4 cm of where the line may go).
const CLIPPED_LINE_END_M: f32 = 0.06;
/// Searches widened and re-centred per leg after the refinement found no lock.
const MAX_WIDENINGS: u8 = 1;
/// A widened coarse pattern is this much larger on each side, m.
const WIDEN_M: f32 = 0.4;
/// A landing clear of the pad keeps this far from the pad's nominal point, m: the pad's centre lies within
/// 0.35 m of it, its corner 0.21 m further, the body 0.06 m, 0.05 m for the drift.
pub(super) const PAD_REACH_M: f32 = 0.67;
/// Failing that, this far from the pad estimate's centre (half the pad's diagonal, the body, drift), m.
const PAD_ESTIMATE_REACH_M: f32 = 0.33;
/// ... and this far from each pad edge seen (the body and drift), m.
pub(super) const PAD_EDGE_REACH_M: f32 = 0.14;
/// How far the goal pad's centre may lie from its nominal point (`docs/formats.md`, world files), m.
const PAD_OFFSET_M: f32 = 0.35;
/// Spacing of the pad centres [`Mission::distance_to_possible_pad_centres`] tries, m.
const PAD_CENTRE_LATTICE_M: f32 = 0.03;
/// An edge seen lies on the rim of a pad whose centre is within half the pad's diagonal plus this (the
/// edge's position error, a few cm, and half the lattice's diagonal), m.
const PAD_CENTRE_EDGE_SLACK_M: f32 = 0.05;
/// A floor spot keeps this far from mapped obstacles and the arena walls, m.
pub(super) const FLOOR_SPOT_CLEARANCE_M: f32 = 0.22;
/// Rings of candidate floor spots around the drone, and their spacing, m.
const FLOOR_SPOT_RINGS: u8 = 9;
const FLOOR_SPOT_STEP_M: f32 = 0.15;
/// Floor spots on each ring but the drone's own position, evenly spaced (with eight, the one direction a
/// cluttered corner leaves open can fall between them, and a search that gives up there finds only spots
/// where the pad could be).
const FLOOR_SPOT_DIRECTIONS: u8 = 16;
/// Candidate floor spots: the drone's own position and [`FLOOR_SPOT_DIRECTIONS`] on each further ring.
const FLOOR_SPOT_CANDIDATES: usize = 1 + FLOOR_SPOT_DIRECTIONS as usize * (FLOOR_SPOT_RINGS as usize - 1);
const REFINE_STAGES: u8 = 8;
/// A live beam reading closer than this closes the way along it, m: the body's radius (0.06 m), the
/// reading's age at 10 Hz and the velocity loop's lag (≈ 0.25 s: 8 cm at 0.3 m/s) and 4 cm of ranger
/// noise and overshoot. (0.13 m let world 20 000 193 overshoot a line's end into a cylinder, 0.4 m/s.)
pub(super) const LIVE_BEAM_STOP_M: f32 = 0.2;
/// The speed allowed towards a live beam's return per metre beyond [`LIVE_BEAM_STOP_M`], 1/s: 0.45 m/s at
/// 0.5 m, so the search speed is only cut where a beam sees something within a few tenths of a metre.
pub(super) const LIVE_BEAM_GAIN_PER_S: f32 = 1.5;
/// A beam's return within this of the arena wall's distance along the beam is that wall, m (the estimate's
/// error with map fixes, a few cm, plus the ranger's).
const LIVE_BEAM_WALL_MATCH_M: f32 = 0.08;
/// Beams reading further than this bound nothing, m.
const LIVE_BEAM_HORIZON_M: f32 = 1.0;

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    pub(super) fn begin_search(&mut self, state: &StateEstimate) -> Setpoint {
        let centre = self.leg_target();
        let arena = ArenaBounds::new(self.params.arena_m.0, self.params.arena_m.1, 0.15);
        let here = (state.position_m[0], state.position_m[1]);
        // The first pass's lines run along the arrival direction: its middle line, through the nominal
        // point, then starts just behind the drone instead of off to its side.
        let mut sweep = self.config.sweep;
        let (vx, vy) = (state.velocity_m_s[0], state.velocity_m_s[1]);
        if libm::hypotf(vx, vy) > 0.1 {
            sweep.axis = if libm::fabsf(vx) >= libm::fabsf(vy) {
                SweepAxis::AlongX
            } else {
                SweepAxis::AlongY
            };
        }
        self.sweep = LawnmowerSweep::new(centre, here, &sweep, &arena).ok();
        // The detector keeps what it saw on the approach (it was reset when the leg began), and so does
        // the memory of its latest estimate, which belongs to those edges.
        let latest = self.touchdown.latest;
        self.touchdown = Touchdown::new();
        self.touchdown.latest = latest;
        let search = Search::Coarse {
            step: 0,
            reverse: false,
        };
        self.phase = Phase::Search(search);
        self.search(search, state, 0.02)
    }

    /// Distance from `p` to the nearest mapped obstacle cell (the cell's square, not its centre) or arena
    /// wall, m, capped at [`CLEARANCE_HORIZON_M`]. Looks at a (2·3+1)² window of cells: O(49).
    pub(super) fn clearance(&self, p: (f32, f32)) -> f32 {
        let (w, h) = self.params.arena_m;
        let mut best = CLEARANCE_HORIZON_M.min(p.0).min(w - p.0).min(p.1).min(h - p.1);
        let cx = libm::floorf(p.0 / CELL_SIZE_M) as i32;
        let cy = libm::floorf(p.1 / CELL_SIZE_M) as i32;
        let reach = libm::ceilf(CLEARANCE_HORIZON_M / CELL_SIZE_M) as i32;
        for y in (cy - reach)..=(cy + reach) {
            for x in (cx - reach)..=(cx + reach) {
                if !self.shape.contains(x, y) || !self.grid.is_occupied(Cell::new(x as u16, y as u16)) {
                    continue;
                }
                let (x0, y0) = (x as f32 * CELL_SIZE_M, y as f32 * CELL_SIZE_M);
                // A cell the arena wall explains (the walls' own returns, one or two cells in with the
                // estimate's drift) is already counted, exactly, as the wall: counting it again keeps
                // every line 0.05–0.1 m further from a wall than the clearance, and a line along a pad
                // against the wall is clipped to nothing.
                if x0 + CELL_SIZE_M <= WALL_CELLS_M
                    || x0 >= w - WALL_CELLS_M
                    || y0 + CELL_SIZE_M <= WALL_CELLS_M
                    || y0 >= h - WALL_CELLS_M
                {
                    continue;
                }
                let dx = (x0 - p.0).max(p.0 - (x0 + CELL_SIZE_M)).max(0.0);
                let dy = (y0 - p.1).max(p.1 - (y0 + CELL_SIZE_M)).max(0.0);
                best = best.min(libm::hypotf(dx, dy));
            }
        }
        best
    }

    /// The point where the straight flight `from → to` must stop to keep [`SEARCH_CLEARANCE_M`] from what
    /// the drone has mapped: the search pattern is laid out blind around the nominal point, and its lines
    /// may run into a wall or box beside the pad. Moving while the clearance grows (leaving a tight spot) is
    /// always allowed; the first sample where it drops below the minimum and keeps shrinking ends the line.
    pub(super) fn clip_to_clearance(&self, from: (f32, f32), to: (f32, f32)) -> (f32, f32) {
        let length = libm::hypotf(to.0 - from.0, to.1 - from.1);
        if !(length.is_finite() && length > 1e-3) {
            return to;
        }
        let steps = libm::ceilf(length / CLEARANCE_STEP_M).min(400.0) as u32;
        let mut previous = (from, self.clearance(from));
        for i in 1..=steps {
            let t = i as f32 / steps as f32;
            let p = (from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1));
            let c = self.clearance(p);
            if c < SEARCH_CLEARANCE_M && c < previous.1 - 1e-4 {
                return previous.0;
            }
            previous = (p, c);
        }
        to
    }

    /// Fly towards `target` at the search speed (stopping short of mapped obstacles, see
    /// [`Self::clip_to_clearance`], and of what the live beams see, see [`Self::live_beam_guard`]); `true`
    /// once within 3 cm of where it can get, or when a beam closes the way ahead.
    pub(super) fn fly_to(
        &mut self,
        state: &StateEstimate,
        target: (f32, f32),
        line_from: Option<(f32, f32)>,
    ) -> (Setpoint, bool) {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let target = self.clip_to_clearance((x, y), target);
        let d = libm::hypotf(target.0 - x, target.1 - y);
        // Along a line (`line_from → target`), steer for a point [`LINE_LOOKAHEAD_M`] ahead on the line
        // rather than straight for its end: a drone that joined the line a few centimetres off (the
        // on-line rule, the end of a turn) converges onto it within a few tenths of a metre instead of
        // flying a slanted track, so the pattern's lines lie where they were laid out.
        // Only off the pad (no entry edge waiting for its exit: a crossing is flown straight, as the
        // detector wants), and only where the way to the steering point keeps the search clearance.
        let on_top = self.pad.edges().last().is_some_and(|e| e.kind == EdgeKind::Enter);
        let aim = line_from
            .filter(|_| !on_top)
            .map(|a| Self::line_carrot((x, y), a, target))
            .filter(|aim| self.clip_to_clearance((x, y), *aim) == *aim)
            .unwrap_or(target);
        let (dx, dy) = (aim.0 - x, aim.1 - y);
        let d_aim = libm::hypotf(dx, dy);
        // Line ends lie off the pad, so they need no precision; a firm approach (about 2.5 m/s² of
        // deceleration demand, 4 cm tolerance) keeps each line short in time, and with it the drift
        // between the crossings the detector compares.
        let mut speed = self.config.search_speed_m_s.min(0.05 + 2.5 * d);
        // A line may run diagonally to all four beams into a region none has looked into (a cylinder
        // beside the pad, first seen at 0.1 m): as while navigating, slow down before it and turn the
        // beam nearest to it onto it until it is seen.
        if d > 0.05 {
            let (observed, unobserved) = self.observed_along((x, y), target, false);
            speed = speed.min(SEARCH_UNOBSERVED_MIN_SPEED_M_S + SEARCH_UNOBSERVED_APPROACH_GAIN * observed);
            if let Some(cell) = unobserved {
                self.heading = Self::look_with_nearest_beam(self.heading, (x, y), cell);
            }
        }
        let (vx, vy) = if d > 1e-3 && d_aim > 1e-3 {
            (speed * dx / d_aim, speed * dy / d_aim)
        } else {
            (0.0, 0.0)
        };
        // The map in the estimate frame may miss what a beam sees now (a thin cylinder, a face the map
        // confirmed late): the live beams bound the speed towards each of their returns, and a line whose
        // way ahead a beam closes ends there, like a line clipped by the map.
        let ((vx, vy), blocked) = self.live_beam_guard(state, (vx, vy));
        let reached = d < 0.04 || blocked;
        (
            Setpoint::Velocity {
                vx_m_s: vx,
                vy_m_s: vy,
                z_m: self.params.height_m,
                yaw_rad: self.heading,
            },
            reached,
        )
    }

    /// The point [`LINE_LOOKAHEAD_M`] beyond `p`'s projection onto the line `a → b`, or `b` itself when
    /// that lies within the look-ahead (or the line is degenerate or not finite).
    pub(super) fn line_carrot(p: (f32, f32), a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
        let (ux, uy) = (b.0 - a.0, b.1 - a.1);
        let length = libm::hypotf(ux, uy);
        if !(length.is_finite() && length > 1e-3) {
            return b;
        }
        let (ux, uy) = (ux / length, uy / length);
        // Within a couple of centimetres of the line, fly straight at its end: a steady heading, which
        // the detector's crossings want, rather than steering after every jump of the estimate.
        let across = (p.0 - a.0) * uy - (p.1 - a.1) * ux;
        if libm::fabsf(across).is_nan() || libm::fabsf(across) <= LINE_STRAIGHT_M {
            return b;
        }
        let along = ((p.0 - a.0) * ux + (p.1 - a.1) * uy).max(0.0) + LINE_LOOKAHEAD_M;
        if !along.is_finite() || along >= length {
            return b;
        }
        (a.0 + along * ux, a.1 + along * uy)
    }

    /// Bounds the arena-frame velocity `v` by what the four horizontal beams read now: the component
    /// towards each beam's return may be at most [`LIVE_BEAM_GAIN_PER_S`]` · (d − `[`LIVE_BEAM_STOP_M`]`)`
    /// (the excess is removed along that beam, so the drone slides along a face instead of stopping), and
    /// `true` when a beam within 45° of the direction of travel reads closer than the stop distance (the
    /// way ahead is closed). A beam with no return, or an invalid one, bounds nothing.
    pub(super) fn live_beam_guard(&self, state: &StateEstimate, v: (f32, f32)) -> ((f32, f32), bool) {
        self.live_beam_guard_at(state, v, LIVE_BEAM_STOP_M)
    }

    /// [`Self::live_beam_guard`] with the stop distance `stop_m` in place of [`LIVE_BEAM_STOP_M`].
    pub(super) fn live_beam_guard_at(&self, state: &StateEstimate, v: (f32, f32), stop_m: f32) -> ((f32, f32), bool) {
        let yaw = state.attitude_rad[2];
        let speed = libm::hypotf(v.0, v.1);
        if !(yaw.is_finite() && speed.is_finite()) || speed < 1e-4 {
            return (v, false);
        }
        let (c, s) = (libm::cosf(yaw), libm::sinf(yaw));
        let (ux0, uy0) = (v.0 / speed, v.1 / speed);
        let ranges = [
            self.last_ranges.front,
            self.last_ranges.back,
            self.last_ranges.left,
            self.last_ranges.right,
        ];
        let mut out = v;
        let mut blocked = false;
        for (range, (bx, by)) in ranges.into_iter().zip(MultiRangerSample::HORIZONTAL_BEAMS_BODY) {
            let Some(d) = range.filter(|d| d.is_finite() && *d > 0.0 && *d < LIVE_BEAM_HORIZON_M) else {
                continue;
            };
            let (ux, uy) = (c * bx - s * by, s * bx + c * by);
            // The arena's walls are known exactly and the lines keep their clearance from them already
            // (`clip_to_clearance`): a return the wall explains bounds nothing, so a pad against a wall is
            // still crossed to its far edge.
            if libm::fabsf(d - self.wall_distance_along((state.position_m[0], state.position_m[1]), (ux, uy)))
                < LIVE_BEAM_WALL_MATCH_M
            {
                continue;
            }
            let allowed = (LIVE_BEAM_GAIN_PER_S * (d - stop_m)).max(0.0);
            let towards = out.0 * ux + out.1 * uy;
            if towards > allowed {
                out = (out.0 - (towards - allowed) * ux, out.1 - (towards - allowed) * uy);
            }
            if d < stop_m && ux0 * ux + uy0 * uy > core::f32::consts::FRAC_1_SQRT_2 {
                blocked = true;
            }
        }
        (out, blocked)
    }

    /// Distance from `p` along the unit vector `u` to the arena's boundary, m (infinite when none is ahead).
    fn wall_distance_along(&self, p: (f32, f32), u: (f32, f32)) -> f32 {
        let (w, h) = self.params.arena_m;
        let along = |pos: f32, dir: f32, size: f32| {
            if dir > 1e-6 {
                (size - pos) / dir
            } else if dir < -1e-6 {
                -pos / dir
            } else {
                f32::INFINITY
            }
        };
        along(p.0, u.0, w).min(along(p.1, u.1, h))
    }

    pub(super) fn search(&mut self, search: Search, state: &StateEstimate, _dt_s: f32) -> Setpoint {
        if let Some(sp) = self.approach_if_locked() {
            return sp;
        }
        match search {
            Search::Coarse { step, reverse } => {
                // The first crossing switches to the refinement around it.
                if let Some(first) = self.pad.crossings().first() {
                    let (dx, dy) = first.direction();
                    let centre = first.midpoint();
                    let refine = Search::Refine {
                        stage: 0,
                        line: 0,
                        end: 0,
                        centre,
                        first_along_x: libm::fabsf(dx) >= libm::fabsf(dy),
                        crossings_before: self.crossing_count(),
                    };
                    self.phase = Phase::Search(refine);
                    return self.search(refine, state, _dt_s);
                }
                let Some((a, b)) = self.coarse_line(step / 2) else {
                    return self.give_up_search(state);
                };
                // Enter each line at the end nearer the drone.
                let reverse = if step % 2 == 0 {
                    let here = (state.position_m[0], state.position_m[1]);
                    libm::hypotf(b.0 - here.0, b.1 - here.1) < libm::hypotf(a.0 - here.0, a.1 - here.1)
                } else {
                    reverse
                };
                let (first, second) = if reverse { (b, a) } else { (a, b) };
                let here = (state.position_m[0], state.position_m[1]);
                // Already on the line between its ends (the first line runs along the arrival, through the
                // nominal point, and navigation hands over short of it): fly on to its far end instead of
                // turning back to its start; the stretch behind was covered by the detector on the approach.
                let step = if step % 2 == 0 && Self::lies_on_segment(here, first, second, ON_LINE_TOLERANCE_M) {
                    step + 1
                } else {
                    step
                };
                // The goal leg's first line (through the nominal point, usually joined on the way in by
                // the rule above, a few centimetres off it) is steered onto, so that it lies where the
                // pattern's coverage assumes (the goal pad may lie up to 0.35 m off that point, and a line
                // a few centimetres off grazes it); the others are flown straight. The home pad lies under
                // the take-off point, so a line joined up to 0.1 m off still crosses it deeply.
                let steer = step / 2 == 0 && self.leg == Leg::Outbound;
                let (wp, line_from) = if step % 2 == 0 {
                    (first, None)
                } else {
                    (second, steer.then_some(first))
                };
                let (sp, reached) = self.fly_to(state, wp, line_from);
                if reached {
                    self.line_end_reached(state, wp);
                }
                self.phase = Phase::Search(Search::Coarse {
                    step: if reached { step + 1 } else { step },
                    reverse,
                });
                sp
            }
            current @ Search::Refine {
                stage,
                line,
                end,
                centre,
                first_along_x,
                crossings_before,
            } => {
                if stage >= REFINE_STAGES {
                    self.pad.flush();
                    return self.approach_if_locked().unwrap_or_else(|| self.give_up_search(state));
                }
                // Even stages fly across the first crossing's direction, odd stages along it; after the first
                // two, more passes re-centred on the latest estimate give the detector more crossings.
                let along_x = if stage % 2 == 0 { !first_along_x } else { first_along_x };
                let offset = (f32::from(line) - 1.0) * self.config.refine_offset_m;
                // The first stage crosses a pad whose centre may lie up to a pad width to either side of the
                // first crossing's line, so its lines are longer; later stages are centred on the estimate.
                // The same holds while every inlier crossing runs one way: the estimate's other coordinate
                // is then only the lines' offset, anywhere within half a pad of the centre.
                let one_direction_only = self.pad.estimate().is_none_or(|e| e.min_direction_crossings < 0.5);
                let length = if stage == 0 || one_direction_only {
                    self.config.refine_line_m + 0.3
                } else {
                    self.config.refine_line_m
                };
                let half = 0.5 * length;
                let (a, b) = if along_x {
                    (
                        (centre.0 - half, centre.1 + offset),
                        (centre.0 + half, centre.1 + offset),
                    )
                } else {
                    (
                        (centre.0 + offset, centre.1 - half),
                        (centre.0 + offset, centre.1 + half),
                    )
                };
                // Alternate directions so consecutive lines join up like a lawnmower.
                let (first, second) = if line % 2 == 0 { (a, b) } else { (b, a) };
                let wp = if end == 0 { first } else { second };
                let (sp, reached) = self.fly_to(state, wp, None);
                if reached {
                    self.line_end_reached(state, wp);
                }
                let crossings_now = self.crossing_count();
                // A line has done its job once it gave a crossing: its remaining length only costs time.
                let line_done = end == 1 && (reached || crossings_now > crossings_before);
                let next = if !reached && !line_done {
                    current
                } else if end == 0 {
                    Search::Refine {
                        stage,
                        line,
                        end: 1,
                        centre,
                        first_along_x,
                        crossings_before: crossings_now,
                    }
                } else if line + 1 < REFINE_LINES && (stage >= 2 || self.inlier_crossings(along_x) < 2) {
                    Search::Refine {
                        stage,
                        line: line + 1,
                        end: 0,
                        centre,
                        first_along_x,
                        crossings_before: crossings_now,
                    }
                } else {
                    // Next stage (this direction has its two crossings, or its lines are flown), centred on
                    // the detector's best estimate so far. After the first round the detector starts
                    // afresh: the position estimate drifts (≈ 1 cm/√s on flow alone), so crossings half a
                    // minute apart disagree by more than the pad detection error.
                    self.pad.flush();
                    // The flush can close the crossing that locks: land on it rather than start afresh
                    // (otherwise a lock several crossings deep is thrown away by the restart below, and the
                    // rounds after it may not lock again before the landing).
                    if let Some(sp) = self.approach_if_locked() {
                        return sp;
                    }
                    let c = self.pad.estimate().map(|e| (e.x, e.y)).unwrap_or(centre);
                    if (stage + 1) % 2 == 0 {
                        self.restart_pad_detector();
                    }
                    Search::Refine {
                        stage: stage + 1,
                        line: 0,
                        end: 0,
                        centre: c,
                        first_along_x,
                        crossings_before: self.crossing_count(),
                    }
                };
                self.phase = Phase::Search(next);
                sp
            }
        }
    }

    /// The approach to the detector's lock (its own or [`Self::two_crossing_lock`]), if it has one.
    fn approach_if_locked(&mut self) -> Option<Setpoint> {
        let (px, py) = self.pad.locked_centre().or_else(|| self.two_crossing_lock())?;
        self.stats.pad_centres[self.leg_index()] = Some((px, py));
        Some(self.begin_approach((px, py), Target::PadTop))
    }

    /// A lock on two crossings, one each way, that agree on a square pad (estimate confidence ≥
    /// [`TWO_CROSSING_LOCK_CONFIDENCE`], no outlier): the detector's own lock waits for a third
    /// (`min_edges`), which a pad boxed in by a wall and an obstacle may never give (every line towards
    /// them ends on the pad), and which costs a refinement line (≈ 2 s) everywhere else. The descent
    /// gate still refuses a descent unless the pad's top reads under the drone.
    fn two_crossing_lock(&self) -> Option<(f32, f32)> {
        self.pad
            .estimate()
            .filter(|e| {
                e.inliers >= 2
                    && e.outliers == 0
                    && e.min_direction_crossings >= 0.8
                    && e.confidence >= TWO_CROSSING_LOCK_CONFIDENCE
            })
            .map(|e| (e.x, e.y))
    }

    /// The drone reached the end of a search line. Where that end was cut short of the waypoint `wp` by
    /// the clearance (a wall or an obstacle just beyond a pad there), a drone that flew onto the pad cannot
    /// fly off its far side: the detector takes the entry edge alone as a half crossing
    /// ([`crate::landing::pad::PadDetector::line_ended`]).
    fn line_end_reached(&mut self, state: &StateEstimate, wp: (f32, f32)) {
        let here = (state.position_m[0], state.position_m[1]);
        if libm::hypotf(wp.0 - here.0, wp.1 - here.1) > CLIPPED_LINE_END_M {
            self.pad.line_ended();
        }
    }

    /// Whether `p` lies within `tolerance` of the segment `a → b`, between its ends.
    pub(super) fn lies_on_segment(p: (f32, f32), a: (f32, f32), b: (f32, f32), tolerance: f32) -> bool {
        let (ux, uy) = (b.0 - a.0, b.1 - a.1);
        let length = libm::hypotf(ux, uy);
        // Also false for a NaN length.
        if length.is_nan() || length <= 1e-3 {
            return false;
        }
        let (ux, uy) = (ux / length, uy / length);
        let (px, py) = (p.0 - a.0, p.1 - a.1);
        let along = px * ux + py * uy;
        let across = libm::fabsf(px * uy - py * ux);
        (0.0..length).contains(&along) && across <= tolerance
    }

    /// Crossings the detector holds (saturating at 255): a line that adds one has done its job.
    pub(super) fn crossing_count(&self) -> u8 {
        u8::try_from(self.pad.crossings().len()).unwrap_or(u8::MAX)
    }

    /// Inlier crossings the detector holds that run along x (`along_x`) or along y.
    pub(super) fn inlier_crossings(&self, along_x: bool) -> usize {
        self.pad
            .crossings()
            .iter()
            .filter(|c| {
                let (dx, dy) = c.direction();
                c.inlier && (libm::fabsf(dx) >= libm::fabsf(dy)) == along_x
            })
            .count()
    }

    /// The `k`-th line of the coarse pattern, lines taken centre-out within each pass of the lawnmower
    /// (the pad lies near the nominal point, so the middle lines are the likeliest to cross it).
    pub(super) fn coarse_line(&self, k: usize) -> Option<((f32, f32), (f32, f32))> {
        let sweep = self.sweep.as_ref()?;
        let [first, second] = sweep.lines_per_pass();
        let (pass_start, lines, j) = if k < first {
            (0, first, k)
        } else {
            (2 * first, second, k.checked_sub(first)?)
        };
        if j >= lines {
            return None;
        }
        // Centre-out: mid, mid+1, mid−1, mid+2, …
        let mid = (lines - 1) / 2;
        let offset = j.div_ceil(2);
        let line = if j % 2 == 1 {
            mid + offset
        } else {
            mid.checked_sub(offset)?
        };
        let line = if line < lines {
            line
        } else {
            mid.checked_sub(offset + 1)?
        };
        let a = sweep.waypoint(pass_start + 2 * line)?;
        let b = sweep.waypoint(pass_start + 2 * line + 1)?;
        Some((a, b))
    }

    /// No lock. The first time on a leg the search widens and re-centres on the best estimate (a fresh
    /// detector, a coarse pattern [`WIDEN_M`] larger); after that the pad is not found: land on the best
    /// estimate only where the descent gate's clearance rule can hold (both coordinates measured), else land
    /// clear of the pad ([`Self::land_clear_of_pad`]); the mission ends with the pad-not-found code.
    pub(super) fn give_up_search(&mut self, state: &StateEstimate) -> Setpoint {
        if self.touchdown.widenings < MAX_WIDENINGS && self.touchdown.refusals <= MAX_REFUSALS {
            self.touchdown.widenings += 1;
            let centre = self
                .pad
                .estimate()
                .map(|e| (e.x, e.y))
                .unwrap_or_else(|| self.leg_target());
            let arena = ArenaBounds::new(self.params.arena_m.0, self.params.arena_m.1, 0.15);
            let here = (state.position_m[0], state.position_m[1]);
            let grow = WIDEN_M * f32::from(self.touchdown.widenings);
            let mut sweep = self.config.sweep;
            sweep.size_x_m += grow;
            sweep.size_y_m += grow;
            sweep.axis = SweepAxis::Auto;
            if let Ok(s) = LawnmowerSweep::new(centre, here, &sweep, &arena) {
                self.sweep = Some(s);
                self.restart_pad_detector();
                let search = Search::Coarse {
                    step: 0,
                    reverse: false,
                };
                self.phase = Phase::Search(search);
                return self.search(search, state, 0.02);
            }
        }
        self.pad_not_found = true;
        self.stats.pad_centres[self.leg_index()] = None;
        let measured = self
            .pad
            .estimate()
            .filter(|e| e.min_direction_crossings >= 0.8 && e.rms_residual_m < 0.03);
        match measured {
            Some(e) if self.touchdown.refusals <= MAX_REFUSALS => {
                // One more try on the estimate: the gate refuses it unless over the pad's interior.
                self.touchdown.refusals = MAX_REFUSALS + 1;
                self.begin_approach((e.x, e.y), Target::PadTop)
            }
            _ => self.land_clear_of_pad(state),
        }
    }

    /// The pad was not found: land where it cannot be, so that the body touches none of its sides. The
    /// spot nearest the drone (rings [`FLOOR_SPOT_STEP_M`] apart, [`FLOOR_SPOT_DIRECTIONS`] points each) that keeps
    /// [`FLOOR_SPOT_CLEARANCE_M`] from what is mapped, is reachable in a straight line, lies at least
    /// [`PAD_REACH_M`] from the pad's nominal point (the pad lies within 0.35 m of it) or, when even that
    /// finds nothing, the spot farthest from where the pad's centre can still be (within 0.35 m of that
    /// point and explaining every edge seen, [`Self::distance_to_possible_pad_centres`]) among those that
    /// keep away from the best estimate (or the latest, if a refit dropped it: [`Touchdown::latest`]), from
    /// every earlier estimate of this leg ([`Touchdown::glimpses`])
    /// and from every pad edge seen; the
    /// descent gate then wants the floor under the drone. Without any such spot: where the drone is.
    pub(super) fn land_clear_of_pad(&mut self, state: &StateEstimate) -> Setpoint {
        let here = (state.position_m[0], state.position_m[1]);
        let spot = self.floor_spot_clear_of_pad(here, usize::from(self.touchdown.floor_refusals));
        self.begin_approach(spot.unwrap_or(here), Target::Floor)
    }

    /// The floor spot of [`Self::land_clear_of_pad`]'s rule, skipping the first `skip` that qualify (spots
    /// refused already), in the rule's order; `None` when none qualifies. At most 2 ×
    /// [`FLOOR_SPOT_CANDIDATES`] (129) candidates, each O(edges + glimpses) plus a clearance look-up and a
    /// straight-line check on the grid.
    pub(super) fn floor_spot_clear_of_pad(&self, here: (f32, f32), skip: usize) -> Option<(f32, f32)> {
        let nominal = self.leg_target();
        let estimate = self.pad.estimate().map(|e| (e.x, e.y));
        let glimpses = self.touchdown.glimpses;
        let latest = self.touchdown.latest;
        let far = |p: (f32, f32), q: (f32, f32), r: f32| libm::hypotf(p.0 - q.0, p.1 - q.1) >= r;
        let candidates = || {
            (0..FLOOR_SPOT_RINGS).flat_map(move |ring| {
                let radius = FLOOR_SPOT_STEP_M * f32::from(ring);
                let points = if ring == 0 { 1 } else { FLOOR_SPOT_DIRECTIONS };
                (0..points).map(move |k| {
                    let a = core::f32::consts::TAU / f32::from(FLOOR_SPOT_DIRECTIONS) * f32::from(k);
                    (here.0 + radius * libm::cosf(a), here.1 + radius * libm::sinf(a))
                })
            })
        };
        let usable =
            |p: (f32, f32)| self.clearance(p) >= FLOOR_SPOT_CLEARANCE_M && self.clip_to_clearance(here, p) == p;
        // Spots where the pad cannot be, nearest the drone first.
        let mut skip = skip;
        for p in candidates().filter(|p| far(*p, nominal, PAD_REACH_M) && usable(*p)) {
            if skip == 0 {
                return Some(p);
            }
            skip -= 1;
        }
        // No such spot (or all refused): spots clear of what the detector saw, farthest first from every
        // place the pad's centre can still have (the nearest to the drone can put the body against the
        // corner of a pad the search never crossed; farthest from the nominal point alone, against the
        // corner of a pad whose two edges the search saw on the far side).
        let mut ranked: heapless::Vec<(f32, (f32, f32)), FLOOR_SPOT_CANDIDATES> = heapless::Vec::new();
        for p in candidates() {
            let clear_of_pad = estimate.is_none_or(|e| far(p, e, PAD_ESTIMATE_REACH_M))
                && latest.is_none_or(|e| far(p, e, PAD_ESTIMATE_REACH_M))
                && glimpses.iter().flatten().all(|g| far(p, *g, PAD_ESTIMATE_REACH_M))
                && self.pad.edges().iter().all(|e| far(p, (e.x, e.y), PAD_EDGE_REACH_M));
            if clear_of_pad && usable(p) {
                // (Capacity is the candidate count: never full.)
                let _ = ranked.push((f32::INFINITY, p));
            }
        }
        self.distance_to_possible_pad_centres(nominal, &mut ranked);
        // Largest distance first (at most FLOOR_SPOT_CANDIDATES: an insertion sort costs less flash than a
        // sort call).
        for i in 1..ranked.len() {
            let mut j = i;
            while j > 0 && ranked[j - 1].0 < ranked[j].0 {
                ranked.swap(j - 1, j);
                j -= 1;
            }
        }
        ranked.get(skip).map(|(_, p)| *p)
    }

    /// Sets each spot's key in `spots` to its distance from the nearest place the leg's pad centre can
    /// still have: a lattice ([`PAD_CENTRE_LATTICE_M`]) over the disc of [`PAD_OFFSET_M`] around the
    /// pad's `nominal` point, less the centres that cannot have put every pad edge seen on their pad's rim
    /// (each edge within half the pad's diagonal of the centre, plus [`PAD_CENTRE_EDGE_SLACK_M`]; the
    /// pad's yaw is unknown). Edges no centre explains together (one of them came from something else)
    /// constrain nothing: the whole disc stays. Without edges the key orders spots as their distance from
    /// the nominal point does. About 530 lattice points, each O(edges + spots): ≤ 60 k multiply-adds, once
    /// per pad-not-found landing (and per spot the descent gate refuses).
    fn distance_to_possible_pad_centres(
        &self,
        nominal: (f32, f32),
        spots: &mut heapless::Vec<(f32, (f32, f32)), FLOOR_SPOT_CANDIDATES>,
    ) {
        let edge_reach = core::f32::consts::FRAC_1_SQRT_2 * self.config.pad.pad_size_m + PAD_CENTRE_EDGE_SLACK_M;
        let edges = self.pad.edges();
        let steps = libm::ceilf(PAD_OFFSET_M / PAD_CENTRE_LATTICE_M) as i32;
        let lattice = move || {
            (-steps..=steps).flat_map(move |i| {
                (-steps..=steps).filter_map(move |j| {
                    let (dx, dy) = (i as f32 * PAD_CENTRE_LATTICE_M, j as f32 * PAD_CENTRE_LATTICE_M);
                    (libm::hypotf(dx, dy) <= PAD_OFFSET_M).then_some((nominal.0 + dx, nominal.1 + dy))
                })
            })
        };
        let explains_edges = |c: (f32, f32)| edges.iter().all(|e| libm::hypotf(e.x - c.0, e.y - c.1) <= edge_reach);
        let any_explains = lattice().any(explains_edges);
        for c in lattice().filter(|c| !any_explains || explains_edges(*c)) {
            for (key, p) in spots.iter_mut() {
                *key = key.min(libm::hypotf(p.0 - c.0, p.1 - c.1));
            }
        }
    }
}
