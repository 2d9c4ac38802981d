//! The benchmark's metrics on hand-made steps, with values worked out by hand:
//! unique states, novel-state ratio, single action effect, normalised distance
//! and success, under the paper's and the strict protocol.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests and benchmarks fail by panicking"
)]
use umpnet_eval::Protocol;
use umpnet_eval::episode::{Metrics, Scoring, score};
use umpnet_sim::env::DELTA;
use umpnet_sim::scene::Task;

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-5
}

fn assert_metrics(m: &Metrics, unique: &[f32], ratio: f32, effect: f32) {
    assert_eq!(m.unique_states, unique, "{m:?}");
    assert!(
        close(m.novel_state_ratio, ratio),
        "ratio {} vs {ratio}",
        m.novel_state_ratio
    );
    assert!(
        close(m.single_action_effect, effect),
        "effect {} vs {effect}",
        m.single_action_effect
    );
}

const DOOR: Scoring = Scoring::Exploration {
    start: 0.0,
    scale: 1.0,
};
// Out, further, back, and further than before: (joint after, |Δ joint|).
const STEPS: [(f32, f32); 4] = [(0.13, 0.13), (0.26, 0.13), (0.13, 0.13), (0.30, 0.17)];

#[test]
fn delta_is_the_papers() {
    assert_eq!(DELTA, 0.15);
}

#[test]
fn exploration_under_the_paper_protocol() {
    // Walk 0.13, 0.26, 0.13, 0.30; sorted greedy count over "more than δ":
    // 0.13 counts, 0.26 is 0.13 above it (no), 0.30 is 0.17 above (yes).
    let m = score(DOOR, &STEPS, 4, Protocol::Paper, false);
    assert_metrics(&m, &[1.0, 1.0, 1.0, 2.0], 2.0 / 4.0, 0.56 / DELTA / 4.0);
}

#[test]
fn exploration_under_the_strict_protocol() {
    // Against the start and every counted state, "at least δ": only 0.26 counts.
    let m = score(DOOR, &STEPS, 4, Protocol::Strict, false);
    assert_metrics(&m, &[0.0, 1.0, 1.0, 1.0], 1.0 / 4.0, 0.56 / DELTA / 4.0);
}

#[test]
fn an_episode_the_protocol_ended_is_scored_on_its_steps_only() {
    // The paper ends at a limit after 2 of 6 steps: the ratio is over 2 steps,
    // and the curve stays at its last value.
    let m = score(DOOR, &[(0.2, 0.2), (0.4, 0.2)], 6, Protocol::Paper, true);
    assert_metrics(&m, &[1.0, 2.0, 2.0, 2.0, 2.0, 2.0], 1.0, 0.4 / DELTA / 2.0);
}

#[test]
fn a_policy_that_stops_early_is_scored_on_the_whole_budget() {
    let m = score(DOOR, &[(0.2, 0.2)], 3, Protocol::Paper, false);
    assert_metrics(&m, &[1.0, 1.0, 1.0], 1.0 / 3.0, 0.2 / DELTA / 3.0);
}

#[test]
fn prismatic_walks_are_divided_by_the_object_scale() {
    // 0.1 m steps on an object scaled by 0.5 walk 0.2 and 0.4: two states more
    // than δ apart. Unscaled (0.1, 0.2) they would be one. The action effect is unscaled.
    let steps = [(0.1, 0.1), (0.2, 0.1)];
    let drawer = Scoring::Exploration {
        start: 0.0,
        scale: 0.5,
    };
    let m = score(drawer, &steps, 2, Protocol::Paper, false);
    assert_metrics(&m, &[1.0, 2.0], 1.0, 0.2 / DELTA / 2.0);
    let m = score(DOOR, &steps, 2, Protocol::Paper, false);
    assert_metrics(&m, &[1.0, 1.0], 0.5, 0.2 / DELTA / 2.0);
}

#[test]
fn goal_distance_and_success() {
    let goal = Scoring::Goal {
        init: 0.0,
        target: 1.0,
        now: 0.95,
    };
    let m = score(
        goal,
        &[(0.3, 0.3), (0.6, 0.3), (0.95, 0.35)],
        3,
        Protocol::Paper,
        false,
    );
    let curve = [0.7, 0.4, 0.05];
    assert!(
        m.normalized_distance_curve
            .iter()
            .zip(curve)
            .all(|(a, b)| close(*a, b)),
        "{m:?}"
    );
    assert!(close(m.normalized_distance, 0.05) && m.success);
    // Ended by the protocol (the goal reached): distance 0 from that step on.
    let goal = Scoring::Goal {
        init: 0.0,
        target: 1.0,
        now: 0.92,
    };
    let m = score(goal, &[(0.5, 0.5), (0.92, 0.42)], 4, Protocol::Paper, true);
    assert_eq!(m.normalized_distance_curve, [0.5, 0.0, 0.0, 0.0]);
    assert!(m.normalized_distance == 0.0 && m.success);
    // Not reached: the distance is where the joint is now, relative to the way.
    let goal = Scoring::Goal {
        init: 0.2,
        target: -0.3,
        now: 0.0,
    };
    let m = score(goal, &[(0.0, 0.2)], 2, Protocol::Strict, false);
    assert!(
        m.normalized_distance_curve.iter().all(|d| close(*d, 0.6)),
        "{m:?}"
    );
    assert!(close(m.normalized_distance, 0.6) && !m.success);
    // Success is "below 0.1" of the way, strictly (9 of 10 is exactly 0.1).
    let m = score(
        Scoring::Goal {
            init: 0.0,
            target: 10.0,
            now: 9.0,
        },
        &[],
        1,
        Protocol::Paper,
        false,
    );
    assert!(m.normalized_distance == 0.1 && !m.success);
    for (now, success) in [(0.91, true), (0.89, false)] {
        let m = score(
            Scoring::Goal {
                init: 0.0,
                target: 1.0,
                now,
            },
            &[],
            1,
            Protocol::Paper,
            false,
        );
        assert_eq!(m.success, success, "{now}");
    }
}

