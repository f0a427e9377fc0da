//! The state estimator: an error-state extended Kalman filter in the spirit of the stock one
//! (\[FW\] src/modules/src/kalman_core/), fusing the IMU (1 kHz), the Flow deck's
//! optical flow (100 Hz) and downward range (40 Hz), with a surface tracker that keeps elevated objects
//! under the drone out of the height estimate (the "pad step", anchors-peers-planning-style.md §A.4).
//!
//! Sans-IO: the caller passes samples and their time steps; nothing here reads a clock.
//!
//! ```text
//!  on_imu (1 kHz) ──► calibration at rest ──► strapdown: q, v, p ──► every 10 ms: P = F P Fᵀ + Q
//!                                                                   └─ on the ground: ZUPT + gravity
//!  on_flow (100 Hz) ─► gates ─► 2 scalar updates (stock mm_flow model, height above the SURFACE)
//!  on_zrange (40 Hz) ─► gates ─► surface tracker ─► height updates │ surface steps │ re-anchoring
//!  state() ◄── p, v, Euler(q), filtered rates, surface height, valid
//! ```
//!
//! ## State
//!
//! Nominal state: position `p` (arena, m), velocity `v` (**arena** frame, m/s), attitude quaternion `q`
//! (body → arena), and the flow's scale error `e`. Error state (10: stock's 9 and `δe`): `δp`, `δv`, `δθ`,
//! `δe`, with the attitude error in the body frame,
//! `R_true = R·exp([δθ]×)`, folded into `q` after every update (stock `kalmanCoreFinalize`, including the
//! covariance rotation `G = I − [δθ/2]×`).
//!
//! *Why arena-frame velocity* (stock uses body-frame PX..PZ): the prediction becomes the textbook
//! strapdown `ṗ = v`, `v̇ = R f − g` with no `ω × v` terms; the controller and the output want arena
//! velocity; and the flow model still sees body velocity through `v_b = Rᵀv`, whose attitude Jacobian
//! (`[v_b]×`) is one line. Price: the flow update also touches the yaw error (correctly: a yaw error
//! rotates `v_b`); yaw stays unobservable, as in stock, and is held by the gyro, except where the map fixes
//! against the arena's walls measure it (below).
//!
//! ## Prediction (IMU)
//!
//! Every IMU sample (1 kHz) integrates the bias-corrected gyro into `q` (`exp` by its series: no
//! trigonometry, no square root) and the specific force into `v` and `p`: the state the controller reads is
//! never older than 1 ms and includes every sample. The covariance is propagated only every 10 ms (stock:
//! 100 Hz prediction, estimator_kalman.c L119) with the block's mean specific force and accumulated
//! rotation, and before any measurement update (so `P` is always current when used). Cost of this choice:
//! one tenth of the covariance work (≈ 0.5 M instead of ≈ 5 M Cortex-M4 instructions per second, see
//! below) for a transition matrix that barely changes in 10 ms.
//!
//! The accelerometer is an *input*, not a gravity measurement: in flight a drag-free quadrotor's
//! accelerometer points along its thrust whatever its tilt, so it says nothing about the tilt. Roll and
//! pitch are corrected, as in stock, through the velocity: a tilt error makes `v` drift by `g·δθ` and the
//! flow sees it. Only on the ground and at rest (not [`Estimator::set_flying`], less than
//! `airborne_height_m` above the surface, gyro and accelerometer quiet) are a gravity-direction update
//! (roll, pitch) and a zero-velocity update applied, every 10 ms.
//!
//! *Level calibration.* At rest a tilt and the accelerometer's horizontal offset read the same. The first
//! rest window takes the drone to stand level, as stock does ("stationary and roughly flat", roll and pitch
//! pulled back to zero on the ground, kalman_core.c `ROLLPITCH_ZERO_REVERSION`): a horizontal reading up to
//! 0.35 m/s² (≈ 2°) is the offset and is subtracted from every later sample; a larger one is a slope, and
//! the attitude is levelled on it. Levelled on an offset instead, the estimate is off by it (0.05 m/s² ≈
//! 0.3°), the controller holds that as a real tilt, and the lift-off slides sideways before the flow loop
//! reacts (a few millimetres: enough to touch a pad's side beside the start). A start on a slope under 2°
//! gives the same error the other way; on a level floor it gives none.
//!
//! Process noise: stock adds `(σ·dt)²` per 10 ms prediction (kalman_core_params_defaults.h); here the same
//! amount is added as a density `σ²·0.01 s·dt`, identical at 100 Hz and right for the shorter steps before
//! an update. The defaults are lower than stock's (acceleration 0.3 xy / 0.15 z instead of 0.5 / 1.0
//! m/s², attitude 0.03 instead of 0.1 rad/s) because this filter integrates the *measured* accelerometer
//! in all axes, while stock in flight replaces x and y by a drag-free thrust model whose error its process
//! noise must cover. With stock's values the range noise drives the vertical velocity (error RMS 18 mm/s,
//! peaks 50), which ruins the short-term height the pad-step logic relies on (z coasts on the IMU for 50 ms to
//! ~1 s across a step; a 1 s range gap drifted 64 mm with stock's values). The
//! `transit_3m_with_motor_vibration` test (1 m/s² and 0.05 rad/s of white IMU noise at 1 kHz, 20× and
//! 10× the bench noise) checks that these values still hold with a vibrating airframe; on the real drone,
//! raise `accel_noise_z` if the logged range innovations show the height lagging. Diagonal bounds
//! 1e-6…100 (stock `MIN_COVARIANCE`/`MAX_COVARIANCE`).
//!
//! ## Attitude and gyro bias
//!
//! At rest before flight the gyro bias is the mean of a 512-sample window whose variance is below the stock
//! threshold (100 LSB², sensors_bmi088_bmp3xx.c L83-91); the same window gives the accelerometer scale
//! (|f| = g, stock `processAccScale`) and the initial roll and pitch; yaw comes from [`Estimator::reset`].
//! **Calibration therefore takes 0.512 s at rest** ([`Estimator::is_calibrated`]); a window with motion
//! is discarded and the next one starts, and nothing is estimated before. Later rest windows on the ground
//! refine bias and scale (25 % per window); in flight they are frozen (stock finds the bias once). In
//! flight, the attitude is the strapdown quaternion corrected by the EKF's attitude-error states (flow
//! through velocity); no Mahony pre-filter: its accelerometer feedback would pull the attitude towards
//! "thrust axis = vertical", wrong whenever the drone accelerates. The rates output is the bias-corrected
//! gyro through the stock 80 Hz second-order low-pass.
//!
//! ## Flow update (stock mm_flow.c)
//!
//! `N_x = dt·(35/0.71674)·(v_bx·R22/h − ω_y)`, `N_y = dt·(35/0.71674)·(v_by·R22/h + ω_x)` against the
//! measured `0.1·dpixel`, std `0.1·flow_std_counts` (stock 2.0 counts), with `h = max(z − s, 0.1 m)` the
//! height above the **surface** and `ω` the mean bias-corrected gyro since the previous flow sample (stock
//! takes the latest sample; the mean is what the sensor integrated). Jacobian: velocity (`R22/h` along the
//! body axis) and attitude error. Deliberately **not** height: the range measures `z` a hundred times
//! better than the flow could, and the flow camera (42° field of view) sees a pad before the range's cone
//! does, which would leak the pad into `z`. Gates (counted in [`Diagnostics`]): `motion_valid` (stock:
//! motion byte 0xB0), `squal ≥ flow_squal_min`, |dpixel| < 100 (stock outlier limit), `0 < dt ≤ 0.1 s`,
//! tilt (`R22 ≥ 0.5`), airborne, and a joint Mahalanobis gate `νx²/Sx + νy²/Sy ≤ flow_gate_sigma²` that
//! yields after `flow_max_gate_rejections` consecutive rejections (a filter that drifted must be able to
//! come back).
//!
//! ## Flow scale
//!
//! A PMW3901 over a real floor reads the translational flow `(1 + e)` times what the model predicts: the
//! height the model divides by is the range's (a few mm off), the lens and the floor's texture differ from
//! the stock constants. The flow alone cannot tell `e` from a velocity, so uncorrected it scales every
//! distance flown: 3 % over a 4 m leg is 12 cm, and in the simulator's stress batch (±3 % per seed) it made
//! most of the estimate's tail. `e` is therefore a state: the flow's
//! prediction is `(1 + e)·c·R22/h·v_b − c·ω` (the rotational part, from the gyro, is not scaled), its
//! Jacobian on `δe` is the translational flow `c·R22/h·v_b`. Only the map fixes against the arena's exact
//! walls *learn* it (through the velocity's correlation with it): they measure position in a frame that
//! does not move with the estimate. To every other update it is a consider state (`scalar_update_bounded`):
//! learnt from the flow and the accelerometer alone it walked to −3 % on a vibrating transit, and from the
//! landmarks (planes placed from the estimate a sweep late) it took their lag for a scale, +1 % with the
//! estimate trailing the truth by 8 mm (the `latency` test). It starts at 0 with std
//! `initial_std_flow_scale` (0.05) at every reset, walks by 0.001/√s (a room's floor is not one texture),
//! moves at most 0.005 per update and is bounded to ±0.3; a divergence reset starts it over. Cost: the
//! error state grows from 9 to 10, about a quarter more work per update.
//!
//! ## Range update (stock mm_tof.c / zranger2.c)
//!
//! Used when `R22 ≥ tof_min_r22` (stock 0.1, here cos 36.9° by default: a steeper beam hits the ground far
//! from below the drone). Cone correction as stock: `α = max(acos R22 − 7.5°, 0)`, so the measured height is
//! `r·cos α`; noise `σ = 0.0025·(1 + exp(2.9214·(r − 2.5)))` m; readings `None`, non-finite, negative or
//! ≥ 5 m are dropped. Every accepted range goes through the surface tracker (module `surface`, whose
//! documentation has the full rules), which turns it into a height update of `z − s`, a surface step, or a
//! re-anchoring of `z` — with a decision delay of two ranges (50 ms; the height coasts on the IMU
//! meanwhile, which is why its short-term accuracy matters).
//!
//! ## Wall anchors (module `wall_hold`)
//!
//! While the commander holds a position ([`Estimator::on_multiranger`] with `hold`), each horizontal
//! Multi-ranger beam within 2.5 m is anchored (its range, the position, its direction) and every later
//! reading is a scalar measurement of the position along the beam: expected range `r₀ − (p − p₀)·u`,
//! Jacobian `−u` on x and y, std `wall_std_floor_m + wall_std_relative·r`, gated at `wall_gate_sigma`.
//! Hovering, this replaces the flow's ≈ 1 cm/√s random walk by the walls' fixed distance. Only for headings
//! within 20° of the arena's axes (the walls run along them); see the module for the rules. Cost: up to
//! four scalar updates at 10 Hz: 19 735 Cortex-M4 instructions per sweep with all four beams fused (the
//! QEMU bench, `tools/qemu-bench`, where `on_flow` with its covariance prediction takes 14 047), 0.2 M/s.
//!
//! ## Map fixes (module `map_fix`)
//!
//! In a mission, the navigator casts each Multi-ranger sweep against the map it has built *before* writing
//! the sweep into it (the arena's exact walls, and obstacle faces frozen as landmarks once confirmed), and
//! hands the stabilizer up to four [`map_fix::MapFix`]es: the distance to a surface along its normal `n`,
//! measured and expected. [`Estimator::on_map_fixes`] fuses each as a scalar measurement `c − p·n`
//! (Jacobian `−n` on x and y), std from the ranger model (and the landmark's plane), gated at
//! `map_fix_gate_sigma`; against the arena's exact walls the Jacobian also has the heading term
//! `−r·n·u⊥·R[2]` on `δθ` (two beams on one wall, or one over several sweeps, correct the yaw; each
//! fix's turn bounded by `map_fix_max_yaw_step_rad`). A fix implying a jump beyond `map_fix_jump_m`
//! (8 cm) is held back unless a fix along the same normal direction in one of the two sweeps before
//! agreed (within 4 cm): one beam that met another surface than the cast predicted, accepted by a gate
//! the position's own uncertainty had widened, made the worst single errors (a 14 cm step in one sweep). Over a default-world mission this holds the
//! horizontal error to an RMS of
//! ≈ 1.5 cm instead of the flow's ≈ 6.6 cm random walk (simulator batches).
//!
//! ## The pad step
//!
//! A range that jumps while the IMU shows no matching vertical motion moves the *surface height* `s`, not
//! `z`. The jump is measured in the implied surface `u = z − r·cos α`, which already contains every
//! movement the IMU saw, so a real climb does not move `u`. Three consecutive ranges that agree (spread
//! within 4σ of the range noise, no trend, no significant slope) form a plateau; a plateau at least
//! `step_min_m` (1 cm) and `step_sigma` (3) standard deviations of `z` away from `s` is a step — a height
//! error that large is improbable, so it is the surface: `s` takes its level (exactly 0 within `snap_m`,
//! 1.5 cm, of the floor), and for up to `step_settle_samples` ranges after it the surface, not `z`,
//! follows the level while it still moves (the tail of a step blurred by the ranger's cone). Ranges inside
//! the transition never reach the filter, and a ramp (least-squares slope over 150 ms beyond what noise
//! and the vertical-velocity uncertainty allow) stops fusion before it can drag `z`. A level below the floor
//! (`s` cannot be negative) or a jump `z` could explain re-anchors `z` instead (its variance, and the
//! vertical velocity's, inflated). Failure modes, by design:
//! * a slow ramp (the implied surface moving slower than ≈ 7 cm/s, e.g. a slope) is followed as height
//!   (test `slow_ramp_is_followed_as_height`: 10 cm over 1 m at 0.5 m/s → 10 cm in `z`); so is any object
//!   lower than `snap_m` over the floor (or `step_min_m` over an object);
//! * a step blurred by the ranger's cone (area-weighted over 7.5°) and crossed slowly is partly followed
//!   as height: worst over 20 seeds 12 mm at 0.3 m/s, 30 mm at 0.2 m/s (7–8 mm at 0.5 m/s, test
//!   `pad_steps_over_many_seeds`); sharp steps are not affected;
//! * a step while `z` itself is uncertain (jump < 3σ_z, e.g. after ≳ 1 s without ranges) is taken as a
//!   height error; over the floor the floor rule repairs it, over an object `z` is off by the object's
//!   height until the drone leaves it (leaving then implies a surface below the floor, which re-anchors `z`);
//!   the same holds for an object under the drone at take-off if `reset` was given the floor's height;
//! * a step during a vertical motion the IMU got wrong (e.g. thrust transients) is split between `z` and
//!   `s` in proportion to the velocity error (z coasts ≈ 50 ms–1 s on the IMU across a step);
//! * hovering over an edge (the range flickering between two levels) keeps the tracker in transition: `z`
//!   coasts on the IMU, a decision on the median is forced after `max_transition_samples` (0.4 s);
//! * a transition in which the implied surface keeps moving one way, at a rate the vertical-velocity
//!   uncertainty explains, is an unseen vertical velocity, not a step: after 0.4 s (1.6 s whatever the
//!   rate) the velocity error is measured from the slope and removed, and `z` re-anchored.
//!
//! ## Validity and supervision
//!
//! [`StateEstimate::valid`] is true when: calibrated; a range reached a decision since the last reset; IMU
//! samples arriving (not more than 30 flow/range samples in a row without one, not more than 50 non-finite
//! IMU samples in a row); the state finite and within the stock kalman_supervisor bounds (|p| ≤ 100 m,
//! |v| ≤ 10 m/s per axis); after a divergence reset, a range (and flow, when airborne) since it; and, while
//! airborne: a sane range within `sensor_timeout_s` (0.5 s), a range *decision* (a height update or a
//! classified plateau) within twice that (a slowly crossed edge keeps the tracker undecided up to ~1 s),
//! and, higher than `flow_required_height_m` (0.15 m) above the surface, a usable flow sample within
//! `sensor_timeout_s`. All clocks start at take-off plus `takeoff_grace_s` (1 s). (The PMW3901 needs ~8 cm,
//! so the last centimetres of a landing have no flow.) The bounds are checked every IMU sample, the
//! covariance every 10 ms and after every update; a violation or anything non-finite resets the filter:
//! position to the last sane one, velocity 0, attitude kept if finite, covariance wide (σ 1 m, 1 m/s,
//! 0.1 rad) so the sensors pull it back; counted in [`Diagnostics::divergence_resets`]. Height, velocity and
//! attitude recover from the sensors; x and y keep whatever the fault did to them (nothing measures them
//! absolutely), so a new divergence reset means "position lost" to the mission.
//!
//! Inputs are never trusted: non-finite gyro/accelerometer samples are replaced by the last good one
//! (counted), values beyond the BMI088's ranges (±2000 °/s, ±24 g) are clamped, a non-finite or
//! non-positive `dt_s` is replaced by the last sane IMU period (the sample itself is still used: the IMU's
//! data-ready paces the calls) and `dt_s > 50 ms` is clamped; a bad configuration value falls back to its
//! default; every division and square root is guarded.
//!
//! ## Size and cost
//!
//! `size_of::<Estimator>()` is 1504 bytes on a 64-bit host (the covariance is 400 of them, the surface
//! tracker's ranges 108, the wall anchors about 120; the `memory_size` test), a little less on the MCU; no
//! heap; the prediction's stack frame holds one 10 × 10 temporary (400 B). Cortex-M4F instructions per call, measured under QEMU (mps2-an386,
//! `-icount`, release profile with `opt-level = "s"` as the firmware), hovering:
//!
//! | call | instructions | per second |
//! |---|---|---|
//! | `on_imu` | 933 | 0.84 M (900 calls) |
//! | `on_imu` with the 10 ms covariance prediction | ≈ 6 000 | 0.60 M (100 calls) |
//! | `on_flow` (2 gated scalar updates) | ≈ 9 700 (max 15 000) | 0.97 M |
//! | `on_zrange` (tracker, 0–3 updates; incl. a partial prediction) | ≈ 8 900 (max 11 900) | 0.36 M |
//! | `state()` | ≈ 510 | |
//!
//! About 2.8 M instructions per second, ≈ 2 % of the 168 MHz core. `libm`'s `sqrtf`, `sinf` and `cosf` are
//! software routines on this target (the latter two through double precision), so none is on the 1 kHz
//! path: the rotation uses series, the quaternion a first-order renormalisation, the rest tests squared
//! norms, and the range's cone correction is skipped below 7.5° of tilt.
//!
//! Files: `predict` (IMU strapdown, covariance propagation, rest windows), `updates` (flow, height through
//! the surface tracker, wall anchors, map fixes; the scalar update), `map_fix` (the map fixes' ray cast and
//! landmarks, run by the navigator), `surface` (pad-step tracking), `calib` (gyro
//! bias and levelling at rest), `wall_hold` (the wall anchors' geometry), `ekf_math` (the 10 × 10 covariance
//! and the rate low-pass; vectors and quaternions are [`crate::math`]); this file holds the state, its
//! configuration, validity and the public readout.

