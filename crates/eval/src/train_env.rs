//! The environment Python trains against: scenes sampled from a split,
//! observations as tensors, scripted actions for exploration and baselines.
#![allow(
    clippy::indexing_slicing,
    reason = "joint and category indices come from the validated configuration and model"
)]
use crate::learned::{camera_frame, observation_tensor, project_pixel};
use crate::policy::{Decision, Observation, Policy};
use crate::scripted::{OraclePolicy, RandomPolicy};
use crate::{EvalError, Result};
use ndarray::Array3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use umpnet_policy::build_observation_into;
use umpnet_sim::camera::{Camera, GlassDepth};
use umpnet_sim::env::{Pick, SimEnv, StepLabels};
use umpnet_sim::math::Vec3;
use umpnet_sim::objects::{Category, InstanceSplit, nth_instance};
use umpnet_sim::physics::PhysicsProfile;
use umpnet_sim::render::{Frame, RendererKind, create_renderer};
use umpnet_sim::scene::{ObjectSource, Scene, Task};

/// Instances per category a training environment draws from.
pub const TRAIN_INSTANCES: u32 = 16;

/// What scenes a [`TrainEnv`] samples.
#[derive(Clone, Debug)]
pub struct EnvConfig {
    /// Categories to draw from.
    pub categories: Vec<Category>,
    /// Training categories' instances: train or held-out test.
    pub split: InstanceSplit,
    /// Exploration or goal.
    pub task: Task,
    /// Observation (height, width).
    pub resolution: (u32, u32),
    /// The renderer.
    pub renderer: RendererKind,
    /// Seed of the generated objects.
    pub dataset_seed: u64,
    /// A URDF file (and where it sits) instead of generated instances.
    pub object: Option<ObjectSource>,
    /// The physics profile.
    pub physics: PhysicsProfile,
    /// What the camera's depth reads on glass.
    pub glass_depth: GlassDepth,
}

impl EnvConfig {
    /// The training categories (and with `Test` the test categories too), at
    /// 96x128, with the auto renderer and the reference physics.
    pub fn new(task: Task, split: InstanceSplit) -> Self {
        let categories = Category::ALL
            .iter()
            .copied()
            .filter(|c| c.is_train() || split == InstanceSplit::Test)
            .collect();
        Self {
            categories,
            split,
            task,
            resolution: (96, 128),
            renderer: RendererKind::Auto,
            dataset_seed: 0,
            object: None,
            physics: PhysicsProfile::default(),
            glass_depth: GlassDepth::Surface,
        }
    }
}

/// One observation as arrays.
#[derive(Clone, Debug)]
pub struct EnvObservation {
    /// H x W x 10: xyz, rgb, normal, depth.
    pub image: Array3<f32>,
    /// Per pixel: the segment id (render::Segment).
    pub segmentation: Vec<u32>,
    /// fx, fy, cx, cy.
    pub intrinsics: [f32; 4],
    /// Camera pose, row-major.
    pub world_from_camera: [[f32; 4]; 4],
    /// Where the gripper is in the image (row, col), once it holds something.
    pub gripper_pixel: Option<(usize, usize)>,
}

/// The small parts of an observation, beside the image and segmentation a
/// caller had written into its own buffers ([`TrainEnv::observe_into`]).
#[derive(Clone, Copy, Debug)]
pub struct ObsMeta {
    /// fx, fy, cx, cy.
    pub intrinsics: [f32; 4],
    /// Camera pose, row-major.
    pub world_from_camera: [[f32; 4]; 4],
    /// Where the gripper is in the image, once it holds something.
    pub gripper_pixel: Option<(usize, usize)>,
}

/// What a position action (a grasp at a pixel) did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PositionInfo {
    /// It holds a link that a movable joint moves (in the goal task: the goal joint).
    pub valid: bool,
    /// The link under the pixel.
    pub link: Option<usize>,
    /// The joint that moves it.
    pub joint: Option<usize>,
    /// The grasped point.
    pub point_in_world: Option<[f32; 3]>,
    /// The grasped joint's limits and the paper protocol's closeness
    /// threshold for it (see `protocol::threshold`).
    pub limits: Option<[f32; 2]>,
    /// The protocol's threshold for that joint.
    pub threshold: Option<f32>,
}

/// A scripted policy's next action, for the Python bindings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScriptedAction {
    /// Grasp at (row, col).
    Pixel(u32, u32),
    /// Move along a direction (world frame).
    Direction([f32; 3]),
    /// Stop the episode.
    Stop,
}

