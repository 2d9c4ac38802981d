//! What `UmpnetPolicy` decides, on the fixture's packages (made by
//! `python -m umpnet_train.fixture DIR`; make test sets UMPNET_FIXTURE):
//! - the untrained package, for the grasp: the test reads its affordance map
//!   and works out the pixel the policy must pick;
//! - `steer`, whose decoder ignores the image: distance 0.3 - 0.2 x, AoT +1
//!   along +x and -1 along -x, so the largest distance is a backward move;
//! - `steer-normal90`, the same with the Where2Act pulling filter;
//! - `inverse`, an Inverse baseline that always regresses (1.2, 1.6, 0),
//!   which its package normalises to (0.6, 0.8, 0).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests fail by panicking"
)]
use nalgebra::Vector3;
use ndarray::{Array3, Axis};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use umpnet_policy::cem::Mode;
use umpnet_policy::policy::GOAL_DIFF_M;
use umpnet_policy::{CHANNELS, DecisionInput, ModelPackage, UmpnetPolicy};

mod common;

/// The fixture's package `name` ("" for the untrained one), or None (skipped;
/// see `common::fixture`).
fn policy(name: &str) -> Option<UmpnetPolicy> {
    let dir = common::fixture()?.join(name);
    let package = ModelPackage::load(&dir, 1, 1, None)
        .unwrap_or_else(|e| panic!("{}: {e} (rebuild the fixture)", dir.display()));
    Some(UmpnetPolicy::new(Arc::new(package)))
}

/// A random observation at the policy's resolution, every pixel with depth.
fn observation(policy: &UmpnetPolicy, seed: u64) -> Array3<f32> {
    use rand::Rng;
    let (h, w) = policy.resolution();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut obs = Array3::from_shape_fn((h, w, CHANNELS), |_| rng.random_range(-1.0f32..1.0));
    obs.index_axis_mut(Axis(2), 9).fill(2.0);
    obs
}

/// The affordance map the policy's package gives for `obs`.
fn affordance(policy: &UmpnetPolicy, obs: &Array3<f32>) -> ndarray::Array2<f32> {
    policy
        .package
        .position(obs.view().insert_axis(Axis(0)))
        .unwrap()
        .index_axis_move(Axis(0), 0)
}

/// The pixel of largest affordance among those `allowed` (first in raster order on ties).
fn best(aff: &ndarray::Array2<f32>, allowed: impl Fn(usize, usize) -> bool) -> (usize, usize) {
    let mut out: Option<((usize, usize), f32)> = None;
    for ((r, c), &a) in aff.indexed_iter() {
        if allowed(r, c) && out.is_none_or(|(_, b)| a > b) {
            out = Some(((r, c), a));
        }
    }
    out.unwrap().0
}

#[test]
fn the_grasp_is_the_best_affordance_among_pixels_with_depth() {
    let Some(policy) = policy("") else { return };
    let mut obs = observation(&policy, 1);
    let aff = affordance(&policy, &obs);
    let top = best(&aff, |_, _| true);
    // Take the depth away from the top pixel and from a band of rows: the
    // affordance map is computed from the same image, so it is re-read.
    obs[[top.0, top.1, 9]] = 0.0;
    for c in 0..obs.shape()[1] {
        obs[[0, c, 9]] = -1.0;
    }
    let aff = affordance(&policy, &obs);
    let chosen = policy.position(obs.view(), None).unwrap();
    assert_eq!(chosen.affordance, aff);
    assert_eq!(chosen.pixel, best(&aff, |r, c| obs[[r, c, 9]] > 0.0));
    assert_ne!(chosen.pixel, top);
    assert_ne!(chosen.pixel.0, 0);
}