mod calib;
mod ekf_math;
pub mod map_fix;
mod predict;
mod surface;
mod updates;
pub mod wall_hold;

pub use surface::{SurfaceEvent, SurfaceMode};

use crate::math::{
    M3, QUAT_IDENTITY, Quat, V3, add3, dot3, euler_from_rot, finite3, mul_m3, mul_m3_v3, mul_m3t_v3, norm3,
    quat_from_euler, quat_from_rotvec, quat_mul, quat_normalize, quat_to_rot, scale3, skew, sub3,
};
use crate::types::{GRAVITY_M_S2, StateEstimate};
use calib::Calibrator;
use ekf_math::{MatN, N, VecN, mul_mat_vec};
use surface::{Params, SurfaceTracker};
use wall_hold::WallHold;

// Error-state indices (stock order: X, Y, Z, PX, PY, PZ, D0, D1, D2; here the velocity is arena-frame).
const SZ: usize = 2;
const SV: usize = 3;
const SD: usize = 6;
/// The flow's scale error `e` (the sensor reads `1 + e` times the translational flow the model predicts).
const SS: usize = 9;
/// The largest flow scale error the state may hold (the world file format, `docs/formats.md`, allows ±0.3 in the simulator).
const FLOW_SCALE_MAX: f32 = 0.3;
/// Random walk of the flow scale error, 1/√s: the floor's texture and the height change across a room.
const FLOW_SCALE_WALK_PER_SQRT_S: f32 = 0.001;
/// The most one scalar update may move the flow scale error. A sound update moves it by far less (the
/// scale is learnt over many sweeps); a larger step comes from garbage that passed a gate (the flow's gate
/// yields after ten rejections so that a drifted filter can come back), and would scale every later metre.
const FLOW_SCALE_MAX_STEP: f32 = 0.005;

