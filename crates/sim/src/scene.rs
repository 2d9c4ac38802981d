//! Scenes: which object, where, in which joint state; a small JSON value that
//! replays bit-identically.
use crate::error::{Result, SimError};
use crate::math::{Pose3, Quat, Vec3};
// The placement lives beside the model; scenes and files name it here too.
use crate::model::ObjectModel;
pub use crate::model::ObjectPose;
use crate::objects::{self, Category};
use crate::physics::PhysicsProfile;
use crate::urdf::{MAX_COORDINATE, load_urdf};
use rand::Rng;
use std::path::PathBuf;

/// The paper's two tasks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Task {
    /// Reach as many new states as possible.
    Exploration,
    /// Reach the state of a goal image.
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

/// Where a scene's object comes from.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum ObjectSource {
    /// A procedurally generated instance, made again from its seed.
    Generated {
        /// Its category.
        category: Category,
        /// Its instance index.
        index: u32,
        /// The generated dataset's seed.
        dataset_seed: u64,
    },
    /// A URDF file on disk (PartNet-Mobility or generated).
    File {
        /// The URDF.
        path: PathBuf,
        /// Where the file's object sits, given by the user (`--scale`,
        /// `--pose`); absent: from `object_meta_info.json` beside the file.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pose: Option<ObjectPose>,
    },
}

impl ObjectSource {
    /// A URDF file placed by its `object_meta_info.json`, if any.
    pub fn file(path: impl Into<PathBuf>) -> Self {
        ObjectSource::File {
            path: path.into(),
            pose: None,
        }
    }

    /// Where the file's object sits: the pose given with the file, else
    /// `object_meta_info.json` beside a URDF when there is one
    /// (PartNet-Mobility's placement, as the paper's code reads it), else as
    /// the file is.
    pub fn pose(&self) -> Result<ObjectPose> {
        let ObjectSource::File { path, pose } = self else {
            return Ok(objects::generated_pose());
        };
        if let Some(p) = pose {
            p.validate()?;
            return Ok(*p);
        }
        let meta = path.with_file_name("object_meta_info.json");
        if !meta.is_file() {
            return Ok(ObjectPose::default());
        }
        #[derive(serde::Deserialize)]
        struct Meta {
            orientation: [f32; 4],
            offset_z: f32,
            scale: f32,
        }
        // A few numbers: a FIFO, a device or a huge file is refused unread.
        let text = crate::fsio::read_text(&meta, 1 << 20)?;
        let m: Meta = serde_json::from_str(&text).map_err(|e| {
            SimError::InvalidScene(format!(
                "{}: {e}; expected `orientation` (4 numbers, x y z w), `offset_z` and `scale`",
                meta.display()
            ))
        })?;
        let pose = ObjectPose {
            orientation: m.orientation,
            offset_z: m.offset_z,
            scale: m.scale,
        };
        pose.validate()
            .map_err(|e| SimError::InvalidScene(format!("{}: {e}", meta.display())))?;
        Ok(pose)
    }

    /// The object as its file has it; [`Scene::load_model`] places and scales it.
    pub fn load(&self) -> Result<ObjectModel> {
        match self {
            ObjectSource::Generated {
                category,
                index,
                dataset_seed,
            } => objects::generate(*category, *index, *dataset_seed).file_model(),
            ObjectSource::File { path, .. } => load_urdf(path),
        }
    }

    /// The object at scene size: its file scaled by its own pose's scale
    /// (what a scene sampled for it will hold).
    pub fn load_scaled(&self) -> Result<ObjectModel> {
        self.load()?.scaled(self.pose()?.scale)
    }
}

/// A goal task's goal: which joint must move, and to what state.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GoalSpec {
    /// The joint that must move (index into the model's joints).
    pub joint: usize,
    /// Joint values of the goal state.
    pub joints: Vec<f32>,
}

/// One scene of the benchmark: an object, where it stands, its joints and,
/// in the goal task, the goal. Its JSON is the scene file format.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    /// Exploration or goal.
    pub task: Task,
    /// The object's category (None for a file scored as its own row).
    pub category: Option<Category>,
    /// The object.
    pub object: ObjectSource,
    /// Base position on the floor plane and yaw (rad).
    pub base_xy: [f32; 2],
    /// Yaw of the base about the vertical (rad).
    pub base_yaw: f32,
    /// Initial joint values, one per model joint (fixed joints 0).
    pub joints: Vec<f32>,
    /// The goal, in the goal task.
    pub goal: Option<GoalSpec>,
    /// The physics the scene runs under (absent in older scene files: `reference`).
    #[serde(default)]
    pub physics: PhysicsProfile,
    /// Placement of the object file (absent: as the file is, unscaled).
    #[serde(default, skip_serializing_if = "ObjectPose::is_identity")]
    pub pose: ObjectPose,
}