#[test]
fn with_a_goal_the_grasp_is_where_the_goal_differs() {
    let Some(policy) = policy("") else { return };
    let (h, _) = policy.resolution();
    let mut obs = observation(&policy, 2);
    obs.slice_mut(ndarray::s![.., .., 0..3]).fill(0.0);
    let aff = affordance(&policy, &obs);
    // The changes lie away from the best pixel overall, so that a wrong mask
    // shows: ten rows moved 5 cm, two rows where the goal image has no depth
    // (the part is elsewhere there). Everywhere else the goal differs by
    // exactly GOAL_DIFF_M, which is not yet a change.
    let top = best(&aff, |_, _| true);
    let start = if top.0 < h / 2 { h / 2 } else { 2 };
    let (moved, gone) = (start..start + 10, start + 10..start + 12);
    let mut goal = obs.clone();
    goal.slice_mut(ndarray::s![.., .., 0]).fill(GOAL_DIFF_M);
    goal.slice_mut(ndarray::s![moved.clone(), .., 1]).fill(0.05);
    goal.slice_mut(ndarray::s![gone.start..gone.start + 1, .., 9])
        .fill(0.0);
    goal.slice_mut(ndarray::s![gone.start + 1..gone.end, .., 9])
        .fill(-1.0);
    let chosen = policy.position(obs.view(), Some(goal.view())).unwrap();
    assert_eq!(
        chosen.pixel,
        best(&aff, |r, _| moved.contains(&r) || gone.contains(&r))
    );
    assert_ne!(chosen.pixel, top);
    // Only the rows that moved.
    let mut moved_only = goal.clone();
    moved_only
        .slice_mut(ndarray::s![gone.clone(), .., 9])
        .fill(2.0);
    let chosen = policy
        .position(obs.view(), Some(moved_only.view()))
        .unwrap();
    assert_eq!(chosen.pixel, best(&aff, |r, _| moved.contains(&r)));
    // A goal that differs nowhere: the best pixel with depth, as without a goal.
    let chosen = policy.position(obs.view(), Some(obs.view())).unwrap();
    assert_eq!(chosen.pixel, top);
    // Changes only where the current image has no depth: nothing there can be
    // grasped, so the best pixel with depth.
    let mut holed = obs.clone();
    holed.slice_mut(ndarray::s![moved.clone(), .., 9]).fill(0.0);
    let aff = affordance(&policy, &holed);
    let chosen = policy
        .position(holed.view(), Some(moved_only.view()))
        .unwrap();
    assert_eq!(chosen.pixel, best(&aff, |r, _| !moved.contains(&r)));
}

#[test]
fn grasp_inputs_that_cannot_be_used_are_errors() {
    let Some(policy) = policy("") else { return };
    let obs = observation(&policy, 3);
    let (h, w) = policy.resolution();
    let small = Array3::<f32>::zeros((h / 2, w, CHANNELS));
    let err = policy.position(obs.view(), Some(small.view())).unwrap_err();
    assert!(
        err.to_string().contains("goal observation has shape"),
        "{err}"
    );
    let mut no_depth = obs.clone();
    no_depth.index_axis_mut(Axis(2), 9).fill(0.0);
    let err = policy.position(no_depth.view(), None).unwrap_err();
    assert!(err.to_string().contains("no pixel with depth"), "{err}");
}

fn decide(
    policy: &UmpnetPolicy,
    obs: &[Array3<f32>],
    modes: &[Mode],
    banned: &[Vector3<f32>],
    seed: u64,
) -> Vec<umpnet_policy::cem::CemResult> {
    let (h, w) = policy.resolution();
    decide_at(policy, obs, modes, banned, seed, (h / 2, w / 2))
}

fn decide_at(
    policy: &UmpnetPolicy,
    obs: &[Array3<f32>],
    modes: &[Mode],
    banned: &[Vector3<f32>],
    seed: u64,
    pixel: (usize, usize),
) -> Vec<umpnet_policy::cem::CemResult> {
    let inputs: Vec<DecisionInput<'_>> = obs
        .iter()
        .zip(modes)
        .map(|(o, &mode)| DecisionInput {
            observation: o.view(),
            reference: o.view(),
            pixel,
            banned,
            previous: None,
            mode,
            joint: None,
            motion: None,
            long_motion: None,
        })
        .collect();
    let mut rngs: Vec<ChaCha8Rng> = (0..obs.len())
        .map(|i| ChaCha8Rng::seed_from_u64(seed + i as u64))
        .collect();
    policy.directions(&inputs, &mut rngs).unwrap()
}

#[test]
fn exploration_moves_forward_and_the_goal_mode_back() {
    let Some(policy) = policy("steer") else {
        return;
    };
    let obs = observation(&policy, 4);
    let r = decide(
        &policy,
        std::slice::from_ref(&obs),
        &[Mode::Explore],
        &[],
        7,
    )
    .remove(0);
    assert_eq!(r.candidates.len(), 128);
    assert_eq!(r.scores.len(), 128);
    // Every candidate's score is what the hand-set decoder gives it.
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        assert!(
            (s.distance - (0.3 - 0.2 * d.x)).abs() < 1e-4,
            "{d:?}: {s:?}"
        );
        let aot = if d.x > 0.1 {
            1
        } else if d.x < -0.1 {
            -1
        } else {
            0
        };
        if (d.x.abs() - 0.1).abs() > 0.01 {
            assert_eq!(s.aot, aot, "{d:?}");
        }
    }
    let chosen = r.direction.unwrap();
    assert!(chosen.x > 0.1, "{chosen:?}");
    // The goal mode: the most backward candidate (largest distance among AoT -1).
    let r = decide(&policy, &[obs], &[Mode::Goal], &[], 7).remove(0);
    let chosen = r.direction.unwrap();
    let most_back = r
        .candidates
        .iter()
        .map(|d| d.x)
        .fold(f32::INFINITY, f32::min);
    assert_eq!(chosen.x, most_back);
    assert!(chosen.x < -0.9);
}