/// Measured counts are ~10× pixels (stock `FLOW_RESOLUTION`).
const FLOW_RESOLUTION: f32 = 0.1;

/// Diagonal bounds of the covariance (stock kalman_core.c `MIN_COVARIANCE`, `MAX_COVARIANCE`).
const COVARIANCE_MIN: f32 = 1e-6;
const COVARIANCE_MAX: f32 = 100.0;
/// Stock kalman_supervisor.c bounds: beyond them the filter is reset.
const MAX_POSITION_M: f32 = 100.0;
const MAX_VELOCITY_M_S: f32 = 10.0;

/// The IMU's nominal rate (stock main loop, `stabilizer.c`): sets the rate-output filter.
const IMU_RATE_HZ: f32 = 1000.0;
/// Gyro low-pass of the rates output (stock `GYRO_LPF_CUTOFF_FREQ`, sensors_bmi088_bmp3xx.c L140).
const GYRO_LPF_HZ: f32 = 80.0;

/// Standard deviations after a divergence reset: position 1 m / 0.5 m (z), velocity 1 m/s, attitude 0.1 rad.
/// (The flow scale restarts at 0 with a std of only 0.01: with the velocity this uncertain a wide scale
/// would take the flow's weight while the state comes back, and recovering comes first.)
const DIVERGENCE_STD: [f32; N] = [1.0, 1.0, 0.5, 1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 0.01];