/// Draws the new state of every environment whose last step was deferred
/// (`step_*_deferred`), all in one batch: one wgpu submission for the lot, or
/// the CPU renderer in parallel across environments. The frames are the
/// ones the immediate steps draw, bit for bit.
pub fn render_pending(envs: &mut [TrainEnv]) -> Result<()> {
    let mut requests = Vec::new();
    let mut which = Vec::new();
    for (i, e) in envs.iter_mut().enumerate() {
        if let (None, Some(env)) = (&e.frame, e.env.as_mut()) {
            requests.push(env.render_request());
            which.push(i);
        }
    }
    let frames = umpnet_sim::render::render_batch(requests)?;
    for (i, frame) in which.into_iter().zip(frames) {
        if let Some(e) = envs.get_mut(i) {
            e.frame = Some(frame);
        }
    }
    Ok(())
}

/// One environment for training and the Python bindings: scenes sampled from its seed, observations as arrays.
pub struct TrainEnv {
    cfg: EnvConfig,
    rng: ChaCha8Rng,
    env: Option<SimEnv>,
    frame: Option<Frame>,
    reference_frame: Option<Frame>,
    reference: Option<Array3<f32>>,
    oracle: OraclePolicy,
    random: RandomPolicy,
    history: Vec<crate::policy::StepRecord>,
}

impl TrainEnv {
    /// An environment drawing scenes from `seed`.
    pub fn new(cfg: EnvConfig, seed: u64) -> Result<Self> {
        if cfg.categories.is_empty() && cfg.object.is_none() {
            return Err(EvalError::Episode("no categories to sample from".into()));
        }
        let mut random = RandomPolicy::default();
        random.reset(seed ^ 0xA5A5);
        Ok(Self {
            cfg,
            rng: ChaCha8Rng::seed_from_u64(seed),
            env: None,
            frame: None,
            reference_frame: None,
            reference: None,
            oracle: OraclePolicy::default(),
            random,
            history: Vec::new(),
        })
    }

    /// Its configuration.
    pub fn config(&self) -> &EnvConfig {
        &self.cfg
    }

    /// A fresh scene from this environment's random stream.
    pub fn sample_scene(&mut self) -> Result<Scene> {
        let (object, category) = match &self.cfg.object {
            Some(o) => (o.clone(), None),
            None => {
                let c = self.cfg.categories[self.rng.random_range(0..self.cfg.categories.len())];
                let split = if c.is_train() {
                    self.cfg.split
                } else {
                    InstanceSplit::Test
                };
                let pool = if split == InstanceSplit::Train {
                    TRAIN_INSTANCES
                } else {
                    crate::benchmark::INSTANCES_PER_CATEGORY
                };
                let index = nth_instance(c, split, self.rng.random_range(0..pool));
                (
                    ObjectSource::Generated {
                        category: c,
                        index,
                        dataset_seed: self.cfg.dataset_seed,
                    },
                    Some(c),
                )
            }
        };
        crate::benchmark::sample_visible_scene(
            &mut self.rng,
            self.cfg.task,
            category,
            object,
            self.cfg.physics,
        )
    }

    fn meta(&self, frame: &Frame) -> Result<ObsMeta> {
        let env = self
            .env
            .as_ref()
            .ok_or_else(|| EvalError::Episode("reset() first".into()))?;
        Ok(ObsMeta {
            intrinsics: [
                frame.intrinsics.fx,
                frame.intrinsics.fy,
                frame.intrinsics.cx,
                frame.intrinsics.cy,
            ],
            world_from_camera: frame
                .world_from_camera
                .to_mat4()
                .transpose()
                .to_cols_array_2d(),
            gripper_pixel: env
                .articulation()
                .gripper_position()
                .map(|g| project_pixel(frame, g)),
        })
    }

    fn observe(&self, frame: &Frame) -> Result<EnvObservation> {
        let meta = self.meta(frame)?;
        Ok(EnvObservation {
            image: observation_tensor(frame)?,
            segmentation: frame.segmentation.clone(),
            intrinsics: meta.intrinsics,
            world_from_camera: meta.world_from_camera,
            gripper_pixel: meta.gripper_pixel,
        })
    }

    fn current_frame(&self) -> Result<&Frame> {
        self.frame.as_ref().ok_or_else(|| {
            EvalError::Episode(match self.env {
                None => "reset() first".into(),
                Some(_) => "the last step was deferred: render_pending() draws it".into(),
            })
        })
    }

    /// The current observation written into the caller's buffers: `image`
    /// (H x W x 10, row-major) and `segmentation` (H x W). Every element is
    /// overwritten; nothing is allocated per call. The same values as
    /// [`TrainEnv::reset_observation`], bit for bit.
    pub fn observe_into(&self, image: &mut [f32], segmentation: &mut [i64]) -> Result<ObsMeta> {
        let frame = self.current_frame()?;
        if segmentation.len() != frame.segmentation.len() {
            return Err(EvalError::Episode(format!(
                "segmentation buffer has {} values, the frame {}",
                segmentation.len(),
                frame.segmentation.len()
            )));
        }
        build_observation_into(&camera_frame(frame), image)?;
        for (out, s) in segmentation.iter_mut().zip(&frame.segmentation) {
            *out = i64::from(*s);
        }
        self.meta(frame)
    }