#[test]
fn mirror_averaging_scores_each_direction_with_its_mirror_image() {
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_mirror_average(true);
    let obs = observation(&policy, 4);
    let r = decide(&policy, &[obs], &[Mode::Explore], &[], 7).remove(0);
    assert_eq!(r.candidates.len(), 128);
    // The decoder gives d 0.3 - 0.2 x, and its mirror image (x -> -x)
    // 0.3 + 0.2 x: the mean is 0.3 whichever way d points.
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        assert!((s.distance - 0.3).abs() < 1e-4, "{d:?}: {s:?}");
        if d.x.abs() < 0.09 {
            assert_eq!(s.aot, 0, "{d:?}");
        }
    }
}

#[test]
fn a_batch_decides_as_its_members_would_alone() {
    let Some(policy) = policy("steer") else {
        return;
    };
    let obs: Vec<Array3<f32>> = (0..3).map(|i| observation(&policy, 10 + i)).collect();
    let modes = [Mode::Explore, Mode::Goal, Mode::Explore];
    let banned = [Vector3::x()];
    let batch = decide(&policy, &obs, &modes, &banned, 20);
    for i in 0..3 {
        let alone = decide(
            &policy,
            std::slice::from_ref(&obs[i]),
            &modes[i..=i],
            &banned,
            20 + i as u64,
        )
        .remove(0);
        assert_eq!(batch[i].candidates, alone.candidates, "member {i}");
        assert_eq!(batch[i].scores, alone.scores, "member {i}");
        assert_eq!(batch[i].direction, alone.direction, "member {i}");
        assert!(
            batch[i]
                .candidates
                .iter()
                .all(|d| d.dot(&Vector3::x()) <= umpnet_policy::cem::BAN_COS)
        );
    }
    // The same seeds, the same decisions.
    let again = decide(&policy, &obs, &modes, &banned, 20);
    assert!(
        batch
            .iter()
            .zip(&again)
            .all(|(a, b)| a.candidates == b.candidates && a.direction == b.direction)
    );
}

#[test]
fn the_normal90_filter_scores_pushes_into_the_surface_as_no_effect() {
    let Some(policy) = policy("steer-normal90") else {
        return;
    };
    let mut obs = observation(&policy, 5);
    let (h, w) = policy.resolution();
    // The surface at the grasp faces -x: any move with a +x component pushes
    // into it. The grasp is in the corner, given past the image's edge.
    for (k, v) in [-1.0, 0.0, 0.0].into_iter().enumerate() {
        obs[[h - 1, w - 1, 6 + k]] = v;
    }
    let r = decide_at(
        &policy,
        &[obs.clone()],
        &[Mode::Explore],
        &[],
        8,
        (h + 2, w + 3),
    )
    .remove(0);
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        if d.x > 0.0 {
            assert_eq!((s.distance, s.aot), (-1.0, 0), "{d:?}");
        } else {
            assert!(
                (s.distance - (0.3 - 0.2 * d.x)).abs() < 1e-4,
                "{d:?}: {s:?}"
            );
        }
    }
    // Nothing left that moves forward: exploration takes the largest distance.
    let chosen = r.direction.unwrap();
    assert!(chosen.x < -0.9, "{chosen:?}");
    // Exploring, the face is read from the reference (the frame the grasp
    // was chosen on), not from the current frame, which shows the gripper
    // there: the same decision whatever the current frame's normal.
    let mut now = obs.clone();
    for (k, v) in [1.0, 0.0, 0.0].into_iter().enumerate() {
        now[[h - 1, w - 1, 6 + k]] = v;
    }
    let input = explore(&now, &obs, (h + 2, w + 3));
    let again = policy
        .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(8)])
        .unwrap()
        .remove(0);
    assert_eq!(again.direction, r.direction);
    assert_eq!(again.scores, r.scores);
}

#[test]
fn the_inverse_baseline_acts_on_its_regressed_direction_in_the_goal_task_only() {
    let Some(policy) = policy("inverse") else {
        return;
    };
    let obs = observation(&policy, 6);
    let r = decide(&policy, std::slice::from_ref(&obs), &[Mode::Goal], &[], 9).remove(0);
    let d = r.direction.unwrap();
    assert!((d - Vector3::new(0.6, 0.8, 0.0)).norm() < 1e-5, "{d:?}");
    assert_eq!(r.candidates, vec![d]);
    // The package's decoder outputs the regression normalised; its length is the score.
    assert!((r.scores[0].distance - 1.0).abs() < 1e-5, "{:?}", r.scores);
    assert_eq!(r.scores[0].aot, -1);
    let (h, w) = policy.resolution();
    let mut rngs = vec![ChaCha8Rng::seed_from_u64(0)];
    let input = DecisionInput {
        observation: obs.view(),
        reference: obs.view(),
        pixel: (h / 2, w / 2),
        banned: &[],
        previous: None,
        mode: Mode::Explore,
        joint: None,
        motion: None,
        long_motion: None,
    };
    let err = policy.directions(&[input], &mut rngs).err().unwrap();
    assert!(
        err.to_string().contains("serves only the goal task"),
        "{err}"
    );
}

