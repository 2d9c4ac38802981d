//! The direction filters but onward45: normal90, prev90, joint45 and goal45.

use super::*;

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
