//! Landing-pad detector: finds an elevated pad (a ~30 × 30 cm box, ~10 cm high) from the steps in the
//! Flow deck's downward range while the drone sweeps at constant absolute height.
//!
//! Job: from a stream of `(range, x, y)` samples, (1) detect *edges*, the places where the range steps
//! down (the drone flies onto the pad, [`EdgeKind::Enter`]) or up (it flies off, [`EdgeKind::Exit`]);
//! (2) pair the entry and exit of each straight pass over the pad into a *crossing*; (3) estimate the pad
//! centre from the crossings with a confidence, and say when the estimate is good enough to land on
//! ([`PadDetector::locked`]).
//!
//! ## Pipeline
//!
//! Step 1 and the detector's state are in this file; steps 2–5 in `steps.rs`, 6 in `crossings.rs`, 7–8
//! in `centre.rs`.
//!
//! 1. **Gate**: non-finite positions and ranges outside `[min_range_m, max_range_m]` are ignored.
//! 2. **Spatial bins**: samples are grouped by distance travelled (`bin_m`, an odd number of samples per
//!    bin) and each bin contributes its median range, located at the bin's centre. One wild sample (the
//!    VL53L1x returns some) never survives its bin; two in one bin give a value far from any level, which
//!    the later stages recognise as stray. Binning by distance makes every length below a distance, the
//!    same at any speed or sample rate.
//! 3. **Smoothed z-score** (the seed's detector): a ring of the last `lag` *filtered* bin values gives a
//!    centre and spread — by default the median and `1.4826·MAD` ([`PadConfig::robust_stats`]), else
//!    the seed's mean and σ. A bin is a signal if it deviates from the centre by more than
//!    `threshold_sigma`·spread **and** by at least `min_step_m` (the absolute floor is what rejects a
//!    1 cm box and keeps a noise-free floor, spread 0, quiet). Signalling values enter the ring only with
//!    weight `influence`, so a step keeps signalling for about `lag` bins instead of being absorbed.
//! 4. **Runs → edges**: `min_run` signals of one sign among the last `min_run + 1` bins confirm a step
//!    (one bad bin inside a step does not split it; shorter bursts are dropped); the step's run ends
//!    after two bins without its signal, so each step gives one edge, not one per sample. The edge is
//!    then *located* where the binned range crosses halfway between the level before (window median at
//!    the first signal) and the level after (median of the run's last bins), interpolated between the
//!    two bins around the crossing, searching backwards from the settled end of the run and skipping
//!    stray bins. Unlike "the first signalling sample", this is not delayed along the direction of
//!    travel when the ranger's footprint blurs the step, which would shift every chord midpoint forward.
//!    Edges are therefore reported when their run ends, ~`lag` bins after the step. A second step of
//!    the same sign within `min_edge_spacing_m` of travel is the same step flickering and is merged.
//! 5. **Edge list** (for plots and the seed's centroid): an edge closer than `min_edge_spacing_m` to an
//!    edge already stored is not stored again (the first is kept).
//! 6. **Crossings**: an `Enter` followed by an `Exit` is a crossing if the drone flew straight between
//!    them (travel ≈ chord, the headings just before both edges along the chord), the chord is a
//!    plausible pad width (`min_chord_ratio`…`max_chord_ratio` × `pad_size_m`), the level in between is
//!    at least `min_step_m` below the level before, the level after matches the level before (same
//!    floor on both sides), and the top in between is flat (10th–90th percentile spread of its bins,
//!    4 cm in from each edge, ≤ 3 cm): a beam grazing a cylinder's curved side or sliding down an
//!    obstacle's foot reads a range that keeps changing, a pad's top does not. Unpaired edges (a line that ends or turns on the pad, a spurious step) never
//!    enter the estimate.
//!    6b. **Turn-backs**: an `Enter` followed by an `Exit` with the opposite heading, both on the same side of
//!    the pad (within 5 cm along the travel), is a line that ended on the pad and came back (next to a
//!    wall the search cannot fly across). It fixes the centre along the travel as that side moved half of
//!    `pad_size_m` inwards, and enters the fit as a crossing flagged [`Crossing::turn_back`]; a pad of
//!    another size shifts it by half the difference.
//!    6c. **Half crossings**: a line that has to end on the pad (a wall or an obstacle 0.1–0.25 m beyond
//!    it, where the search keeps its clearance) never sees the far side. When the caller says the line ends
//!    ([`PadDetector::line_ended`]) while the drone is still on a flat top at the level an entry stepped to,
//!    at least 6 cm past that entry and straight on from it, the entry edge fixes the centre along the
//!    travel as half of `pad_size_m` inwards: a crossing flagged [`Crossing::turn_back`], as in 6b.
//! 7. **Centre**: a crossing fixes the centre only *along* its chord: for a square pad, the chord's
//!    midpoint has the centre's coordinate along the chord direction `d`, whatever the line's offset.
//!    Across the chord it only says "within half a pad of this line". So the centre `c` minimises
//!    `Σ (d·(c − m))²` over crossings (midpoints `m`), a 2 × 2 least-squares problem, plus a tiny
//!    (`1e-3`) pull towards the midpoints' centroid that only matters in a direction no crossing
//!    measures. The plain centroid of edges (the seed's) is biased by where the lines happen to cross;
//!    this is not. A crossing whose residual exceeds `outlier_m` is dropped and the fit redone.
//!    7b. **Half crossings beside a side**: a half crossing (6b, 6c) assumes the drone entered over the
//!    side facing its travel. An entry that the fit of the others puts within 4 cm (about the ranger's
//!    footprint) of a side *parallel* to the travel may have come over that side instead, and then half a
//!    pad inwards along the travel is not the centre: once the full crossings measure the coordinate across
//!    its travel, such a half crossing is set aside (counted as an outlier) and the fit redone.
//! 8. **Confidence** ∈ [0, 1] is the product of
//!    * *coverage*: `min(1, λmin / min_crossings_per_direction)`, where `λmin` is the smaller eigenvalue
//!      of `Σ d dᵀ`, i.e. about the number of crossings in the worse-covered direction. Crossings in one
//!      direction only (a single pass, or a pad seen half) give 0: the other coordinate is unknown;
//!    * *fit*: `1 − rms(residual)/fit_tolerance_m`: crossings agree on the centre;
//!    * *shape*: the seed's `1 − std/mean` of the distances from the centre to the supporting edges;
//!    * *consensus*: the fraction of crossings kept as inliers.
//!
//!    [`PadDetector::locked`] needs confidence ≥ `lock_confidence`, `λmin ≥ 0.8·min_crossings_per_direction`
//!    and at least `min_edges` supporting edges (edges of inlier crossings).
//!
//! ## Assumptions and non-goals
//!
//! The drone flies straight lines at constant absolute height (the range itself steps; slow height
//! drift is tolerated by the z-score's adaptation); the pad's sides are roughly aligned with the sweep
//! lines (a pad rotated by θ moves a chord's midpoint by `offset·tan θ`, which averages out only over
//! symmetric lines); one pad. Not goals: flight control, choosing where to fly (see [`crate::landing::sweep`]),
//! pads lower than `min_step_m`.
//!
//! ## Units, frames, size
//!
//! Metres, arena frame (x right, y up). Memory: `16·EDGES` bytes of edges + `24·EDGES` of crossings +
//! a 64-bin ring (2 KiB) + ~0.5 KiB of filter state: 3.8 KiB for `EDGES = 32` (the `memory_size` test).
//! Complexity per sample: O(1), plus per closed bin (every ~1 cm) two insertion-sort medians of the
//! `lag ≤ 32` window (exact, no running sums to drift), plus O(`lag`) when a step ends; per new crossing
//! O(`EDGES`²) in the worst case (refit with outlier removal), a few thousand flops at most.

