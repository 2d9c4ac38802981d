//! Python bindings: `umpnet.Env`, `umpnet.VecEnv`, `umpnet.Policy`,
//! `umpnet.Articulation` (physics only, in physics.rs).
//! Errors become ValueError (bad input) or RuntimeError (anything else);
//! no Rust panic crosses into Python.
#![allow(
    clippy::indexing_slicing,
    reason = "every index follows a shape check of the array it indexes, which raises ValueError otherwise"
)]
use arrays::Arr2;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use umpnet_eval::EvalError;
use umpnet_eval::train_env::{PositionInfo, ScriptedAction, TrainEnv};
use umpnet_sim::env::StepLabels;
use umpnet_sim::scene::{Scene, Task};

/// Bounds on what a caller may ask for: far above any machine's use, far below
/// what exhausts memory or threads.
pub(crate) const MAX_ENVS: usize = 4096;
pub(crate) const MAX_THREADS: usize = 1024;

fn runtime_err(e: impl std::fmt::Display) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

/// A package or an input that is wrong is the caller's ValueError; a runtime
/// that fails (ONNX Runtime missing or broken) is a RuntimeError.
pub(crate) fn policy_err(e: umpnet_policy::PolicyError) -> PyErr {
    match e {
        umpnet_policy::PolicyError::Input(_) | umpnet_policy::PolicyError::Package { .. } => {
            PyValueError::new_err(e.to_string())
        }
        other => runtime_err(other),
    }
}

pub(crate) fn eval_err(e: EvalError) -> PyErr {
    match e {
        EvalError::Sim(umpnet_sim::SimError::InvalidAction(m)) => PyValueError::new_err(m),
        EvalError::Sim(umpnet_sim::SimError::InvalidScene(m)) => PyValueError::new_err(m),
        EvalError::Policy(umpnet_policy::PolicyError::Input(m)) => PyValueError::new_err(m),
        EvalError::Policy(p) => policy_err(p),
        other => runtime_err(other),
    }
}

/// A scene as a Python dict (through its JSON form, the one schema).
pub(crate) fn scene_to_py<'py>(py: Python<'py>, scene: &Scene) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (scene.to_json(),))
}

/// A scene from a dict (as `.scene` gives it) or its JSON text.
pub(crate) fn scene_from_py(obj: &Bound<'_, PyAny>) -> PyResult<Scene> {
    let text: String = if let Ok(s) = obj.extract::<String>() {
        s
    } else if obj.is_instance_of::<PyDict>() {
        obj.py()
            .import("json")?
            .call_method1("dumps", (obj,))?
            .extract()?
    } else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "scene must be a dict (from .scene) or its JSON text, got {}",
            obj.get_type().name()?
        )));
    };
    Scene::from_json(&text).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn labels_dict<'py>(py: Python<'py>, l: &StepLabels) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("r_dist", l.r_dist)?;
    d.set_item("aot", l.aot)?;
    d.set_item("moved", l.moved)?;
    d.set_item("train_aot", l.train.aot)?;
    d.set_item("train_moved", l.train.moved)?;
    Ok(d)
}

fn step_info<'py>(
    py: Python<'py>,
    l: &StepLabels,
    joints: Vec<f32>,
    gripper: Option<[f32; 3]>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("gripper_in_world", gripper.map(|g| g.to_vec()))?;
    d.set_item("joint_before", l.joint_before)?;
    d.set_item("joint_after", l.joint_after)?;
    d.set_item("reached_limit", l.reached_limit)?;
    d.set_item("back_at_start", l.back_at_start)?;
    d.set_item("suction_lost", l.suction_lost)?;
    d.set_item("reached_boundary", l.train.reached_boundary)?;
    d.set_item("reached_init", l.train.reached_init)?;
    d.set_item("joints", joints)?;
    Ok(d)
}

