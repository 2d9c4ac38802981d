//! One episode: position action, then up to N direction actions, with the
//! metrics of a [`Protocol`] computed from the grasped joint's trajectory.
#![allow(
    clippy::indexing_slicing,
    reason = "joint indices come from a scene validated against its model before the episode starts"
)]
use crate::Result;
use crate::policy::{Candidates, Decision, Observation, Policy, StepRecord};
use crate::protocol::{self, Protocol};
use umpnet_sim::camera::Camera;
use umpnet_sim::env::{DELTA, Pick, SimEnv};
use umpnet_sim::render::{Frame, Renderer};
use umpnet_sim::scene::{Scene, Task};

/// One direction action of an episode.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Step {
    /// The direction and what the simulator measured.
    pub record: StepRecord,
    /// Gripper position when the action started.
    pub gripper_in_world: [f32; 3],
    /// What the policy considered, if it says.
    pub candidates: Option<Candidates>,
}

/// One episode: what was grasped, each step, and the metrics.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Episode {
    /// The policy's name.
    pub policy: String,
    /// The scene it ran on.
    pub scene: Scene,
    /// The grasped pixel (row, col).
    pub pixel: (u32, u32),
    /// The position landed on a valid link (for the goal task: the goal joint's).
    pub valid_position: bool,
    /// The joint the grasp moves, if any.
    pub joint: Option<usize>,
    /// The direction actions, in order.
    pub steps: Vec<Step>,
    /// The policy chose to stop.
    pub stopped_early: bool,
    /// The protocol ended the episode (paper: a limit reached in exploration,
    /// the goal reached in the goal task).
    pub ended_by_protocol: bool,
    /// Direction actions allowed.
    pub budget: usize,
    /// The protocol that ended and scored it.
    pub protocol: Protocol,
    /// Its scores.
    pub metrics: Metrics,
}

/// How an episode runs: its budget of direction actions, the policy's seed
/// and the protocol that ends and scores it.
#[derive(Clone, Copy, Debug)]
pub struct EpisodeConfig {
    /// Direction actions allowed.
    pub budget: usize,
    /// The policy's seed for the episode.
    pub seed: u64,
    /// Ends and scores the episode.
    pub protocol: Protocol,
}

/// An episode's scores under its protocol (the paper's tables' metrics).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    /// Exploration: unique states after each step (length = budget), as the
    /// protocol counts them.
    pub unique_states: Vec<f32>,
    /// Exploration: unique states over the steps taken.
    pub novel_state_ratio: f32,
    /// Exploration: the mean joint change per step.
    pub single_action_effect: f32,
    /// Goal: normalised distance after each step (length = budget).
    pub normalized_distance_curve: Vec<f32>,
    /// Goal: the final distance to the goal over the initial one.
    pub normalized_distance: f32,
    /// Goal: the joint ended within the protocol's threshold of the goal.
    pub success: bool,
    /// Exploration: the grasped joint's axis inferred from the moving steps
    /// (the paper's structure inference), against the true axis. None when
    /// fewer than two steps moved the part.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<AxisError>,
}

/// How far the axis inferred from an episode's actions is from the truth.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxisError {
    /// The true joint is prismatic (the paper reports the two kinds apart).
    pub prismatic: bool,
    /// Angle between the true axis and the one the paper infers for a joint
    /// of the true kind (the mean move of a slide, the normal of a hinge's
    /// plane of moves), ignoring sign, in degrees: 0 to 90.
    pub degrees: f32,
    /// Whether the moves alone look like a slide's (what `explore` and
    /// `infer` report without knowing the kind): a hinge turned through a
    /// small angle does.
    pub looks_prismatic: bool,
}

/// The paper's joint-axis inference over the steps that moved the part,
/// for a joint of the true kind, against `true_axis`.
pub fn axis_error(steps: &[Step], prismatic: bool, true_axis: [f32; 3]) -> Option<AxisError> {
    use nalgebra::Vector3;
    use umpnet_policy::axis::{JointEstimate, axis_angle_deg, axis_of_known_kind, infer_joint};
    let moved = steps.iter().filter(|s| s.record.labels.moved);
    let (directions, points): (Vec<_>, Vec<_>) = moved
        .map(|s| {
            (
                Vector3::from(s.record.direction),
                Vector3::from(s.gripper_in_world),
            )
        })
        .unzip();
    let axis = axis_of_known_kind(&directions, prismatic)?;
    Some(AxisError {
        prismatic,
        degrees: axis_angle_deg(&axis, &Vector3::from(true_axis)),
        looks_prismatic: matches!(
            infer_joint(&directions, &points),
            Some(JointEstimate::Prismatic { .. })
        ),
    })
}