/// No held-back map-fix jump (see `Estimator::map_jump_mm`).
const NO_JUMP: i16 = i16::MIN;

/// Validity: this many flow/range samples in a row without an IMU sample means the IMU stopped.
const MAX_SAMPLES_WITHOUT_IMU: u16 = 30;
/// Validity: this many non-finite IMU samples in a row means the IMU is broken.
const MAX_BAD_IMU_STREAK: u32 = 50;

/// Tuning. [`Default`] gives the values documented on each field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorConfig {
    /// Horizontal acceleration process noise, m/s²: `(σ·0.01 s)²` per 10 ms on each horizontal velocity.
    /// Default 0.3 (stock `procNoiseAcc_xy` 0.5; see the module docs, "Process noise").
    pub accel_noise_xy: f32,
    /// Vertical acceleration process noise, m/s². Default 0.15 (stock `procNoiseAcc_z` 1.0).
    pub accel_noise_z: f32,
    /// Roll/pitch process noise, rad/s: `(σ·0.01 s)²` per 10 ms. Default 0.03 (stock
    /// `measNoiseGyro_rollpitch` 0.1).
    pub gyro_noise_roll_pitch: f32,
    /// Yaw process noise, rad/s. Default 0.03 (stock `measNoiseGyro_yaw` 0.1).
    pub gyro_noise_yaw: f32,
    /// Flow measurement std, sensor counts (stock `motion.flowStdFixed` 2.0; ×0.1 in pixel units).
    pub flow_std_counts: f32,
    /// Flow samples with a lower SQUAL are dropped (stock has no such gate; default 10: PMW3901 surfaces
    /// with usable texture read tens to ~100).
    pub flow_squal_min: u8,
    /// |dpixel| at or above this is an outlier (stock flowdeck_v1v2.c: 100).
    pub flow_outlier_counts: u16,
    /// Flow Mahalanobis gate, in standard deviations (joint over both axes). Default 5.
    pub flow_gate_sigma: f32,
    /// After this many consecutive gate rejections the next flow sample is fused anyway. Default 10.
    pub flow_max_gate_rejections: u8,
    /// Ranges are used only when R22 (the cosine of the tilt) is at least this. Default 0.8 (36.9°);
    /// stock 0.1.
    pub tof_min_r22: f32,
    /// Half-angle of the ranger's cone, rad (stock mm_tof.c: 7.5°).
    pub tof_cone_half_angle_rad: f32,
    /// Ranges at or beyond this are dropped, m (stock zranger2.c `RANGE_OUTLIER_LIMIT` 5000 mm).
    pub tof_max_range_m: f32,
    /// Smallest range jump taken as a surface step (if also ≥ `step_sigma`·σ_z), m. Default 0.01.
    pub step_min_m: f32,
    /// A surface within this of the floor is the floor: `surface_height_m` snaps to exactly 0 (and the
    /// difference goes to the height). Default 0.015.
    pub snap_m: f32,
    /// A step down to within this of a surface the drone stepped up from (the floor included) returns to
    /// that surface exactly, m: over many pad crossings the blurred edges' errors would add up. Default 0.04.
    pub level_return_m: f32,
    /// An implied surface this far below the floor means the height is wrong, m. Default 0.03.
    pub below_floor_m: f32,
    /// Height-update gate, in standard deviations of the innovation. Default 3.
    pub surface_gate_sigma: f32,
    /// Smallest height-update gate, m. Default 0.008.
    pub surface_gate_min_m: f32,
    /// A window of ranges is flat when its spread is at most this many range std's. Default 4.
    pub surface_flat_sigma: f32,
    /// ... or at most this, m. Default 0.01.
    pub surface_flat_min_m: f32,
    /// A jump is attributed to the surface only if it is also at least this many standard deviations of
    /// the height estimate (a height error that large is improbable). Default 3.
    pub step_sigma: f32,
    /// A transition without a plateau is decided after this many ranges. Default 16 (0.4 s: before the
    /// range counts as missing for `valid`).
    pub max_transition_samples: u16,
    /// After a step the surface (not the height) follows the new level for this many ranges, so that the
    /// slow tail of a step blurred by the ranger's cone goes to the surface. Default 20 (0.5 s).
    pub step_settle_samples: u16,
    /// The downward ranger's period, s (stock zranger2: 25 ms). Three ranges spanning more than 3.2
    /// periods are not consecutive and cannot form a plateau.
    pub tof_period_s: f32,
    /// While airborne, flow or range missing for longer than this makes the estimate invalid, s.
    /// Default 0.5.
    pub sensor_timeout_s: f32,
    /// Extra time after take-off before missing flow/range count, s. Default 1.0.
    pub takeoff_grace_s: f32,
    /// Flow is required for `valid` only above this height over the surface, m: the PMW3901 needs ~8 cm,
    /// so the last centimetres of a landing (and the first of a take-off) have none. Default 0.15.
    pub flow_required_height_m: f32,
    /// Above this height over the surface the drone is airborne even without `set_flying(true)`, m.
    /// Default 0.05.
    pub airborne_height_m: f32,
    /// Zero-velocity update std at rest on the ground, m/s. Default 0.02.
    pub rest_velocity_std_m_s: f32,
    /// Fuse the horizontal Multi-ranger beams against the walls they saw when a hold began (module
    /// `wall_hold`). Default true.
    pub wall_hold: bool,
    /// Wall-range std: this floor plus [`EstimatorConfig::wall_std_relative`] times the range, m. Default
    /// 0.005 (the VL53L1x's ranging noise is a few mm plus about 1 % of the range; doubled here for walls
    /// that are not quite flat or square).
    pub wall_std_floor_m: f32,
    /// Wall-range std per metre of range. Default 0.02.
    pub wall_std_relative: f32,
    /// Wall readings whose innovation exceeds this many standard deviations are rejected. Default 3.
    pub wall_gate_sigma: f32,
    /// Fuse the map-relative fixes the navigator casts from each Multi-ranger sweep (module `map_fix`,
    /// [`Estimator::on_map_fixes`]). Default true.
    pub map_fix: bool,
    /// Map fixes whose innovation exceeds this many standard deviations are rejected. Default 3.
    pub map_fix_gate_sigma: f32,
    /// A map fix whose innovation exceeds this (m) moves the estimate only when a fix along the same
    /// normal direction in one of the two sweeps before it implied the same jump (within
    /// `map_fix_jump_agree_m`): a real drift shows in every sweep, a beam that met another surface than
    /// the cast (a corner, an obstacle's side, a ranger outlier) in one. Default 0.08 (measured at 0.06
    /// on training seeds 20–23, where single-sweep
    /// jumps of up to 14 cm were the worst estimate errors; 0.06 failed two runs of the CI batches).
    pub map_fix_jump_m: f32,
    /// See `map_fix_jump_m`, m. Default 0.04.
    pub map_fix_jump_agree_m: f32,
    /// Let the map fixes against the arena's exact walls correct the heading too (their Jacobian on the
    /// heading error, module `map_fix`, "Heading"). Default true.
    pub map_fix_heading: bool,
    /// The most one map fix may turn the heading, rad; a fix that would turn it more is rejected (a wrong
    /// wall, an outlier the position gate let through). Default 0.02 (1.1°).
    pub map_fix_max_yaw_step_rad: f32,
    /// Gravity-direction update std at rest on the ground, m/s² per axis. Default 0.2.
    pub rest_accel_std_m_s2: f32,
    /// Initial std of x and y at a reset, m. Default 0.05 (the start pad's position is known).
    pub initial_std_xy_m: f32,
    /// Initial std of z, m. Default 0.02.
    pub initial_std_z_m: f32,
    /// Initial std of the velocity, m/s (stock 0.01).
    pub initial_std_velocity_m_s: f32,
    /// Initial std of roll and pitch, rad (stock 0.01).
    pub initial_std_roll_pitch_rad: f32,
    /// Initial std of yaw, rad (stock 0.01).
    pub initial_std_yaw_rad: f32,
    /// Initial std of the flow's scale error at a reset (a fraction; module docs, "Flow scale"). Default
    /// 0.05; 0 leaves the scale at 1 (no scale state).
    pub initial_std_flow_scale: f32,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            accel_noise_xy: 0.3,
            accel_noise_z: 0.15,
            gyro_noise_roll_pitch: 0.03,
            gyro_noise_yaw: 0.03,
            flow_std_counts: 2.0,
            flow_squal_min: 10,
            flow_outlier_counts: 100,
            flow_gate_sigma: 5.0,
            flow_max_gate_rejections: 10,
            tof_min_r22: 0.8,
            tof_cone_half_angle_rad: 7.5 * core::f32::consts::PI / 180.0,
            tof_max_range_m: 5.0,
            step_min_m: 0.01,
            snap_m: 0.015,
            level_return_m: 0.04,
            below_floor_m: 0.03,
            surface_gate_sigma: 3.0,
            surface_gate_min_m: 0.008,
            surface_flat_sigma: 4.0,
            surface_flat_min_m: 0.01,
            step_sigma: 3.0,
            max_transition_samples: 16,
            step_settle_samples: 20,
            tof_period_s: 0.025,
            sensor_timeout_s: 0.5,
            takeoff_grace_s: 1.0,
            flow_required_height_m: 0.15,
            airborne_height_m: 0.05,
            rest_velocity_std_m_s: 0.02,
            wall_hold: true,
            wall_std_floor_m: 0.005,
            wall_std_relative: 0.02,
            wall_gate_sigma: 3.0,
            map_fix: true,
            map_fix_gate_sigma: 3.0,
            map_fix_jump_m: 0.08,
            map_fix_jump_agree_m: 0.04,
            map_fix_heading: true,
            map_fix_max_yaw_step_rad: 0.02,
            rest_accel_std_m_s2: 0.2,
            initial_std_xy_m: 0.05,
            initial_std_z_m: 0.02,
            initial_std_velocity_m_s: 0.01,
            initial_std_roll_pitch_rad: 0.01,
            initial_std_yaw_rad: 0.01,
            initial_std_flow_scale: 0.05,
        }
    }
}

