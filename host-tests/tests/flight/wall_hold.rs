//! The estimator's wall anchors (`cfnav::flight::estimator::wall_hold`): the range each anchored beam expects after
//! a movement, checked against ray distances to the walls of a rectangular room (an independent oracle),
//! and the rules for anchoring, turning, oblique headings, outliers and bad input.

use cfnav::flight::estimator::wall_hold::{MAX_RANGE_M, REANCHOR_AFTER_OUTLIERS, WallHold};
use proptest::prelude::*;

/// A room `[0, w] × [0, h]`: the distance from `p` along the horizontal direction at `angle` to the first
/// wall (ray–box exit distance).
fn ray_to_walls(p: [f32; 2], angle: f32, room: [f32; 2]) -> f32 {
    let d = [angle.cos(), angle.sin()];
    let mut best = f32::INFINITY;
    for axis in 0..2 {
        if d[axis].abs() < 1e-6 {
            continue;
        }
        let wall = if d[axis] > 0.0 { room[axis] } else { 0.0 };
        best = best.min((wall - p[axis]) / d[axis]);
    }
    best
}

/// The four beams' ranges (front, back, left, right) at `p` with heading `yaw`, `None` beyond 4 m.
fn beams(p: [f32; 2], yaw: f32, room: [f32; 2]) -> [Option<f32>; 4] {
    use std::f32::consts::{FRAC_PI_2, PI};
    [0.0, PI, FRAC_PI_2, -FRAC_PI_2].map(|offset| Some(ray_to_walls(p, yaw + offset, room)).filter(|r| *r <= 4.0))
}

#[test]
fn the_first_reading_anchors_and_the_next_is_fused() {
    let room = [2.0, 1.8];
    let mut hold = WallHold::default();
    let p0 = [0.6, 1.0];
    let first = hold.begin(beams(p0, 0.0, room), 0.0, p0);
    assert!(
        first.iter().all(Option::is_none),
        "nothing to fuse against yet: {first:?}"
    );
    let second = hold.begin(beams(p0, 0.0, room), 0.0, p0);
    // Front 1.4 m, back 0.6 m, left 0.8 m, right 1.0 m: all within the anchoring range.
    assert!(second.iter().all(Option::is_some), "{second:?}");
}

proptest! {
    /// Square to the walls (any multiple of 90°, within the axis tolerance) the expected range after any
    /// small movement is the ray distance from the new position, within the error a heading a few degrees
    /// off square makes.
    #[test]
    fn expected_ranges_match_the_walls(
        x in 0.8f32..1.6,
        y in 0.8f32..1.4,
        quarter in 0i32..4,
        yaw_offset in -0.03f32..0.03,
        dx in -0.1f32..0.1,
        dy in -0.1f32..0.1,
    ) {
        let room = [2.4, 2.2];
        let yaw = quarter as f32 * std::f32::consts::FRAC_PI_2 + yaw_offset;
        let p0 = [x, y];
        let mut hold = WallHold::default();
        hold.begin(beams(p0, yaw, room), yaw, p0);
        let p1 = [x + dx, y + dy];
        let now = beams(p1, yaw, room);
        let anchors = hold.begin(now, yaw, p1);
        for (beam, anchor) in anchors.iter().enumerate() {
            let (Some(anchor), Some(truth)) = (anchor, now[beam]) else {
                // Only beams beyond the anchoring range have no anchor.
                prop_assert!(now[beam].is_none_or(|r| r > MAX_RANGE_M), "beam {beam}: {:?}", now[beam]);
                continue;
            };
            let expected = anchor.expected_range_m(p1);
            // A heading ε off square stretches a range r by r·(1/cos ε − 1) ≤ 2.2 m · 0.00045 and turns a
            // 0.14 m movement by ε: about 5 mm at most.
            prop_assert!((expected - truth).abs() < 0.005, "beam {beam}: expected {expected}, truth {truth}");
        }
    }
}