fn position_info<'py>(
    py: Python<'py>,
    i: &PositionInfo,
    gripper: Option<[f32; 3]>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("gripper_in_world", gripper.map(|g| g.to_vec()))?;
    d.set_item("valid", i.valid)?;
    d.set_item("link", i.link)?;
    d.set_item("joint", i.joint)?;
    d.set_item("point_in_world", i.point_in_world.map(|p| p.to_vec()))?;
    d.set_item("limits", i.limits.map(|l| l.to_vec()))?;
    d.set_item("threshold", i.threshold)?;
    Ok(d)
}

/// (row, col), [x, y, z] or None.
pub(crate) fn scripted_to_py(py: Python<'_>, a: ScriptedAction) -> PyResult<Py<PyAny>> {
    Ok(match a {
        ScriptedAction::Pixel(r, c) => (r, c).into_pyobject(py)?.into_any().unbind(),
        ScriptedAction::Direction(d) => d.to_vec().into_pyobject(py)?.into_any().unbind(),
        ScriptedAction::Stop => py.None(),
    })
}

pub(crate) fn parse_direction(v: Vec<f32>) -> PyResult<[f32; 3]> {
    let d: [f32; 3] = v.try_into().map_err(|v: Vec<f32>| {
        PyValueError::new_err(format!("direction must have 3 components, got {}", v.len()))
    })?;
    if !d.iter().all(|x| x.is_finite()) || d.iter().map(|x| x * x).sum::<f32>() < 1e-12 {
        return Err(PyValueError::new_err(format!(
            "direction {d:?} must be finite and non-zero"
        )));
    }
    Ok(d)
}

/// One simulated scene: reset, a position action (a pixel), then direction
/// actions (unit vectors in the world frame). Observations are dicts of numpy
/// arrays: `image` and `reference` (H x W x 10 float32: xyz, rgb, normal,
/// depth), `segmentation`, `intrinsics`, `world_from_camera`, `gripper_pixel`.
///
/// The arrays are the environment's own buffers, rewritten in place by every
/// step (the zero-copy path, see buffers.rs): copy what you keep past the
/// next step, or pass `copy=True` for fresh arrays each time.
#[pyclass(module = "umpnet")]
struct Env {
    inner: TrainEnv,
    buffers: buffers::ObsBuffers,
    copy: bool,
    /// The scene again at a display size (`render_rgb`), remade when the
    /// scene or the size changes.
    display: Option<umpnet_sim::env::SimEnv>,
}

#[pymethods]
impl Env {
    /// `Env(category=None, seed=0, copy=False, config=None, **options)`:
    /// the scenes come from `config` (an `EnvConfig`), or from `category`
    /// and `options`, `EnvConfig`'s keyword arguments.
    #[new]
    #[pyo3(signature = (category=None, seed=0, copy=false, config=None, **options))]
    fn new(
        py: Python<'_>,
        category: Option<Bound<'_, PyAny>>,
        seed: u64,
        copy: bool,
        config: Option<PyRef<'_, config::EnvConfig>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let cfg = config::resolve(py, category, config, options)?;
        let (h, w) = (cfg.resolution.0 as usize, cfg.resolution.1 as usize);
        Ok(Self {
            inner: TrainEnv::new(cfg, seed).map_err(eval_err)?,
            buffers: buffers::ObsBuffers::new(py, None, h, w)?,
            copy,
            display: None,
        })
    }

