//! Articulation fields for Python: `Env.articulation_fields` and
//! `VecEnv.articulation_fields`, the dense labels of the current observation
//! as numpy arrays stacked over environments.
use numpy::{IntoPyArray, PyArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use umpnet_sim::fields::ArticulationFields;

/// `flow` (n, H, W, 3) float32, `speed` (n, H, W) float32 (relative to each
/// part's fastest point), `joint` (n, H, W) int32, `movable` (n, H, W)
/// bool and `goal_displacement` (n, H, W, 3) float32, or None when no scene
/// has a goal (exploration).
pub(crate) fn fields_dict<'py>(
    py: Python<'py>,
    fields: &[ArticulationFields],
) -> PyResult<Bound<'py, PyDict>> {
    let Some(first) = fields.first() else {
        return Err(PyRuntimeError::new_err("no environments"));
    };
    let (h, w) = (first.height as usize, first.width as usize);
    if fields
        .iter()
        .any(|f| f.height as usize != h || f.width as usize != w)
    {
        return Err(PyRuntimeError::new_err(
            "environments of different resolutions",
        ));
    }
    let n = fields.len();
    let flat3 = |get: &dyn Fn(&ArticulationFields) -> Option<&Vec<[f32; 3]>>| -> Vec<f32> {
        let mut out = Vec::with_capacity(n * h * w * 3);
        for f in fields {
            match get(f) {
                Some(v) => out.extend(v.iter().flatten()),
                None => out.extend(std::iter::repeat_n(0.0, h * w * 3)),
            }
        }
        out
    };
    let shape3 = [n, h, w, 3];
    let d = PyDict::new(py);
    let flow = flat3(&|f| Some(&f.flow_in_world));
    d.set_item("flow", flow.into_pyarray(py).reshape(shape3)?)?;
    let speed: Vec<f32> = fields
        .iter()
        .flat_map(|f| f.speed.iter().copied())
        .collect();
    d.set_item("speed", speed.into_pyarray(py).reshape([n, h, w])?)?;
    let joint: Vec<i32> = fields
        .iter()
        .flat_map(|f| f.joint.iter().copied())
        .collect();
    let movable: Vec<bool> = joint.iter().map(|j| *j >= 0).collect();
    d.set_item("joint", joint.into_pyarray(py).reshape([n, h, w])?)?;
    d.set_item("movable", movable.into_pyarray(py).reshape([n, h, w])?)?;
    if fields
        .iter()
        .any(|f| f.goal_displacement_in_world.is_some())
    {
        let goal = flat3(&|f| f.goal_displacement_in_world.as_ref());
        d.set_item("goal_displacement", goal.into_pyarray(py).reshape(shape3)?)?;
    } else {
        d.set_item("goal_displacement", py.None())?;
    }
    Ok(d)
}
