//! Dense articulation labels of a rendered frame, for training with more
//! signal per image than one executed action (FlowBot3D's articulation flow):
//! for every pixel on a part that a joint moves, the direction its surface
//! point moves when that joint opens, and, in a goal scene, where the point
//! must go to reach the goal state.
use crate::env::{OBJECT_ID, SimEnv};
use crate::error::{Result, SimError};
use crate::math::{Pose3, Vec3};
use crate::model::JointKind;
use crate::physics::kinematics::forward_kinematics;
use crate::render::{Frame, Segment};

/// Per-pixel articulation labels, row-major like the frame they label.
#[derive(Clone, Debug, PartialEq)]
pub struct ArticulationFields {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The unit direction in which the pixel's surface point moves when the
    /// joint that moves its part opens (its value grows), in the world frame:
    /// `axis × (p − origin)` normalised for a hinge, the axis for a slider.
    /// Zero on fixed parts, the floor, the gripper and the background, and on
    /// a hinge's own axis.
    pub flow_in_world: Vec<[f32; 3]>,
    /// How fast each pixel's point moves for a given joint speed, relative to
    /// the fastest point of its part in this frame (FlowBot3D's normalised
    /// flow is `speed × flow`): the distance from the hinge axis over the
    /// largest such distance among the part's pixels, 1 on a slider, 0 where
    /// `flow_in_world` is zero. With it a single frame locates a hinge.
    pub speed: Vec<f32>,
    /// The joint that moves each pixel's part (the one a grasp there would
    /// move), or -1.
    pub joint: Vec<i32>,
    /// Goal scenes: the displacement (m, world frame) that takes each pixel's
    /// point to where it is in the goal state; zero where the goal moves
    /// nothing. `None` in exploration scenes.
    pub goal_displacement_in_world: Option<Vec<[f32; 3]>>,
}

impl ArticulationFields {
    /// The pixels on a movable part (where `joint` is not -1).
    pub fn movable(&self) -> impl Iterator<Item = bool> + '_ {
        self.joint.iter().map(|j| *j >= 0)
    }
}

impl SimEnv {
    /// The articulation labels of `frame`, which must show this environment's
    /// current state (the frame [`SimEnv::render`] just returned).
    pub fn articulation_fields(&self, frame: &Frame) -> Result<ArticulationFields> {
        let n = (frame.width as usize) * (frame.height as usize);
        if frame.segmentation.len() != n || frame.depth.len() != n {
            return Err(SimError::InvalidAction(format!(
                "a {}x{} frame with {} segment and {} depth values",
                frame.height,
                frame.width,
                frame.segmentation.len(),
                frame.depth.len()
            )));
        }
        let model = self.model();
        let art = self.articulation();
        let axes: Vec<(JointKind, Vec3, Vec3)> = (0..model.joints.len())
            .map(|j| {
                let (axis, origin) = art.joint_axis_in_world(j);
                let kind = model.joints.get(j).map_or(JointKind::Fixed, |jm| jm.kind);
                (kind, axis, origin)
            })
            .collect();
        // Each link's motion from now to the goal state: goal_from_now(p) is
        // where the point p (world, now) is in the goal state.
        let goal_from_now: Option<Vec<Pose3>> = match &self.scene().goal {
            Some(goal) => {
                let mut at_goal = vec![Pose3::IDENTITY; model.links.len()];
                forward_kinematics(
                    model,
                    self.scene().world_from_base(),
                    &goal.joints,
                    &mut at_goal,
                );
                Some(
                    at_goal
                        .iter()
                        .enumerate()
                        .map(|(l, g)| *g * art.world_from_link(l).inverse())
                        .collect(),
                )
            }
            None => None,
        };
        let mut flow = vec![[0.0f32; 3]; n];
        let mut speed = vec![0.0f32; n];
        let mut joint = vec![-1i32; n];
        let mut goal = goal_from_now.as_ref().map(|_| vec![[0.0f32; 3]; n]);
        for row in 0..frame.height {
            for col in 0..frame.width {
                let i = frame.index(row, col);
                let segment = frame.segmentation.get(i).copied().unwrap_or_default();
                let Segment::Link {
                    object: OBJECT_ID,
                    link,
                } = Segment::decode(segment)
                else {
                    continue;
                };
                let Some(p) = frame.point_in_world(row, col) else {
                    continue;
                };
                if let (Some(out), Some(motion)) = (
                    goal.as_mut().and_then(|g| g.get_mut(i)),
                    goal_from_now.as_ref().and_then(|m| m.get(link)),
                ) {
                    *out = (motion.transform_point(p) - p).to_array();
                }
                let Some(j) = self.joint_moving_link(link) else {
                    continue;
                };
                let Some((kind, axis, origin)) = axes.get(j).copied() else {
                    continue;
                };
                let v = match kind {
                    JointKind::Prismatic => axis,
                    JointKind::Revolute | JointKind::Continuous => axis.cross(p - origin),
                    JointKind::Fixed => Vec3::ZERO,
                };
                if let (Some(f), Some(s), Some(jo)) =
                    (flow.get_mut(i), speed.get_mut(i), joint.get_mut(i))
                {
                    *f = v.normalize_or_zero().to_array();
                    *s = if *f == [0.0; 3] { 0.0 } else { v.length() };
                    *jo = i32::try_from(j).unwrap_or(-1);
                }
            }
        }
        relative_to_fastest(&mut speed, &joint, model.joints.len());
        Ok(ArticulationFields {
            width: frame.width,
            height: frame.height,
            flow_in_world: flow,
            speed,
            joint,
            goal_displacement_in_world: goal,
        })
    }
}

/// Each pixel's speed over the largest among the pixels of the same joint.
fn relative_to_fastest(speed: &mut [f32], joint: &[i32], joints: usize) {
    let mut fastest = vec![0.0f32; joints];
    for (s, j) in speed.iter().zip(joint) {
        if let Some(m) = usize::try_from(*j).ok().and_then(|j| fastest.get_mut(j)) {
            *m = m.max(*s);
        }
    }
    for (s, j) in speed.iter_mut().zip(joint) {
        if let Some(m) = usize::try_from(*j).ok().and_then(|j| fastest.get(j)) {
            *s = if *m > 0.0 { *s / *m } else { 0.0 };
        }
    }
}
