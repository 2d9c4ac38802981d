//! VecEnv's mixed step (`step_mixed`, gymnasium's next-step autoreset): one
//! action kind per environment, and the info dict of what each did; and
//! the step helpers every VecEnv step shares.
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use umpnet_eval::EvalError;
use umpnet_eval::train_env::render_pending;
use umpnet_eval::train_env::{PositionInfo, TrainEnv};
use umpnet_sim::env::StepLabels;

/// The direction budget of a scene without a category (an object file), as
/// the gymnasium envs use.
pub(crate) const DEFAULT_BUDGET: i64 = 10;

#[derive(Clone, Copy)]
pub(crate) enum Mixed {
    Idle,
    Reset,
    Grasp(u32, u32),
    Move([f32; 3]),
}

pub(crate) enum Outcome {
    Idle,
    Reset,
    Grasp {
        info: PositionInfo,
        start: f32,
        goal: f32,
    },
    Move(StepLabels),
}

/// One environment's part of `step_mixed`. With `batch`, grasps and moves
/// leave their drawing to `render_pending`; a reset draws its own frames (it
/// needs the goal image as well).
pub(crate) fn mixed_step(e: &mut TrainEnv, a: Mixed, batch: bool) -> Result<Outcome, EvalError> {
    Ok(match a {
        Mixed::Idle => Outcome::Idle,
        Mixed::Reset => {
            e.reset_in_place(None)?;
            Outcome::Reset
        }
        Mixed::Grasp(r, c) => {
            let info = grasp_at(e, r, c, batch)?;
            let value = |joints: &[f32]| {
                info.joint
                    .and_then(|j| joints.get(j).copied())
                    .unwrap_or(f32::NAN)
            };
            let start = value(&e.joint_positions());
            let goal = e
                .scene()
                .and_then(|s| s.goal.as_ref())
                .map_or(f32::NAN, |g| value(&g.joints));
            Outcome::Grasp { info, start, goal }
        }
        Mixed::Move(d) => Outcome::Move(move_along(e, d, batch)?),
    })
}

/// What the moves of a mixed step did (NaN, 0 or false for the others).
fn move_fields(py: Python<'_>, d: &Bound<'_, PyDict>, outcomes: &[Outcome]) -> PyResult<()> {
    let moved = |f: &dyn Fn(&StepLabels) -> f32| -> Vec<f32> {
        outcomes
            .iter()
            .map(|o| match o {
                Outcome::Move(l) => f(l),
                _ => f32::NAN,
            })
            .collect()
    };
    d.set_item(
        "joint_before",
        PyArray1::from_vec(py, moved(&|l| l.joint_before)),
    )?;
    d.set_item(
        "joint_after",
        PyArray1::from_vec(py, moved(&|l| l.joint_after)),
    )?;
    d.set_item("r_dist", PyArray1::from_vec(py, moved(&|l| l.r_dist)))?;
    d.set_item(
        "aot",
        PyArray1::from_vec(
            py,
            outcomes
                .iter()
                .map(|o| match o {
                    Outcome::Move(l) => i64::from(l.aot),
                    _ => 0,
                })
                .collect::<Vec<_>>(),
        ),
    )?;
    d.set_item(
        "suction_lost",
        PyArray1::from_vec(
            py,
            outcomes
                .iter()
                .map(|o| matches!(o, Outcome::Move(l) if l.suction_lost))
                .collect::<Vec<_>>(),
        ),
    )?;
    Ok(())
}

pub(crate) fn mixed_info<'py>(
    py: Python<'py>,
    outcomes: &[Outcome],
    budgets: Vec<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    let n = outcomes.len();
    let d = PyDict::new(py);
    let kind: Vec<i64> = outcomes
        .iter()
        .map(|o| match o {
            Outcome::Idle => 0,
            Outcome::Reset => 1,
            Outcome::Grasp { .. } => 2,
            Outcome::Move(_) => 3,
        })
        .collect();
    d.set_item("kind", PyArray1::from_vec(py, kind))?;
    let grasp = |f: &dyn Fn(&PositionInfo, f32, f32) -> f32| -> Vec<f32> {
        outcomes
            .iter()
            .map(|o| match o {
                Outcome::Grasp { info, start, goal } => f(info, *start, *goal),
                _ => f32::NAN,
            })
            .collect()
    };
    d.set_item(
        "valid",
        PyArray1::from_vec(
            py,
            outcomes
                .iter()
                .map(|o| matches!(o, Outcome::Grasp { info, .. } if info.valid))
                .collect::<Vec<_>>(),
        ),
    )?;
    d.set_item(
        "joint",
        PyArray1::from_vec(
            py,
            outcomes
                .iter()
                .map(|o| match o {
                    Outcome::Grasp { info, .. } => info.joint.map_or(-1, |j| j as i64),
                    _ => -1,
                })
                .collect::<Vec<_>>(),
        ),
    )?;
    let limits: Vec<f32> = outcomes
        .iter()
        .flat_map(|o| match o {
            Outcome::Grasp { info, .. } => info.limits.unwrap_or([f32::NAN; 2]),
            _ => [f32::NAN; 2],
        })
        .collect();
    d.set_item("limits", PyArray1::from_vec(py, limits).reshape([n, 2])?)?;
    d.set_item(
        "threshold",
        PyArray1::from_vec(py, grasp(&|i, _, _| i.threshold.unwrap_or(f32::NAN))),
    )?;
    d.set_item("start", PyArray1::from_vec(py, grasp(&|_, s, _| s)))?;
    d.set_item("goal", PyArray1::from_vec(py, grasp(&|_, _, g| g)))?;
    move_fields(py, &d, outcomes)?;
    d.set_item("budget", PyArray1::from_vec(py, budgets))?;
    Ok(d)
}

/// `f` on every environment in parallel, then the frames its steps left to
/// draw, in one batch. They are drawn even when one environment failed: the
/// others' steps happened, and their observations must show them.
pub(crate) fn step_all<T: Send>(
    envs: &mut [TrainEnv],
    f: impl Fn(usize, &mut TrainEnv) -> Result<T, EvalError> + Sync + Send,
) -> Result<Vec<T>, EvalError> {
    let out = envs
        .par_iter_mut()
        .enumerate()
        .map(|(i, e)| f(i, e))
        .collect();
    render_pending(envs)?;
    out
}

/// A grasp whose frame `step_all` draws with the batch (`batch`), or at once.
pub(crate) fn grasp_at(
    e: &mut TrainEnv,
    row: u32,
    col: u32,
    batch: bool,
) -> Result<PositionInfo, EvalError> {
    if batch {
        e.step_position_deferred(row, col)
    } else {
        e.step_position_in_place(row, col)
    }
}

/// A move whose frame `step_all` draws with the batch (`batch`), or at once.
pub(crate) fn move_along(
    e: &mut TrainEnv,
    d: [f32; 3],
    batch: bool,
) -> Result<StepLabels, EvalError> {
    if batch {
        e.step_direction_deferred(d)
    } else {
        e.step_direction_in_place(d)
    }
}