    /// The articulation labels of the current observation: per pixel, the
    /// opening direction of its part and, in a goal scene, its displacement
    /// to the goal state ([`umpnet_sim::fields::ArticulationFields`]).
    pub fn articulation_fields(&self) -> Result<umpnet_sim::fields::ArticulationFields> {
        let frame = self.current_frame()?;
        let env = self
            .env
            .as_ref()
            .ok_or_else(|| EvalError::Episode("reset() first".into()))?;
        Ok(env.articulation_fields(frame)?)
    }

    /// The reference observation (see [`TrainEnv::reference`]) written into `out`.
    pub fn reference_into(&self, out: &mut [f32]) -> Result<()> {
        let r = self
            .reference
            .as_ref()
            .ok_or_else(|| EvalError::Episode("reset() first".into()))?;
        match r.as_slice() {
            Some(values) if values.len() == out.len() => {
                out.copy_from_slice(values);
                Ok(())
            }
            _ => Err(EvalError::Episode(format!(
                "reference buffer has {} values, the observation {}",
                out.len(),
                r.len()
            ))),
        }
    }

    /// Starts an episode on `scene`, or on a newly sampled one.
    pub fn reset(&mut self, scene: Option<Scene>) -> Result<EnvObservation> {
        self.reset_in_place(scene)?;
        self.reset_observation()
    }

    /// [`TrainEnv::reset`] without building the observation (see [`TrainEnv::observe_into`]).
    pub fn reset_in_place(&mut self, scene: Option<Scene>) -> Result<()> {
        let scene = match scene {
            Some(s) => s,
            None => self.sample_scene()?,
        };
        let camera = Camera {
            glass_depth: self.cfg.glass_depth,
            ..Camera::reference(self.cfg.resolution.0, self.cfg.resolution.1)
        };
        match self.env.as_mut() {
            Some(env) if env.scene().object == scene.object && env.camera() == &camera => {
                env.reset(scene)?
            }
            _ => {
                self.env = Some(SimEnv::new(
                    scene,
                    camera,
                    create_renderer(self.cfg.renderer)?,
                )?)
            }
        }
        let env = self
            .env
            .as_mut()
            .ok_or_else(|| EvalError::Episode("no environment".into()))?;
        let frame = env.render()?;
        let reference_frame = match env.scene().task {
            Task::Goal => env.render_goal()?.unwrap_or_else(|| frame.clone()),
            Task::Exploration => frame.clone(),
        };
        self.reference = Some(observation_tensor(&reference_frame)?);
        self.reference_frame = Some(reference_frame);
        self.oracle.reset(0);
        self.history.clear();
        self.frame = Some(frame);
        Ok(())
    }

    /// The current scene, after a reset.
    pub fn scene(&self) -> Option<&Scene> {
        self.env.as_ref().map(|e| e.scene())
    }

    /// The simulated scene, after a reset.
    pub fn sim(&self) -> Option<&SimEnv> {
        self.env.as_ref()
    }

    /// The reference observation: the initial one (exploration) or the goal.
    pub fn reference(&self) -> Option<&Array3<f32>> {
        self.reference.as_ref()
    }

    /// The object's joint values now.
    pub fn joint_positions(&self) -> Vec<f32> {
        self.env
            .as_ref()
            .map(|e| e.joint_positions())
            .unwrap_or_default()
    }

    /// Where the gripper is (world frame), if it holds something: what a
    /// robot knows of its own pose.
    pub fn gripper_in_world(&self) -> Option<[f32; 3]> {
        self.env
            .as_ref()
            .and_then(|e| e.articulation().gripper_position())
            .map(|g| g.to_array())
    }

    /// The joint the gripper moves, if it holds something.
    pub fn grasped_joint(&self) -> Option<usize> {
        self.env.as_ref().and_then(|e| e.grasped_joint())
    }

    /// Renders the current state again (for a caller that changed nothing, the
    /// same frame): what `Env.observe()` times and returns.
    pub fn render_in_place(&mut self) -> Result<()> {
        let env = self
            .env
            .as_mut()
            .ok_or_else(|| EvalError::Episode("reset() first".into()))?;
        self.frame = Some(env.render()?);
        Ok(())
    }

    /// The current observation, without acting.
    pub fn reset_observation(&self) -> Result<EnvObservation> {
        self.observe(self.current_frame()?)
    }

    /// Grasps at a pixel; the observation after it.
    pub fn step_position(&mut self, row: u32, col: u32) -> Result<(EnvObservation, PositionInfo)> {
        let info = self.step_position_in_place(row, col)?;
        Ok((self.reset_observation()?, info))
    }

