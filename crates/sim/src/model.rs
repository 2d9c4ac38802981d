//! The articulated object the simulator works on: links with their visuals
//! and inertia, joints with their frames, axes and limits. The URDF loader
//! (`crate::urdf`) and the generator (`crate::objects`) produce it; physics,
//! rendering and labels read it.
use crate::error::{Result, SimError};
use crate::math::{Mat3, Pose3, Vec3};
use crate::mesh::TriMesh;
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    Fixed,
    Revolute,
    Continuous,
    Prismatic,
}

impl JointKind {
    pub fn is_movable(self) -> bool {
        self != JointKind::Fixed
    }
    pub fn is_prismatic(self) -> bool {
        self == JointKind::Prismatic
    }
}

#[derive(Clone, Debug)]
pub struct VisualModel {
    /// Mesh in the link frame (origin and scale applied).
    pub mesh_in_link: TriMesh,
    pub color: [f32; 3],
}

#[derive(Clone, Debug)]
pub struct LinkModel {
    pub name: String,
    pub visuals: Vec<VisualModel>,
    pub mass: f32,
    pub com_in_link: Vec3,
    /// Inertia tensor about the centre of mass, in link axes.
    pub inertia_in_link: Mat3,
    /// True when the file gave no `<inertial>` and one was derived.
    pub inertial_derived: bool,
}

#[derive(Clone, Debug)]
pub struct JointModel {
    pub name: String,
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// Joint frame (= child frame at joint value 0) in the parent link frame.
    pub parent_from_joint: Pose3,
    /// Unit axis in the joint frame.
    pub axis_in_joint: Vec3,
    /// Limits; continuous joints have (-inf, inf).
    pub lower: f32,
    pub upper: f32,
    pub damping: f32,
    pub friction: f32,
}

/// How far (rad or m) a joint value given as input may lie past a limit:
/// more than the solvers overshoot one by, far less than a part's travel.
pub const JOINT_LIMIT_SLACK: f32 = 0.01;

/// A loaded, validated articulated object: a tree of links rooted at `root`.
#[derive(Clone, Debug)]
pub struct ObjectModel {
    pub source: PathBuf,
    pub name: String,
    pub links: Vec<LinkModel>,
    /// Joints ordered so that every parent link appears before its child.
    pub joints: Vec<JointModel>,
    pub root: usize,
}

impl ObjectModel {
    /// The object uniformly scaled by `scale`, as PyBullet's `globalScaling`
    /// does: geometry, joint origins, centres of mass and prismatic limits
    /// scale; masses keep their value and inertias scale with its square.
    pub fn scaled(mut self, scale: f32) -> Result<Self> {
        if !(scale.is_finite() && scale > 0.0 && scale <= 1000.0) {
            return Err(SimError::InvalidScene(format!(
                "object scale must be a number in (0, 1000], got {scale}"
            )));
        }
        if scale == 1.0 {
            return Ok(self);
        }
        for link in &mut self.links {
            for v in &mut link.visuals {
                for p in &mut v.mesh_in_link.positions {
                    *p *= scale;
                }
            }
            link.com_in_link *= scale;
            link.inertia_in_link *= scale * scale;
        }
        for joint in &mut self.joints {
            joint.parent_from_joint.translation *= scale;
            if joint.kind.is_prismatic() {
                joint.lower *= scale;
                joint.upper *= scale;
            }
        }
        Ok(self)
    }

    /// Checks joint values before anything is set from them: one per joint,
    /// finite, and each movable joint's within its limits (continuous joints
    /// within ±[`crate::urdf::MAX_LIMIT`] rad). `what` names the values in the
    /// message (`joints`, `goal.joints`, ...). Fixed joints' values are not read.
    pub fn check_joint_values(&self, values: &[f32], what: &str) -> Result<()> {
        if values.len() != self.joints.len() {
            return Err(SimError::InvalidScene(format!(
                "`{what}` has {} values, {} has {} joints",
                values.len(),
                self.name,
                self.joints.len()
            )));
        }
        for (joint, &v) in self.joints.iter().zip(values) {
            let unit = if joint.kind.is_prismatic() {
                "m"
            } else {
                "rad"
            };
            let (lower, upper) = match joint.kind {
                JointKind::Fixed => continue,
                JointKind::Continuous => {
                    let m = crate::urdf::MAX_LIMIT as f32;
                    (-m, m)
                }
                JointKind::Revolute | JointKind::Prismatic => (joint.lower, joint.upper),
            };
            if !(v.is_finite() && v >= lower - JOINT_LIMIT_SLACK && v <= upper + JOINT_LIMIT_SLACK)
            {
                return Err(SimError::InvalidScene(format!(
                    "`{what}`: joint `{}` = {v} is outside its limits [{lower}, {upper}] ({unit})",
                    joint.name
                )));
            }
        }
        Ok(())
    }

    pub fn movable_joints(&self) -> impl Iterator<Item = (usize, &JointModel)> {
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.kind.is_movable())
    }
    pub fn joint_by_name(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }
    /// The joint whose child is `link`, if any.
    pub fn parent_joint_of(&self, link: usize) -> Option<usize> {
        self.joints.iter().position(|j| j.child == link)
    }
}
