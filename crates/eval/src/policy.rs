//! The `Policy` trait every policy plugs into (scripted, learned, Python).
use crate::Result;
use umpnet_sim::env::{SimEnv, StepLabels};
use umpnet_sim::math::Vec3;
use umpnet_sim::render::Frame;

/// What a policy sees at each step: the frame and, as the paper's reference
/// input, the initial observation (exploration) or the goal image (goal task).
pub struct Observation<'a> {
    /// The current frame.
    pub frame: &'a Frame,
    /// The reference frame: the first (exploration) or the goal.
    pub reference: &'a Frame,
    /// Where the robot's own gripper is (proprioception), once it holds something.
    pub gripper_in_world: Option<Vec3>,
}

/// Extra output a policy may give for pictures: candidate directions with
/// predicted distance and AoT.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Candidates {
    /// Candidate directions (world frame).
    pub directions: Vec<[f32; 3]>,
    /// Predicted joint change of each.
    pub distance: Vec<f32>,
    /// Predicted Arrow of Time of each: -1, 0 or +1.
    pub aot: Vec<i8>,
}

impl Candidates {
    /// The index of the candidate that `executed` is, if any: the same
    /// direction within the float rounding of the normalisation it went
    /// through on its way to the simulator (cosine above 0.9999).
    pub fn index_of(&self, executed: Vec3) -> Option<usize> {
        let executed = executed.normalize_or_zero();
        self.directions
            .iter()
            .enumerate()
            .map(|(k, d)| (k, Vec3::from(*d).normalize_or_zero().dot(executed)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|(_, cos)| *cos > 0.9999)
            .map(|(k, _)| k)
    }
}

/// A policy's choice for the next direction action.
pub enum Decision {
    /// Move the gripper 0.18 m along `direction` (world frame, unit).
    Move {
        /// The direction (world frame, unit).
        direction: Vec3,
        /// What the policy considered, for pictures.
        candidates: Option<Candidates>,
    },
    /// The policy is done (goal task: no direction is predicted to move toward the goal).
    Stop,
}

/// One executed step, as a policy sees the history.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepRecord {
    /// The executed direction (world frame, unit).
    pub direction: [f32; 3],
    /// What the simulator measured.
    pub labels: StepLabels,
}

/// A policy the benchmark runs: scripted, learned, or a caller's.
pub trait Policy: Send {
    /// Its name in tables.
    fn name(&self) -> String;
    /// Called at the start of each episode with a seed derived from the scene.
    fn reset(&mut self, seed: u64);
    /// The pixel (row, col) to grasp. Scripted policies may read the simulator
    /// through `env`; learned ones must use only `obs`.
    fn position(&mut self, obs: &Observation<'_>, env: &SimEnv) -> Result<(u32, u32)>;
    /// The next direction action, or stop; `history` holds the episode's
    /// steps so far. Learned policies must use only `obs` and `history`.
    fn direction(
        &mut self,
        obs: &Observation<'_>,
        env: &SimEnv,
        history: &[StepRecord],
    ) -> Result<Decision>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_executed_direction_is_found_among_the_candidates() {
        let c = Candidates {
            directions: vec![[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -1.0]],
            distance: vec![0.1, 0.2, 0.3],
            aot: vec![1, -1, 0],
        };
        // Unnormalised and rounded on the way: still the same candidate.
        assert_eq!(c.index_of(Vec3::new(0.0, 0.5, 1e-4)), Some(1));
        assert_eq!(c.index_of(Vec3::new(0.0, 0.0, -3.0)), Some(2));
        // Between candidates, or nothing at all: none of them.
        assert_eq!(c.index_of(Vec3::new(1.0, 1.0, 0.0)), None);
        assert_eq!(c.index_of(Vec3::ZERO), None);
        assert_eq!(Candidates::default().index_of(Vec3::X), None);
    }
}
