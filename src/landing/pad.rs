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

/// Largest supported z-score window, bins.
pub const MAX_LAG: usize = 32;

/// Most raw samples one bin holds (odd); a hovering drone closes a bin every this many samples.
pub const MAX_BIN_SAMPLES: usize = 15;

/// The position is re-anchored (heading and odometer updated) every time the drone has moved this far.
/// 2 cm averages out position noise in the heading, yet is < 10 samples at 0.3 m/s and 100 Hz.
const HEADING_BASELINE_M: f32 = 0.02;

/// A crossing's chord must be within 20° of the drone's heading at both edges: straight flight.
const COS_MAX_HEADING_ERROR: f32 = 0.9397;

/// Travel between the edges of a crossing may exceed the chord by 5 % + 2 cm (position noise) at most.
const TRAVEL_SLACK_RATIO: f32 = 1.05;
const TRAVEL_SLACK_M: f32 = 0.02;
/// A crossing's top, between its edges less this at each end, must be flat (see `flat_between`), m.
const FLAT_TOP_INSET_M: f32 = 0.04;
/// Largest spread (10th to 90th percentile of the bins) of a flat top, m: ten times the VL53L1x's noise at
/// 0.4 m, a third of a 10 cm pad's height.
const FLAT_TOP_SPREAD_M: f32 = 0.03;
/// A half crossing (a line that ends on the pad, [`PadDetector::line_ended`]) needs the drone this far onto
/// the top past the entry edge, m: beyond the footprint's blur, so the level read is the top's.
const HALF_CROSSING_MIN_TOP_M: f32 = 0.06;
/// Fewest bins the flatness check needs (fewer: the ring no longer holds the top, the check passes).
const FLAT_TOP_MIN_BINS: usize = 5;
/// A turn-back's two edges must lie on one pad side: their separation along the travel direction, m.
const TURN_BACK_SIDE_TOLERANCE_M: f32 = 0.05;

/// The heading at an edge is measured over this many bins before it (~2 cm): recent enough to notice a
/// turn just before the edge, long enough to average position noise.
const HEADING_BINS: u32 = 2;

/// A half crossing whose entry lies within this of a pad side parallel to its travel (by the fit of the
/// others) is set aside, m: about the downward ranger's footprint over the pad's top (7.5° half-angle at
/// 0.4 m, 5 cm) less the position noise between the crossings. Measured: world 163 000 537 entered 1 cm
/// beyond such a side on a line 17° off the axis and put the centre 15 cm off along the travel.
const HALF_CROSSING_SIDE_MARGIN_M: f32 = 0.04;
/// ... when the full crossings' directions weigh at least this much across the half crossing's travel
/// (about one crossing along it): otherwise nothing says where the sides are.
const HALF_CROSSING_LATERAL_WEIGHT: f32 = 0.8;

/// Weight of the pull towards the midpoints' centroid in the centre fit (see the module docs, step 7).
const CENTROID_PULL: f32 = 1e-3;

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

/// Bins whose median is the level after a step (two stray bins among them cannot move it).
const AFTER_BINS: usize = 5;

