//! Where the policy grasps: the best affordance among pixels with depth,
//! where a goal frame differs, weighted by the JointNet's movable mask.

use super::*;

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
