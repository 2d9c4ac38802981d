//! Dense labels for Python: `Env.probe_directions` and `VecEnv.probe_directions`
//! simulate candidate directions from the current state without changing it.
#![allow(
    clippy::indexing_slicing,
    reason = "each function checks the array's shape before it indexes it"
)]
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use umpnet_eval::train_env::TrainEnv;
use umpnet_sim::env::StepLabels;

fn checked(d: [f32; 3], at: &str) -> PyResult<[f32; 3]> {
    let norm = d.iter().map(|x| x * x).sum::<f32>().sqrt();
    if norm.is_finite() && norm > 1e-6 {
        Ok(d)
    } else {
        Err(PyValueError::new_err(format!(
            "directions[{at}] = {d:?}: expected a finite, non-zero vector"
        )))
    }
}

/// The (k, 3) array as k finite, non-zero directions.
pub(crate) fn directions_2d(a: &PyReadonlyArray2<'_, f32>) -> PyResult<Vec<[f32; 3]>> {
    let s = a.shape();
    if s.len() != 2 || s[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "directions has shape {s:?}, expected (K, 3) float32"
        )));
    }
    check_k(s[0])?;
    let v = a.as_array();
    (0..s[0])
        .map(|k| checked([v[[k, 0]], v[[k, 1]], v[[k, 2]]], &k.to_string()))
        .collect()
}

/// Most directions probed per environment in one call: each is a simulated
/// action (about a millisecond), and a call cannot be interrupted.
pub(crate) const MAX_PROBES: usize = 1024;

fn check_k(k: usize) -> PyResult<()> {
    if k > MAX_PROBES {
        return Err(PyValueError::new_err(format!(
            "directions: {k} per environment; at most {MAX_PROBES} per call (split larger sets into calls)"
        )));
    }
    Ok(())
}

/// The (n, k, 3) array as n lists of k finite, non-zero directions.
pub(crate) fn directions(a: &PyReadonlyArray3<'_, f32>, n: usize) -> PyResult<Vec<Vec<[f32; 3]>>> {
    let s = a.shape();
    if s.len() != 3 || s[0] != n || s[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "directions has shape {s:?}, expected ({n}, K, 3) float32"
        )));
    }
    check_k(s[1])?;
    let v = a.as_array();
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut row = Vec::with_capacity(s[1]);
        for k in 0..s[1] {
            row.push(checked(
                [v[[i, k, 0]], v[[i, k, 1]], v[[i, k, 2]]],
                &format!("{i}, {k}"),
            )?);
        }
        out.push(row);
    }
    Ok(out)
}

/// Directions probed between two checks for Ctrl-C: a few hundred
/// milliseconds of work at most, so an interrupt is answered promptly.
const PROBES_PER_SIGNAL_CHECK: usize = 32;

/// Probes every environment (in parallel, without the GIL); an environment
/// without a grasp gives None. Every [`PROBES_PER_SIGNAL_CHECK`] directions
/// the GIL is taken back to ask Python for pending signals, so a KeyboardInterrupt
/// stops a long call.
pub(crate) fn probe_all(
    py: Python<'_>,
    envs: &[TrainEnv],
    dirs: &[Vec<[f32; 3]>],
) -> PyResult<Vec<Option<Vec<StepLabels>>>> {
    let k = dirs.iter().map(Vec::len).max().unwrap_or(0);
    let mut out: Vec<Option<Vec<StepLabels>>> = envs
        .iter()
        .map(|e| e.grasped_joint().map(|_| Vec::new()))
        .collect();
    let mut start = 0;
    loop {
        let end = (start + PROBES_PER_SIGNAL_CHECK).min(k);
        let chunk = py
            .detach(|| {
                envs.par_iter()
                    .zip(dirs)
                    .zip(&out)
                    .map(|((e, d), o)| match (o, d.get(start..end.min(d.len()))) {
                        (Some(_), Some(part)) => e.probe_directions(part).map(Some),
                        _ => Ok(None),
                    })
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(crate::eval_err)?;
        for (o, c) in out.iter_mut().zip(chunk) {
            if let (Some(o), Some(c)) = (o.as_mut(), c) {
                o.extend(c);
            }
        }
        py.check_signals()?;
        if end >= k {
            return Ok(out);
        }
        start = end;
    }
}

/// Labels as (n, k) arrays: r_dist, aot, moved, joint_after; `active` (n,)
/// says which environments held a grasp.
pub(crate) fn labels_dict<'py>(
    py: Python<'py>,
    labels: &[Option<Vec<StepLabels>>],
    k: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let n = labels.len();
    let cell = |f: &dyn Fn(&StepLabels) -> f32| -> Vec<f32> {
        labels
            .iter()
            .flat_map(|l| match l {
                Some(v) => v.iter().map(f).collect::<Vec<_>>(),
                None => vec![0.0; k],
            })
            .collect()
    };
    let d = PyDict::new(py);
    d.set_item(
        "r_dist",
        PyArray1::from_vec(py, cell(&|l| l.r_dist)).reshape([n, k])?,
    )?;
    d.set_item(
        "joint_after",
        PyArray1::from_vec(py, cell(&|l| l.joint_after)).reshape([n, k])?,
    )?;
    let aot: Vec<i64> = cell(&|l| l.aot as f32).iter().map(|&a| a as i64).collect();
    d.set_item("aot", PyArray1::from_vec(py, aot).reshape([n, k])?)?;
    let moved: Vec<bool> = cell(&|l| l.moved as u8 as f32)
        .iter()
        .map(|&m| m > 0.5)
        .collect();
    d.set_item("moved", PyArray1::from_vec(py, moved).reshape([n, k])?)?;
    // The reference training code's labels (umpnet_sim::labels::train_labels).
    let aot: Vec<i64> = cell(&|l| l.train.aot as f32)
        .iter()
        .map(|&a| a as i64)
        .collect();
    d.set_item("train_aot", PyArray1::from_vec(py, aot).reshape([n, k])?)?;
    let moved: Vec<bool> = cell(&|l| l.train.moved as u8 as f32)
        .iter()
        .map(|&m| m > 0.5)
        .collect();
    d.set_item(
        "train_moved",
        PyArray1::from_vec(py, moved).reshape([n, k])?,
    )?;
    d.set_item(
        "active",
        PyArray1::from_vec(py, labels.iter().map(|l| l.is_some()).collect::<Vec<_>>()),
    )?;
    Ok(d)
}
