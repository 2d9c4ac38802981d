//! One episode: position action, then up to N direction actions, with the
//! paper's metrics computed from the grasped joint's trajectory.
use crate::Result;
use crate::policy::{Candidates, Decision, Observation, Policy, StepRecord};
use umpnet_sim::camera::Camera;
use umpnet_sim::env::{DELTA, Pick, SimEnv};
use umpnet_sim::render::{Frame, Renderer};
use umpnet_sim::scene::{Scene, Task};

#[derive(Clone, Debug, serde::Serialize)]
pub struct Step {
    pub record: StepRecord,
    /// Gripper position when the action started.
    pub gripper_in_world: [f32; 3],
    pub candidates: Option<Candidates>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Episode {
    pub policy: String,
    pub scene: Scene,
    /// The grasped pixel (row, col).
    pub pixel: (u32, u32),
    /// The position landed on a valid link (for the goal task: the goal joint's).
    pub valid_position: bool,
    pub joint: Option<usize>,
    pub steps: Vec<Step>,
    pub stopped_early: bool,
    pub budget: usize,
    pub metrics: Metrics,
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Metrics {
    /// Exploration: unique states after each step (length = budget).
    pub unique_states: Vec<f32>,
    pub novel_state_ratio: f32,
    pub single_action_effect: f32,
    /// Goal: normalised distance after each step (length = budget).
    pub normalized_distance_curve: Vec<f32>,
    pub normalized_distance: f32,
    pub success: bool,
}

/// Hooks for pictures: called with each frame the policy saw.
pub type FrameHook<'a> = &'a mut dyn FnMut(usize, &Frame, Option<&Step>, (u32, u32));

/// Runs one episode of `policy` on `scene` with a renderer of the caller's.
pub fn run_episode(
    scene: &Scene,
    camera: &Camera,
    renderer: Box<dyn Renderer>,
    policy: &mut dyn Policy,
    budget: usize,
    seed: u64,
    mut hook: Option<FrameHook>,
) -> Result<Episode> {
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
    let mut frame = first;
    if let Some(h) = hook.as_mut() {
        h(0, &frame, None, pixel);
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
                h(t + 1, &after, Some(&step), pixel);
            }
            steps.push(step);
        }
    }
    let metrics = metrics(scene, joint.filter(|_| valid), &env, &steps, budget);
    Ok(Episode {
        policy: policy.name(),
        scene: scene.clone(),
        pixel,
        valid_position: valid,
        joint,
        steps,
        stopped_early,
        budget,
        metrics,
    })
}

fn metrics(
    scene: &Scene,
    joint: Option<usize>,
    env: &SimEnv,
    steps: &[Step],
    budget: usize,
) -> Metrics {
    let mut m = Metrics::default();
    match scene.task {
        Task::Exploration => {
            let mut visited: Vec<f32> = Vec::new();
            if let (Some(_), Some(first)) = (joint, steps.first()) {
                visited.push(first.record.labels.joint_before);
            }
            let mut effect = 0.0;
            for t in 0..budget {
                if let Some(s) = steps.get(t) {
                    let v = s.record.labels.joint_after;
                    if visited.iter().all(|u| (u - v).abs() >= DELTA) {
                        visited.push(v);
                    }
                    effect += s.record.labels.r_dist / DELTA;
                }
                // The initial state is not a discovery.
                m.unique_states.push(visited.len().saturating_sub(1) as f32);
            }
            m.novel_state_ratio =
                m.unique_states.last().copied().unwrap_or(0.0) / budget.max(1) as f32;
            m.single_action_effect = effect / budget.max(1) as f32;
        }
        Task::Goal => {
            let goal = scene.goal.as_ref();
            let dist = |v: f32| -> f32 {
                match goal {
                    Some(g) => {
                        let (init, target) = (scene.joints[g.joint], g.joints[g.joint]);
                        (v - target).abs() / (target - init).abs().max(1e-6)
                    }
                    None => 1.0,
                }
            };
            let mut last = 1.0;
            for t in 0..budget {
                if joint.is_some()
                    && let Some(s) = steps.get(t)
                {
                    last = dist(s.record.labels.joint_after);
                }
                m.normalized_distance_curve.push(last);
            }
            m.normalized_distance = match (joint, goal) {
                (Some(_), Some(g)) => dist(env.articulation().joint_position(g.joint)),
                _ => 1.0,
            };
            m.success = m.normalized_distance < 0.1;
        }
    }
    m
}