/// The strict protocol's goal budget (the paper's text; its code uses the
/// category's budget).
pub const GOAL_STEPS: usize = 15;

/// How far the reference moves a freely moving grasp point in one action (m).
const FREE_PULL: f32 = 0.13;

/// A joint's lever: the largest distance of its part's geometry from a hinge
/// axis (1 for a slider, whose value is in metres already).
fn joint_lever(model: &ObjectModel, joint: usize) -> f32 {
    let Some(jm) = model.joints.get(joint) else {
        return 1.0;
    };
    if jm.kind.is_prismatic() {
        return 1.0;
    }
    let axis = jm.axis_in_joint;
    // The child's frame is the joint frame at value 0, so its vertices are
    // already in joint coordinates.
    model
        .links
        .get(jm.child)
        .into_iter()
        .flat_map(|l| &l.visuals)
        .flat_map(|v| v.mesh_in_link.positions.iter())
        .map(|p| (*p - axis * p.dot(axis)).length())
        .fold(0.0, f32::max)
}

impl Scene {
    /// Where the object's base stands: on the floor at `base_xy`, turned by
    /// `base_yaw` after its pose's orientation, lifted by its offset.
    pub fn world_from_base(&self) -> Pose3 {
        let p = &self.pose;
        Pose3::from_parts(
            Vec3::new(self.base_xy[0], self.base_xy[1], p.scale * p.offset_z),
            Quat::from_rotation_z(self.base_yaw) * Quat::from_array(p.orientation).normalize(),
        )
    }

    /// The scene's object, loaded and scaled by its pose.
    pub fn load_model(&self) -> Result<ObjectModel> {
        self.pose.validate()?;
        self.object.load()?.scaled(self.pose.scale)
    }

    /// The scene as JSON (the scene file format).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// A scene from its JSON; an error names what is wrong.
    pub fn from_json(text: &str) -> Result<Scene> {
        serde_json::from_str(text).map_err(|e| SimError::InvalidScene(format!("scene JSON: {e}")))
    }

