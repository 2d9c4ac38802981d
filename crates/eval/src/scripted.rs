//! Policies that need no learning: `random` (the lower bound) and `oracle`
//! (privileged ground truth; the upper bound).
#![allow(
    clippy::indexing_slicing,
    reason = "joint indices come from the validated scene and model; pixel indices from the frame's own mask"
)]
use crate::policy::{Decision, Observation, Policy, StepRecord};
use crate::protocol;
use crate::{EvalError, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use umpnet_sim::env::{DELTA, SimEnv};
use umpnet_sim::math::Vec3;
use umpnet_sim::render::{SEG_OBJECT_BASE, Segment};
use umpnet_sim::scene::Task;

/// A direction drawn uniformly from the unit sphere.
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
    fn position(&mut self, obs: &Observation<'_>, _env: &SimEnv) -> Result<(u32, u32)> {
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
    fn direction(&mut self, _: &Observation<'_>, _: &SimEnv, _: &[StepRecord]) -> Result<Decision> {
        Ok(Decision::Move {
            direction: uniform_direction(&mut self.rng),
            candidates: None,
        })
    }
}

/// Uses the true joint axes and limits: grasps where the lever is longest and
/// moves along the joint's motion, toward novel states or toward the goal.
pub struct OraclePolicy {
    /// +1 or -1: the sign of joint motion currently pursued (exploration).
    sign: f32,
    /// Plan exploration steps on the simulator (see `plan_exploration_step`).
    plan: bool,
}

impl Default for OraclePolicy {
    fn default() -> Self {
        Self {
            sign: 0.0,
            plan: true,
        }
    }
}

impl OraclePolicy {
    /// The oracle without planning: every step pulls along the joint's motion
    /// (a fixed action for benchmarks).
    pub fn plain() -> Self {
        Self {
            sign: 0.0,
            plan: false,
        }
    }

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
    fn position(&mut self, obs: &Observation<'_>, env: &SimEnv) -> Result<(u32, u32)> {
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
        // No pixel of the part reads as such (a depth camera that reads
        // nothing on its glass): the oracle grasps what it sees, a static
        // surface, the protocol's wrong grasp, as any policy's would be there.
        let i = match best {
            Some((_, i)) => i,
            None => (0..f.segmentation.len())
                .find(|&i| {
                    f.depth[i] > 0.0
                        && !matches!(Segment::decode(f.segmentation[i]),
                            Segment::Link { link, .. } if env.joint_moving_link(link).is_some())
                })
                .ok_or_else(|| {
                    EvalError::Episode(format!(
                        "the oracle's grasp: nothing of {} is in view of the camera",
                        env.model().source.display(),
                    ))
                })?,
        };
        Ok(((i as u32) / f.width, (i as u32) % f.width))
    }
    fn direction(
        &mut self,
        _obs: &Observation<'_>,
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
                if self.plan
                    && let Some(planned) =
                        plan_exploration_step(env, joint, dir, self.sign, history)?
                {
                    return Ok(Decision::Move {
                        direction: planned,
                        candidates: None,
                    });
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

/// Tilts of the pull away from the joint's motion: a tilted pull moves the
/// part less (the mount holds its line), which is how the oracle sets a
/// step's length.
const TILTS_DEG: [f32; 8] = [0.0, 20.0, 35.0, 45.0, 55.0, 62.0, 70.0, 78.0];

/// The exploration oracle's step, planned on the simulator: the tilts of the
/// joint's motion (both senses) are simulated on copies of the articulation
/// and scored by the paper's metric one step ahead:
/// 1. a new state that ends the episode at the limit;
/// 2. a new state that leaves a last step long enough to be new too;
/// 3. any new state; 4. the end of the episode; then the longest move.
///
/// Without it, a free pull's fixed length (about 0.13 m) often leaves a gap
/// to the limit too short for a new state and too long to end the episode,
/// and one step in three is wasted on short sliders. None when no simulated
/// step moves the part (the caller's bounce takes over).
fn plan_exploration_step(
    env: &SimEnv,
    joint: usize,
    motion: Vec3,
    sign: f32,
    history: &[StepRecord],
) -> Result<Option<Vec3>> {
    let jm = &env.model().joints[joint];
    let Some(start) = env.grasp_start_value() else {
        return Ok(None);
    };
    let prismatic = jm.kind.is_prismatic();
    let scale = if prismatic {
        env.scene().pose.scale
    } else {
        1.0
    };
    let thr = protocol::threshold(prismatic, jm.lower, jm.upper);
    let values: Vec<f32> = history.iter().map(|s| s.labels.joint_after).collect();
    let walk = protocol::paper_walk(start, &values, scale);
    let count = protocol::paper_unique_states(&walk);
    let gap_is_dead = |after: f32| {
        // A gap to the heading limit that no step can both end and count.
        let gap = if after >= start {
            jm.upper - after
        } else {
            after - jm.lower
        };
        gap > thr && gap <= DELTA * scale
    };
    let score = |candidates: &[Vec3]| -> Result<Option<(u8, f32, Vec3)>> {
        let labels = env.probe_directions(candidates)?;
        let mut best: Option<(u8, f32, Vec3)> = None;
        for (dir, l) in candidates.iter().zip(&labels) {
            if l.r_dist < 1e-4 {
                continue;
            }
            let mut next = values.clone();
            next.push(l.joint_after);
            let new =
                protocol::paper_unique_states(&protocol::paper_walk(start, &next, scale)) > count;
            let ends = protocol::reached_limit(l.joint_after, start, jm.lower, jm.upper, thr);
            let rank = match (new, ends) {
                (true, true) => 4,
                (true, false) if !gap_is_dead(l.joint_after) => 3,
                (true, false) => 2,
                (false, true) => 1,
                (false, false) => 0,
            };
            if best.is_none_or(|(r, d, _)| (rank, l.r_dist) > (r, d)) {
                best = Some((rank, l.r_dist, *dir));
            }
        }
        Ok(best)
    };
    // The plain pull first: most steps need nothing else.
    if let Some(b) = score(&[motion * sign])?.filter(|(rank, ..)| *rank >= 3) {
        return Ok(Some(b.2));
    }
    let up = if motion.z.abs() < 0.9 {
        Vec3::Z
    } else {
        Vec3::X
    };
    let side = (up - motion * up.dot(motion)).normalize();
    let other = motion.cross(side);
    let mut candidates = Vec::with_capacity(2 * (1 + 4 * (TILTS_DEG.len() - 1)));
    for s in [sign, -sign] {
        candidates.push(motion * s);
        for deg in &TILTS_DEG[1..] {
            let (sin, cos) = deg.to_radians().sin_cos();
            for towards in [side, -side, other, -other] {
                candidates.push((motion * (s * cos) + towards * sin).normalize());
            }
        }
    }
    let best = score(&candidates)?;
    Ok(best.filter(|(rank, ..)| *rank > 0).map(|(.., d)| d))
}