/// A run ends after this many bins without its signal (one bad bin does not split a step in two).
const RUN_END_MISSES: u8 = 2;

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

    /// Updates the heading and odometer; returns the sample's motion data.
    fn track_motion(&mut self, x: f32, y: f32) -> Sample {
        let Some(anchor) = self.anchor else {
            self.anchor = Some((x, y));
            return Sample {
                x,
                y,
                odo: self.odo_at_anchor,
            };
        };
        let d = libm::hypotf(x - anchor.0, y - anchor.1);
        if d >= HEADING_BASELINE_M {
            self.heading = ((x - anchor.0) / d, (y - anchor.1) / d);
            self.odo_at_anchor += d;
            self.anchor = Some((x, y));
            return Sample {
                x,
                y,
                odo: self.odo_at_anchor,
            };
        }
        Sample {
            x,
            y,
            odo: self.odo_at_anchor + d,
        }
    }

    /// Closes the open bin: z-score, ring, run logic. Returns an edge stored as a result.
    fn close_bin(&mut self) -> Option<Edge> {
        let n = self.bin_len.max(1) as f32;
        let range = median(self.bin.get_mut(..self.bin_len).unwrap_or(&mut []));
        let level = self.window_median();
        let signal = self.z_score(range);
        let bin = Bin {
            range,
            x: self.bin_sum.0 / n,
            y: self.bin_sum.1 / n,
            odo: self.bin_sum.2 / n,
            heading: self.heading,
            signal,
            level,
        };
        self.bin_len = 0;
        let serial = self.bins;
        if let Some(slot) = self.ring.get_mut(serial as usize % RING) {
            *slot = bin;
        }
        self.bins = self.bins.wrapping_add(1);
        let detection = self.follow_runs(serial, signal)?;
        self.on_detection(detection)
    }

    /// The smoothed z-score of one value: -1, 0 or +1. Updates the window.
    fn z_score(&mut self, y: f32) -> i8 {
        let cfg = &self.config;
        if self.window_len < cfg.lag {
            // Training: the first `lag` values fill the window as they are.
            self.push_window(y);
            return 0;
        }
        let (centre, spread) = if cfg.robust_stats {
            self.window_robust_stats()
        } else {
            self.window_stats()
        };
        let dev = y - centre;
        let signal = if libm::fabsf(dev) > cfg.threshold_sigma * spread && libm::fabsf(dev) >= cfg.min_step_m {
            if dev > 0.0 { 1 } else { -1 }
        } else {
            0
        };
        let filtered = if signal != 0 {
            cfg.influence * y + (1.0 - cfg.influence) * self.last_filtered
        } else {
            y
        };
        self.push_window(filtered);
        signal
    }

    fn push_window(&mut self, v: f32) {
        let lag = self.config.lag;
        if let Some(slot) = self.window.get_mut(self.window_head) {
            *slot = v;
        }
        self.window_head = (self.window_head + 1) % lag;
        self.window_len = (self.window_len + 1).min(lag);
        self.last_filtered = v;
    }

    /// Mean and population standard deviation of the window (two passes: exact, no drift).
    fn window_stats(&self) -> (f32, f32) {
        let values = self.window.get(..self.window_len).unwrap_or(&[]);
        if values.is_empty() {
            return (0.0, 0.0);
        }
        let n = values.len() as f32;
        let mean = values.iter().sum::<f32>() / n;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
        (mean, libm::sqrtf(var))
    }

    /// Median and σ estimated from the median absolute deviation (`1.4826·MAD`, the Gaussian σ). Neither
    /// moves for a few stray values in the window, or for the first bins of a blurred step.
    fn window_robust_stats(&self) -> (f32, f32) {
        let mut copy = [0.0f32; MAX_LAG];
        let (Some(dst), Some(src)) = (copy.get_mut(..self.window_len), self.window.get(..self.window_len)) else {
            return (self.last_filtered, 0.0);
        };
        if src.is_empty() {
            return (self.last_filtered, 0.0);
        }
        dst.copy_from_slice(src);
        let med = median(dst);
        for v in dst.iter_mut() {
            *v = libm::fabsf(*v - med);
        }
        (med, 1.4826 * median(dst))
    }

    /// Median of the window: the level before a step, robust to the first part of a blurred step and
    /// to stray values. The last value pushed stands in while the window is empty.
    fn window_median(&self) -> f32 {
        let mut copy = [0.0f32; MAX_LAG];
        let Some(dst) = copy.get_mut(..self.window_len) else {
            return self.last_filtered;
        };
        let Some(src) = self.window.get(..self.window_len) else {
            return self.last_filtered;
        };
        if src.is_empty() {
            return self.last_filtered;
        }
        dst.copy_from_slice(src);
        median(dst)
    }

    /// Direction of travel into bin `serial` (at `hit`), from the bin [`HEADING_BINS`] before it; the
    /// slower-moving anchor heading when that is missing or too close (hovering).
    fn heading_before(&self, serial: u32, hit: Bin) -> (f32, f32) {
        let from = serial.checked_sub(HEADING_BINS).and_then(|s| self.ring_bin(s));
        if let Some(b) = from {
            let (dx, dy) = (hit.x - b.x, hit.y - b.y);
            let d = libm::hypotf(dx, dy);
            if d >= 0.005 {
                return (dx / d, dy / d);
            }
        }
        hit.heading
    }

    fn ring_bin(&self, serial: u32) -> Option<&Bin> {
        // Only the last RING serials are still in the ring.
        if self.bins.wrapping_sub(serial) as usize > RING || serial >= self.bins {
            return None;
        }
        self.ring.get(serial as usize % RING)
    }

    /// Run bookkeeping after bin `serial` with `signal`: ends runs, confirms new ones (module docs,
    /// step 4). Returns the detection of a run that ended.
    fn follow_runs(&mut self, serial: u32, signal: i8) -> Option<Detection> {
        let mut ended = None;
        if let Some(mut run) = self.run {
            run.misses = if signal == run.sign {
                0
            } else {
                run.misses.saturating_add(1)
            };
            // A run older than the ring can hold is located now, before its start is overwritten.
            let too_long = serial.wrapping_sub(run.first) as usize + self.config.lag + 2 >= RING;
            if run.misses >= RUN_END_MISSES || too_long {
                ended = self.locate(&run, serial);
                self.run = None;
            } else {
                self.run = Some(run);
            }
        }
        if signal != 0 && self.run.is_none_or(|r| r.sign != signal) {
            // m of n: `min_run` of the last `min_run + 1` bins carry this sign.
            let n = self.config.min_run as u32 + 1;
            let mut count = 0usize;
            let mut first = serial;
            for back in 0..n {
                let Some(s) = serial.checked_sub(back) else { break };
                if self.ring_bin(s).is_some_and(|b| b.signal == signal) {
                    count += 1;
                    first = s;
                }
            }
            if count >= self.config.min_run {
                // An opposite run still open ends here (a narrow crossing); report it first.
                if let Some(run) = self.run.take() {
                    ended = ended.or(first.checked_sub(1).and_then(|end| self.locate(&run, end)));
                }
                self.run = Some(ActiveRun {
                    sign: signal,
                    first,
                    misses: 0,
                });
            }
        }
        ended
    }

    /// Locates a finished run's step (module docs, step 4): where the binned range crosses halfway
    /// between the levels before and after, interpolated between bin centres.
    /// `end` is the run's last bin (the newest, or the one before a new run took over).
    fn locate(&mut self, run: &ActiveRun, end: u32) -> Option<Detection> {
        let first = *self.ring_bin(run.first)?;
        let before = first.level;
        // The level after: median of the run's last bins, signalling or not. (Not "the last signalling
        // bins": once the window has caught up with the step only stray bins still signal.)
        let mut tail = [0.0f32; AFTER_BINS];
        let mut k = 0usize;
        let mut s = end;
        while k < tail.len() && s >= run.first {
            if let (Some(b), Some(slot)) = (self.ring_bin(s), tail.get_mut(k)) {
                *slot = b.range;
                k += 1;
            }
            let Some(prev) = s.checked_sub(1) else { break };
            s = prev;
        }
        let after = median(tail.get_mut(..k).unwrap_or(&mut []));
        let height = after - before;
        if libm::fabsf(height) < self.config.min_step_m {
            return None;
        }
        // Position of a bin between the two levels: 0 = before, 1 = after. Bins beyond either level by
        // more than half the step are stray (outliers that survived the bin) and are skipped.
        let level_of = |b: &Bin| (b.range - before) / height;
        let stray = |b: &Bin| !(-0.5..=1.5).contains(&level_of(b));
        let new_side = |b: &Bin| level_of(b) > 0.5;

        // Walk back from the settled end of the run to the first two consecutive (non-stray) bins on the
        // old side of the half level: the step lies between the later of them and the next non-stray bin.
        // Starting from the settled end (not the first signal) keeps a stray bin just before a blurred
        // step from being taken for the step; needing two old-side bins skips a stray one on the new level.
        let start = end.wrapping_add(1);
        let limit = serial_span(run.first, start) + self.config.lag;
        let mut later: Option<(u32, Bin)> = None;
        let mut old_pair: Option<Bin> = None;
        let mut crossing = None;
        let mut s = start;
        for _ in 0..limit {
            let Some(prev) = s.checked_sub(1) else { break };
            s = prev;
            let Some(b) = self.ring_bin(s).copied() else { break };
            if stray(&b) {
                continue;
            }
            if new_side(&b) {
                later = Some((s, b));
                old_pair = None;
            } else if let Some(first_old) = old_pair {
                crossing = later.map(|(at, hit)| (first_old, hit, at));
                break;
            } else {
                old_pair = Some(b);
            }
        }
        let (old, hit, at_serial) = match crossing {
            Some(found) => found,
            // No clean old level found in the ring: fall back to the first signalling bin.
            None => (*self.ring_bin(run.first)?, *self.ring_bin(run.first)?, run.first),
        };
        let (mut x, mut y, mut odo) = (hit.x, hit.y, hit.odo);
        let t = (0.5 - level_of(&old)) / (level_of(&hit) - level_of(&old));
        if t.is_finite() {
            let t = t.clamp(0.0, 1.0);
            x = old.x + t * (hit.x - old.x);
            y = old.y + t * (hit.y - old.y);
            odo = old.odo + t * (hit.odo - old.odo);
        }
        let kind = if height < 0.0 { EdgeKind::Enter } else { EdgeKind::Exit };
        let detection = Detection {
            edge: Edge {
                x,
                y,
                kind,
                step_m: height,
            },
            odo,
            heading: self.heading_before(at_serial, hit),
            level_before: before,
            level_after: after,
        };
        // The same step flickering back on: merge it with the edge it belongs to.
        if let Some(last) = self.last_detection
            && last.edge.kind == kind
            && libm::fabsf(detection.odo - last.odo) < self.config.min_edge_spacing_m
        {
            return None;
        }
        self.last_detection = Some(detection);
        Some(detection)
    }

    /// Stores the edge (unless a duplicate) and pairs it into a crossing.
    fn on_detection(&mut self, det: Detection) -> Option<Edge> {
        let stored = self.store_edge(det.edge);
        match det.edge.kind {
            EdgeKind::Enter => self.pending_enter = Some(det),
            EdgeKind::Exit => {
                if let Some(enter) = self.pending_enter.take()
                    && let Some(crossing) = self.pair(&enter, &det).or_else(|| self.turn_back(&enter, &det))
                {
                    if self.crossings.push(crossing).is_err() {
                        self.dropped = self.dropped.saturating_add(1);
                    } else {
                        self.refit();
                    }
                }
            }
        }
        stored
    }

    fn store_edge(&mut self, edge: Edge) -> Option<Edge> {
        let spacing = self.config.min_edge_spacing_m;
        if self
            .edges
            .iter()
            .any(|e| libm::hypotf(e.x - edge.x, e.y - edge.y) < spacing)
        {
            return None;
        }
        if self.edges.push(edge).is_err() {
            self.dropped = self.dropped.saturating_add(1);
            return None;
        }
        Some(edge)
    }

    /// The crossing made by `enter` then `exit`, if it is one (module docs, step 6).
    fn pair(&self, enter: &Detection, exit: &Detection) -> Option<Crossing> {
        let cfg = &self.config;
        let (dx, dy) = (exit.edge.x - enter.edge.x, exit.edge.y - enter.edge.y);
        let chord = libm::hypotf(dx, dy);
        let lo = cfg.pad_size_m * cfg.min_chord_ratio;
        let hi = cfg.pad_size_m * cfg.max_chord_ratio;
        if !(chord >= lo && chord <= hi) {
            return None;
        }
        let dir = (dx / chord, dy / chord);
        let along = |h: (f32, f32)| dir.0 * h.0 + dir.1 * h.1 >= COS_MAX_HEADING_ERROR;
        if !(along(enter.heading) && along(exit.heading)) {
            return None;
        }
        if exit.odo - enter.odo > TRAVEL_SLACK_RATIO * chord + TRAVEL_SLACK_M {
            return None;
        }
        // Levels: the floor before entering and the pad while on it are window medians; the floor after
        // leaving is the median of the exit run's last bins. The pad must be lower than the floor by at
        // least a minimum step, and the floor must be the same on both sides.
        let floor_before = enter.level_before;
        let pad_level = exit.level_before;
        let floor_after = exit.level_after;
        let height = floor_before - pad_level;
        if height.is_nan() || height < cfg.min_step_m {
            return None;
        }
        if libm::fabsf(floor_after - floor_before) > cfg.step_match_m + 0.5 * height {
            return None;
        }
        if !self.flat_between(enter.odo, exit.odo) {
            return None;
        }
        Some(Crossing {
            enter: (enter.edge.x, enter.edge.y),
            exit: (exit.edge.x, exit.edge.y),
            step_m: height,
            inlier: true,
            turn_back: false,
        })
    }

    /// Whether the binned ranges between two edges (travel `from_odo` to `to_odo`, less
    /// [`FLAT_TOP_INSET_M`] at each end where the footprint blurs the step) form a flat top: the spread
    /// between their 10th and 90th percentiles is at most [`FLAT_TOP_SPREAD_M`] (module docs, step 6).
    /// A pad's top is flat; a beam grazing a cylinder's curved side, or sliding down an obstacle's foot,
    /// reads a range that keeps changing. Passes when the ring no longer holds enough of those bins.
    fn flat_between(&self, from_odo: f32, to_odo: f32) -> bool {
        let (lo, hi) = (from_odo + FLAT_TOP_INSET_M, to_odo - FLAT_TOP_INSET_M);
        let mut values = [0.0f32; RING];
        let mut n = 0usize;
        let newest = self.bins.wrapping_sub(1);
        for back in 0..RING as u32 {
            let Some(serial) = newest.checked_sub(back) else { break };
            let Some(b) = self.ring_bin(serial) else { break };
            if b.odo < lo {
                break;
            }
            if b.odo <= hi
                && let Some(slot) = values.get_mut(n)
            {
                *slot = b.range;
                n += 1;
            }
        }
        if n < FLAT_TOP_MIN_BINS {
            return true;
        }
        let values = values.get_mut(..n).unwrap_or(&mut []);
        values.sort_unstable_by(f32::total_cmp);
        let p10 = values.get(n / 10).copied().unwrap_or(0.0);
        let p90 = values.get(n - 1 - n / 10).copied().unwrap_or(0.0);
        p90 - p10 <= FLAT_TOP_SPREAD_M
    }

    /// The half crossing made by entering the pad and leaving it over the same side after turning back
    /// (module docs, step 6b), if `enter` then `exit` is one: the headings are opposite, both edges lie on one
    /// line across the travel direction, the travel in between is at most a pad width there and back, and
    /// the levels are those of a pad on a flat floor.
    fn turn_back(&self, enter: &Detection, exit: &Detection) -> Option<Crossing> {
        let cfg = &self.config;
        let d = enter.heading;
        let back = exit.heading;
        if d.0 * back.0 + d.1 * back.1 > -COS_MAX_HEADING_ERROR {
            return None;
        }
        let (dx, dy) = (exit.edge.x - enter.edge.x, exit.edge.y - enter.edge.y);
        if libm::fabsf(d.0 * dx + d.1 * dy) > TURN_BACK_SIDE_TOLERANCE_M {
            return None;
        }
        // In, to the line's end, across to the next line (at most a pad width) and back out.
        if exit.odo - enter.odo > (2.0 * cfg.max_chord_ratio + 1.0) * cfg.pad_size_m + TRAVEL_SLACK_M {
            return None;
        }
        let height = enter.level_before - exit.level_before;
        if height.is_nan() || height < cfg.min_step_m {
            return None;
        }
        if libm::fabsf(exit.level_after - enter.level_before) > cfg.step_match_m + 0.5 * height {
            return None;
        }
        let side = (0.5 * (enter.edge.x + exit.edge.x), 0.5 * (enter.edge.y + exit.edge.y));
        let inwards = (side.0 + cfg.pad_size_m * d.0, side.1 + cfg.pad_size_m * d.1);
        (inwards.0.is_finite() && inwards.1.is_finite()).then_some(Crossing {
            enter: side,
            exit: inwards,
            step_m: height,
            inlier: true,
            turn_back: true,
        })
    }

    /// The line being flown ends here, short of where it was laid out (a wall or an obstacle ahead; the
    /// caller turns back next). A drone that entered the pad on this line and is still on its top will
    /// never see the far side: the entry edge alone fixes the centre along the travel, half of
    /// `pad_size_m` inwards (module docs, step 6c). Returns whether such a half crossing was added.
    pub fn line_ended(&mut self) -> bool {
        self.flush();
        let cfg = self.config;
        let Some(enter) = self.pending_enter else {
            return false;
        };
        // Where the drone is now: the newest bins (the median of up to three, one stray reading is not
        // the level).
        let newest = self.bins.wrapping_sub(1);
        let Some(now) = self.ring_bin(newest).copied() else {
            return false;
        };
        let mut levels = [0.0f32; 3];
        let mut n = 0usize;
        for back in 0..3u32 {
            if let Some(b) = newest.checked_sub(back).and_then(|s| self.ring_bin(s))
                && let Some(slot) = levels.get_mut(n)
            {
                *slot = b.range;
                n += 1;
            }
        }
        let level_now = median(levels.get_mut(..n).unwrap_or(&mut []));
        let d = enter.heading;
        let (dx, dy) = (now.x - enter.edge.x, now.y - enter.edge.y);
        let along = d.0 * dx + d.1 * dy;
        let across = libm::fabsf(d.0 * dy - d.1 * dx);
        // Straight on from the entry, far enough onto the top to have seen it, not past its far side.
        if !(along >= HALF_CROSSING_MIN_TOP_M && along <= cfg.pad_size_m && across <= TURN_BACK_SIDE_TOLERANCE_M) {
            return false;
        }
        if now.odo - enter.odo > TRAVEL_SLACK_RATIO * along + TRAVEL_SLACK_M {
            return false;
        }
        let height = enter.level_before - enter.level_after;
        if height.is_nan() || height < cfg.min_step_m {
            return false;
        }
        // Still on the top: the level now is the level the entry stepped to, and the top is flat.
        let off_level = libm::fabsf(level_now - enter.level_after);
        if off_level.is_nan() || off_level > cfg.step_match_m + 0.25 * height {
            return false;
        }
        if !self.flat_between(enter.odo, now.odo + FLAT_TOP_INSET_M) {
            return false;
        }
        let side = (enter.edge.x, enter.edge.y);
        let inwards = (side.0 + cfg.pad_size_m * d.0, side.1 + cfg.pad_size_m * d.1);
        if !(inwards.0.is_finite() && inwards.1.is_finite()) {
            return false;
        }
        self.pending_enter = None;
        let half = Crossing {
            enter: side,
            exit: inwards,
            step_m: height,
            inlier: true,
            turn_back: true,
        };
        if self.crossings.push(half).is_err() {
            self.dropped = self.dropped.saturating_add(1);
            return false;
        }
        self.refit();
        true
    }

    /// Refits the centre over the crossings, dropping outliers one at a time (worst first), then half
    /// crossings whose entry the fit puts beside a side parallel to their travel (module docs, step 7b).
    fn refit(&mut self) {
        // Half crossings set aside so far, by index (only the first 64 can be; more is never reached with
        // the detector's capacity of at most a few dozen crossings).
        let mut set_aside = 0u64;
        for _ in 0..self.crossings.len() {
            self.refit_without(set_aside);
            let Some(estimate) = self.estimate else {
                return;
            };
            match self.half_crossing_beside_a_side(estimate.x, estimate.y) {
                Some(i) if i < 64 => set_aside |= 1 << i,
                _ => return,
            }
        }
    }

    /// The inlier half crossing (turn-back or line end) whose entry lies furthest across its travel from
    /// the centre `(cx, cy)`, if that is within [`HALF_CROSSING_SIDE_MARGIN_M`] of the pad's side parallel
    /// to the travel and the full crossings measure that coordinate (their directions' weight along it at
    /// least [`HALF_CROSSING_LATERAL_WEIGHT`]). Such an entry may have been over that side, not the one
    /// facing the travel, and then the pad's half size inwards along the travel is not the centre.
    fn half_crossing_beside_a_side(&self, cx: f32, cy: f32) -> Option<usize> {
        let limit = 0.5 * self.config.pad_size_m - HALF_CROSSING_SIDE_MARGIN_M;
        let mut worst: Option<(usize, f32)> = None;
        for (i, half) in self.crossings.iter().enumerate() {
            if !(half.inlier && half.turn_back) {
                continue;
            }
            // The pad's sides run along the arena's axes: the side crossed faces the axis nearest the
            // travel, the other axis is across it.
            let d = half.direction();
            let across = usize::from(libm::fabsf(d.0) >= libm::fabsf(d.1));
            let weight: f32 = self
                .crossings
                .iter()
                .filter(|c| c.inlier && !c.turn_back)
                .map(|c| {
                    let dc = c.direction();
                    let along = if across == 0 { dc.0 } else { dc.1 };
                    along * along
                })
                .sum();
            if weight < HALF_CROSSING_LATERAL_WEIGHT {
                continue;
            }
            let offset = if across == 0 {
                half.enter.0 - cx
            } else {
                half.enter.1 - cy
            };
            let offset = libm::fabsf(offset);
            if offset > limit && worst.is_none_or(|(_, w)| offset > w) {
                worst = Some((i, offset));
            }
        }
        worst.map(|(i, _)| i)
    }

    /// [`Self::refit`]'s outlier loop over the crossings not in the bit set `set_aside`.
    fn refit_without(&mut self, set_aside: u64) {
        for (i, c) in self.crossings.iter_mut().enumerate() {
            c.inlier = i >= 64 || set_aside & (1 << i) == 0;
        }
        self.estimate = None;
        let total = self.crossings.len();
        // At most half the crossings may be rejected: beyond that "outlier" has no meaning.
        for _ in 0..=total / 2 {
            let Some((cx, cy)) = fit_centre(&self.crossings) else {
                return;
            };
            let worst = self
                .crossings
                .iter()
                .enumerate()
                .filter(|(_, c)| c.inlier)
                .map(|(i, c)| (i, libm::fabsf(residual(c, cx, cy))))
                .fold(None, |acc: Option<(usize, f32)>, (i, r)| match acc {
                    Some((_, best)) if best >= r => acc,
                    _ => Some((i, r)),
                });
            let inliers = self.crossings.iter().filter(|c| c.inlier).count();
            match worst {
                Some((i, r)) if r > self.config.outlier_m && inliers > 1 && total - inliers < total / 2 => {
                    if let Some(c) = self.crossings.get_mut(i) {
                        c.inlier = false;
                    }
                }
                _ => {
                    self.estimate = Some(self.score(cx, cy));
                    return;
                }
            }
        }
        // Out of iterations: score the last fit anyway.
        if let Some((cx, cy)) = fit_centre(&self.crossings) {
            self.estimate = Some(self.score(cx, cy));
        }
    }

    /// Confidence and diagnostics of the centre `(cx, cy)` over the inlier crossings.
    fn score(&self, cx: f32, cy: f32) -> PadEstimate {
        let cfg = &self.config;
        let total = self.crossings.len();
        let inl = || self.crossings.iter().filter(|c| c.inlier);
        let inliers = inl().count();

        let (mut a, mut b, mut c) = (0.0f32, 0.0f32, 0.0f32);
        let mut sq = 0.0f32;
        for cr in inl() {
            let d = cr.direction();
            a += d.0 * d.0;
            b += d.0 * d.1;
            c += d.1 * d.1;
            let r = residual(cr, cx, cy);
            sq += r * r;
        }
        let lambda_min = 0.5 * (a + c) - libm::sqrtf(0.25 * (a - c) * (a - c) + b * b);
        let rms = if inliers > 0 {
            libm::sqrtf(sq / inliers as f32)
        } else {
            0.0
        };

        // The seed's spread: distances from the centre to every supporting edge.
        let mut sum = 0.0f32;
        let mut sum_sq = 0.0f32;
        let mut n = 0.0f32;
        for cr in inl() {
            for p in [cr.enter, cr.exit] {
                let r = libm::hypotf(p.0 - cx, p.1 - cy);
                sum += r;
                sum_sq += r * r;
                n += 1.0;
            }
        }
        let shape = if n > 0.0 && sum > 0.0 {
            let mean = sum / n;
            let std = libm::sqrtf((sum_sq / n - mean * mean).max(0.0));
            (1.0 - std / mean).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let wanted = f32::from(cfg.min_crossings_per_direction.max(1));
        let coverage = (lambda_min / wanted).clamp(0.0, 1.0);
        let fit = (1.0 - rms / cfg.fit_tolerance_m).clamp(0.0, 1.0);
        let consensus = if total > 0 { inliers as f32 / total as f32 } else { 0.0 };
        let confidence = coverage * fit * shape * consensus;
        PadEstimate {
            x: cx,
            y: cy,
            confidence: if confidence.is_finite() { confidence } else { 0.0 },
            inliers,
            outliers: total - inliers,
            min_direction_crossings: lambda_min.max(0.0),
            rms_residual_m: rms,
        }
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

/// Signed distance along the chord from the crossing's midpoint to the centre.
fn residual(c: &Crossing, cx: f32, cy: f32) -> f32 {
    let d = c.direction();
    let m = c.midpoint();
    d.0 * (cx - m.0) + d.1 * (cy - m.1)
}

/// Least-squares centre over the inlier crossings (module docs, step 7); `None` without inliers.
fn fit_centre(crossings: &[Crossing]) -> Option<(f32, f32)> {
    // Work relative to the first inlier midpoint: keeps the sums small (f32 precision).
    let origin = crossings.iter().find(|c| c.inlier)?.midpoint();
    let (mut m00, mut m01, mut m11) = (0.0f32, 0.0f32, 0.0f32);
    let (mut r0, mut r1) = (0.0f32, 0.0f32);
    let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for c in crossings.iter().filter(|c| c.inlier) {
        let d = c.direction();
        let m = c.midpoint();
        let m = (m.0 - origin.0, m.1 - origin.1);
        let dm = d.0 * m.0 + d.1 * m.1;
        m00 += d.0 * d.0;
        m01 += d.0 * d.1;
        m11 += d.1 * d.1;
        r0 += d.0 * dm;
        r1 += d.1 * dm;
        sx += m.0;
        sy += m.1;
        n += 1.0;
    }
    let k = CENTROID_PULL * n;
    let (m00, m11) = (m00 + k, m11 + k);
    let (r0, r1) = (r0 + CENTROID_PULL * sx, r1 + CENTROID_PULL * sy);
    let det = m00 * m11 - m01 * m01;
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let cx = (m11 * r0 - m01 * r1) / det;
    let cy = (m00 * r1 - m01 * r0) / det;
    Some((cx + origin.0, cy + origin.1))
}