    /// Checks the scene against its model: one value per joint, finite, goal joint movable.
    pub fn validate(&self, model: &ObjectModel) -> Result<()> {
        self.pose.validate()?;
        if let Some(v) = self
            .base_xy
            .iter()
            .find(|v| !(v.is_finite() && v.abs() <= MAX_COORDINATE))
        {
            return Err(SimError::InvalidScene(format!(
                "`base_xy` must be within ±{MAX_COORDINATE} m of the origin, got {v} in {:?}",
                self.base_xy
            )));
        }
        if !self.base_yaw.is_finite() {
            return Err(SimError::InvalidScene(format!(
                "`base_yaw` must be finite, got {}",
                self.base_yaw
            )));
        }
        model.check_joint_values(&self.joints, "joints")?;
        if let Some(g) = &self.goal {
            model.check_joint_values(&g.joints, "goal.joints")?;
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

/// Samples a scene for `model` (the object as the scene loads it: scaled by
/// the pose its source gives): placement and joint state as the protocol says.
/// `goal_joints` restricts which joints a goal may be set on (e.g. visible ones).
pub fn sample_scene(
    rng: &mut impl Rng,
    task: Task,
    category: Option<Category>,
    object: ObjectSource,
    model: &ObjectModel,
    goal_joints: Option<&[usize]>,
) -> Result<Scene> {
    let object_pose = object.pose()?;
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
            let j = candidates
                .get(rng.random_range(0..candidates.len()))
                .copied()
                .unwrap_or_default();
            let Some(jm) = model.joints.get(j) else {
                return Err(SimError::InvalidScene(format!(
                    "joint {j} is not in the model"
                )));
            };
            let (lo, hi) = if jm.lower.is_finite() {
                (jm.lower, jm.upper)
            } else {
                (-1.5, 1.5)
            };
            // The goal sits at a limit; the start at most 70% as far from it as
            // the category's budget of free pulls can cover with this part's
            // lever (the reference moves a free grasp point about 0.13 m per
            // action; a grasp short of the farthest point moves the part less),
            // and at least half of that.
            let budget = category.map_or(GOAL_STEPS, |c| c.step_budget());
            let per_step = FREE_PULL / joint_lever(model, j).max(FREE_PULL);
            let reach = (hi - lo).min(0.7 * budget as f32 * per_step);
            let gap = reach * rng.random_range(0.5f32..=1.0);
            let (goal_v, init_v) = if rng.random_bool(0.5) {
                (hi, hi - gap)
            } else {
                (lo, lo + gap)
            };
            let mut goal = joints.clone();
            for (values, v) in [(&mut joints, init_v), (&mut goal, goal_v)] {
                if let Some(slot) = values.get_mut(j) {
                    *slot = v;
                }
            }
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
        pose: object_pose,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        Scene {
            task: Task::Exploration,
            category: Some(Category::Door),
            object: ObjectSource::Generated {
                category: Category::Door,
                index: 0,
                dataset_seed: 0,
            },
            base_xy: [0.0, -0.5],
            base_yaw: 0.1,
            joints: vec![0.3],
            goal: None,
            physics: PhysicsProfile::Ideal,
            pose: ObjectPose {
                orientation: [
                    0.0,
                    0.0,
                    std::f32::consts::FRAC_1_SQRT_2,
                    std::f32::consts::FRAC_1_SQRT_2,
                ],
                offset_z: 0.4,
                scale: 0.55,
            },
        }
    }

    #[test]
    fn physics_and_pose_round_trip_and_default_when_absent() {
        let s = scene();
        assert_eq!(Scene::from_json(&s.to_json()).unwrap(), s);
        // A scene file written before the two fields existed.
        let old = r#"{"task":"exploration","category":"Door","object":{"kind":"generated","category":"Door","index":0,"dataset_seed":0},"base_xy":[0.0,-0.5],"base_yaw":0.1,"joints":[0.3],"goal":null}"#;
        let s = Scene::from_json(old).unwrap();
        assert_eq!(s.physics, PhysicsProfile::Reference);
        assert_eq!(s.pose, ObjectPose::default());
    }

    #[test]
    fn the_pose_lifts_turns_and_scales_the_base() {
        let s = scene();
        let p = s.world_from_base();
        assert!((p.translation.z - 0.55 * 0.4).abs() < 1e-6);
        // The file's +x turns to +y (the pose's 90 degrees) plus the yaw.
        let x = p.rotation * Vec3::X;
        assert!((x.y - 0.1f32.cos()).abs() < 1e-5, "{x}");
        let bad = Scene {
            pose: ObjectPose {
                scale: -1.0,
                ..ObjectPose::default()
            },
            ..scene()
        };
        assert!(bad.load_model().is_err());
    }

    #[test]
    fn object_meta_info_beside_a_urdf_sets_the_pose_and_bad_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let urdf = objects::generate(Category::Microwave, 0, 0)
            .write(dir.path())
            .unwrap();
        let source = ObjectSource::file(urdf.clone());
        assert_eq!(source.pose().unwrap(), objects::generated_pose());
        let meta = urdf.with_file_name("object_meta_info.json");
        std::fs::write(
            &meta,
            r#"{"orientation":[0,0,0,1],"offset_z":0.3,"scale":0.5,"moveable_link":{}}"#,
        )
        .unwrap();
        assert_eq!(source.pose().unwrap().offset_z, 0.3);
        std::fs::write(&meta, r#"{"orientation":[0,0,0],"scale":0.5}"#).unwrap();
        let e = source.pose().unwrap_err().to_string();
        assert!(e.contains("object_meta_info.json"), "{e}");
        std::fs::remove_file(&meta).unwrap();
        assert_eq!(source.pose().unwrap(), ObjectPose::default());
    }

    #[test]
    fn magnitudes_that_parse_but_mean_nothing_are_refused_by_name() {
        let s = scene();
        let model = s.load_model().unwrap();
        s.validate(&model).unwrap();
        let refused = |bad: Scene, expect: &str| {
            let e = bad.validate(&model).unwrap_err().to_string();
            assert!(e.contains(expect), "{e} does not say {expect:?}");
        };
        let pose = |orientation: [f32; 4], offset_z: f32| Scene {
            pose: ObjectPose {
                orientation,
                offset_z,
                ..s.pose
            },
            ..s.clone()
        };
        refused(pose([1e30, 0.0, 0.0, 0.0], 0.4), "unit quaternion");
        refused(pose([0.0, 0.0, 0.0, 2.0], 0.4), "(norm 2)");
        refused(
            pose([0.0, 0.0, 0.0, 1.0], 1e30),
            "`pose.offset_z` must be within",
        );
        refused(
            Scene {
                base_xy: [1e30, 0.0],
                ..s.clone()
            },
            "`base_xy` must be within",
        );
        refused(
            Scene {
                base_yaw: f32::NAN,
                ..s.clone()
            },
            "`base_yaw` must be finite",
        );
        let door = model.movable_joints().next().unwrap().1;
        let mut joints = s.joints.clone();
        joints[0] = 1e6;
        refused(
            Scene {
                joints,
                ..s.clone()
            },
            &format!(
                "`joints`: joint `{}` = 1000000 is outside its limits",
                door.name
            ),
        );
        // Within the slack a value is the limit it rounds to, not an error.
        let mut joints = s.joints.clone();
        joints[0] = door.upper + 0.5 * crate::model::JOINT_LIMIT_SLACK;
        Scene {
            joints,
            ..s.clone()
        }
        .validate(&model)
        .unwrap();
        refused(
            Scene {
                joints: vec![],
                ..s.clone()
            },
            "`joints` has 0 values",
        );
    }
}
