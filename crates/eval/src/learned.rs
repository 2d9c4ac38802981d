//! The learned UMPNet policy behind the `Policy` trait: it sees only images
//! (and where its own gripper is), never the simulator's state.
use crate::policy::{Candidates, Decision, Observation, Policy, StepRecord};
use crate::{EvalError, Result};
use nalgebra::Vector3;
use ndarray::Array3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::sync::Arc;
use umpnet_policy::cem::Mode;
use umpnet_policy::memory::EpisodeMemory;
use umpnet_policy::{CameraFrame, ModelPackage, UmpnetPolicy, build_observation};
use umpnet_sim::env::SimEnv;
use umpnet_sim::math::Vec3;
use umpnet_sim::render::Frame;
use umpnet_sim::scene::Task;

/// The simulator's frame as plain camera data for the policy runtime.
pub fn camera_frame(f: &Frame) -> CameraFrame<'_> {
    CameraFrame {
        width: f.width as usize,
        height: f.height as usize,
        rgb: &f.rgb,
        depth: &f.depth,
        intrinsics: [
            f.intrinsics.fx,
            f.intrinsics.fy,
            f.intrinsics.cx,
            f.intrinsics.cy,
        ],
        world_from_camera: f.world_from_camera.to_mat4().transpose().to_cols_array_2d(),
    }
}

/// The 10-channel observation of a rendered frame, as the runtime builds it from a camera's.
pub fn observation_tensor(f: &Frame) -> Result<Array3<f32>> {
    Ok(build_observation(&camera_frame(f))?)
}

/// Pixel (row, col) of a world point, clamped into the image.
pub fn project_pixel(f: &Frame, p: Vec3) -> (usize, usize) {
    let c = f.world_from_camera.inverse_transform_point(p);
    let z = c.z.max(1e-3);
    let col = (f.intrinsics.fx * c.x / z + f.intrinsics.cx)
        .floor()
        .clamp(0.0, f.width as f32 - 1.0);
    let row = (f.intrinsics.fy * c.y / z + f.intrinsics.cy)
        .floor()
        .clamp(0.0, f.height as f32 - 1.0);
    (row as usize, col as usize)
}

/// A model package behind the [`Policy`] trait: it sees images and its own gripper only.
pub struct LearnedPolicy {
    name: String,
    policy: UmpnetPolicy,
    rng: ChaCha8Rng,
    memory: EpisodeMemory,
    reference: Option<Array3<f32>>,
    /// The grasped part's joint read at the grasp, for the joint45 and
    /// onward45 filters.
    joint: Option<umpnet_policy::axis::JointEstimate>,
}

impl LearnedPolicy {
    /// The package's policy, named `name` in tables.
    pub fn new(name: &str, package: Arc<ModelPackage>) -> Self {
        Self::from_policy(name, UmpnetPolicy::new(package))
    }

    /// `policy` as it is configured (its direction filter, grasp rule,
    /// sampler, mirror averaging), named `name` in tables.
    pub fn from_policy(name: &str, policy: UmpnetPolicy) -> Self {
        Self {
            name: name.into(),
            policy,
            rng: ChaCha8Rng::seed_from_u64(0),
            memory: EpisodeMemory::default(),
            reference: None,
            joint: None,
        }
    }

    /// Loads a package with `sessions` concurrent session sets (one per worker thread).
    pub fn load(dir: &Path, sessions: usize) -> Result<Arc<ModelPackage>> {
        Ok(Arc::new(ModelPackage::load(dir, sessions, 1, None)?))
    }

    fn check_resolution(&self, f: &Frame) -> Result<()> {
        let (h, w) = self.policy.resolution();
        if (f.height as usize, f.width as usize) != (h, w) {
            return Err(EvalError::Episode(format!(
                "frames are {}x{}, the model takes {h}x{w}: render at the model's resolution",
                f.height, f.width
            )));
        }
        Ok(())
    }
}

impl Policy for LearnedPolicy {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn reset(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        self.memory.clear();
        self.reference = None;
        self.joint = None;
    }
    fn position(&mut self, obs: &Observation<'_>, env: &SimEnv) -> Result<(u32, u32)> {
        self.check_resolution(obs.frame)?;
        let current = observation_tensor(obs.frame)?;
        let reference = observation_tensor(obs.reference)?;
        let goal = (env.scene().task == Task::Goal).then_some(reference.view());
        let choice = self.policy.position(current.view(), goal)?;
        self.reference = Some(reference);
        if self.policy.direction_filter.reads_joint() {
            self.joint = self
                .policy
                .joint_at_grasp(current.view(), &choice)?
                .map(|j| j.estimate);
        }
        Ok((choice.pixel.0 as u32, choice.pixel.1 as u32))
    }
    fn direction(
        &mut self,
        obs: &Observation<'_>,
        env: &SimEnv,
        history: &[StepRecord],
    ) -> Result<Decision> {
        self.check_resolution(obs.frame)?;
        if let Some(last) = history.last() {
            self.memory
                .record(Vector3::from(last.direction), last.labels.moved);
        }
        if let Some(g) = obs.gripper_in_world {
            self.memory.gripper_at(Vector3::new(g.x, g.y, g.z));
        }
        let current = observation_tensor(obs.frame)?;
        let reference = match &self.reference {
            Some(r) => r.clone(),
            None => observation_tensor(obs.reference)?,
        };
        let pixel = obs
            .gripper_in_world
            .map(|g| project_pixel(obs.frame, g))
            .unwrap_or((0, 0));
        let mode = if env.scene().task == Task::Goal {
            Mode::Goal
        } else {
            Mode::Explore
        };
        let input = self.memory.decision_input(
            current.view(),
            reference.view(),
            pixel,
            mode,
            self.joint.as_ref(),
        );
        let mut out = self.policy.directions(
            std::slice::from_ref(&input),
            std::slice::from_mut(&mut self.rng),
        )?;
        let r = out
            .pop()
            .ok_or_else(|| EvalError::Episode("no decision".into()))?;
        let candidates = Candidates {
            directions: r.candidates.iter().map(|d| [d.x, d.y, d.z]).collect(),
            distance: r.scores.iter().map(|s| s.distance).collect(),
            aot: r.scores.iter().map(|s| s.aot).collect(),
        };
        Ok(match r.direction {
            Some(d) => Decision::Move {
                direction: Vec3::new(d.x, d.y, d.z),
                candidates: Some(candidates),
            },
            None => Decision::Stop,
        })
    }
}