impl EstimatorConfig {
    /// Every field that is non-finite or out of its sensible range replaced by its default (the
    /// estimator only ever runs on a sanitised configuration, so no setting can produce a NaN).
    pub fn sanitized(self) -> Self {
        let d = Self::default();
        let pos = |v: f32, def: f32| if v.is_finite() && v > 0.0 { v } else { def };
        let nonneg = |v: f32, def: f32| if v.is_finite() && v >= 0.0 { v } else { def };
        Self {
            accel_noise_xy: nonneg(self.accel_noise_xy, d.accel_noise_xy),
            accel_noise_z: nonneg(self.accel_noise_z, d.accel_noise_z),
            gyro_noise_roll_pitch: nonneg(self.gyro_noise_roll_pitch, d.gyro_noise_roll_pitch),
            gyro_noise_yaw: nonneg(self.gyro_noise_yaw, d.gyro_noise_yaw),
            flow_std_counts: pos(self.flow_std_counts, d.flow_std_counts),
            flow_squal_min: self.flow_squal_min,
            flow_outlier_counts: if self.flow_outlier_counts > 0 {
                self.flow_outlier_counts
            } else {
                d.flow_outlier_counts
            },
            flow_gate_sigma: pos(self.flow_gate_sigma, d.flow_gate_sigma),
            flow_max_gate_rejections: self.flow_max_gate_rejections,
            tof_min_r22: if self.tof_min_r22.is_finite() {
                self.tof_min_r22.clamp(0.1, 1.0)
            } else {
                d.tof_min_r22
            },
            tof_cone_half_angle_rad: if self.tof_cone_half_angle_rad.is_finite() {
                self.tof_cone_half_angle_rad.clamp(0.0, 0.5)
            } else {
                d.tof_cone_half_angle_rad
            },
            tof_max_range_m: pos(self.tof_max_range_m, d.tof_max_range_m).min(d.tof_max_range_m),
            step_min_m: pos(self.step_min_m, d.step_min_m),
            snap_m: nonneg(self.snap_m, d.snap_m),
            level_return_m: nonneg(self.level_return_m, d.level_return_m),
            below_floor_m: nonneg(self.below_floor_m, d.below_floor_m),
            surface_gate_sigma: pos(self.surface_gate_sigma, d.surface_gate_sigma),
            surface_gate_min_m: nonneg(self.surface_gate_min_m, d.surface_gate_min_m),
            surface_flat_sigma: pos(self.surface_flat_sigma, d.surface_flat_sigma),
            surface_flat_min_m: nonneg(self.surface_flat_min_m, d.surface_flat_min_m),
            step_sigma: pos(self.step_sigma, d.step_sigma),
            max_transition_samples: self.max_transition_samples.max(1),
            step_settle_samples: self.step_settle_samples,
            tof_period_s: if self.tof_period_s.is_finite() {
                self.tof_period_s.clamp(0.005, 0.5)
            } else {
                d.tof_period_s
            },
            sensor_timeout_s: pos(self.sensor_timeout_s, d.sensor_timeout_s),
            takeoff_grace_s: nonneg(self.takeoff_grace_s, d.takeoff_grace_s),
            flow_required_height_m: nonneg(self.flow_required_height_m, d.flow_required_height_m),
            airborne_height_m: pos(self.airborne_height_m, d.airborne_height_m),
            rest_velocity_std_m_s: pos(self.rest_velocity_std_m_s, d.rest_velocity_std_m_s),
            wall_hold: self.wall_hold,
            wall_std_floor_m: pos(self.wall_std_floor_m, d.wall_std_floor_m),
            wall_std_relative: nonneg(self.wall_std_relative, d.wall_std_relative),
            wall_gate_sigma: pos(self.wall_gate_sigma, d.wall_gate_sigma),
            map_fix: self.map_fix,
            map_fix_gate_sigma: pos(self.map_fix_gate_sigma, d.map_fix_gate_sigma),
            map_fix_jump_m: pos(self.map_fix_jump_m, d.map_fix_jump_m),
            map_fix_jump_agree_m: pos(self.map_fix_jump_agree_m, d.map_fix_jump_agree_m),
            map_fix_heading: self.map_fix_heading,
            map_fix_max_yaw_step_rad: pos(self.map_fix_max_yaw_step_rad, d.map_fix_max_yaw_step_rad),
            rest_accel_std_m_s2: pos(self.rest_accel_std_m_s2, d.rest_accel_std_m_s2),
            initial_std_xy_m: pos(self.initial_std_xy_m, d.initial_std_xy_m),
            initial_std_z_m: pos(self.initial_std_z_m, d.initial_std_z_m),
            initial_std_velocity_m_s: pos(self.initial_std_velocity_m_s, d.initial_std_velocity_m_s),
            initial_std_roll_pitch_rad: pos(self.initial_std_roll_pitch_rad, d.initial_std_roll_pitch_rad),
            initial_std_yaw_rad: pos(self.initial_std_yaw_rad, d.initial_std_yaw_rad),
            initial_std_flow_scale: if self.initial_std_flow_scale.is_finite() {
                self.initial_std_flow_scale.clamp(0.0, FLOW_SCALE_MAX)
            } else {
                d.initial_std_flow_scale
            },
        }
    }