fn explore<'a>(
    observation: &'a Array3<f32>,
    reference: &'a Array3<f32>,
    pixel: (usize, usize),
) -> DecisionInput<'a> {
    DecisionInput {
        observation: observation.view(),
        reference: reference.view(),
        pixel,
        banned: &[],
        previous: None,
        mode: Mode::Explore,
        joint: None,
        motion: None,
        long_motion: None,
    }
}

#[test]
fn decision_inputs_that_do_not_fit_are_errors() {
    let Some(policy) = policy("steer") else {
        return;
    };
    let obs = observation(&policy, 7);
    let (h, w) = policy.resolution();
    let input = |reference, pixel| explore(&obs, reference, pixel);
    let mut two = vec![ChaCha8Rng::seed_from_u64(0); 2];
    let err = policy
        .directions(&[input(&obs, (0, 0))], &mut two)
        .err()
        .unwrap();
    assert!(
        err.to_string().contains("1 inputs but 2 random generators"),
        "{err}"
    );
    assert!(policy.directions(&[], &mut []).unwrap().is_empty());
    let small = Array3::<f32>::zeros((h, w / 2, CHANNELS));
    let err = policy
        .directions(&[input(&small, (0, 0))], &mut two[..1])
        .err()
        .unwrap();
    assert!(err.to_string().contains("the model takes"), "{err}");
    // A grasp pixel past the image's edge is clamped onto it: the untrained
    // package's scores depend on the embedding at the pixel.
    let Some(policy) = self::policy("") else {
        return;
    };
    let obs = observation(&policy, 7);
    let input = |reference, pixel| explore(&obs, reference, pixel);
    let edge = policy
        .directions(
            &[input(&obs, (h - 1, w - 1))],
            &mut [ChaCha8Rng::seed_from_u64(1)],
        )
        .unwrap();
    let past = policy
        .directions(
            &[input(&obs, (h + 5, w + 9))],
            &mut [ChaCha8Rng::seed_from_u64(1)],
        )
        .unwrap();
    assert_eq!(edge[0].scores, past[0].scores);
    let inside = policy
        .directions(
            &[input(&obs, (h / 2, w / 2))],
            &mut [ChaCha8Rng::seed_from_u64(1)],
        )
        .unwrap();
    assert_ne!(edge[0].scores, inside[0].scores);
}

#[test]
fn the_normal90_filter_bans_nothing_where_the_grasp_has_no_normal() {
    let Some(policy) = policy("steer-normal90") else {
        return;
    };
    let mut obs = observation(&policy, 6);
    // A pixel with no surface normal (zero, as the observation gives where
    // normals cannot be estimated): no direction pushes into a surface there.
    for k in 0..3 {
        obs[[3, 4, 6 + k]] = 0.0;
    }
    let r = decide_at(&policy, &[obs], &[Mode::Explore], &[], 9, (3, 4)).remove(0);
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        assert!(
            (s.distance - (0.3 - 0.2 * d.x)).abs() < 1e-4,
            "{d:?}: {s:?}"
        );
    }
}

#[test]
fn the_prev90_filter_rules_out_turning_back_on_the_last_move() {
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Prev90);
    let obs = observation(&policy, 7);
    let (h, w) = policy.resolution();
    let decide_after = |previous: Option<Vector3<f32>>, mode: Mode| {
        let input = DecisionInput {
            previous,
            mode,
            joint: None,
            ..explore(&obs, &obs, (h / 2, w / 2))
        };
        policy.directions(&[input], &mut [ChaCha8Rng::seed_from_u64(3)])
    };
    // The last move went along -x: every candidate with a +x part turns back
    // on it and scores as no effect, the forward ones included.
    let back = Vector3::new(-1.0, 0.0, 0.0);
    let r = decide_after(Some(back), Mode::Explore).unwrap().remove(0);
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        if d.dot(&back) < 0.0 {
            assert_eq!((s.distance, s.aot), (-1.0, 0), "{d:?}");
        } else {
            assert!(
                (s.distance - (0.3 - 0.2 * d.x)).abs() < 1e-4,
                "{d:?}: {s:?}"
            );
        }
    }
    assert!(r.direction.unwrap().x < -0.9, "{:?}", r.direction);
    // Before the first move nothing is ruled out: exploration goes forward.
    let first = decide_after(None, Mode::Explore).unwrap().remove(0);
    assert!(first.scores.iter().all(|s| s.distance >= 0.0));
    assert!(first.direction.unwrap().x > 0.0, "{:?}", first.direction);
    // The heuristic has no meaning for a goal behind the last move.
    let err = decide_after(Some(back), Mode::Goal).err().unwrap();
    assert!(err.to_string().contains("exploration only"), "{err}");
}

