//! The articulated object the simulator works on: links with their visuals
//! and inertia, joints with their frames, axes and limits. The URDF loader
//! (`crate::urdf`) and the generator (`crate::objects`) produce it; physics,
//! rendering and labels read it. [`ObjectPose`] is how a file's object is
//! placed in a scene.
use crate::error::{Result, SimError};
use crate::math::{Mat3, Pose3, Quat, Vec3};
use crate::mesh::TriMesh;
use std::path::PathBuf;

/// A URDF joint's type (floating and planar joints are refused by the loader).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// No motion.
    Fixed,
    /// A hinge with limits.
    Revolute,
    /// A hinge without limits.
    Continuous,
    /// A slide with limits.
    Prismatic,
}

impl JointKind {
    /// Anything but fixed.
    pub fn is_movable(self) -> bool {
        self != JointKind::Fixed
    }
    /// A slide (metres), not a hinge (radians).
    pub fn is_prismatic(self) -> bool {
        self == JointKind::Prismatic
    }
}

/// One `<visual>` of a link.
#[derive(Clone, Debug)]
pub struct VisualModel {
    /// Mesh in the link frame (origin and scale applied).
    pub mesh_in_link: TriMesh,
    /// Linear RGB in [0, 1] (the material's, the MTL's, or white).
    pub color: [f32; 3],
    /// The material's alpha: 1 is opaque; below 1 the visual is drawn as
    /// glass (see [`crate::render::RenderMesh::opacity`]).
    pub opacity: f32,
}

/// One `<link>`.
#[derive(Clone, Debug)]
pub struct LinkModel {
    /// Its name in the file.
    pub name: String,
    /// What is drawn.
    pub visuals: Vec<VisualModel>,
    /// Mass (kg).
    pub mass: f32,
    /// Centre of mass in the link frame.
    pub com_in_link: Vec3,
    /// Inertia tensor about the centre of mass, in link axes.
    pub inertia_in_link: Mat3,
    /// True when the file gave no `<inertial>` and one was derived.
    pub inertial_derived: bool,
}

/// One `<joint>`.
#[derive(Clone, Debug)]
pub struct JointModel {
    /// Its name in the file.
    pub name: String,
    /// Its type.
    pub kind: JointKind,
    /// The parent link's index.
    pub parent: usize,
    /// The child link's index.
    pub child: usize,
    /// Joint frame (= child frame at joint value 0) in the parent link frame.
    pub parent_from_joint: Pose3,
    /// Unit axis in the joint frame.
    pub axis_in_joint: Vec3,
    /// Limits; continuous joints have (-inf, inf).
    pub lower: f32,
    /// Upper limit (rad or m).
    pub upper: f32,
    /// `<dynamics damping>`.
    pub damping: f32,
    /// `<dynamics friction>`.
    pub friction: f32,
}

/// Bounds every model keeps, whichever reader made it. They are f32's
/// comfortable range, not any object's size.
///
/// Largest coordinate (m) of any origin or vertex in a link's frame.
pub const MAX_COORDINATE: f32 = 1000.0;
/// Joint limits, in metres (prismatic) or radians (revolute): a wider range
/// is a continuous joint written as a limited one, or a unit mistake.
pub const MAX_LIMIT: f64 = 1000.0;

/// How far (rad or m) a joint value given as input may lie past a limit:
/// more than the solvers overshoot one by, far less than a part's travel.
pub const JOINT_LIMIT_SLACK: f32 = 0.01;

/// A loaded, validated articulated object: a tree of links rooted at `root`.
#[derive(Clone, Debug)]
pub struct ObjectModel {
    /// The file it was read from.
    pub source: PathBuf,
    /// The robot's name.
    pub name: String,
    /// Its links.
    pub links: Vec<LinkModel>,
    /// Joints ordered so that every parent link appears before its child.
    pub joints: Vec<JointModel>,
    /// The root link's index.
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
    /// within ±[`MAX_LIMIT`] rad). `what` names the values in the
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
                    let m = MAX_LIMIT as f32;
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

    /// The joints that move, with their indices.
    pub fn movable_joints(&self) -> impl Iterator<Item = (usize, &JointModel)> {
        self.joints
            .iter()
            .enumerate()
            .filter(|(_, j)| j.kind.is_movable())
    }
    /// The index of the joint called `name`.
    pub fn joint_by_name(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }
    /// The joint whose child is `link`, if any.
    pub fn parent_joint_of(&self, link: usize) -> Option<usize> {
        self.joints.iter().position(|j| j.child == link)
    }
}

/// How the object file sits in the scene, as the paper's code reads it from a
/// PartNet-Mobility `object_meta_info.json`: a rotation from the file's axes
/// (so the front faces the camera), a lift onto the floor and a global scale.
/// Generated objects need none of it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ObjectPose {
    /// Quaternion (x, y, z, w) applied before the scene's yaw.
    pub orientation: [f32; 4],
    /// Lift of the base above the floor, in the file's units (times `scale`).
    pub offset_z: f32,
    /// Uniform scale of the whole object (PartNet-Mobility: 0.55).
    pub scale: f32,
}

impl Default for ObjectPose {
    fn default() -> Self {
        Self {
            orientation: [0.0, 0.0, 0.0, 1.0],
            offset_z: 0.0,
            scale: 1.0,
        }
    }
}

impl ObjectPose {
    /// As the file is: no rotation, lift or scale.
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }

    /// A unit quaternion, a lift within the simulator's extent, a scale in (0, 1000].
    pub fn validate(&self) -> Result<()> {
        let norm = Quat::from_array(self.orientation).length();
        if !(self.orientation.iter().all(|v| v.is_finite()) && (norm - 1.0).abs() <= 0.01) {
            return Err(SimError::InvalidScene(format!(
                "`pose.orientation` must be a unit quaternion (x, y, z, w; norm 1 within 0.01), got {:?} (norm {norm})",
                self.orientation
            )));
        }
        if !(self.offset_z.is_finite() && self.offset_z.abs() <= MAX_COORDINATE) {
            return Err(SimError::InvalidScene(format!(
                "`pose.offset_z` must be within ±{MAX_COORDINATE} m, got {}",
                self.offset_z
            )));
        }
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1000.0) {
            return Err(SimError::InvalidScene(format!(
                "`pose.scale` must be in (0, 1000], got {}",
                self.scale
            )));
        }
        Ok(())
    }
}