use heapless::Vec;

mod centre;
mod crossings;
mod steps;

/// Largest supported z-score window, bins.
pub const MAX_LAG: usize = 32;

/// Most raw samples one bin holds (odd); a hovering drone closes a bin every this many samples.
pub const MAX_BIN_SAMPLES: usize = 15;

/// Whether the range stepped down (onto the pad) or up (off it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeKind {
    /// The range dropped: the drone flew onto something higher (the pad).
    Enter,
    /// The range rose: the drone flew off it.
    Exit,
}

/// A detected step in the downward range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    /// Arena x where the range crossed halfway between the two levels, metres.
    pub x: f32,
    /// Arena y where the range crossed halfway between the two levels, metres.
    pub y: f32,
    /// Step direction.
    pub kind: EdgeKind,
    /// Range change across the step, metres (negative for [`EdgeKind::Enter`]).
    pub step_m: f32,
}

/// A straight pass over the pad: the entry and exit edges of one line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// Where the drone flew onto the pad (x, y), metres.
    pub enter: (f32, f32),
    /// Where it flew off (x, y), metres.
    pub exit: (f32, f32),
    /// Height of the pad above the floor as measured on this crossing, metres.
    pub step_m: f32,
    /// Whether the last centre fit kept this crossing.
    pub inlier: bool,
    /// A *turn-back* half crossing: the drone entered the pad, turned back on it and left over the same
    /// side (a search line cut short by a wall). Both edges lie on one side, so only the pad size places
    /// the centre: `exit` is the mean edge point moved `pad_size_m` inwards, which makes [`Self::midpoint`]
    /// the side's point moved half a pad inwards.
    pub turn_back: bool,
}

