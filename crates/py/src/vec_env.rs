//! `umpnet.VecEnv`: n environments stepped in parallel Rust threads, and the
//! mixed step that a gymnasium `VectorEnv` needs (each environment resets,
//! grasps or moves, as its own episode stands).
#![allow(
    clippy::indexing_slicing,
    reason = "every index follows a shape check of the array it indexes, which raises ValueError otherwise"
)]
use crate::arrays::{Arr1, Arr2, Arr3};
use crate::mixed::{DEFAULT_BUDGET, Mixed, grasp_at, mixed_info, mixed_step, move_along, step_all};
use crate::{
    MAX_ENVS, buffers, eval_err, parse_direction, probe, scene_from_py, scene_to_py, scripted_to_py,
};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use umpnet_eval::train_env::TrainEnv;
use umpnet_sim::camera::GlassDepth;
use umpnet_sim::env::StepLabels;
use umpnet_sim::scene::Scene;

/// n environments stepped in parallel Rust threads (GIL released); env i is
/// seeded `seed + i`. Results are stacked into one numpy array per field.
///
/// Like `Env`, observations are buffers rewritten in place by every step
/// unless `copy=True`.
///
/// With `batch_render=True` (the default) a step runs every environment's
/// physics in parallel, then draws all their frames in one batch (one wgpu
/// submission, or the CPU renderer in parallel across environments). False
/// draws each environment as its step ends; the observations are the same,
/// bit for bit.
#[pyclass(module = "umpnet")]
pub(crate) struct VecEnv {
    envs: Vec<TrainEnv>,
    buffers: buffers::ObsBuffers,
    copy: bool,
    batch_render: bool,
    /// Each environment's scene at a display size (`render_rgb`).
    displays: Vec<Option<umpnet_sim::env::SimEnv>>,
}

