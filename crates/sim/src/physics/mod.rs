//! The articulated object, the suction gripper and the 0.18 m action
//! primitive, in one of two physics profiles:
//!
//! - [`PhysicsProfile::Reference`] (the default) reproduces the paper's
//!   released simulator: a stiff, force-limited 3-axis mount driven along a
//!   straight line, a force-limited point-to-point suction, and PyBullet's
//!   default velocity motor left on every object joint (a dry brake). Its
//!   fidelity is checked against PyBullet by `tests/reference/`.
//! - [`PhysicsProfile::Ideal`] is a rapier3d multibody whose gripper follows
//!   the commanded line as far as the joint's path allows: every direction
//!   with a component along the path moves the part the full 0.18 m.
//!
//! No contacts in either (the reference protocol): only articulated dynamics,
//! joint limits, the suction joint and the gripper drive.
#![allow(
    clippy::indexing_slicing,
    reason = "joint and link indices come from the validated model this module was built from"
)]
mod ideal;
pub(crate) mod kinematics;
mod pgs;
mod reference;
mod reference_rows;

use crate::error::Result;
use crate::math::{Pose3, Vec3};
use crate::mesh::TriMesh;
use crate::model::ObjectModel;
use std::sync::Arc;

pub use reference::ReferenceParams;

/// Which simulator stands behind the action primitive.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum PhysicsProfile {
    /// The paper's PyBullet setup (see the module docs).
    #[default]
    Reference,
    /// The ideal projection of every pull onto the joint's path (rapier3d).
    Ideal,
}

impl PhysicsProfile {
    /// Every profile, the default first.
    pub const ALL: &'static [PhysicsProfile] = &[PhysicsProfile::Reference, PhysicsProfile::Ideal];

    /// `reference` or `ideal`, as on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            PhysicsProfile::Reference => "reference",
            PhysicsProfile::Ideal => "ideal",
        }
    }
}

impl std::fmt::Display for PhysicsProfile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PhysicsProfile {
    type Err = crate::SimError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "reference" => Ok(PhysicsProfile::Reference),
            "ideal" => Ok(PhysicsProfile::Ideal),
            _ => Err(crate::SimError::Other(format!(
                "unknown physics profile `{s}`; expected reference or ideal"
            ))),
        }
    }
}

/// Physical constants of the protocol; the defaults mirror the reference code.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct PhysicsConfig {
    /// Which solver acts.
    pub profile: PhysicsProfile,
    /// Force limit of the gripper drive, per mount axis (reference: 1500 N).
    pub gripper_max_force: f32,
    /// Force limit of the suction (reference: 2000 N, per axis of its constraint).
    pub suction_max_force: f32,
    /// Length of one direction action.
    pub action_length: f32,
    /// `ideal` only: rapier step and solver iterations.
    pub dt: f32,
    /// `ideal` only: solver substeps per step.
    pub substeps: usize,
    /// `ideal` only: speed of the drive's set-point along the action.
    pub action_speed: f32,
    /// `ideal` only: joint damping used when the file gives less.
    pub min_joint_damping: f32,
    /// `ideal` only: dry friction of every joint.
    pub joint_friction: f32,
    /// `reference` only: the mount, the brake and the solver.
    pub reference: ReferenceParams,
}

impl Default for PhysicsConfig {
    fn default() -> Self {
        Self {
            profile: PhysicsProfile::Reference,
            gripper_max_force: 1500.0,
            suction_max_force: 2000.0,
            action_length: 0.18,
            dt: 1.0 / 60.0,
            substeps: 4,
            action_speed: 0.6,
            min_joint_damping: 2.0,
            joint_friction: 0.5,
            reference: ReferenceParams::default(),
        }
    }
}

impl PhysicsConfig {
    /// The defaults under `profile`.
    pub fn with_profile(profile: PhysicsProfile) -> Self {
        Self {
            profile,
            ..Self::default()
        }
    }
}