    /// The current state in colour at `height` x `width` (uint8, H x W x 3),
    /// gripper included, from the same camera pose the observations use:
    /// pictures for people, whatever size the observations are.
    #[pyo3(signature = (height=480, width=640))]
    fn render_rgb<'py>(
        &mut self,
        py: Python<'py>,
        height: i64,
        width: i64,
    ) -> PyResult<Bound<'py, numpy::PyArray3<u8>>> {
        let size = display::size(height, width)?;
        let rgb = display::draw(&mut self.display, &self.inner, size)?;
        Ok(numpy::PyArray3::from_owned_array(py, rgb))
    }

    /// Starts an episode on a new scene, or on `scene` (a dict from `.scene`,
    /// or its JSON text). Returns the observation.
    #[pyo3(signature = (scene=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        scene: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let scene = scene.map(|s| scene_from_py(&s)).transpose()?;
        self.inner.reset_in_place(scene).map_err(eval_err)?;
        self.buffers
            .fill(py, std::slice::from_mut(&mut self.inner), true, self.copy)
    }

    /// Renders the current state into the observation buffers without acting
    /// (the same observation the last step returned, bit for bit).
    fn observe<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.inner.render_in_place().map_err(eval_err)?;
        self.buffers
            .fill(py, std::slice::from_mut(&mut self.inner), false, self.copy)
    }

    /// Dense labels of the current observation, for training: `flow` (H, W, 3),
    /// each pixel's opening direction in the world frame (zero off movable
    /// parts); `joint` (H, W), the joint a grasp there moves (-1: none);
    /// `movable` (H, W); `goal_displacement` (H, W, 3), the way each point goes
    /// to the goal state (m), or None without a goal.
    fn articulation_fields<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let f = self.inner.articulation_fields().map_err(eval_err)?;
        let stacked = fields::fields_dict(py, std::slice::from_ref(&f))?;
        let d = PyDict::new(py);
        for (k, v) in stacked.iter() {
            let v = if v.is_none() { v } else { v.get_item(0)? };
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    /// The scene as a dict; `reset(scene=...)` replays it exactly.
    #[getter]
    fn scene<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let s = self
            .inner
            .scene()
            .ok_or_else(|| PyRuntimeError::new_err("reset() first"))?;
        scene_to_py(py, s)
    }

    /// Grasps at pixel (row, col). Returns (observation, info); info["valid"] is
    /// False when the pixel is not on a movable link (or not on the goal joint).
    fn step_position<'py>(
        &mut self,
        py: Python<'py>,
        row: i64,
        col: i64,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let (Ok(r), Ok(c)) = (u32::try_from(row), u32::try_from(col)) else {
            return Err(PyValueError::new_err(format!(
                "pixel ({row}, {col}) must be non-negative and inside the image"
            )));
        };
        let info = self.inner.step_position_in_place(r, c).map_err(eval_err)?;
        let obs = self
            .buffers
            .fill(py, std::slice::from_mut(&mut self.inner), false, self.copy)?;
        let gripper = self.inner.gripper_in_world();
        Ok((obs, position_info(py, &info, gripper)?))
    }

    /// Moves the gripper 0.18 m along `direction`. Returns (observation, labels, info).
    fn step_direction<'py>(
        &mut self,
        py: Python<'py>,
        direction: Vec<f32>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let d = parse_direction(direction)?;
        let labels = self.inner.step_direction_in_place(d).map_err(eval_err)?;
        let obs = self
            .buffers
            .fill(py, std::slice::from_mut(&mut self.inner), false, self.copy)?;
        let joints = self.inner.joint_positions();
        let gripper = self.inner.gripper_in_world();
        Ok((
            obs,
            labels_dict(py, &labels)?,
            step_info(py, &labels, joints, gripper)?,
        ))
    }

    /// Dense labels: what each of `directions` (float32, k x 3) would do from
    /// the current state, which stays as it is. Returns arrays of length k:
    /// r_dist, aot, moved, joint_after.
    fn probe_directions<'py>(
        &self,
        py: Python<'py>,
        directions: Arr2<'py, f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let directions = directions.0;
        let dirs = vec![probe::directions_2d(&directions)?];
        let k = dirs[0].len();
        let labels = probe::probe_all(py, std::slice::from_ref(&self.inner), &dirs)?;
        if labels.first().is_none_or(|l| l.is_none()) {
            return Err(PyValueError::new_err(
                "probe_directions before a valid position action",
            ));
        }
        let out = probe::labels_dict(py, &labels, k)?;
        let flat = PyDict::new(py);
        for key in ["r_dist", "joint_after", "aot", "moved"] {
            if let Some(v) = out.get_item(key)? {
                flat.set_item(key, v.call_method1("reshape", (k,))?)?;
            }
        }
        Ok(flat)
    }

    /// The action `oracle` or `random` would take now: (row, col) before the
    /// grasp, a direction after, None when the policy stops.
    fn scripted_action(&mut self, py: Python<'_>, policy: &str) -> PyResult<Py<PyAny>> {
        scripted_to_py(py, self.inner.scripted_action(policy).map_err(eval_err)?)
    }

    /// Current joint values of the object.
    fn joint_positions(&self) -> Vec<f32> {
        self.inner.joint_positions()
    }
}

