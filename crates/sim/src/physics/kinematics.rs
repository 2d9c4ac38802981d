//! Kinematics of an [`ObjectModel`] tree in reduced coordinates: link poses
//! from joint values, the movable joints above a link, the links a joint moves.
#![allow(
    clippy::indexing_slicing,
    reason = "joint and link indices come from the validated model"
)]
use crate::math::{Pose3, Quat};
use crate::model::{JointKind, ObjectModel};

/// The child frame's pose in the joint frame at joint value `q`.
pub(crate) fn joint_motion(kind: JointKind, axis_in_joint: crate::math::Vec3, q: f32) -> Pose3 {
    match kind {
        JointKind::Revolute | JointKind::Continuous => {
            Pose3::from_rotation(Quat::from_axis_angle(axis_in_joint, q))
        }
        JointKind::Prismatic => Pose3::from_translation(axis_in_joint * q),
        JointKind::Fixed => Pose3::IDENTITY,
    }
}

/// Every link's pose for joint values `q` (one per joint). The model's joints
/// are ordered parent-first, so one pass suffices.
pub(crate) fn forward_kinematics(
    model: &ObjectModel,
    world_from_base: Pose3,
    q: &[f32],
    world_from_link: &mut [Pose3],
) {
    world_from_link[model.root] = world_from_base;
    for (j, joint) in model.joints.iter().enumerate() {
        world_from_link[joint.child] = world_from_link[joint.parent]
            * joint.parent_from_joint
            * joint_motion(joint.kind, joint.axis_in_joint, q[j]);
    }
}

/// The movable joints between the root and `link`, root first.
pub(crate) fn movable_chain(model: &ObjectModel, link: usize) -> Vec<usize> {
    let mut chain = Vec::new();
    let mut l = link;
    while let Some(j) = model.parent_joint_of(l) {
        if model.joints[j].kind.is_movable() {
            chain.push(j);
        }
        l = model.joints[j].parent;
    }
    chain.reverse();
    chain
}

/// The links that joint `joint` moves: its child and everything below it.
pub(crate) fn moved_links(model: &ObjectModel, joint: usize) -> Vec<usize> {
    let mut links = vec![model.joints[joint].child];
    // Parent-first order: one pass collects the whole subtree.
    for j in &model.joints {
        if links.contains(&j.parent) && !links.contains(&j.child) {
            links.push(j.child);
        }
    }
    links
}
