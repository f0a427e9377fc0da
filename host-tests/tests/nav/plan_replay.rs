//! `cfnav plan`'s replay against the Dijkstra oracle on every example map and on random maps.

use cfnav::nav::map::Cell;
use cfnav_tools::nav::replay::{ReplayMap, replay};
use host_tests::oracle::{VecMap, dijkstra};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn layer(map: &ReplayMap, blocked: impl Fn(Cell) -> bool) -> VecMap {
    let mut m = VecMap::new(map.width, map.height);
    for c in m.cells().collect::<Vec<_>>() {
        m.set(c, blocked(c));
    }
    m
}

/// The replay reaches the goal exactly when the true map has a path (unknown cells are assumed free,
/// so the drone learns every wall that matters); its first plan costs what Dijkstra says on the initial
/// belief; the cost flown is the sum of its moves and never beats the true optimum.
fn check(map: ReplayMap, radius: u16, name: &str) {
    let truth = layer(&map, |c| map.is_obstacle(c));
    let belief = layer(&map, |c| map.is_believed_blocked(c));
    let (start, goal) = (map.start, map.goal);
    let report = replay(map, radius).expect("replay");
    let best_true = dijkstra(&truth, start, goal);
    assert_eq!(
        report.status == "reached",
        best_true.is_some(),
        "{name}: status {}",
        report.status
    );
    let first = &report.steps[0];
    assert_eq!((first.x, first.y), (start.x, start.y), "{name}");
    // The first plan is made after the first sense, which may already reveal cells near the start.
    if first.changed == 0 {
        assert_eq!(first.cost, dijkstra(&belief, start, goal), "{name}: first plan");
    }
    assert_eq!(
        report.steps.len(),
        report.moves as usize + 1,
        "{name}: one step per move plus the first"
    );
    if let Some(best) = best_true {
        assert!(
            report.path_cost >= best,
            "{name}: flew {} < optimum {best}",
            report.path_cost
        );
        let last = report.steps.last().unwrap();
        assert_eq!((last.x, last.y, last.cost), (goal.x, goal.y, Some(0)), "{name}");
    } else {
        assert_eq!(report.steps.last().unwrap().cost, None, "{name}");
    }
    for pair in report.steps.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        assert!(
            a.x.abs_diff(b.x) <= 1 && a.y.abs_diff(b.y) <= 1,
            "{name}: one cell per move"
        );
    }
}

#[test]
fn example_maps() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../maps");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "map") {
            let text = std::fs::read_to_string(&path).unwrap();
            let map = ReplayMap::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            check(map, 2, &path.display().to_string());
            n += 1;
        }
    }
    assert!(n >= 5, "example maps found: {n}");
}

#[test]
fn random_maps() {
    for seed in 0..300u64 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let (w, h) = (rng.random_range(3..40usize), rng.random_range(3..30usize));
        let mut rows: Vec<Vec<char>> = (0..h)
            .map(|_| {
                (0..w)
                    .map(|_| match rng.random_range(0..100) {
                        0..12 => 'o',
                        12..18 => '#',
                        _ => '.',
                    })
                    .collect()
            })
            .collect();
        rows[rng.random_range(0..h)][rng.random_range(0..w)] = 'S';
        loop {
            let (r, c) = (rng.random_range(0..h), rng.random_range(0..w));
            if rows[r][c] != 'S' {
                rows[r][c] = 'G';
                break;
            }
        }
        let text: String = rows.iter().map(|r| r.iter().collect::<String>() + "\n").collect();
        let map = ReplayMap::parse(&text).unwrap();
        check(map, rng.random_range(1..4), &format!("seed {seed}"));
    }
}

#[test]
fn malformed_maps_are_refused_with_the_line() {
    let cases = [
        ("", "no rows"),
        ("S..\n..G\n.x.\n", "line 3"),
        ("S..\n..\n..G\n", "line 2"),
        ("...\n..G\n", "no start"),
        ("S..\n...\n", "no goal"),
        ("S.S\n..G\n", "second start"),
        ("; only a comment\n", "no rows"),
    ];
    for (text, want) in cases {
        let err = ReplayMap::parse(text).expect_err(text).to_string();
        assert!(err.contains(want), "{text:?}: {err}");
    }
    let huge = format!("S{}\n{}G\n", ".".repeat(199), ".".repeat(199));
    let big: String = std::iter::repeat_n(huge.as_str(), 50).collect();
    assert!(ReplayMap::parse(&big).unwrap_err().to_string().contains("at most"));
}
