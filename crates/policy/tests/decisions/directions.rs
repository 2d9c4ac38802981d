//! How the policy picks a move: forward in exploration and back toward a
//! goal, mirror averaging, batches, the Inverse baseline, and the inputs it
//! refuses.

use super::*;

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