impl Crossing {
    /// Midpoint of the chord, metres.
    pub fn midpoint(&self) -> (f32, f32) {
        (0.5 * (self.enter.0 + self.exit.0), 0.5 * (self.enter.1 + self.exit.1))
    }

    /// Chord length, metres.
    pub fn length(&self) -> f32 {
        libm::hypotf(self.exit.0 - self.enter.0, self.exit.1 - self.enter.1)
    }

    /// Unit chord direction (from enter to exit); (0, 0) for a zero-length chord.
    pub fn direction(&self) -> (f32, f32) {
        let l = self.length();
        if l > 0.0 {
            ((self.exit.0 - self.enter.0) / l, (self.exit.1 - self.enter.1) / l)
        } else {
            (0.0, 0.0)
        }
    }
}

/// The current pad-centre estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PadEstimate {
    /// Centre x, metres.
    pub x: f32,
    /// Centre y, metres.
    pub y: f32,
    /// Confidence in [0, 1] (module docs, step 8).
    pub confidence: f32,
    /// Crossings kept by the fit.
    pub inliers: usize,
    /// Crossings rejected as outliers.
    pub outliers: usize,
    /// Smaller eigenvalue of `Σ d dᵀ` over inliers: ≈ crossings in the worse-covered direction.
    pub min_direction_crossings: f32,
    /// RMS distance (along the chords) between the centre and the inlier crossings' midpoints, metres.
    pub rms_residual_m: f32,
}

impl PadEstimate {
    /// Edges supporting the estimate: both edges of every inlier crossing.
    pub fn supporting_edges(&self) -> usize {
        2 * self.inliers
    }
}