/// What a hook sees after each action: the frame, the step that led to it
/// (none for the grasp), the grasped pixel and the simulator itself (for
/// link poses, joint values and the gripper).
pub struct HookFrame<'a> {
    /// 0 after the grasp, t after the t-th direction action.
    pub t: usize,
    /// The frame after the action.
    pub frame: &'a Frame,
    /// The direction step it follows (None after the grasp).
    pub step: Option<&'a Step>,
    /// The grasped pixel (row, col).
    pub pixel: (u32, u32),
    /// The environment, for recordings of its state.
    pub env: &'a SimEnv,
}

/// Hooks for pictures and recordings: called after each action.
pub type FrameHook<'a> = &'a mut dyn FnMut(&HookFrame<'_>);

/// Runs one episode of `policy` on `scene` with a renderer of the caller's.
#[expect(
    clippy::too_many_lines,
    reason = "the paper's episode loop read top to bottom, as the protocol states it"
)]
pub fn run_episode(
    scene: &Scene,
    camera: &Camera,
    renderer: Box<dyn Renderer>,
    policy: &mut dyn Policy,
    config: EpisodeConfig,
    mut hook: Option<FrameHook<'_>>,
) -> Result<Episode> {
    let EpisodeConfig {
        budget,
        seed,
        protocol,
    } = config;
    let mut env = SimEnv::new(scene.clone(), camera.clone(), renderer)?;
    policy.reset(seed);
    let first = env.render()?;
    let reference = match scene.task {
        Task::Goal => env.render_goal()?.unwrap_or_else(|| first.clone()),
        Task::Exploration => first.clone(),
    };
    let pixel = policy.position(
        &Observation {
            frame: &first,
            reference: &reference,
            gripper_in_world: None,
        },
        &env,
    )?;
    let pick = env.step_position(&first, pixel.0, pixel.1)?;
    let valid = env.pick_is_valid(&pick);
    let joint = match pick {
        Pick::Movable { joint, .. } => Some(joint),
        Pick::NoMovableLink => None,
    };
    let mut steps: Vec<Step> = Vec::new();
    let mut stopped_early = false;
    let mut ended_by_protocol = false;
    let mut frame = first;
    if let Some(h) = hook.as_mut() {
        h(&HookFrame {
            t: 0,
            frame: &frame,
            step: None,
            pixel,
            env: &env,
        });
    }
    if valid {
        for t in 0..budget {
            frame = env.render()?;
            let history: Vec<StepRecord> = steps.iter().map(|s| s.record.clone()).collect();
            let decision = policy.direction(
                &Observation {
                    frame: &frame,
                    reference: &reference,
                    gripper_in_world: env.articulation().gripper_position(),
                },
                &env,
                &history,
            )?;
            let (direction, candidates) = match decision {
                Decision::Move {
                    direction,
                    candidates,
                } => (direction, candidates),
                Decision::Stop => {
                    stopped_early = true;
                    break;
                }
            };
            let gripper = env
                .articulation()
                .gripper_position()
                .unwrap_or_default()
                .to_array();
            let labels = env.step_direction(direction)?;
            let step = Step {
                record: StepRecord {
                    direction: direction.normalize().to_array(),
                    labels,
                },
                gripper_in_world: gripper,
                candidates,
            };
            if let Some(h) = hook.as_mut() {
                let after = env.render()?;
                h(&HookFrame {
                    t: t + 1,
                    frame: &after,
                    step: Some(&step),
                    pixel,
                    env: &env,
                });
            }
            let done = protocol == Protocol::Paper
                && joint.is_some_and(|j| paper_episode_over(scene, &env, j, &step));
            steps.push(step);
            if done {
                ended_by_protocol = true;
                break;
            }
        }
    }
    let metrics = metrics(
        scene,
        joint.filter(|_| valid),
        &env,
        &steps,
        budget,
        protocol,
        ended_by_protocol,
    );
    Ok(Episode {
        policy: policy.name(),
        scene: scene.clone(),
        pixel,
        valid_position: valid,
        joint,
        steps,
        stopped_early,
        ended_by_protocol,
        budget,
        protocol,
        metrics,
    })
}

/// The paper's early end after `step` (module docs of [`protocol`]).
fn paper_episode_over(scene: &Scene, env: &SimEnv, joint: usize, step: &Step) -> bool {
    let jm = &env.model().joints[joint];
    let thr = protocol::threshold(jm.kind.is_prismatic(), jm.lower, jm.upper);
    let l = &step.record.labels;
    match (&scene.task, &scene.goal) {
        (Task::Exploration, _) => {
            let start = env.grasp_start_value().unwrap_or(l.joint_before);
            protocol::reached_limit(l.joint_after, start, jm.lower, jm.upper, thr)
        }
        (Task::Goal, Some(g)) => {
            g.joint == joint
                && protocol::reached_goal(l.joint_before, l.joint_after, g.joints[joint], thr)
        }
        (Task::Goal, None) => false,
    }
}