    fn surface_params(&self) -> Params {
        Params {
            step_min: self.step_min_m,
            snap: self.snap_m,
            return_tol: self.level_return_m,
            floor_tol: self.below_floor_m,
            gate_sigma: self.surface_gate_sigma,
            gate_min: self.surface_gate_min_m,
            flat_sigma: self.surface_flat_sigma,
            flat_min: self.surface_flat_min_m,
            step_sigma: self.step_sigma,
            max_transition: self.max_transition_samples,
            max_span_us: (self.tof_period_s * 1e6 * 3.2) as u32,
            settle: self.step_settle_samples,
        }
    }
}

/// What the estimator did, for logs. Counters saturate; ages are capped at 1000 s ("never").
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Diagnostics {
    /// Estimator time (sum of the IMU steps), s.
    pub time_s: f32,
    /// Gyro bias subtracted, rad/s.
    pub gyro_bias_rad_s: [f32; 3],
    /// Accelerometer scale applied.
    pub accel_scale: f32,
    /// Accelerometer offset subtracted (body x, y), m/s²: the level calibration at the first rest.
    pub accel_offset_m_s2: [f32; 2],
    /// See [`Estimator::is_calibrated`].
    pub calibrated: bool,
    /// Flying (`set_flying(true)`) or higher than `airborne_height_m` above the surface.
    pub airborne: bool,
    /// Standard deviations from the covariance: position, m.
    pub position_std_m: [f32; 3],
    /// Velocity, m/s.
    pub velocity_std_m_s: [f32; 3],
    /// Attitude error (body axes), rad.
    pub attitude_std_rad: [f32; 3],
    /// Last flow innovation (measured − predicted), pixels (0.1 counts), x and y.
    pub flow_innovation_px: [f32; 2],
    /// Its squared Mahalanobis distance (both axes).
    pub flow_mahalanobis_sq: f32,
    /// Flow samples fused.
    pub flow_fused: u32,
    /// Dropped: `motion_valid` false or SQUAL below the minimum.
    pub flow_rejected_invalid: u32,
    /// Dropped: |dpixel| at the outlier limit or a bad `dt_s`.
    pub flow_rejected_outlier: u32,
    /// Dropped by the Mahalanobis gate.
    pub flow_rejected_gate: u32,
    /// Not used: not calibrated, on the ground, or too tilted.
    pub flow_unused: u32,
    /// Time since the last usable flow sample, s.
    pub flow_age_s: f32,
    /// Last range's implied surface minus the current surface height, m (the height innovation, sign
    /// flipped; a step shows here first).
    pub tof_innovation_m: f32,
    /// Ranges fused as height updates.
    pub tof_fused: u32,
    /// Dropped: `None`, non-finite, negative or beyond the maximum range.
    pub tof_rejected_range: u32,
    /// Dropped: too tilted.
    pub tof_rejected_tilt: u32,
    /// Ranges inside surface transitions, never fused.
    pub tof_discarded: u32,
    /// Time since the last range that reached a decision (a height update or a classified plateau), s.
    pub tof_age_s: f32,
    /// Surface tracker mode.
    pub surface_mode: SurfaceMode,
    /// Steps attributed to the surface.
    pub surface_steps: u32,
    /// The last step (new − old surface height), m.
    pub last_step_m: f32,
    /// The last classification of a range plateau.
    pub last_surface_event: SurfaceEvent,
    /// IMU samples with a non-finite value (replaced by the last good one).
    pub imu_rejected: u32,
    /// IMU calls with a non-finite or non-positive `dt_s` (ignored).
    pub imu_bad_dt: u32,
    /// Rest updates applied on the ground (10 ms blocks).
    pub rest_updates: u32,
    /// Filter resets by the supervisor (state out of bounds, non-finite).
    pub divergence_resets: u32,
    /// Wall ranges fused (module `wall_hold`).
    pub wall_fused: u32,
    /// Wall ranges rejected by the gate.
    pub wall_rejected: u32,
    /// Map-relative fixes fused (module `map_fix`).
    pub map_fused: u32,
    /// Map-relative fixes rejected by the gate (or by the heading bound, `map_fix_max_yaw_step_rad`).
    pub map_rejected: u32,
    /// Map-relative fixes held back: a jump beyond `map_fix_jump_m` no earlier sweep confirmed.
    pub map_jumps_held: u32,
    /// Map-relative fixes fused with their heading term (against the arena's walls).
    pub map_heading_fused: u32,
    /// Sum of what the map-relative fixes moved the horizontal position (arena x, y), m. Whoever holds
    /// positions recorded in the estimate's frame (the pad search) moves them by this sum's jumps.
    pub map_fix_shift_m: [f32; 2],
    /// The flow's scale error the filter holds (the sensor reads `1 +` this times the model), and its std.
    pub flow_scale_error: f32,
    /// The std of [`Diagnostics::flow_scale_error`].
    pub flow_scale_std: f32,
}

