//! Scenes: which object, where, in which joint state; a small JSON value that
//! replays bit-identically.
use crate::error::{Result, SimError};
use crate::math::{Pose3, Quat, Vec3};
use crate::objects::{self, Category};
use crate::physics::PhysicsProfile;
use crate::urdf::{ObjectModel, load_urdf};
use rand::Rng;
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Task {
    Exploration,
    Goal,
}

impl std::str::FromStr for Task {
    type Err = SimError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "exploration" | "explore" => Ok(Task::Exploration),
            "goal" => Ok(Task::Goal),
            _ => Err(SimError::Other(format!(
                "unknown task `{s}`; expected exploration or goal"
            ))),
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ObjectSource {
    /// A procedurally generated instance, made again from its seed.
    Generated {
        category: Category,
        index: u32,
        dataset_seed: u64,
    },
    /// A URDF file on disk (PartNet-Mobility or generated).
    File { path: PathBuf },
}

impl ObjectSource {
    pub fn load(&self) -> Result<ObjectModel> {
        match self {
            ObjectSource::Generated {
                category,
                index,
                dataset_seed,
            } => objects::generate(*category, *index, *dataset_seed).model(),
            ObjectSource::File { path } => load_urdf(path),
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GoalSpec {
    /// The joint that must move (index into the model's joints).
    pub joint: usize,
    /// Joint values of the goal state.
    pub joints: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    pub task: Task,
    pub category: Option<Category>,
    pub object: ObjectSource,
    /// Base position on the floor plane and yaw (rad).
    pub base_xy: [f32; 2],
    pub base_yaw: f32,
    /// Initial joint values, one per model joint (fixed joints 0).
    pub joints: Vec<f32>,
    pub goal: Option<GoalSpec>,
    /// The physics the scene runs under (absent in older scene files: `reference`).
    #[serde(default)]
    pub physics: PhysicsProfile,
}

/// Goal scenes put the initial state at most this many δ from the goal, so
/// that the paper's 15 steps can reach it.
pub const GOAL_STEPS: usize = 15;

impl Scene {
    pub fn world_from_base(&self) -> Pose3 {
        Pose3::from_parts(
            Vec3::new(self.base_xy[0], self.base_xy[1], 0.0),
            Quat::from_rotation_z(self.base_yaw),
        )
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    pub fn from_json(text: &str) -> Result<Scene> {
        serde_json::from_str(text).map_err(|e| SimError::InvalidScene(format!("scene JSON: {e}")))
    }

    /// Checks the scene against its model: one value per joint, finite, goal joint movable.
    pub fn validate(&self, model: &ObjectModel) -> Result<()> {
        let n = model.joints.len();
        if self.joints.len() != n {
            return Err(SimError::InvalidScene(format!(
                "`joints` has {} values, the object has {n} joints",
                self.joints.len()
            )));
        }
        if !self
            .base_xy
            .iter()
            .chain([&self.base_yaw])
            .chain(&self.joints)
            .all(|v| v.is_finite())
        {
            return Err(SimError::InvalidScene(
                "base pose and joint values must be finite".into(),
            ));
        }
        if let Some(g) = &self.goal {
            if g.joints.len() != n {
                return Err(SimError::InvalidScene(format!(
                    "`goal.joints` has {} values, the object has {n} joints",
                    g.joints.len()
                )));
            }
            if !model
                .joints
                .get(g.joint)
                .is_some_and(|j| j.kind.is_movable())
            {
                return Err(SimError::InvalidScene(format!(
                    "`goal.joint` {} is not a movable joint",
                    g.joint
                )));
            }
        }
        if model.movable_joints().next().is_none() {
            return Err(SimError::InvalidScene(format!(
                "{} has no movable joint",
                model.source.display()
            )));
        }
        Ok(())
    }
}

/// One joint's initial value: 15% near the lower limit, 15% at the upper, else uniform.
fn sample_joint_value(rng: &mut impl Rng, lower: f32, upper: f32) -> f32 {
    let (lo, hi) = if lower.is_finite() && upper.is_finite() {
        (lower, upper)
    } else {
        (-std::f32::consts::PI, std::f32::consts::PI)
    };
    let r: f32 = rng.random();
    if r < 0.15 {
        lo + 0.1 * (hi - lo)
    } else if r < 0.30 {
        hi
    } else {
        rng.random_range(lo..=hi)
    }
}

/// Samples a scene for `model`: placement and joint state as the protocol says.
/// `goal_joints` restricts which joints a goal may be set on (e.g. visible ones).
pub fn sample_scene(
    rng: &mut impl Rng,
    task: Task,
    category: Option<Category>,
    object: ObjectSource,
    model: &ObjectModel,
    goal_joints: Option<&[usize]>,
) -> Result<Scene> {
    let base_xy = [
        rng.random_range(-0.05..0.05),
        -0.5 + rng.random_range(-0.05..0.05),
    ];
    let base_yaw = rng.random_range(-45f32..=45.0).to_radians();
    let mut joints: Vec<f32> = model
        .joints
        .iter()
        .map(|j| {
            if j.kind.is_movable() {
                sample_joint_value(rng, j.lower, j.upper)
            } else {
                0.0
            }
        })
        .collect();
    let goal = match task {
        Task::Exploration => None,
        Task::Goal => {
            let candidates: Vec<usize> = match goal_joints {
                Some(list) => list.to_vec(),
                None => model.movable_joints().map(|(i, _)| i).collect(),
            };
            if candidates.is_empty() {
                return Err(SimError::InvalidScene(format!(
                    "{}: no movable joint for a goal",
                    model.source.display()
                )));
            }
            let j = candidates[rng.random_range(0..candidates.len())];
            let jm = &model.joints[j];
            let (lo, hi) = if jm.lower.is_finite() {
                (jm.lower, jm.upper)
            } else {
                (-1.5, 1.5)
            };
            let reach = (hi - lo).min(GOAL_STEPS as f32 * crate::env::DELTA);
            let (goal_v, init_v) = if rng.random_bool(0.5) {
                (hi, hi - reach)
            } else {
                (lo, lo + reach)
            };
            joints[j] = init_v;
            let mut goal = joints.clone();
            goal[j] = goal_v;
            Some(GoalSpec {
                joint: j,
                joints: goal,
            })
        }
    };
    Ok(Scene {
        task,
        category,
        object,
        base_xy,
        base_yaw,
        joints,
        goal,
        physics: PhysicsProfile::default(),
    })
}