/// What one direction action did to the grasped joint.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ActionOutcome {
    /// The grasped joint's value before the action.
    pub joint_before: f32,
    /// Its value after.
    pub joint_after: f32,
    /// How far the gripper moved (m).
    pub gripper_moved: f32,
    /// `ideal` only: the suction let go because its force passed the limit.
    /// The reference suction never lets go: it slips, holding at most its limit.
    pub suction_lost: bool,
    /// Simulation steps taken (reference: steps of 1/240 s).
    pub steps: usize,
}

enum Backend {
    Ideal(Box<ideal::IdealArticulation>),
    Reference(Box<reference::ReferenceArticulation>),
}

/// Farthest a grasp point may lie from its link's geometry (m): the suction
/// cup touches the surface it holds, and picked points lie on it.
pub const MAX_GRASP_GAP: f32 = 0.05;

/// One articulated object (fixed base) plus the gripper.
pub struct Articulation {
    model: Arc<ObjectModel>,
    config: PhysicsConfig,
    world_from_base: Pose3,
    backend: Backend,
}

macro_rules! dispatch {
    ($self:ident, $b:ident => $e:expr) => {
        match &$self.backend {
            Backend::Ideal($b) => $e,
            Backend::Reference($b) => $e,
        }
    };
    (mut $self:ident, $b:ident => $e:expr) => {
        match &mut $self.backend {
            Backend::Ideal($b) => $e,
            Backend::Reference($b) => $e,
        }
    };
}

impl Articulation {
    /// The object at `world_from_base`, every joint at 0, nothing grasped.
    pub fn new(model: Arc<ObjectModel>, world_from_base: Pose3, config: PhysicsConfig) -> Self {
        let backend = match config.profile {
            PhysicsProfile::Ideal => Backend::Ideal(Box::new(ideal::IdealArticulation::new(
                model.clone(),
                world_from_base,
                config.clone(),
            ))),
            PhysicsProfile::Reference => Backend::Reference(Box::new(
                reference::ReferenceArticulation::new(model.clone(), world_from_base, &config),
            )),
        };
        let mut art = Self {
            model,
            config,
            world_from_base,
            backend,
        };
        // Joints start at 0, as a URDF's zero pose; where the limits exclude 0
        // they start at the nearer limit, as the physics would push them there.
        if art
            .model
            .joints
            .iter()
            .any(|j| j.kind.is_movable() && !(j.lower <= 0.0 && 0.0 <= j.upper))
        {
            let zeros = vec![0.0; art.model.joints.len()];
            dispatch!(mut art, b => b.set_joint_positions(&zeros));
        }
        art
    }

    /// The object.
    pub fn model(&self) -> &Arc<ObjectModel> {
        &self.model
    }
    /// The physical constants.
    pub fn config(&self) -> &PhysicsConfig {
        &self.config
    }
    /// Which solver acts.
    pub fn profile(&self) -> PhysicsProfile {
        self.config.profile
    }
    /// Where the object's base stands.
    pub fn world_from_base(&self) -> Pose3 {
        self.world_from_base
    }

    /// Current value of a joint (rad or m); 0 for fixed joints.
    pub fn joint_position(&self, joint: usize) -> f32 {
        dispatch!(self, b => b.joint_position(joint))
    }

    /// Every joint's value, in the model's order (0 for fixed joints).
    pub fn joint_positions(&self) -> Vec<f32> {
        (0..self.model.joints.len())
            .map(|j| self.joint_position(j))
            .collect()
    }

    /// A joint's velocity (rad/s or m/s); 0 for fixed joints.
    pub fn joint_velocity(&self, joint: usize) -> f32 {
        dispatch!(self, b => b.joint_velocity(joint))
    }

    /// Sets every joint to the given values, zeroes velocities and lets go of
    /// anything the gripper holds. A value past a limit by more than
    /// [`crate::model::JOINT_LIMIT_SLACK`] is an error naming the joint; one
    /// within the slack is clamped.
    pub fn set_joint_positions(&mut self, values: &[f32]) -> Result<()> {
        self.model.check_joint_values(values, "joint values")?;
        dispatch!(mut self, b => b.set_joint_positions(values));
        Ok(())
    }