#[test]
fn direction_filters_are_named_as_in_model_json() {
    use umpnet_policy::policy::DirectionFilter;
    for f in DirectionFilter::ALL {
        assert_eq!(f.name().parse::<DirectionFilter>().unwrap(), f);
    }
    let err = "prev45".parse::<DirectionFilter>().unwrap_err();
    assert!(
        err.to_string()
            .contains("none, normal90, prev90, joint45, goal45 or onward45"),
        "{err}"
    );
}

#[test]
fn the_joint45_filter_keeps_directions_along_the_joint_the_package_read() {
    use umpnet_policy::axis::JointEstimate;
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("joint") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Joint45);
    let obs = observation(&policy, 11);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    let gripper = Vector3::new(
        obs[[pixel.0, pixel.1, 0]],
        obs[[pixel.0, pixel.1, 1]],
        obs[[pixel.0, pixel.1, 2]],
    );
    let hinge = JointEstimate::Revolute {
        axis: [0.0, 0.0, 1.0],
        point: (gripper - Vector3::new(0.5, 0.0, 0.0)).into(),
    };
    let slide = JointEstimate::Prismatic {
        axis: [0.0, 0.6, 0.8],
    };
    // A hinge about z half a metre in -x of the gripper moves it along y.
    for (joint, line) in [
        (&hinge, Vector3::new(0.0, 1.0, 0.0)),
        (&slide, Vector3::new(0.0, 0.6, 0.8)),
    ] {
        for mode in [Mode::Explore, Mode::Goal] {
            let input = DecisionInput {
                joint: Some(joint),
                mode,
                ..explore(&obs, &obs, pixel)
            };
            let mut rng = vec![ChaCha8Rng::seed_from_u64(3)];
            let r = policy.directions(&[input], &mut rng).unwrap().remove(0);
            for (d, s) in r.candidates.iter().zip(&r.scores) {
                let along = d.dot(&line).abs() >= std::f32::consts::FRAC_1_SQRT_2;
                assert_eq!(s.distance >= 0.0, along, "{d:?} {s:?}");
            }
            let chosen = r.direction.unwrap();
            assert!(chosen.dot(&line).abs() >= std::f32::consts::FRAC_1_SQRT_2);
        }
    }
    // Without a joint (the vote found no part) nothing is ruled out.
    let mut rng = vec![ChaCha8Rng::seed_from_u64(3)];
    let r = policy
        .directions(&[explore(&obs, &obs, pixel)], &mut rng)
        .unwrap()
        .remove(0);
    assert!(r.scores.iter().all(|s| s.distance >= 0.0));
    // A package without a JointNet cannot serve the filter.
    let plain = self::policy("steer")
        .unwrap()
        .with_direction_filter(DirectionFilter::Joint45);
    let err = plain
        .directions(&[explore(&obs, &obs, pixel)], &mut rng)
        .err()
        .unwrap();
    assert!(err.to_string().contains("has none"), "{err}");
}

/// An H x W observation through a pinhole at the origin looking down +z of
/// a wall at z = 2 with a 0.4 m panel in front of it at depth `z`, centred
/// at (`x`, 0).
fn panel(policy: &UmpnetPolicy, x: f32, z: f32) -> Array3<f32> {
    let (h, w) = policy.resolution();
    let f = w as f32;
    let mut obs = Array3::<f32>::zeros((h, w, CHANNELS));
    for r in 0..h {
        for c in 0..w {
            let u = (c as f32 + 0.5 - w as f32 / 2.0) / f;
            let v = (r as f32 + 0.5 - h as f32 / 2.0) / f;
            let depth = if (u * z - x).abs() < 0.2 && (v * z).abs() < 0.2 {
                z
            } else {
                2.0
            };
            obs[[r, c, 0]] = u * depth;
            obs[[r, c, 1]] = v * depth;
            obs[[r, c, 2]] = depth;
            obs[[r, c, 9]] = depth;
        }
    }
    obs
}