/// Tuning of [`PadDetector`]. [`Default`] gives the values below.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PadConfig {
    /// Bin length, metres: raw samples are grouped by distance travelled (an odd number per bin) and
    /// each bin's median is one z-score input. Default 0.008 m: 3 samples (9 mm) at 0.3 m/s and 100 Hz,
    /// so a single outlier never survives its bin; it also makes every length below a distance rather
    /// than a sample count, independent of speed and rate. Edges are interpolated between bins.
    /// 0 = one bin per sample.
    pub bin_m: f32,
    /// z-score window, bins, `2..=MAX_LAG`. Default 12 (≈ 11 cm at 9 mm bins). It must be longer than
    /// the blur of an edge (the ranger's footprint turns a step into a ramp; a ramp longer than the
    /// window follows the mean and is never a 2σ outlier) and clearly shorter than the pad (30 cm),
    /// so that the window settles on the pad's level between its edges. (The seed's 5–8 were samples.)
    pub lag: usize,
    /// Use the window's median and MAD-based σ (true) or its mean and standard deviation (false, the
    /// seed's form). Default true: a stray value or the first bins of a blurred step inflate the
    /// standard deviation enough to hide the rest of the step; the median and MAD barely move.
    pub robust_stats: bool,
    /// Signal threshold, standard deviations. Default 2.0 (seed 1.5–2.0): the upper end, since the
    /// absolute `min_step_m` already makes a 10 cm step fire; this only guards against noisy windows.
    pub threshold_sigma: f32,
    /// Weight of a signalling value in the window, [0, 1]. Default 0.2 (seed 0.2–0.6): low, so a step
    /// keeps signalling for about `lag` bins (plenty for `min_run`) and outliers barely move the mean.
    pub influence: f32,
    /// Smallest step that counts, metres. Default 0.03 m: a third of the 10 cm pad height, 6σ of 5 mm
    /// noise, and three times a 1 cm box or cable, which must not count.
    pub min_step_m: f32,
    /// Signalling bins (among the last `min_run + 1`) that confirm a step. Default 3 (~3 cm): stray
    /// bins are rare and isolated; every real step signals for ~`lag` bins.
    pub min_run: usize,
    /// Minimum distance between stored edges (and between two runs of one step), metres. Default 0.05 m
    /// (seed 5–10 cm): far more than a step's flicker, far less than the 0.15–0.2 m line spacing.
    pub min_edge_spacing_m: f32,
    /// Shortest valid range, metres. Default 0.02 m.
    pub min_range_m: f32,
    /// Longest valid range, metres. Default 4.0 m (VL53L1x long-distance limit).
    pub max_range_m: f32,
    /// Expected pad side, metres. Default 0.3 m.
    pub pad_size_m: f32,
    /// Shortest accepted chord, as a fraction of `pad_size_m`. Default 0.7 (0.21 m): a line across an
    /// aligned square pad has a chord of exactly its side; shorter chords are corner clips of a rotated
    /// pad (whose midpoints say little about the centre) or a line that turned or ended on the pad.
    pub min_chord_ratio: f32,
    /// Longest accepted chord, as a fraction of `pad_size_m`. Default 1.6 (0.48 m): the diagonal of the
    /// pad (1.41) plus room for a footprint that makes the pad look wider; longer "crossings" pair
    /// edges of unrelated steps.
    pub max_chord_ratio: f32,
    /// The floor levels before entering and after leaving a crossing may differ by this much plus half
    /// the pad's measured height, metres. Default 0.02 m: it is the same floor, up to the height-hold
    /// drift over the ~1 s crossing (a few cm); an edge made by a burst of outliers has a "floor" tens of
    /// cm off.
    pub step_match_m: f32,
    /// A crossing whose midpoint is further than this from the fitted centre (along its chord) is an
    /// outlier, metres. Default 0.05 m: about 10× the midpoint noise, a sixth of the pad.
    pub outlier_m: f32,
    /// RMS residual at which the fit factor of the confidence reaches 0, metres. Default 0.05 m.
    pub fit_tolerance_m: f32,
    /// Crossings wanted in each of two directions. Default 2, so every coordinate of the centre is
    /// cross-checked by two independent crossings. One crossing per direction already pins both
    /// coordinates to the edge-detection noise (a coarse 0.2 m crosshatch, with `min_edges` 4, locks
    /// within 2 cm too; tested), but a single spurious pair could then go unnoticed.
    pub min_crossings_per_direction: u8,
    /// Confidence needed to lock, [0, 1]. Default 0.6 (the seed's).
    pub lock_confidence: f32,
    /// Supporting edges needed to lock. Default 12 (the project's requirement): with one edge per step
    /// transition that is three crossings per direction, which a crosshatch at ≤ 0.1 m spacing gives over
    /// a 0.3 m pad; a coarser 0.2 m crosshatch yields only 4–8 edges, so the mission refines its sweep
    /// around the first crossings (or lowers this, see `min_crossings_per_direction`).
    pub min_edges: usize,
}

impl Default for PadConfig {
    fn default() -> Self {
        Self {
            bin_m: 0.008,
            lag: 12,
            robust_stats: true,
            threshold_sigma: 2.0,
            influence: 0.2,
            min_step_m: 0.03,
            min_run: 3,
            min_edge_spacing_m: 0.05,
            min_range_m: 0.02,
            max_range_m: 4.0,
            pad_size_m: 0.3,
            min_chord_ratio: 0.7,
            max_chord_ratio: 1.6,
            step_match_m: 0.02,
            outlier_m: 0.05,
            fit_tolerance_m: 0.05,
            min_crossings_per_direction: 2,
            lock_confidence: 0.6,
            min_edges: 12,
        }
    }
}