#[test]
fn a_turn_re_anchors_every_beam() {
    let room = [2.0, 2.0];
    let p = [1.0, 1.0];
    let mut hold = WallHold::default();
    hold.begin(beams(p, 0.0, room), 0.0, p);
    assert!(
        hold.begin(beams(p, 0.05, room), 0.05, p).iter().all(Option::is_some),
        "3° is not a turn"
    );
    let after_turn = hold.begin(beams(p, 0.12, room), 0.12, p);
    assert!(after_turn.iter().all(Option::is_none), "7° re-anchors: {after_turn:?}");
    assert!(hold.begin(beams(p, 0.12, room), 0.12, p).iter().all(Option::is_some));
}

#[test]
fn oblique_headings_are_not_anchored() {
    let room = [2.0, 2.0];
    let p = [1.0, 1.0];
    let mut hold = WallHold::default();
    for yaw in [0.5f32, std::f32::consts::FRAC_PI_4, -2.3] {
        for _ in 0..3 {
            let fused = hold.begin(beams(p, yaw, room), yaw, p);
            assert!(fused.iter().all(Option::is_none), "yaw {yaw}: {fused:?}");
        }
    }
    // Square again: anchored by the first reading, fused from the second.
    hold.begin(beams(p, 0.2, room), 0.2, p);
    assert!(hold.begin(beams(p, 0.2, room), 0.2, p).iter().all(Option::is_some));
}

#[test]
fn readings_out_of_range_are_not_anchored_and_a_gap_keeps_the_anchor() {
    let mut hold = WallHold::default();
    let p = [1.0, 1.0];
    hold.begin([Some(3.0), Some(0.01), None, Some(f32::NAN)], 0.0, p);
    let fused = hold.begin([Some(3.0), Some(0.01), None, Some(f32::NAN)], 0.0, p);
    assert!(fused.iter().all(Option::is_none), "{fused:?}");
    hold.begin([Some(1.0), None, None, None], 0.0, p);
    // A missing reading neither fuses nor drops the anchor.
    assert!(hold.begin([None, None, None, None], 0.0, p)[0].is_none());
    let back = hold.begin([Some(1.01), None, None, None], 0.0, p);
    assert_eq!(back[0].map(|a| a.range0_m), Some(1.0));
}

#[test]
fn repeated_outliers_re_anchor_the_beam_at_its_new_reading() {
    let mut hold = WallHold::default();
    let p = [1.0, 1.0];
    hold.begin([Some(1.5), None, None, None], 0.0, p);
    // A box comes into the beam 0.7 m away.
    for k in 1..=REANCHOR_AFTER_OUTLIERS {
        let fused = hold.begin([Some(0.7), None, None, None], 0.0, p);
        assert_eq!(fused[0].map(|a| a.range0_m), Some(1.5), "outlier {k}");
        hold.rejected(0, 0.7, p);
    }
    let fused = hold.begin([Some(0.7), None, None, None], 0.0, p);
    assert_eq!(fused[0].map(|a| a.range0_m), Some(0.7));
    // An accepted reading resets the count: two more outliers do not re-anchor.
    hold.accepted(0);
    hold.rejected(0, 1.2, p);
    hold.rejected(0, 1.2, p);
    hold.accepted(0);
    hold.rejected(0, 1.2, p);
    let fused = hold.begin([Some(0.7), None, None, None], 0.0, p);
    assert_eq!(fused[0].map(|a| a.range0_m), Some(0.7));
}

#[test]
fn bad_input_clears_the_anchors_without_panicking() {
    let mut hold = WallHold::default();
    let p = [1.0, 1.0];
    hold.begin([Some(1.0); 4], 0.0, p);
    assert!(hold.begin([Some(1.0); 4], f32::NAN, p).iter().all(Option::is_none));
    assert!(
        hold.begin([Some(1.0); 4], 0.0, [f32::INFINITY, 0.0])
            .iter()
            .all(Option::is_none)
    );
    // Cleared: the next good reading anchors afresh.
    assert!(hold.begin([Some(1.0); 4], 0.0, p).iter().all(Option::is_none));
    assert!(hold.begin([Some(1.0); 4], 0.0, p).iter().all(Option::is_some));
    hold.rejected(9, 1.0, p);
    hold.accepted(9);
}