#[test]
fn the_goal45_filter_moves_toward_where_the_goal_frame_shows_the_part() {
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Goal45);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    // The goal shows the panel 0.25 m to the right: +x, the way the steer
    // package's Arrow of Time calls forward (away from any goal).
    let (now, goal) = (panel(&policy, 0.0, 1.2), panel(&policy, 0.25, 1.2));
    let decide = |previous: Option<Vector3<f32>>, banned: &[Vector3<f32>], goal: &Array3<f32>| {
        let input = DecisionInput {
            mode: Mode::Goal,
            previous,
            banned,
            ..explore(&now, goal, pixel)
        };
        policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(5)])
            .unwrap()
            .remove(0)
    };
    let r = decide(None, &[], &goal);
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        if d.x >= std::f32::consts::FRAC_1_SQRT_2 {
            assert_eq!(s.aot, -1, "toward the goal: {d:?} {s:?}");
            assert!(s.distance >= 0.0, "{d:?} {s:?}");
        } else {
            assert_eq!((s.distance, s.aot), (-1.0, 0), "{d:?}");
        }
    }
    let chosen = r.direction.unwrap();
    assert!(chosen.x >= std::f32::consts::FRAC_1_SQRT_2, "{chosen:?}");
    // Frames that show no change: onward along a last move that moved the
    // part, the heads' own call after one that did not.
    let up = Vector3::new(0.0, 0.0, -1.0);
    let onward = decide(Some(up), &[], &now).direction.unwrap();
    assert!(
        onward.dot(&up) >= std::f32::consts::FRAC_1_SQRT_2,
        "{onward:?}"
    );
    let heads = decide(Some(up), &[up], &now);
    assert!(heads.scores.iter().all(|s| s.distance >= 0.0));
    assert!(
        heads.direction.unwrap().x < -0.9,
        "the steer heads' goal move"
    );
    // Exploring there is no goal frame: refused by name.
    let err = policy
        .directions(
            &[explore(&now, &now, pixel)],
            &mut [ChaCha8Rng::seed_from_u64(5)],
        )
        .err()
        .unwrap();
    assert!(err.to_string().contains("goal45"), "{err}");
}

#[test]
fn the_goal45_filter_follows_the_grippers_own_motion_where_it_agrees_with_the_frames() {
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Goal45);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    // The frames' shift is +x; the gripper's last motion says which way
    // along it the part gives, when it went far enough to say.
    let (now, goal) = (panel(&policy, 0.0, 1.2), panel(&policy, 0.25, 1.2));
    let kept = |motion: Vector3<f32>, long_motion: Option<Vector3<f32>>| {
        let input = DecisionInput {
            mode: Mode::Goal,
            motion: Some(motion),
            long_motion,
            ..explore(&now, &goal, pixel)
        };
        let r = policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(5)])
            .unwrap()
            .remove(0);
        r.candidates
            .iter()
            .zip(&r.scores)
            .map(|(d, s)| (*d, s.aot == -1 && s.distance >= 0.0))
            .collect::<Vec<_>>()
    };
    let cone = std::f32::consts::FRAC_1_SQRT_2;
    let arc = Vector3::new(1.0, 0.0, -1.0).normalize();
    let back = Vector3::new(-1.0, 0.0, -1.0).normalize();
    for (motion, long_motion, way) in [
        // Agrees with the shift: its own direction is the way.
        (arc * 0.1, Some(arc * 0.1), arc),
        // Went against the frames (past the goal): the frames' shift.
        (back * 0.1, Some(back * 0.1), Vector3::x()),
        // Within 2 cm, with no motion before it, it says nothing: the
        // frames' shift.
        (arc * 0.015, None, Vector3::x()),
        // A move that stalled after one that went along the arc: the arc
        // still stands, where it agrees with the frames.
        (arc * 0.015, Some(arc * 0.1), arc),
        (arc * 0.015, Some(back * 0.1), Vector3::x()),
    ] {
        for (d, k) in kept(motion, long_motion) {
            assert_eq!(
                k,
                d.dot(&way) >= cone,
                "motion {motion:?} after {long_motion:?}: {d:?}"
            );
        }
    }
}