mod arrays;
mod buffers;
mod config;
mod display;
mod fields;
mod mixed;
mod physics;
mod policy;
mod probe;
mod vec_env;

/// The object categories in the paper's order: (name, split, step budget),
/// split "train" or "test" (the categories held out from training).
#[pyfunction]
fn categories() -> Vec<(&'static str, &'static str, usize)> {
    umpnet_sim::objects::Category::ALL
        .iter()
        .map(|c| {
            let split = if c.is_train() { "train" } else { "test" };
            (c.name(), split, c.step_budget())
        })
        .collect()
}

/// The seeds `umpnet eval --seed SEED` gives scene `index` of a row (a
/// category's name, or with `object=True` an `eval --objects` folder's
/// name): (the scene's, the policy's). With the scene from its
/// episodes.jsonl and `Policy.reset(policy_seed)`, `Policy.act` makes the
/// benchmark's moves.
#[pyfunction]
#[pyo3(signature = (task, row, index, seed=0, object=false))]
fn benchmark_seeds(
    task: &str,
    row: &str,
    index: u32,
    seed: u64,
    object: bool,
) -> PyResult<(u64, u64)> {
    use umpnet_eval::benchmark::{ObjectRow, Row, policy_seed, row_seed};
    let task: Task = task
        .parse()
        .map_err(|e: umpnet_sim::SimError| PyValueError::new_err(e.to_string()))?;
    let row = if object {
        Row::Object(ObjectRow {
            name: row.to_owned(),
            urdf: std::path::PathBuf::new(),
        })
    } else {
        Row::Category(
            row.parse::<umpnet_sim::objects::Category>()
                .map_err(|e| PyValueError::new_err(e.to_string()))?,
        )
    };
    Ok((
        row_seed(seed, task, &row, index),
        policy_seed(seed, task, &row, index),
    ))
}

/// The reward, success and farthest distance of one direction step, by the
/// paper's protocol as `umpnet eval` applies it (umpnet_eval::rewards):
/// what gymnasium's environments return, defined once, in Rust.
#[pyfunction]
#[pyo3(signature = (task, before, after, start, farthest, lower, upper, threshold, goal))]
#[expect(
    clippy::too_many_arguments,
    reason = "the Rust rule's inputs, one Python argument each"
)]
fn score_step(
    task: &str,
    before: f32,
    after: f32,
    start: f32,
    farthest: f32,
    lower: f32,
    upper: f32,
    threshold: f32,
    goal: f32,
) -> PyResult<(f32, bool, f32)> {
    let task: Task = task
        .parse()
        .map_err(|e: umpnet_sim::SimError| PyValueError::new_err(e.to_string()))?;
    let s = umpnet_eval::rewards::score_step(
        task,
        before,
        after,
        start,
        farthest,
        (lower, upper),
        threshold,
        goal,
    );
    Ok((s.reward, s.success, s.farthest))
}

#[pymodule]
fn _umpnet(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(categories, m)?)?;
    m.add_function(wrap_pyfunction!(score_step, m)?)?;
    m.add_function(wrap_pyfunction!(benchmark_seeds, m)?)?;
    m.add_function(wrap_pyfunction!(policy::onnxruntime_in_site_packages, m)?)?;
    m.add_function(wrap_pyfunction!(policy::joint_from_fields, m)?)?;
    m.add_function(wrap_pyfunction!(policy::mirrored_observations, m)?)?;
    m.add("DELTA", umpnet_sim::env::DELTA)?;
    m.add_class::<Env>()?;
    m.add_class::<config::EnvConfig>()?;
    m.add_class::<physics::Articulation>()?;
    m.add_class::<vec_env::VecEnv>()?;
    m.add_class::<policy::Policy>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