    /// [`TrainEnv::step_position`] without building the observation.
    pub fn step_position_in_place(&mut self, row: u32, col: u32) -> Result<PositionInfo> {
        let info = self.step_position_deferred(row, col)?;
        self.render_in_place()?;
        Ok(info)
    }

    /// [`TrainEnv::step_position_in_place`] without drawing the new state:
    /// [`render_pending`] draws it, for many environments at once.
    pub fn step_position_deferred(&mut self, row: u32, col: u32) -> Result<PositionInfo> {
        let (env, frame) = match (self.env.as_mut(), self.frame.as_ref()) {
            (Some(e), Some(f)) => (e, f),
            (None, _) => return Err(EvalError::Episode("step_position before reset()".into())),
            (Some(_), None) => {
                return Err(EvalError::Episode(
                    "step_position after a deferred step: render_pending() draws it first".into(),
                ));
            }
        };
        let pick = env.step_position(frame, row, col)?;
        let valid = env.pick_is_valid(&pick);
        let info = match pick {
            Pick::Movable {
                point_in_world,
                link,
                joint,
                ..
            } => {
                let jm = &env.model().joints[joint];
                PositionInfo {
                    valid,
                    link: Some(link),
                    joint: Some(joint),
                    point_in_world: Some(point_in_world.to_array()),
                    limits: Some([jm.lower, jm.upper]),
                    threshold: Some(crate::protocol::threshold(
                        jm.kind.is_prismatic(),
                        jm.lower,
                        jm.upper,
                    )),
                }
            }
            Pick::NoMovableLink => PositionInfo::default(),
        };
        self.frame = None;
        Ok(info)
    }

    /// Dense labels of `directions` from the current state, which stays as it
    /// is (see `SimEnv::probe_directions`).
    pub fn probe_directions(&self, directions: &[[f32; 3]]) -> Result<Vec<StepLabels>> {
        let env = self
            .env
            .as_ref()
            .ok_or_else(|| EvalError::Episode("probe_directions before reset()".into()))?;
        let dirs: Vec<umpnet_sim::math::Vec3> = directions
            .iter()
            .map(|d| umpnet_sim::math::Vec3::from(*d))
            .collect();
        Ok(env.probe_directions(&dirs)?)
    }

    /// Moves 0.18 m along a direction; the observation after it and the labels.
    pub fn step_direction(&mut self, direction: [f32; 3]) -> Result<(EnvObservation, StepLabels)> {
        let labels = self.step_direction_in_place(direction)?;
        Ok((self.reset_observation()?, labels))
    }

    /// [`TrainEnv::step_direction`] without building the observation.
    pub fn step_direction_in_place(&mut self, direction: [f32; 3]) -> Result<StepLabels> {
        let labels = self.step_direction_deferred(direction)?;
        self.render_in_place()?;
        Ok(labels)
    }

    /// [`TrainEnv::step_direction_in_place`] without drawing the new state:
    /// [`render_pending`] draws it, for many environments at once.
    pub fn step_direction_deferred(&mut self, direction: [f32; 3]) -> Result<StepLabels> {
        let env = self
            .env
            .as_mut()
            .ok_or_else(|| EvalError::Episode("step_direction before reset()".into()))?;
        let labels = env.step_direction(Vec3::from(direction))?;
        self.history.push(crate::policy::StepRecord {
            direction: Vec3::from(direction).normalize().to_array(),
            labels: labels.clone(),
        });
        self.frame = None;
        Ok(labels)
    }

    /// What `oracle` or `random` would do now (a pixel before the grasp, a direction after).
    pub fn scripted_action(&mut self, policy: &str) -> Result<ScriptedAction> {
        let (env, frame, reference) = match (
            self.env.as_ref(),
            self.frame.as_ref(),
            self.reference_frame.as_ref(),
        ) {
            (Some(e), Some(f), Some(r)) => (e, f, r),
            _ => return Err(EvalError::Episode("scripted_action before reset()".into())),
        };
        let p: &mut dyn Policy = match policy {
            "oracle" => &mut self.oracle,
            "random" => &mut self.random,
            other => {
                return Err(EvalError::Episode(format!(
                    "unknown scripted policy `{other}`; expected oracle or random"
                )));
            }
        };
        let obs = Observation {
            frame,
            reference,
            gripper_in_world: env.articulation().gripper_position(),
        };
        if env.grasped_joint().is_none() {
            let (r, c) = p.position(&obs, env)?;
            return Ok(ScriptedAction::Pixel(r, c));
        }
        Ok(match p.direction(&obs, env, &self.history)? {
            Decision::Move { direction, .. } => ScriptedAction::Direction(direction.to_array()),
            Decision::Stop => ScriptedAction::Stop,
        })
    }
}