/// Why a [`PadConfig`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PadConfigError {
    /// A field is NaN or infinite.
    NonFinite,
    /// `lag` is outside `2..=MAX_LAG`.
    Lag,
    /// A field is outside its documented range.
    OutOfRange,
}

impl PadConfig {
    /// Checks the config; [`PadDetector::new`] calls this.
    pub fn validate(&self) -> Result<(), PadConfigError> {
        let all = [
            self.bin_m,
            self.threshold_sigma,
            self.influence,
            self.min_step_m,
            self.min_edge_spacing_m,
            self.min_range_m,
            self.max_range_m,
            self.pad_size_m,
            self.min_chord_ratio,
            self.max_chord_ratio,
            self.step_match_m,
            self.outlier_m,
            self.fit_tolerance_m,
            self.lock_confidence,
        ];
        if all.iter().any(|v| !v.is_finite()) {
            return Err(PadConfigError::NonFinite);
        }
        if !(2..=MAX_LAG).contains(&self.lag) {
            return Err(PadConfigError::Lag);
        }
        let ok = self.bin_m >= 0.0
            && self.threshold_sigma > 0.0
            && (0.0..=1.0).contains(&self.influence)
            && self.min_step_m > 0.0
            && self.min_run >= 1
            && self.min_edge_spacing_m >= 0.0
            && self.min_range_m >= 0.0
            && self.max_range_m > self.min_range_m
            && self.pad_size_m > 0.0
            && self.min_chord_ratio > 0.0
            && self.max_chord_ratio > self.min_chord_ratio
            && self.step_match_m >= 0.0
            && self.outlier_m > 0.0
            && self.fit_tolerance_m > 0.0
            && (0.0..=1.0).contains(&self.lock_confidence);
        if ok { Ok(()) } else { Err(PadConfigError::OutOfRange) }
    }
}

/// One gated sample with where and how the drone was moving.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    x: f32,
    y: f32,
    /// Distance travelled since the detector started, metres.
    odo: f32,
}

/// One closed bin: its median range at its centre, and the z-score's verdict on it.
#[derive(Clone, Copy, Debug, Default)]
struct Bin {
    range: f32,
    /// Centre of the bin's samples.
    x: f32,
    y: f32,
    odo: f32,
    heading: (f32, f32),
    /// z-score signal: -1 (range dropped), 0, +1 (range rose).
    signal: i8,
    /// Median of the z-score window just before this bin: the level it was compared with.
    level: f32,
}

/// An edge as detected, with the motion data pairing needs (stored edges drop those).
#[derive(Clone, Copy, Debug)]
struct Detection {
    edge: Edge,
    odo: f32,
    heading: (f32, f32),
    /// The level before the step (median of the z-score window before the step's first signal).
    level_before: f32,
    /// The level after the step (median of the run's last bins).
    level_after: f32,
}

/// A confirmed run of same-sign signals: one step in progress.
#[derive(Clone, Copy, Debug)]
struct ActiveRun {
    /// -1 (range dropped: [`EdgeKind::Enter`]) or +1 (range rose: [`EdgeKind::Exit`]).
    sign: i8,
    /// Serial number of the run's first signalling bin.
    first: u32,
    /// Consecutive bins without this sign's signal.
    misses: u8,
}

/// Bins kept for locating a step after it has settled: twice the largest window, which covers the part
/// of a blurred step before the first signal (< `lag` bins) plus the run itself (~`lag` bins).
const RING: usize = 2 * MAX_LAG;