/// What the metrics need to know of an episode besides its steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scoring {
    /// Nothing was grasped (or the goal task has no goal): the task's worst score.
    Missed(Task),
    /// Exploration of the grasped joint from `start`; the paper's walk divides
    /// prismatic moves by the object's `scale` (1 for revolute joints).
    Exploration {
        /// The joint's value at the grasp.
        start: f32,
        /// The object's scale.
        scale: f32,
    },
    /// The goal joint from `init` toward `target`; `now` is its value after the
    /// episode (the goal joint need not be the grasped one).
    Goal {
        /// The goal joint's value at the start.
        init: f32,
        /// Its value in the goal state.
        target: f32,
        /// Its value after the episode.
        now: f32,
    },
}

/// An episode's metrics from its steps' (joint value after, |Δ joint|) under
/// `protocol`: pure, so that every metric can be checked on hand-made steps.
pub fn score(
    what: Scoring,
    steps: &[(f32, f32)],
    budget: usize,
    protocol: Protocol,
    ended_by_protocol: bool,
) -> Metrics {
    let mut m = Metrics::default();
    let after: Vec<f32> = steps.iter().map(|s| s.0).collect();
    match what {
        Scoring::Missed(Task::Exploration) => m.unique_states = vec![0.0; budget],
        Scoring::Missed(Task::Goal) => {
            m.normalized_distance = 1.0;
            m.normalized_distance_curve = vec![1.0; budget];
        }
        Scoring::Exploration { start, scale } => {
            // Steps the protocol scores: the paper stops at a limit; a policy
            // that stopped leaves the state as it was for the rest.
            let scored = if ended_by_protocol {
                after.len()
            } else {
                budget
            };
            let value_at = |t: usize| after.get(t).or(after.last()).copied().unwrap_or(start);
            m.single_action_effect =
                steps.iter().map(|s| s.1 / DELTA).sum::<f32>() / scored.max(1) as f32;
            match protocol {
                Protocol::Paper => {
                    let values: Vec<f32> = (0..scored).map(value_at).collect();
                    let visited = protocol::paper_walk(start, &values, scale);
                    m.unique_states = (0..budget)
                        .map(|t| {
                            protocol::paper_unique_states(&visited[..(t + 1).min(scored)]) as f32
                        })
                        .collect();
                    m.novel_state_ratio =
                        protocol::paper_unique_states(&visited) as f32 / scored.max(1) as f32;
                }
                Protocol::Strict => {
                    let values: Vec<f32> = (0..budget).map(value_at).collect();
                    m.unique_states = protocol::strict_unique_states(start, &values)
                        .into_iter()
                        .map(|u| u as f32)
                        .collect();
                    m.novel_state_ratio =
                        m.unique_states.last().copied().unwrap_or(0.0) / budget.max(1) as f32;
                }
            }
        }
        Scoring::Goal { init, target, now } => {
            let dist = |v: f32| -> f32 { (v - target).abs() / (target - init).abs().max(1e-6) };
            let mut last = 1.0;
            for t in 0..budget {
                if let Some(v) = after.get(t) {
                    last = dist(*v);
                }
                if ended_by_protocol && t + 1 >= after.len() {
                    last = 0.0;
                }
                m.normalized_distance_curve.push(last);
            }
            m.normalized_distance = if ended_by_protocol { 0.0 } else { dist(now) };
            m.success = m.normalized_distance < 0.1;
        }
    }
    m
}

fn metrics(
    scene: &Scene,
    joint: Option<usize>,
    env: &SimEnv,
    steps: &[Step],
    budget: usize,
    protocol: Protocol,
    ended_by_protocol: bool,
) -> Metrics {
    let what = match (scene.task, joint, scene.goal.as_ref()) {
        (Task::Exploration, Some(j), _) => Scoring::Exploration {
            start: steps
                .first()
                .map(|s| s.record.labels.joint_before)
                .unwrap_or_else(|| env.articulation().joint_position(j)),
            scale: if env.model().joints[j].kind.is_prismatic() {
                scene.pose.scale
            } else {
                1.0
            },
        },
        (Task::Goal, Some(_), Some(g)) => Scoring::Goal {
            init: scene.joints[g.joint],
            target: g.joints[g.joint],
            now: env.articulation().joint_position(g.joint),
        },
        _ => Scoring::Missed(scene.task),
    };
    let records: Vec<(f32, f32)> = steps
        .iter()
        .map(|s| (s.record.labels.joint_after, s.record.labels.r_dist))
        .collect();
    let mut m = score(what, &records, budget, protocol, ended_by_protocol);
    if let (Task::Exploration, Some(j)) = (scene.task, joint) {
        let (true_axis, _) = env.articulation().joint_axis_in_world(j);
        let prismatic = env.model().joints[j].kind.is_prismatic();
        m.axis = axis_error(steps, prismatic, true_axis.to_array());
    }
    m
}