#[test]
fn missing_the_part_scores_worst() {
    let m = score(
        Scoring::Missed(Task::Exploration),
        &[],
        5,
        Protocol::Paper,
        false,
    );
    assert_metrics(&m, &[0.0; 5], 0.0, 0.0);
    let m = score(Scoring::Missed(Task::Goal), &[], 3, Protocol::Paper, false);
    assert_eq!(m.normalized_distance_curve, [1.0; 3]);
    assert!(m.normalized_distance == 1.0 && !m.success);
}

fn step(direction: [f32; 3], at: [f32; 3], moved: bool) -> umpnet_eval::episode::Step {
    umpnet_eval::episode::Step {
        record: umpnet_eval::policy::StepRecord {
            direction,
            labels: umpnet_sim::labels::StepLabels {
                joint_before: 0.0,
                joint_after: 0.0,
                r_dist: 0.0,
                aot: 0,
                moved,
                reached_limit: false,
                back_at_start: false,
                suction_lost: false,
                train: Default::default(),
            },
        },
        gripper_in_world: at,
        candidates: None,
    }
}

/// A handle on a door hinged on the world z axis, 0.5 m out, pulled along the
/// tangent of its arc at angles 0, 0.3, 0.6 and 0.9 rad.
fn door_steps() -> Vec<umpnet_eval::episode::Step> {
    [0.0f32, 0.3, 0.6, 0.9]
        .iter()
        .map(|a| {
            step(
                [-a.sin(), a.cos(), 0.0],
                [0.5 * a.cos(), 0.5 * a.sin(), 0.4],
                true,
            )
        })
        .collect()
}

#[test]
fn the_axis_inferred_from_a_doors_arc_is_its_hinge_and_a_slide_is_its_own_axis() {
    use umpnet_eval::episode::axis_error;
    let door = axis_error(&door_steps(), false, [0.0, 0.0, -1.0]).unwrap();
    assert!(!door.prismatic && !door.looks_prismatic, "{door:?}");
    assert!(door.degrees < 1.0, "{door:?}");
    // The same moves judged against a wrong axis: the error is the angle to it.
    let tilted = axis_error(&door_steps(), false, [0.0, 1.0, 1.0]).unwrap();
    assert!((tilted.degrees - 45.0).abs() < 1.0, "{tilted:?}");

    let slide: Vec<_> = (0..3)
        .map(|k| step([0.0, 0.0, 1.0], [0.1, 0.2, 0.3 + 0.1 * k as f32], true))
        .collect();
    let drawer = axis_error(&slide, true, [0.0, 0.0, 1.0]).unwrap();
    assert!(drawer.prismatic && drawer.looks_prismatic, "{drawer:?}");
    assert!(drawer.degrees < 1e-3, "{drawer:?}");
    let across = axis_error(&slide, true, [1.0, 0.0, 0.0]).unwrap();
    assert!((across.degrees - 90.0).abs() < 1e-3, "{across:?}");
}

#[test]
fn a_hinge_turned_a_little_looks_like_a_slide_but_its_axis_is_still_found() {
    use umpnet_eval::episode::axis_error;
    // Two pulls 0.3 rad apart: their mean is within 9 degrees of each, so the
    // moves alone pass for a slide's. Knowing it is a hinge, as the paper's
    // evaluation does, the plane of the moves gives the axis all the same.
    let hinge = axis_error(&door_steps()[..2], false, [0.0, 0.0, 1.0]).unwrap();
    assert!(hinge.looks_prismatic && hinge.degrees < 1.0, "{hinge:?}");
}

#[test]
fn the_axis_is_inferred_only_from_steps_that_moved_the_part() {
    use umpnet_eval::episode::axis_error;
    let mut steps = door_steps();
    // Pushes that moved nothing say nothing about the joint.
    steps.insert(1, step([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], false));
    steps.push(step([0.0, 0.0, 1.0], [0.3, 0.3, 0.0], false));
    let with = axis_error(&steps, false, [0.0, 0.0, 1.0]).unwrap();
    let without = axis_error(&door_steps(), false, [0.0, 0.0, 1.0]).unwrap();
    assert_eq!(with, without);
    // One move is not enough to tell an axis.
    let one = [
        door_steps()[0].clone(),
        step([1.0, 0.0, 0.0], [0.0; 3], false),
    ];
    assert_eq!(axis_error(&one, false, [0.0, 0.0, 1.0]), None);
}