/// The landing-pad detector; `EDGES` bounds the stored edges and crossings. See the module docs.
#[derive(Clone, Debug)]
pub struct PadDetector<const EDGES: usize> {
    config: PadConfig,
    // Motion tracking.
    anchor: Option<(f32, f32)>,
    odo_at_anchor: f32,
    heading: (f32, f32),
    // The open spatial bin.
    bin_first: Sample,
    bin_sum: (f32, f32, f32),
    bin: [f32; MAX_BIN_SAMPLES],
    bin_len: usize,
    // z-score window of filtered values (ring).
    window: [f32; MAX_LAG],
    window_len: usize,
    window_head: usize,
    last_filtered: f32,
    // Closed bins (ring) and their serial numbers: bin `n` is at `ring[n % RING]`.
    ring: [Bin; RING],
    bins: u32,
    run: Option<ActiveRun>,
    last_detection: Option<Detection>,
    pending_enter: Option<Detection>,
    // Results.
    edges: Vec<Edge, EDGES>,
    crossings: Vec<Crossing, EDGES>,
    estimate: Option<PadEstimate>,
    dropped: u32,
}

impl<const EDGES: usize> PadDetector<EDGES> {
    /// A detector with a validated config and no history.
    pub fn new(config: PadConfig) -> Result<Self, PadConfigError> {
        config.validate()?;
        Ok(Self::fresh(config))
    }

    fn fresh(config: PadConfig) -> Self {
        Self {
            config,
            anchor: None,
            odo_at_anchor: 0.0,
            heading: (0.0, 0.0),
            bin_first: Sample::default(),
            bin_sum: (0.0, 0.0, 0.0),
            bin: [0.0; MAX_BIN_SAMPLES],
            bin_len: 0,
            window: [0.0; MAX_LAG],
            window_len: 0,
            window_head: 0,
            last_filtered: 0.0,
            ring: [Bin::default(); RING],
            bins: 0,
            run: None,
            last_detection: None,
            pending_enter: None,
            edges: Vec::new(),
            crossings: Vec::new(),
            estimate: None,
            dropped: 0,
        }
    }

    /// The config in use.
    pub fn config(&self) -> &PadConfig {
        &self.config
    }

    /// Forgets everything (filter state, edges, crossings, estimate); the config is kept.
    pub fn reset(&mut self) {
        *self = Self::fresh(self.config);
    }

    /// Moves everything recorded (the motion anchor, the open bin, the closed bins, pending detections,
    /// edges, crossings and the estimate) by `(dx_m, dy_m)`: the position estimate these were recorded in
    /// has just been corrected by that much (a map fix's jump), and edges left in the old frame would put
    /// the centre off by the correction. Non-finite shifts are ignored. O(`EDGES` + bins kept).
    pub fn translate(&mut self, dx_m: f32, dy_m: f32) {
        if !(dx_m.is_finite() && dy_m.is_finite()) {
            return;
        }
        let shift = |p: &mut (f32, f32)| {
            p.0 += dx_m;
            p.1 += dy_m;
        };
        if let Some(anchor) = self.anchor.as_mut() {
            shift(anchor);
        }
        self.bin_first.x += dx_m;
        self.bin_first.y += dy_m;
        let n = self.bin_len as f32;
        self.bin_sum.0 += n * dx_m;
        self.bin_sum.1 += n * dy_m;
        for bin in self.ring.iter_mut() {
            bin.x += dx_m;
            bin.y += dy_m;
        }
        for detection in [self.last_detection.as_mut(), self.pending_enter.as_mut()]
            .into_iter()
            .flatten()
        {
            detection.edge.x += dx_m;
            detection.edge.y += dy_m;
        }
        for edge in self.edges.iter_mut() {
            edge.x += dx_m;
            edge.y += dy_m;
        }
        for crossing in self.crossings.iter_mut() {
            shift(&mut crossing.enter);
            shift(&mut crossing.exit);
        }
        if let Some(estimate) = self.estimate.as_mut() {
            estimate.x += dx_m;
            estimate.y += dy_m;
        }
    }