/// The estimator. See the module documentation.
#[derive(Clone, Debug)]
pub struct Estimator {
    cfg: EstimatorConfig,
    // Nominal state.
    pos: V3,
    vel: V3,
    quat: Quat,
    cov: MatN,
    /// The flow's scale error `e` (state `SS`).
    flow_scale: f32,
    // Calibration and IMU processing.
    calibrated: bool,
    calib: Calibrator,
    gyro_bias: V3,
    accel_scale: f32,
    /// The accelerometer's horizontal offset (body x, y; scaled, m/s²), measured at the first rest on the
    /// assumption that the drone stands level (see `on_rest_window`); subtracted from every sample.
    accel_offset_xy: [f32; 2],
    last_gyro: V3,
    last_accel: V3,
    have_imu: bool,
    omega: V3,
    rates_lpf: [ekf_math::Lpf2; 3],
    rates: V3,
    // The current 10 ms covariance block.
    blk_dt: f32,
    blk_f: V3,
    blk_rot: V3,
    blk_rest: bool,
    // Gyro integrated since the previous flow sample.
    flow_rot: V3,
    flow_dt: f32,
    flow_reject_streak: u8,
    /// Per wall direction (axis × side of the normal): the innovation of the last map fix that implied a
    /// jump beyond `map_fix_jump_m` and was held back, and the sweep it came in (see `on_map_fixes`).
    /// (In millimetres, [`NO_JUMP`] for none, and the sweep's number: 12 bytes.)
    map_jump_mm: [i16; 4],
    map_jump_sweep: [u8; 4],
    /// Map-fix sweeps received.
    map_sweeps: u8,
    walls: WallHold,
    surface: SurfaceTracker,
    // Time and health.
    now_us: u64,
    last_flow_us: Option<u64>,
    /// The last sane range (for the tracker's ring).
    last_range_us: Option<u64>,
    /// The last range that reached a decision (a height update or a classified plateau): "range fresh".
    last_tof_us: Option<u64>,
    airborne_since_us: u64,
    flying_cmd: bool,
    airborne: bool,
    samples_without_imu: u16,
    /// The last sane IMU step, s (used for a sample whose `dt_s` is not).
    last_dt: f32,
    bad_imu_streak: u32,
    last_reset_us: Option<u64>,
    // The pose of the last reset (used when calibration completes) and the last sane state.
    home_pos: V3,
    home_yaw: f32,
    sane_pos: V3,
    sane_quat: Quat,
    diag: Diagnostics,
}

impl Estimator {
    /// A new estimator at the origin, yaw 0, not calibrated (call [`Self::reset`] with the start pose).
    pub fn new(config: EstimatorConfig) -> Self {
        let cfg = config.sanitized();
        let lpf = ekf_math::Lpf2::new(IMU_RATE_HZ, GYRO_LPF_HZ);
        let mut e = Self {
            cfg,
            pos: [0.0; 3],
            vel: [0.0; 3],
            quat: QUAT_IDENTITY,
            cov: [[0.0; N]; N],
            flow_scale: 0.0,
            calibrated: false,
            calib: Calibrator::new(),
            gyro_bias: [0.0; 3],
            accel_scale: 1.0,
            accel_offset_xy: [0.0; 2],
            last_gyro: [0.0; 3],
            last_accel: [0.0, 0.0, GRAVITY_M_S2],
            have_imu: false,
            omega: [0.0; 3],
            rates_lpf: [lpf; 3],
            rates: [0.0; 3],
            blk_dt: 0.0,
            blk_f: [0.0; 3],
            blk_rot: [0.0; 3],
            blk_rest: true,
            flow_rot: [0.0; 3],
            flow_dt: 0.0,
            flow_reject_streak: 0,
            map_jump_mm: [NO_JUMP; 4],
            map_jump_sweep: [0; 4],
            map_sweeps: 0,
            walls: WallHold::default(),
            surface: SurfaceTracker::new(0.0),
            now_us: 0,
            last_flow_us: None,
            last_range_us: None,
            last_tof_us: None,
            airborne_since_us: 0,
            flying_cmd: false,
            airborne: false,
            samples_without_imu: 0,
            last_dt: 1.0 / IMU_RATE_HZ,
            bad_imu_streak: 0,
            last_reset_us: None,
            home_pos: [0.0; 3],
            home_yaw: 0.0,
            sane_pos: [0.0; 3],
            sane_quat: QUAT_IDENTITY,
            diag: Diagnostics {
                accel_scale: 1.0,
                ..Diagnostics::default()
            },
        };
        e.reset([0.0; 3], 0.0);
        e
    }

    /// The configuration in use (sanitised).
    pub fn config(&self) -> &EstimatorConfig {
        &self.cfg
    }

    /// A new flow measurement std, counts (the `motion.flowStdFixed` parameter), used from the next flow
    /// sample; a value that is not finite and positive is ignored.
    pub fn set_flow_std(&mut self, counts: f32) {
        if counts.is_finite() && counts > 0.0 {
            self.cfg.flow_std_counts = counts;
        }
    }

    /// Start over at a known pose: the drone standing on its pad at `position_m` (z = the pad's top, or 0
    /// on the floor) with heading `yaw_rad`. Velocity 0, roll and pitch kept (from the accelerometer once
    /// calibrated), covariance initial, surface height = `position_m[2]`; the gyro calibration is kept.
    /// `valid` needs a new range after this. Non-finite arguments are replaced by 0.
    pub fn reset(&mut self, position_m: [f32; 3], yaw_rad: f32) {
        let fin = |v: f32| if v.is_finite() { v } else { 0.0 };
        self.home_pos = [fin(position_m[0]), fin(position_m[1]), fin(position_m[2])];
        self.home_yaw = fin(yaw_rad);
        let (roll, pitch) = if self.calibrated {
            let e = euler_from_rot(&quat_to_rot(self.quat));
            (e[0], e[1])
        } else {
            (0.0, 0.0)
        };
        self.pos = self.home_pos;
        self.vel = [0.0; 3];
        self.quat = quat_from_euler(roll, pitch, self.home_yaw);
        self.cov = self.initial_covariance();
        self.flow_scale = 0.0;
        self.surface.reset(self.home_pos[2]);
        self.clear_blocks();
        self.flow_reject_streak = 0;
        self.map_jump_mm = [NO_JUMP; 4];
        self.walls.clear();
        self.last_flow_us = None;
        self.last_range_us = None;
        self.last_tof_us = None;
        self.last_reset_us = None;
        self.sane_pos = self.pos;
        self.sane_quat = self.quat;
        self.update_airborne();
    }

    /// Tell the estimator whether the motors are lifting the drone (stock `quadIsFlying`): `true` from the
    /// moment thrust is applied for take-off, `false` once landed and the motors stop. On the ground and at
    /// rest the estimator applies zero-velocity and gravity updates and refines the gyro bias; those must
    /// stop the instant the drone lifts off. (Above `airborne_height_m` it counts as airborne anyway.)
    pub fn set_flying(&mut self, flying: bool) {
        self.flying_cmd = flying;
        self.update_airborne();
    }

