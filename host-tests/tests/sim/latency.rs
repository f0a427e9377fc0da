//! The rangers' latency (`cfnav::stack::{ZRANGE_MIDPOINT_US, BEAM_MIDPOINT_US}`): the simulator hands a
//! VL53L1x reading over half a timing budget after it measured the scene, as the chip does, and the flight
//! stack maps and casts its map fixes from the pose the reading was taken at. Judged on the simulator's
//! truth: while cruising, the estimate's error along the direction of travel.

use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{RunOptions, run};

/// The mean and the RMS of the estimate's error along the true direction of travel while cruising
/// (≥ 0.3 m/s, navigation states 11 and 21), m, over one default-world mission.
fn along_track_error(seed: u64) -> (f64, f64) {
    let world = World::default_world();
    let mut options = RunOptions::for_world(&world);
    options.seed = seed;
    options.record = true;
    let r = run(&world, &options).expect("runs");
    assert_eq!(r.report.outcome, "completed", "seed {seed}: {:?}", r.report);
    let (mut sum, mut sum_sq, mut n) = (0.0, 0.0, 0.0);
    for w in r.trace.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let dt = b.t_s - a.t_s;
        if !(matches!(b.state, 11 | 21) && dt > 0.0) {
            continue;
        }
        let v = [
            f64::from(b.truth[0] - a.truth[0]) / dt,
            f64::from(b.truth[1] - a.truth[1]) / dt,
        ];
        let speed = v[0].hypot(v[1]);
        if speed < 0.3 {
            continue;
        }
        let e = [
            f64::from(b.estimate[0] - b.truth[0]),
            f64::from(b.estimate[1] - b.truth[1]),
        ];
        let along = (e[0] * v[0] + e[1] * v[1]) / speed;
        sum += along;
        sum_sq += along * along;
        n += 1.0;
    }
    assert!(n > 100.0, "seed {seed}: {n} cruising samples");
    (sum / n, (sum_sq / n).sqrt())
}

/// Mapped and cast from the current pose, a beam's return lies half a budget's travel (1.25 cm at 0.5 m/s)
/// ahead of where the wall is, and every sweep's map fixes pull the estimate back by as much: the estimate
/// trails the truth. Measured over seeds 1–4 without the backdating: mean along-track error −6.7, −5.8,
/// −10.5 and −0.7 mm (RMS 11–21 mm); with it: +1.8, −1.1, −1.0, −1.3 mm (RMS 8–11 mm).
/// One seed's mean moves by a few millimetres with the path flown (a change to the
/// surface tracker alone moved seed 2 by 2.5 mm), so the test judges
/// the average over seeds 1–8 (within ±3 mm; the trailing code's seeds 1–4 average −5.9 mm) and, per seed,
/// only trailing (no seed's mean below −4 mm).
#[test]
fn the_estimate_does_not_trail_the_truth_while_cruising() {
    let mut means = Vec::new();
    for seed in 1..=8 {
        let (mean, rms) = along_track_error(seed);
        println!(
            "seed {seed}: along-track error mean {:.1} mm, RMS {:.1} mm",
            mean * 1e3,
            rms * 1e3
        );
        assert!(
            mean > -0.004,
            "seed {seed}: the estimate trails the truth by {:.1} mm on average",
            -mean * 1e3
        );
        means.push(mean);
    }
    let average = means.iter().sum::<f64>() / means.len() as f64;
    println!("average over seeds 1–8: {:.1} mm", average * 1e3);
    assert!(
        average.abs() < 0.003,
        "average along-track error {:.1} mm",
        average * 1e3
    );
}