    /// Feeds one downward-range sample taken at arena position `(x_m, y_m)`. Returns the edge stored
    /// because of this sample, if any (edges are reported once their step has settled, about `lag` bins
    /// after it). Non-finite or out-of-range samples are ignored.
    pub fn update(&mut self, range_m: f32, x_m: f32, y_m: f32) -> Option<Edge> {
        if !(range_m.is_finite() && x_m.is_finite() && y_m.is_finite()) {
            return None;
        }
        if range_m < self.config.min_range_m || range_m > self.config.max_range_m {
            return None;
        }
        let sample = self.track_motion(x_m, y_m);

        // Spatial binning: close the open bin once the drone has left it (or it is full, when hovering)
        // and process its median; this sample opens the next bin.
        let mut stored = None;
        if self.bin_len > 0 {
            let moved = libm::hypotf(x_m - self.bin_first.x, y_m - self.bin_first.y);
            // Odd counts only: then the median is one real sample, and two outliers in a bin give a value
            // far from both levels (recognisably stray) rather than halfway between them.
            let odd = self.bin_len % 2 == 1;
            if (moved >= self.config.bin_m && odd) || self.bin_len >= MAX_BIN_SAMPLES {
                stored = self.close_bin();
            }
        }
        if self.bin_len == 0 {
            self.bin_first = sample;
            self.bin_sum = (0.0, 0.0, 0.0);
        }
        if let Some(slot) = self.bin.get_mut(self.bin_len) {
            *slot = range_m;
            self.bin_len += 1;
            self.bin_sum = (self.bin_sum.0 + x_m, self.bin_sum.1 + y_m, self.bin_sum.2 + sample.odo);
        }
        stored
    }

    /// Reports a step still in progress (its run has not ended yet because no bins followed it), e.g.
    /// when the sweep is over and the drone stops feeding samples. Returns the edge stored, if any.
    pub fn flush(&mut self) -> Option<Edge> {
        let run = self.run.take()?;
        let end = self.bins.checked_sub(1)?;
        let detection = self.locate(&run, end)?;
        self.on_detection(detection)
    }

    /// The current centre estimate (from crossings), if any crossing has been seen.
    pub fn estimate(&self) -> Option<PadEstimate> {
        self.estimate
    }

    /// Confidence of the current estimate, 0 without one.
    pub fn confidence(&self) -> f32 {
        self.estimate.map_or(0.0, |e| e.confidence)
    }

    /// Whether the estimate is good enough to land on (module docs, step 8).
    pub fn locked(&self) -> bool {
        let cfg = &self.config;
        self.estimate.is_some_and(|e| {
            e.confidence >= cfg.lock_confidence
                && e.supporting_edges() >= cfg.min_edges
                && e.min_direction_crossings >= 0.8 * f32::from(cfg.min_crossings_per_direction)
        })
    }

    /// The locked centre `(x, y)`, or `None` while not locked.
    pub fn locked_centre(&self) -> Option<(f32, f32)> {
        if self.locked() {
            self.estimate.map(|e| (e.x, e.y))
        } else {
            None
        }
    }

    /// The stored edges, in detection order.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// The crossings, in detection order (with their inlier flag from the last fit).
    pub fn crossings(&self) -> &[Crossing] {
        &self.crossings
    }

    /// The seed's estimate: the plain centroid of the stored edges (for comparison and plots).
    pub fn edge_centroid(&self) -> Option<(f32, f32)> {
        if self.edges.is_empty() {
            return None;
        }
        let n = self.edges.len() as f32;
        let (sx, sy) = self.edges.iter().fold((0.0, 0.0), |(sx, sy), e| (sx + e.x, sy + e.y));
        Some((sx / n, sy / n))
    }

    /// Edges and crossings that did not fit in `EDGES` and were discarded.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
}

/// Bins from serial `a` to serial `b` (0 if `b` is before `a`).
fn serial_span(a: u32, b: u32) -> usize {
    b.saturating_sub(a) as usize
}

/// Median of a short slice (sorted in place by insertion sort: at most [`MAX_LAG`] values); the mean
/// of the two middle values for an even length, so one outlier in four cannot move it; 0 when empty.
fn median(values: &mut [f32]) -> f32 {
    for i in 1..values.len() {
        let mut j = i;
        while j > 0 {
            let Some([a, b]) = values.get_mut(j - 1..=j) else { break };
            if *a <= *b {
                break;
            }
            core::mem::swap(a, b);
            j -= 1;
        }
    }
    let n = values.len();
    match (values.get((n.max(1) - 1) / 2), values.get(n / 2)) {
        (Some(a), Some(b)) => 0.5 * (a + b),
        _ => 0.0,
    }
}