    /// Whether the gyro bias has been measured at rest (≥ 0.512 s still after power-up). Nothing is
    /// estimated before.
    pub fn is_calibrated(&self) -> bool {
        self.calibrated
    }

    /// The current estimate.
    pub fn state(&self) -> StateEstimate {
        let att = euler_from_rot(&quat_to_rot(self.quat));
        StateEstimate {
            position_m: self.pos,
            velocity_m_s: self.vel,
            attitude_rad: att,
            rates_rad_s: self.rates,
            surface_height_m: self.surface.surface(),
            valid: self.is_valid(),
        }
    }

    /// [`Diagnostics::map_fix_shift_m`] alone (read at every step, without copying the diagnostics).
    pub fn map_fix_shift_m(&self) -> [f32; 2] {
        self.diag.map_fix_shift_m
    }

    /// Counters, innovations and health for logs.
    pub fn diagnostics(&self) -> Diagnostics {
        let mut d = self.diag;
        d.time_s = self.now_us as f32 * 1e-6;
        d.gyro_bias_rad_s = self.gyro_bias;
        d.accel_scale = self.accel_scale;
        d.accel_offset_m_s2 = self.accel_offset_xy;
        d.calibrated = self.calibrated;
        d.airborne = self.airborne;
        for i in 0..3 {
            d.position_std_m[i] = libm::sqrtf(self.cov[i][i].max(0.0));
            d.velocity_std_m_s[i] = libm::sqrtf(self.cov[SV + i][SV + i].max(0.0));
            d.attitude_std_rad[i] = libm::sqrtf(self.cov[SD + i][SD + i].max(0.0));
        }
        d.flow_scale_error = self.flow_scale;
        d.flow_scale_std = libm::sqrtf(self.cov[SS][SS].max(0.0));
        d.flow_age_s = self.age_s(self.last_flow_us);
        d.tof_age_s = self.age_s(self.last_tof_us);
        d.surface_mode = self.surface.mode();
        d.surface_steps = self.surface.steps;
        d.last_step_m = self.surface.last_step_m;
        d.last_surface_event = self.surface.last_event;
        d
    }

    fn age_s(&self, t: Option<u64>) -> f32 {
        match t {
            Some(t) => (self.now_us.saturating_sub(t) as f32 * 1e-6).min(1000.0),
            None => 1000.0,
        }
    }

    fn is_valid(&self) -> bool {
        if !(self.calibrated && self.last_tof_us.is_some()) {
            return false;
        }
        if self.samples_without_imu > MAX_SAMPLES_WITHOUT_IMU || self.bad_imu_streak > MAX_BAD_IMU_STREAK {
            return false;
        }
        if !self.state_in_bounds() {
            return false;
        }
        if let Some(reset) = self.last_reset_us {
            let after = |t: Option<u64>| t.is_some_and(|t| t > reset);
            if !after(self.last_tof_us) || (self.airborne && !after(self.last_flow_us)) {
                return false;
            }
        }
        if self.airborne {
            // Each sensor's clock starts at take-off plus the grace period.
            let grace_us = (self.cfg.takeoff_grace_s * 1e6) as u64;
            let start = self.airborne_since_us.saturating_add(grace_us);
            let timeout_us = (self.cfg.sensor_timeout_s * 1e6) as u64;
            let fresh = |t: Option<u64>| self.now_us.saturating_sub(t.unwrap_or(0).max(start)) <= timeout_us;
            // Ranges arriving, and the height not coasting on the IMU alone for more than twice as long (a
            // slowly crossed edge keeps the surface tracker undecided for up to ~1 s).
            let decided = self.now_us.saturating_sub(self.last_tof_us.unwrap_or(0).max(start)) <= 2 * timeout_us;
            let flow_needed = self.pos[SZ] - self.surface.surface() > self.cfg.flow_required_height_m;
            if !fresh(self.last_range_us) || !decided || (flow_needed && !fresh(self.last_flow_us)) {
                return false;
            }
        }
        true
    }

    fn state_in_bounds(&self) -> bool {
        finite3(self.pos)
            && finite3(self.vel)
            && self.quat.iter().all(|q| q.is_finite())
            && self.pos.iter().all(|p| p.abs() <= MAX_POSITION_M)
            && self.vel.iter().all(|v| v.abs() <= MAX_VELOCITY_M_S)
    }

    fn update_airborne(&mut self) {
        let above = self.calibrated && self.pos[SZ] - self.surface.surface() > self.cfg.airborne_height_m;
        let airborne = self.flying_cmd || above;
        if airborne && !self.airborne {
            self.airborne_since_us = self.now_us;
            self.calib.restart();
        }
        self.airborne = airborne;
    }

    /// The covariance at a reset on the pad (the configured initial std's).
    fn initial_covariance(&self) -> MatN {
        let c = &self.cfg;
        diagonal([
            c.initial_std_xy_m,
            c.initial_std_xy_m,
            c.initial_std_z_m,
            c.initial_std_velocity_m_s,
            c.initial_std_velocity_m_s,
            c.initial_std_velocity_m_s,
            c.initial_std_roll_pitch_rad,
            c.initial_std_roll_pitch_rad,
            c.initial_std_yaw_rad,
            c.initial_std_flow_scale,
        ])
    }

    fn clear_blocks(&mut self) {
        self.blk_dt = 0.0;
        self.blk_f = [0.0; 3];
        self.blk_rot = [0.0; 3];
        self.blk_rest = true;
        self.flow_rot = [0.0; 3];
        self.flow_dt = 0.0;
    }

    /// Stock kalman_supervisor: a state out of bounds or anything non-finite resets the filter.
    fn supervise(&mut self, check_covariance: bool) {
        let cov_ok = !check_covariance || self.cov.iter().all(|row| row.iter().all(|x| x.is_finite()));
        if self.state_in_bounds() && cov_ok {
            self.sane_pos = self.pos;
            self.sane_quat = self.quat;
            return;
        }
        self.diag.divergence_resets = self.diag.divergence_resets.saturating_add(1);
        self.last_reset_us = Some(self.now_us);
        if !self.state_in_bounds() {
            self.pos = self.sane_pos;
            self.vel = [0.0; 3];
            if !self.quat.iter().all(|q| q.is_finite()) {
                self.quat = self.sane_quat;
            }
        }
        self.quat = quat_normalize(self.quat);
        // Unlike a reset on the pad, nothing is known well after a divergence: wide enough for the flow and
        // the range to pull the state back (with the pad's 1 cm/s, a wrong velocity would stay).
        self.cov = diagonal(DIVERGENCE_STD);
        // Whatever diverged may have dragged the scale along: start it over too.
        self.flow_scale = 0.0;
        self.surface.clear();
        self.clear_blocks();
    }
}

/// A covariance with these standard deviations on the diagonal (bounded as always).
fn diagonal(std: [f32; N]) -> MatN {
    let mut p = [[0.0; N]; N];
    for (i, row) in p.iter_mut().enumerate() {
        row[i] = sq(std[i]).clamp(COVARIANCE_MIN, COVARIANCE_MAX);
    }
    p
}

fn sq(x: f32) -> f32 {
    x * x
}

fn dot_n(a: &VecN, b: &VecN) -> f32 {
    a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
}