#[test]
fn the_movable_grasp_weights_the_affordance_by_the_joint_nets_mask() {
    use umpnet_policy::policy::GraspRule;
    let Some(plain) = policy("steer") else {
        return;
    };
    // Without a JointNet the rule is refused by name.
    let err = plain
        .clone()
        .with_grasp(GraspRule::AffordanceTimesMovable)
        .err()
        .unwrap();
    assert!(
        err.to_string().contains("affordance_times_movable")
            && err.to_string().contains("files.joint"),
        "{err}"
    );
    let Some(joint) = policy("joint") else {
        return;
    };
    // The fixture's JointNet calls every pixel movable with logit 5: the
    // chosen map is the PositionNet's scaled by that probability, pixel by
    // pixel.
    let joint = joint.with_grasp(GraspRule::AffordanceTimesMovable).unwrap();
    let obs = observation(&joint, 21);
    let aff = affordance(&joint, &obs);
    let chosen = joint.position(obs.view(), None).unwrap();
    let movable = 1.0 / (1.0 + (-5.0f32).exp());
    for ((r, c), &a) in aff.indexed_iter() {
        let got = chosen.affordance[[r, c]];
        assert!(
            (got - a * movable).abs() < 1e-5,
            "({r}, {c}): {got} vs {a} x {movable}"
        );
    }
    assert_eq!(chosen.pixel, best(&aff, |_, _| true));
    // The joint read at the grasp from the fields the rule kept is the one
    // a fresh JointNet run reads.
    assert!(chosen.joint_fields.is_some());
    let kept = joint.joint_at_grasp(obs.view(), &chosen).unwrap();
    let fresh = joint.frame_joint(obs.view(), chosen.pixel).unwrap();
    assert!(kept.is_some());
    assert_eq!(kept, fresh);
    // The lever rule also weighs each pixel by its lever arm: the fixture's
    // JointNet reads a slide (hinge logit -5) with no arm, so by the hinge
    // probability's complement, and the grasp stays where it was.
    let lever = joint
        .clone()
        .with_grasp(GraspRule::AffordanceTimesMovableLever)
        .unwrap();
    let levered = lever.position(obs.view(), None).unwrap();
    let slide = 1.0 - 1.0 / (1.0 + 5.0f32.exp());
    for ((r, c), &a) in aff.indexed_iter() {
        let got = levered.affordance[[r, c]];
        assert!(
            (got - a * movable * slide).abs() < 1e-5,
            "({r}, {c}): {got} vs {a} x {movable} x {slide}"
        );
    }
    assert_eq!(levered.pixel, chosen.pixel);
    assert!(
        plain
            .clone()
            .with_grasp(GraspRule::AffordanceTimesMovableLever)
            .is_err()
    );
    // Under the paper's rule the map is the PositionNet's own.
    let paper = joint.with_grasp(GraspRule::Affordance).unwrap();
    let choice = paper.position(obs.view(), None).unwrap();
    assert_eq!(choice.affordance, aff);
    assert!(choice.joint_fields.is_none());
}

#[test]
fn the_onward45_filter_explores_onward_along_where_the_gripper_went() {
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Onward45);
    let obs = observation(&policy, 13);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    let went = Vector3::new(0.0, 0.6, -0.8);
    let decide = |motion: Option<Vector3<f32>>| {
        let input = DecisionInput {
            motion,
            long_motion: None,
            ..explore(&obs, &obs, pixel)
        };
        policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(9)])
            .unwrap()
            .remove(0)
    };
    let cone = std::f32::consts::FRAC_1_SQRT_2;
    let r = decide(Some(went * 0.12));
    for (d, s) in r.candidates.iter().zip(&r.scores) {
        if d.dot(&went) >= cone {
            assert_eq!(s.aot, 1, "onward is forward: {d:?} {s:?}");
        } else {
            assert_eq!((s.distance, s.aot), (-1.0, 0), "{d:?}");
        }
    }
    // The heads' choice lies in the cone, and the move keeps to the motion
    // itself, not to that choice.
    assert!(
        r.candidates
            .iter()
            .zip(&r.scores)
            .any(|(d, s)| s.distance >= 0.0 && (d - went).norm() > 1e-3)
    );
    assert!((r.direction.unwrap() - went).norm() < 1e-5, "{r:?}");
    // Before a motion, or after one the part stopped within 2 cm, a package
    // without a JointNet leaves the choice to its heads.
    for motion in [None, Some(went * 0.01)] {
        let r = decide(motion);
        assert!(r.scores.iter().all(|s| s.distance >= 0.0), "{motion:?}");
    }
    // Toward a goal, onward may be past it: refused by name.
    let input = DecisionInput {
        mode: Mode::Goal,
        ..explore(&obs, &obs, pixel)
    };
    let err = policy
        .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(9)])
        .err()
        .unwrap();
    assert!(err.to_string().contains("onward45"), "{err}");
}

