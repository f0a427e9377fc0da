//! The control step's input gate: at most one costly input per step, the next one a step later, order kept,
//! nothing lost, on the sensors' real schedules.

use cfnav::system::step_pacing::HeavyInputGate;

/// Drains `queue` as the firmware's control task does; returns what one step applied.
fn step(gate: &mut HeavyInputGate<(char, u32)>, queue: &mut Vec<(char, u32)>) -> Vec<(char, u32)> {
    let mut applied = Vec::new();
    if let Some(i) = gate.begin_step() {
        applied.push(i);
    }
    while !gate.holding() && !queue.is_empty() {
        let i = queue.remove(0);
        let heavy = matches!(i.0, 'F' | 'M');
        if let Some(i) = gate.admit(i, heavy) {
            applied.push(i);
        }
    }
    applied
}

#[test]
fn a_second_costly_input_waits_one_step_and_order_is_kept() {
    let mut gate = HeavyInputGate::new();
    // Flow, height, Multi-ranger, battery all arrive before step 0.
    let mut queue = vec![('F', 0), ('Z', 0), ('M', 0), ('B', 0)];
    assert_eq!(step(&mut gate, &mut queue), [('F', 0), ('Z', 0)]);
    assert!(gate.holding());
    assert_eq!(queue, [('B', 0)]);
    assert_eq!(step(&mut gate, &mut queue), [('M', 0), ('B', 0)]);
    assert!(!gate.holding());
    // A lone costly input goes through at once; cheap ones never wait.
    let mut queue = vec![('Z', 2), ('M', 2), ('B', 2), ('Z', 2)];
    assert_eq!(step(&mut gate, &mut queue), [('Z', 2), ('M', 2), ('B', 2), ('Z', 2)]);
    assert_eq!(step(&mut gate, &mut Vec::new()), []);
}

#[test]
fn on_the_sensor_schedules_every_input_arrives_at_most_one_step_late() {
    let mut gate = HeavyInputGate::new();
    let mut queue = Vec::new();
    let mut arrived = 0;
    let mut applied_all = Vec::new();
    for k in 0..10_000u32 {
        // Flow and battery at 100 Hz, height at 40 Hz, Multi-ranger at 10 Hz, all aligned every 100 ms.
        for (due, kind) in [
            (k % 10 == 0, 'F'),
            (k % 25 == 0, 'Z'),
            (k % 100 == 0, 'M'),
            (k % 10 == 0, 'B'),
        ] {
            if due {
                queue.push((kind, k));
                arrived += 1;
            }
        }
        let applied = step(&mut gate, &mut queue);
        assert!(
            applied.iter().filter(|i| matches!(i.0, 'F' | 'M')).count() <= 1,
            "step {k}: {applied:?}"
        );
        for &(kind, at) in &applied {
            assert!(k - at <= 1, "{kind} from step {at} applied at {k}");
        }
        applied_all.extend(applied);
    }
    applied_all.extend(step(&mut gate, &mut queue));
    assert_eq!(applied_all.len(), arrived);
    // Order within each kind is kept.
    for kind in ['F', 'Z', 'M', 'B'] {
        let at: Vec<u32> = applied_all.iter().filter(|i| i.0 == kind).map(|i| i.1).collect();
        assert!(at.windows(2).all(|w| w[0] < w[1]), "{kind}");
    }
}
