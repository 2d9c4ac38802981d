//! The onward45 filter: exploring onward along where the gripper went.

use super::*;

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