    /// A link's pose in the world.
    pub fn world_from_link(&self, link: usize) -> Pose3 {
        dispatch!(self, b => b.world_from_link(link))
    }

    /// World-frame pose of a joint's frame (its axis is `axis_in_joint` there).
    pub fn world_from_joint(&self, joint: usize) -> Pose3 {
        let j = &self.model.joints[joint];
        self.world_from_link(j.parent) * j.parent_from_joint
    }

    /// Joint axis (unit) and a point on it, in world frame.
    pub fn joint_axis_in_world(&self, joint: usize) -> (Vec3, Vec3) {
        let pose = self.world_from_joint(joint);
        (
            pose.rotation * self.model.joints[joint].axis_in_joint,
            pose.translation,
        )
    }

    /// The triangles of each link in world frame (with the visual colour).
    pub fn world_meshes(&self) -> Vec<(usize, TriMesh, [f32; 3])> {
        let mut out = Vec::new();
        for (l, link) in self.model.links.iter().enumerate() {
            let pose = self.world_from_link(l);
            for v in &link.visuals {
                out.push((l, v.mesh_in_link.transformed(&pose), v.color));
            }
        }
        out
    }

    /// Where the gripper is (reference: the mount's suction point).
    pub fn gripper_position(&self) -> Option<Vec3> {
        dispatch!(self, b => b.gripper_position())
    }

    /// The link the suction holds, if any.
    pub fn grasped_link(&self) -> Option<usize> {
        dispatch!(self, b => b.grasped_link())
    }

    /// Attaches the suction gripper at `point_in_world` on `link`.
    pub fn attach(&mut self, point_in_world: Vec3, link: usize) -> Result<()> {
        if link >= self.model.links.len() || !point_in_world.is_finite() {
            return Err(crate::SimError::InvalidAction(format!(
                "cannot attach to link {link} at {point_in_world}"
            )));
        }
        let gap = self.distance_to_link(point_in_world, link);
        if gap > MAX_GRASP_GAP {
            return Err(crate::SimError::InvalidAction(format!(
                "cannot attach to link `{}` at {point_in_world}: the point is {gap:.3} m from the link's geometry; suction holds a surface within {MAX_GRASP_GAP} m",
                self.model.links.get(link).map_or("?", |l| l.name.as_str())
            )));
        }
        dispatch!(mut self, b => b.attach(point_in_world, link))
    }

    /// How far a world point lies outside the link's bounding box (its visual
    /// geometry where it has some, its frame's origin where it has none).
    fn distance_to_link(&self, point_in_world: Vec3, link: usize) -> f32 {
        let point_in_link = self
            .world_from_link(link)
            .inverse_transform_point(point_in_world);
        let mut positions = self
            .model
            .links
            .get(link)
            .into_iter()
            .flat_map(|l| &l.visuals)
            .flat_map(|v| v.mesh_in_link.positions.iter().copied())
            .peekable();
        if positions.peek().is_none() {
            return point_in_link.length();
        }
        let (lo, hi) = positions.fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        );
        (point_in_link - point_in_link.clamp(lo, hi)).length()
    }

    /// Removes the gripper from the world.
    pub fn release(&mut self) {
        dispatch!(mut self, b => b.release())
    }

    /// An independent copy in the same state: what a probe acts on so that
    /// the original is not disturbed.
    pub fn duplicate(&self) -> Self {
        let backend = match &self.backend {
            Backend::Ideal(b) => Backend::Ideal(Box::new(b.duplicate())),
            Backend::Reference(b) => Backend::Reference(b.clone()),
        };
        Self {
            model: self.model.clone(),
            config: self.config.clone(),
            world_from_base: self.world_from_base,
            backend,
        }
    }

    /// Moves the gripper `action_length` along `direction` (unit, world frame)
    /// as the profile defines; `joint` is the joint whose value is reported.
    pub fn move_gripper(&mut self, direction: Vec3, joint: usize) -> Result<ActionOutcome> {
        dispatch!(mut self, b => b.move_gripper(direction, joint))
    }
}
