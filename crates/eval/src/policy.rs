//! The `Policy` trait every policy plugs into (scripted, learned, Python).
use crate::Result;
use umpnet_sim::env::{SimEnv, StepLabels};
use umpnet_sim::math::Vec3;
use umpnet_sim::render::Frame;

/// What a policy sees at each step: the frame and, as the paper's reference
/// input, the initial observation (exploration) or the goal image (goal task).
pub struct Observation<'a> {
    pub frame: &'a Frame,
    pub reference: &'a Frame,
    /// Where the robot's own gripper is (proprioception), once it holds something.
    pub gripper_in_world: Option<Vec3>,
}

/// Extra output a policy may give for pictures: candidate directions with
/// predicted distance and AoT.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Candidates {
    pub directions: Vec<[f32; 3]>,
    pub distance: Vec<f32>,
    pub aot: Vec<i8>,
}

pub enum Decision {
    Move {
        direction: Vec3,
        candidates: Option<Candidates>,
    },
    /// The policy is done (goal task: no direction is predicted to move toward the goal).
    Stop,
}

/// One executed step, as a policy sees the history.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepRecord {
    pub direction: [f32; 3],
    pub labels: StepLabels,
}

pub trait Policy: Send {
    fn name(&self) -> String;
    /// Called at the start of each episode with a seed derived from the scene.
    fn reset(&mut self, seed: u64);
    /// The pixel (row, col) to grasp. Scripted policies may read the simulator
    /// through `env`; learned ones must use only `obs`.
    fn position(&mut self, obs: &Observation, env: &SimEnv) -> Result<(u32, u32)>;
    fn direction(
        &mut self,
        obs: &Observation,
        env: &SimEnv,
        history: &[StepRecord],
    ) -> Result<Decision>;
}
