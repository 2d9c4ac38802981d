//! Policies that need no learning: `random` (the lower bound) and `oracle`
//! (privileged ground truth; the upper bound).
use crate::policy::{Decision, Observation, Policy, StepRecord};
use crate::{EvalError, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use umpnet_sim::env::{DELTA, SimEnv};
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{SEG_OBJECT_BASE, Segment};
use umpnet_sim::scene::Task;

pub fn uniform_direction(rng: &mut impl Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 1e-3 && l <= 1.0 {
            return v / l;
        }
    }
}

/// Uniform pixel on the object mask, uniform direction on the sphere.
pub struct RandomPolicy {
    rng: ChaCha8Rng,
}

impl Default for RandomPolicy {
    fn default() -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(0),
        }
    }
}

impl Policy for RandomPolicy {
    fn name(&self) -> String {
        "random".into()
    }
    fn reset(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }
    fn position(&mut self, obs: &Observation, _env: &SimEnv) -> Result<(u32, u32)> {
        let f = obs.frame;
        let mask: Vec<usize> = (0..f.segmentation.len())
            .filter(|&i| f.segmentation[i] >= SEG_OBJECT_BASE)
            .collect();
        if mask.is_empty() {
            return Err(EvalError::Episode("the object is not in view".into()));
        }
        let i = mask[self.rng.random_range(0..mask.len())];
        Ok(((i as u32) / f.width, (i as u32) % f.width))
    }
    fn direction(&mut self, _: &Observation, _: &SimEnv, _: &[StepRecord]) -> Result<Decision> {
        Ok(Decision::Move {
            direction: uniform_direction(&mut self.rng),
            candidates: None,
        })
    }
}

/// Uses the true joint axes and limits: grasps where the lever is longest and
/// moves along the joint's motion, toward novel states or toward the goal.
#[derive(Default)]
pub struct OraclePolicy {
    /// +1 or -1: the sign of joint motion currently pursued (exploration).
    sign: f32,
}

impl OraclePolicy {
    /// Direction that moves `joint` in the + sense at the grasped point.
    fn motion_direction(env: &SimEnv, joint: usize) -> Option<Vec3> {
        let art = env.articulation();
        let (axis, origin) = art.joint_axis_in_world(joint);
        if env.model().joints[joint].kind.is_prismatic() {
            return Some(axis);
        }
        let g = env.grasp_point_in_world()?;
        let t = axis.cross(g - origin);
        (t.length() > 1e-4).then(|| t.normalize())
    }
}

impl Policy for OraclePolicy {
    fn name(&self) -> String {
        "oracle".into()
    }
    fn reset(&mut self, _seed: u64) {
        self.sign = 0.0;
    }
    fn position(&mut self, obs: &Observation, env: &SimEnv) -> Result<(u32, u32)> {
        let f = obs.frame;
        let goal_joint = env.scene().goal.as_ref().map(|g| g.joint);
        let mut best: Option<(f32, usize)> = None;
        for i in 0..f.segmentation.len() {
            let Segment::Link { link, .. } = Segment::decode(f.segmentation[i]) else {
                continue;
            };
            if f.segmentation[i] < SEG_OBJECT_BASE {
                continue;
            }
            let Some(joint) = env.joint_moving_link(link) else {
                continue;
            };
            if env.scene().task == Task::Goal && Some(joint) != goal_joint {
                continue;
            }
            let (row, col) = ((i as u32) / f.width, (i as u32) % f.width);
            let Some(p) = f.point_in_world(row, col) else {
                continue;
            };
            let (axis, origin) = env.articulation().joint_axis_in_world(joint);
            let n = Vec3::from(f.normal_in_world[i]);
            let score = if env.model().joints[joint].kind.is_prismatic() {
                // Pull on faces the axis leaves through (a drawer's front).
                0.5 + n.dot(axis).abs()
            } else {
                let r = p - origin;
                (r - axis * r.dot(axis)).length()
            };
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, i));
            }
        }
        let (_, i) = best.ok_or_else(|| EvalError::Episode("no movable link in view".into()))?;
        Ok(((i as u32) / f.width, (i as u32) % f.width))
    }
    fn direction(
        &mut self,
        _obs: &Observation,
        env: &SimEnv,
        history: &[StepRecord],
    ) -> Result<Decision> {
        let Some(joint) = env.grasped_joint() else {
            return Ok(Decision::Stop);
        };
        let Some(dir) = Self::motion_direction(env, joint) else {
            return Ok(Decision::Stop);
        };
        let jm = &env.model().joints[joint];
        let j = env.articulation().joint_position(joint);
        let sign = match &env.scene().goal {
            Some(g) => {
                let target = g.joints[joint];
                if (target - j).abs() < DELTA / 3.0 {
                    return Ok(Decision::Stop);
                }
                (target - j).signum()
            }
            None => {
                if self.sign == 0.0 {
                    self.sign = if (jm.upper - j) >= (j - jm.lower) {
                        1.0
                    } else {
                        -1.0
                    };
                } else if history
                    .last()
                    .is_some_and(|s| s.labels.reached_limit || !s.labels.moved)
                {
                    self.sign = -self.sign; // bounce off a limit
                }
                self.sign
            }
        };
        Ok(Decision::Move {
            direction: dir * sign,
            candidates: None,
        })
    }
}