#[test]
fn after_stalls_onward45_tries_the_joints_other_side_then_the_surface_normal() {
    use umpnet_policy::axis::JointEstimate;
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("joint") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Onward45);
    let now = observation(&policy, 17);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    // The episode's first frame shows the grasped face turned to -z; the
    // current one shows whatever covers the grasp (the gripper's own side).
    let mut first = now.clone();
    let normal = Vector3::new(0.0, 0.0, -1.0);
    for (k, v) in normal.iter().enumerate() {
        first[[pixel.0, pixel.1, 6 + k]] = *v;
    }
    let slide = JointEstimate::Prismatic {
        axis: [0.0, 1.0, 0.0],
    };
    let line = Vector3::new(0.0, 1.0, 0.0);
    let cone = std::f32::consts::FRAC_1_SQRT_2;
    let decide = |joint: Option<&JointEstimate>, banned: &[Vector3<f32>]| {
        let input = DecisionInput {
            joint,
            banned,
            // The last move stalled: the gripper went 1 cm.
            motion: Some(line * 0.01),
            ..explore(&now, &first, pixel)
        };
        policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(5)])
            .unwrap()
            .remove(0)
    };
    // Before any stall: either way along the joint's line.
    let r = decide(Some(&slide), &[]);
    assert!(r.direction.unwrap().dot(&line).abs() >= cone, "{r:?}");
    // One side stalled (a limit): the other side, forward.
    for side in [1.0f32, -1.0] {
        let stalled = [Vector3::new(0.2, side, 0.1).normalize()];
        let r = decide(Some(&slide), &stalled);
        for (d, s) in r.candidates.iter().zip(&r.scores) {
            if -side * d.dot(&line) >= cone {
                assert_eq!(s.aot, 1, "{d:?} {s:?}");
            } else {
                assert_eq!((s.distance, s.aot), (-1.0, 0), "{d:?}");
            }
        }
        assert!(-side * r.direction.unwrap().dot(&line) >= cone, "{r:?}");
    }
    // Both sides stalled, or no joint read: off the face along its normal,
    // exactly, then into it, then wherever the heads choose.
    let both = [line, -line];
    for (joint, banned) in [(Some(&slide), &both[..]), (None, &[-line][..])] {
        let r = decide(joint, banned);
        assert!((r.direction.unwrap() - normal).norm() < 1e-5, "{r:?}");
        let more: Vec<Vector3<f32>> = banned.iter().copied().chain([normal]).collect();
        let r = decide(joint, &more);
        assert!((r.direction.unwrap() + normal).norm() < 1e-5, "{r:?}");
        let all: Vec<Vector3<f32>> = more.iter().copied().chain([-normal]).collect();
        let r = decide(joint, &all);
        assert!(r.scores.iter().all(|s| s.distance >= 0.0), "{r:?}");
    }
}

#[test]
fn onward45_on_a_hinge_turns_the_last_move_with_the_part() {
    use umpnet_policy::axis::JointEstimate;
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Onward45);
    let mut obs = observation(&policy, 19);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    // The gripper's point now, 0.25 m from a vertical hinge.
    let point = Vector3::new(0.1, -0.4, 0.6);
    for (k, v) in point.iter().enumerate() {
        obs[[pixel.0, pixel.1, k]] = *v;
    }
    let centre = point - Vector3::new(0.25, 0.0, 0.0);
    let on_circle = |t: f32| centre + 0.25 * Vector3::new(t.cos(), t.sin(), 0.0);
    // The last move turned the part by 0.6 rad to where it is now.
    let motion = point - on_circle(-0.6);
    let next = (on_circle(0.6) - point).normalize();
    let decide = |joint: Option<&JointEstimate>| {
        let input = DecisionInput {
            joint,
            motion: Some(motion),
            ..explore(&obs, &obs, pixel)
        };
        policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(3)])
            .unwrap()
            .remove(0)
            .direction
            .unwrap()
    };
    let hinge = JointEstimate::Revolute {
        axis: [0.0, 0.0, 1.0],
        point: [centre.x, centre.y, 0.0],
    };
    let d = decide(Some(&hinge));
    assert!(
        (d - next).norm() < 1e-4,
        "the next chord: {d:?} vs {next:?}"
    );
    // A slide, or no joint read: straight on.
    let slide = JointEstimate::Prismatic {
        axis: [0.0, 1.0, 0.0],
    };
    for joint in [Some(&slide), None] {
        let d = decide(joint);
        assert!((d - motion.normalize()).norm() < 1e-5, "{joint:?}: {d:?}");
    }
}

#[test]
fn onward45_does_not_follow_a_motion_that_left_the_part_where_it_was() {
    use umpnet_policy::policy::DirectionFilter;
    let Some(policy) = policy("steer") else {
        return;
    };
    let policy = policy.with_direction_filter(DirectionFilter::Onward45);
    let mut obs = observation(&policy, 23);
    let (h, w) = policy.resolution();
    let pixel = (h / 2, w / 2);
    // The grasped face looks along -y (exploring, its normal is read from the reference).
    for (k, v) in [0.0, -1.0, 0.0].iter().enumerate() {
        obs[[pixel.0, pixel.1, 6 + k]] = *v;
    }
    let last = Vector3::new(1.0, 0.0, 0.0);
    // The gripper went 0.1 m up over the last move.
    let motion = Vector3::new(0.0, 0.0, 0.1);
    let decide = |banned: &[Vector3<f32>]| {
        let input = DecisionInput {
            banned,
            previous: Some(last),
            motion: Some(motion),
            ..explore(&obs, &obs, pixel)
        };
        policy
            .directions(&[input], &mut [ChaCha8Rng::seed_from_u64(5)])
            .unwrap()
            .remove(0)
            .direction
            .unwrap()
    };
    // The move moved the part: onward along where the gripper went.
    let d = decide(&[]);
    assert!((d - Vector3::z()).norm() < 1e-5, "{d:?}");
    // It moved something else (the part's parent swung): a stall, and the
    // next try is off the grasped face, not along the parent's path.
    let d = decide(&[last]);
    assert!((d - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-5, "{d:?}");
}