#[pymethods]
impl VecEnv {
    /// `VecEnv(n, category=None, seed=0, copy=False, batch_render=True,
    /// config=None, glass_depths=None, **options)`: environment i has seed
    /// `seed + i`; the scenes come from `config` (an `EnvConfig`), or from
    /// `category` and `options`, `EnvConfig`'s keyword arguments.
    /// `glass_depths`, one reading per environment (`surface`, `through`,
    /// `missing`), gives each environment's camera its own way of reading
    /// glass, over the config's `glass_depth`.
    #[new]
    #[pyo3(signature = (n, category=None, seed=0, copy=false, batch_render=true, config=None, glass_depths=None, **options))]
    #[expect(
        clippy::too_many_arguments,
        reason = "Python keyword arguments, each with a default"
    )]
    fn new(
        py: Python<'_>,
        n: i64,
        category: Option<Bound<'_, PyAny>>,
        seed: u64,
        copy: bool,
        batch_render: bool,
        config: Option<PyRef<'_, crate::config::EnvConfig>>,
        glass_depths: Option<Vec<String>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let n = match usize::try_from(n) {
            Ok(n) if (1..=MAX_ENVS).contains(&n) => n,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "n = {n}: expected 1 to {MAX_ENVS} environments"
                )));
            }
        };
        let cfg = crate::config::resolve(py, category, config, options)?;
        let readings: Vec<GlassDepth> = match glass_depths {
            None => vec![cfg.glass_depth; n],
            Some(names) if names.len() != n => {
                return Err(PyValueError::new_err(format!(
                    "glass_depths: {} readings for {n} environments",
                    names.len()
                )));
            }
            Some(names) => names
                .iter()
                .map(|name| {
                    name.parse()
                        .map_err(|e| PyValueError::new_err(format!("glass_depths: {e}")))
                })
                .collect::<PyResult<_>>()?,
        };
        let envs = readings
            .iter()
            .enumerate()
            .map(|(i, &glass_depth)| {
                let cfg = umpnet_eval::train_env::EnvConfig {
                    glass_depth,
                    ..cfg.clone()
                };
                TrainEnv::new(cfg, seed + i as u64)
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(eval_err)?;
        let (h, w) = (cfg.resolution.0 as usize, cfg.resolution.1 as usize);
        Ok(Self {
            envs,
            buffers: buffers::ObsBuffers::new(py, Some(n), h, w)?,
            copy,
            batch_render,
            displays: (0..n).map(|_| None).collect(),
        })
    }

    fn __len__(&self) -> usize {
        self.envs.len()
    }

    /// Every environment's current state in colour at `height` x `width`
    /// (uint8, n x H x W x 3), as `Env.render_rgb` draws one.
    #[pyo3(signature = (height=480, width=640))]
    fn render_rgb<'py>(
        &mut self,
        py: Python<'py>,
        height: i64,
        width: i64,
    ) -> PyResult<Bound<'py, numpy::PyArray4<u8>>> {
        let (h, w) = crate::display::size(height, width)?;
        let mut all =
            numpy::ndarray::Array4::<u8>::zeros((self.envs.len(), h as usize, w as usize, 3));
        for ((env, display), mut out) in self
            .envs
            .iter()
            .zip(self.displays.iter_mut())
            .zip(all.outer_iter_mut())
        {
            out.assign(&crate::display::draw(display, env, (h, w))?);
        }
        Ok(numpy::PyArray4::from_owned_array(py, all))
    }

    /// Current joint values of every environment's object (a list each).
    fn joint_positions(&self) -> Vec<Vec<f32>> {
        self.envs.iter().map(TrainEnv::joint_positions).collect()
    }

    /// Resets every environment (optionally to given scenes: dicts from
    /// `.scenes`, or their JSON text, one each).
    #[pyo3(signature = (scenes=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        scenes: Option<Vec<Bound<'py, PyAny>>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = self.envs.len();
        let scenes: Vec<Option<Scene>> = match scenes {
            Some(s) if s.len() != n => {
                return Err(PyValueError::new_err(format!(
                    "{} scenes for {n} environments",
                    s.len()
                )));
            }
            Some(s) => s
                .iter()
                .map(|j| scene_from_py(j).map(Some))
                .collect::<PyResult<_>>()?,
            None => vec![None; n],
        };
        let envs = &mut self.envs;
        py.detach(|| {
            envs.par_iter_mut()
                .zip(scenes)
                .map(|(e, s)| e.reset_in_place(s))
                .collect::<Result<Vec<_>, _>>()
        })
        .map_err(eval_err)?;
        self.buffers.fill(py, &mut self.envs, true, self.copy)
    }

    /// Scenes of all environments as dicts (None before the first reset).
    #[getter]
    fn scenes<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        self.envs
            .iter()
            .map(|e| match e.scene() {
                Some(s) => scene_to_py(py, s),
                None => Ok(py.None().into_bound(py)),
            })
            .collect()
    }

    /// pixels: int array n x 2 (row, col). Returns (observations, info) with info["valid"] a bool array
    /// and info["gripper_in_world"] (n x 3) where each gripper holds the part.
    fn step_position<'py>(
        &mut self,
        py: Python<'py>,
        pixels: Arr2<'py, i64>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let pixels = pixels.0;
        let n = self.envs.len();
        if pixels.shape() != [n, 2] {
            return Err(PyValueError::new_err(format!(
                "pixels has shape {:?}, expected ({n}, 2)",
                pixels.shape()
            )));
        }
        // Checked, not cast: 2**32 + r must not wrap round to r.
        let Ok(p) = pixels
            .as_array()
            .iter()
            .map(|&v| u32::try_from(v))
            .collect::<Result<Vec<u32>, _>>()
        else {
            return Err(PyValueError::new_err(
                "pixels must be non-negative and inside the image",
            ));
        };
        let (envs, batch) = (&mut self.envs, self.batch_render);
        let out = py
            .detach(|| step_all(envs, |i, e| grasp_at(e, p[2 * i], p[2 * i + 1], batch)))
            .map_err(eval_err)?;
        let infos = out;
        let obs = self.buffers.fill(py, &mut self.envs, false, self.copy)?;
        let info = PyDict::new(py);
        info.set_item(
            "valid",
            PyArray1::from_vec(py, infos.iter().map(|i| i.valid).collect::<Vec<_>>()),
        )?;
        info.set_item(
            "joint",
            infos
                .iter()
                .map(|i| i.joint.map(|j| j as i64).unwrap_or(-1))
                .collect::<Vec<_>>(),
        )?;
        // (n, 2) limits and (n,) thresholds of the grasped joints; NaN where no grasp.
        let limits: Vec<f32> = infos
            .iter()
            .flat_map(|i| i.limits.unwrap_or([f32::NAN; 2]))
            .collect();
        info.set_item("limits", PyArray1::from_vec(py, limits).reshape([n, 2])?)?;
        info.set_item(
            "threshold",
            PyArray1::from_vec(
                py,
                infos
                    .iter()
                    .map(|i| i.threshold.unwrap_or(f32::NAN))
                    .collect::<Vec<_>>(),
            ),
        )?;
        info.set_item("gripper_in_world", grippers(py, &self.envs)?)?;
        Ok((obs, info))
    }

    /// directions: float array n x 3. Environments without a valid grasp are
    /// skipped (info["active"] False, labels zero). Returns (observations, labels, info);
    /// info["gripper_in_world"] (n x 3) is where each gripper is after its move.
    fn step_direction<'py>(
        &mut self,
        py: Python<'py>,
        directions: Arr2<'py, f32>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let directions = directions.0;
        let n = self.envs.len();
        if directions.shape() != [n, 3] {
            return Err(PyValueError::new_err(format!(
                "directions has shape {:?}, expected ({n}, 3)",
                directions.shape()
            )));
        }
        let a = directions.as_array();
        let dirs: Vec<[f32; 3]> = (0..n).map(|i| [a[[i, 0]], a[[i, 1]], a[[i, 2]]]).collect();
        for (i, d) in dirs.iter().enumerate() {
            if self.envs[i].grasped_joint().is_some() {
                parse_direction(d.to_vec())
                    .map_err(|e| PyValueError::new_err(format!("row {i}: {e}")))?;
            }
        }
        let (envs, batch) = (&mut self.envs, self.batch_render);
        let out = py
            .detach(|| {
                step_all(envs, |i, e| match e.grasped_joint() {
                    None => Ok(None),
                    Some(_) => move_along(e, dirs[i], batch).map(Some),
                })
            })
            .map_err(eval_err)?;
        let obs = self.buffers.fill(py, &mut self.envs, false, self.copy)?;
        let labels = PyDict::new(py);
        let get = |f: &dyn Fn(&StepLabels) -> f32| -> Vec<f32> {
            out.iter()
                .map(|l| l.as_ref().map(f).unwrap_or(0.0))
                .collect()
        };
        labels.set_item("r_dist", PyArray1::from_vec(py, get(&|l| l.r_dist)))?;
        labels.set_item(
            "aot",
            PyArray1::from_vec(
                py,
                out.iter()
                    .map(|l| l.as_ref().map(|l| l.aot as i64).unwrap_or(0))
                    .collect::<Vec<_>>(),
            ),
        )?;
        labels.set_item(
            "moved",
            PyArray1::from_vec(
                py,
                out.iter()
                    .map(|l| l.as_ref().is_some_and(|l| l.moved))
                    .collect::<Vec<_>>(),
            ),
        )?;
        labels.set_item(
            "train_aot",
            PyArray1::from_vec(
                py,
                out.iter()
                    .map(|l| l.as_ref().map(|l| l.train.aot as i64).unwrap_or(0))
                    .collect::<Vec<_>>(),
            ),
        )?;
        let flag = |f: &dyn Fn(&StepLabels) -> bool| -> Vec<bool> {
            out.iter().map(|l| l.as_ref().is_some_and(f)).collect()
        };
        labels.set_item(
            "train_moved",
            PyArray1::from_vec(py, flag(&|l| l.train.moved)),
        )?;
        let info = PyDict::new(py);
        info.set_item(
            "active",
            PyArray1::from_vec(py, out.iter().map(|l| l.is_some()).collect::<Vec<_>>()),
        )?;
        info.set_item(
            "joint_after",
            PyArray1::from_vec(py, get(&|l| l.joint_after)),
        )?;
        info.set_item(
            "suction_lost",
            PyArray1::from_vec(py, flag(&|l| l.suction_lost)),
        )?;
        info.set_item("gripper_in_world", grippers(py, &self.envs)?)?;
        info.set_item(
            "reached_boundary",
            PyArray1::from_vec(py, flag(&|l| l.train.reached_boundary)),
        )?;
        info.set_item(
            "reached_init",
            PyArray1::from_vec(py, flag(&|l| l.train.reached_init)),
        )?;
        Ok((obs, labels, info))
    }

    /// One step of every environment, each as its own episode stands: the
    /// step a gymnasium `VectorEnv` with autoreset needs. For environment i:
    /// - `reset[i]`: a new episode (a scene from its own seed stream); its
    ///   reference is rewritten;
    /// - else `phase[i] == 0`: grasp `pixels[i]`;
    /// - else, holding a grasp: move along `directions[i]`;
    /// - else nothing.
    ///
    /// Returns (observations, info) with one array per field, `kind` saying
    /// what each environment did (0 nothing, 1 reset, 2 grasp, 3 move).
    /// Grasps fill `valid`, `joint`, `limits`, `threshold`, `start` (the
    /// grasped joint's value) and `goal` (its goal value; NaN outside the goal
    /// task); moves fill `joint_before`, `joint_after`, `r_dist`, `aot` and
    /// `suction_lost`; `budget` is the current scene's category budget of
    /// direction steps (10 for an object file). Fields that do not apply are
    /// NaN, -1 or false.
    fn step_mixed<'py>(
        &mut self,
        py: Python<'py>,
        reset: Arr1<'py, bool>,
        phase: Arr1<'py, i64>,
        pixels: Arr2<'py, i64>,
        directions: Arr2<'py, f32>,
    ) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let n = self.envs.len();
        let (reset, phase, pixels, directions) = (reset.0, phase.0, pixels.0, directions.0);
        for (name, shape, want) in [
            ("reset", reset.shape(), vec![n]),
            ("phase", phase.shape(), vec![n]),
            ("pixels", pixels.shape(), vec![n, 2]),
            ("directions", directions.shape(), vec![n, 3]),
        ] {
            if shape != want.as_slice() {
                return Err(PyValueError::new_err(format!(
                    "{name} has shape {shape:?}, expected {want:?}"
                )));
            }
        }
        let (reset, phase, pixels, directions) = (
            reset.as_array(),
            phase.as_array(),
            pixels.as_array(),
            directions.as_array(),
        );
        let mut actions = Vec::with_capacity(n);
        for i in 0..n {
            actions.push(if reset[i] {
                Mixed::Reset
            } else if phase[i] == 0 {
                let (Ok(r), Ok(c)) = (u32::try_from(pixels[[i, 0]]), u32::try_from(pixels[[i, 1]]))
                else {
                    return Err(PyValueError::new_err(format!(
                        "pixels row {i}: must be non-negative and inside the image"
                    )));
                };
                Mixed::Grasp(r, c)
            } else if self.envs[i].grasped_joint().is_some() {
                let d = [directions[[i, 0]], directions[[i, 1]], directions[[i, 2]]];
                parse_direction(d.to_vec())
                    .map_err(|e| PyValueError::new_err(format!("directions row {i}: {e}")))?;
                Mixed::Move(d)
            } else {
                Mixed::Idle
            });
        }
        let (envs, batch) = (&mut self.envs, self.batch_render);
        let outcomes = py
            .detach(|| step_all(envs, |i, e| mixed_step(e, actions[i], batch)))
            .map_err(eval_err)?;
        let reset: Vec<bool> = actions.iter().map(|a| matches!(a, Mixed::Reset)).collect();
        let obs = self
            .buffers
            .fill_masked(py, &mut self.envs, &reset, self.copy)?;
        let budgets: Vec<i64> = self
            .envs
            .iter()
            .map(|e| {
                e.scene()
                    .and_then(|s| s.category)
                    .map_or(DEFAULT_BUDGET, |c| c.step_budget() as i64)
            })
            .collect();
        let info = mixed_info(py, &outcomes, budgets)?;
        Ok((obs, info))
    }

    /// Dense labels for every environment: `directions` is float32 (n, k, 3);
    /// returns (n, k) arrays r_dist, aot, moved, joint_after and `active` (n,),
    /// False where an environment holds no grasp (its labels are zero). The
    /// environments' states do not change.
    fn probe_directions<'py>(
        &self,
        py: Python<'py>,
        directions: Arr3<'py, f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let directions = directions.0;
        let dirs = probe::directions(&directions, self.envs.len())?;
        let k = directions.shape()[1];
        let labels = probe::probe_all(py, &self.envs, &dirs)?;
        probe::labels_dict(py, &labels, k)
    }

    /// Dense labels of every environment's current observation, stacked
    /// (see Env.articulation_fields): `flow`, `joint`, `movable`,
    /// `goal_displacement` with a leading (n,) axis.
    fn articulation_fields<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let fields = self
            .envs
            .iter()
            .map(|e| e.articulation_fields().map_err(eval_err))
            .collect::<PyResult<Vec<_>>>()?;
        crate::fields::fields_dict(py, &fields)
    }

    /// Scripted actions for every environment (see Env.scripted_action).
    fn scripted_actions(&mut self, py: Python<'_>, policy: &str) -> PyResult<Vec<Py<PyAny>>> {
        let mut out = Vec::with_capacity(self.envs.len());
        for e in &mut self.envs {
            out.push(scripted_to_py(
                py,
                e.scripted_action(policy).map_err(eval_err)?,
            )?);
        }
        Ok(out)
    }
}

/// Where each environment's gripper is (n x 3, world frame), as the policy's
/// `onward45` and `goal45` filters read it (`Policy.decide(gripper=...)`);
/// NaN where it holds nothing.
fn grippers<'py>(py: Python<'py>, envs: &[TrainEnv]) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let flat: Vec<f32> = envs
        .iter()
        .flat_map(|e| e.gripper_in_world().unwrap_or([f32::NAN; 3]))
        .collect();
    PyArray1::from_vec(py, flat).reshape([envs.len(), 3])
}
