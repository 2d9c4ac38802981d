//! Observation buffers owned by an environment and reused between steps: the
//! zero-copy path. Each step writes the new observation into the same numpy
//! arrays (built in parallel, without the GIL) and returns the same dict, so
//! a 480x640 step allocates nothing and copies no 12 MB tensor. The reference
//! observation is written at reset only.
//!
//! The arrays are views of the environment's state: a caller that keeps an
//! observation past the next step copies it (`obs["image"].copy()`), as with
//! any reused buffer. `copy=True` on the environment returns fresh arrays.
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use umpnet_eval::train_env::{ObsMeta, TrainEnv};
use umpnet_policy::CHANNELS;

pub struct ObsBuffers {
    /// None for a single environment (no leading batch axis).
    batch: Option<usize>,
    pixels: usize,
    dict: Py<PyDict>,
    image: Py<PyArrayDyn<f32>>,
    reference: Py<PyArrayDyn<f32>>,
    segmentation: Py<PyArrayDyn<i64>>,
    intrinsics: Py<PyArrayDyn<f32>>,
    world_from_camera: Py<PyArrayDyn<f32>>,
    gripper_pixel: Py<PyArrayDyn<i64>>,
}

fn err(e: impl std::fmt::Display) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

impl ObsBuffers {
    pub fn new(
        py: Python<'_>,
        batch: Option<usize>,
        height: usize,
        width: usize,
    ) -> PyResult<Self> {
        let lead: Vec<usize> = batch.into_iter().collect();
        let shape = |tail: &[usize]| [lead.as_slice(), tail].concat();
        let f32s = |tail: &[usize]| PyArrayDyn::<f32>::zeros(py, shape(tail), false).unbind();
        let i64s = |tail: &[usize]| PyArrayDyn::<i64>::zeros(py, shape(tail), false).unbind();
        let b = Self {
            batch,
            pixels: height * width,
            dict: PyDict::new(py).unbind(),
            image: f32s(&[height, width, CHANNELS]),
            reference: f32s(&[height, width, CHANNELS]),
            segmentation: i64s(&[height, width]),
            intrinsics: f32s(&[3, 3]),
            world_from_camera: f32s(&[4, 4]),
            gripper_pixel: i64s(&[2]),
        };
        let d = b.dict.bind(py);
        d.set_item("image", b.image.bind(py))?;
        d.set_item("reference", b.reference.bind(py))?;
        d.set_item("segmentation", b.segmentation.bind(py))?;
        d.set_item("intrinsics", b.intrinsics.bind(py))?;
        d.set_item("world_from_camera", b.world_from_camera.bind(py))?;
        d.set_item("gripper_pixel", b.gripper_pixel.bind(py))?;
        Ok(b)
    }

    fn count(&self) -> usize {
        self.batch.unwrap_or(1)
    }

    /// Writes every environment's current observation (and, after a reset,
    /// its reference) into the buffers; returns the dict, a fresh copy of it
    /// when `copy`.
    pub fn fill<'py>(
        &self,
        py: Python<'py>,
        envs: &mut [TrainEnv],
        with_reference: bool,
        copy: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.fill_masked(py, envs, &vec![with_reference; envs.len()], copy)
    }

    /// `fill`, writing the reference only of the environments whose entry in
    /// `reference` is true (those that were just reset).
    pub fn fill_masked<'py>(
        &self,
        py: Python<'py>,
        envs: &mut [TrainEnv],
        reference: &[bool],
        copy: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        if envs.len() != self.count() || reference.len() != envs.len() {
            return Err(err(format!(
                "{} environments for buffers of {}",
                envs.len(),
                self.count()
            )));
        }
        let per_image = self.pixels * CHANNELS;
        let metas: Vec<ObsMeta> = {
            let mut image = self.image.bind(py).try_readwrite().map_err(err)?;
            let mut seg = self.segmentation.bind(py).try_readwrite().map_err(err)?;
            let mut reference_buffer = self.reference.bind(py).try_readwrite().map_err(err)?;
            let (image, seg, reference_buffer) = (
                image.as_slice_mut().map_err(err)?,
                seg.as_slice_mut().map_err(err)?,
                reference_buffer.as_slice_mut().map_err(err)?,
            );
            let pixels = self.pixels;
            py.detach(|| {
                envs.par_iter_mut()
                    .zip(image.par_chunks_mut(per_image))
                    .zip(seg.par_chunks_mut(pixels))
                    .zip(reference_buffer.par_chunks_mut(per_image))
                    .zip(reference.par_iter())
                    .map(|((((e, img), s), r), &with_reference)| {
                        if with_reference {
                            e.reference_into(r)?;
                        }
                        e.observe_into(img, s)
                    })
                    .collect::<Result<Vec<_>, _>>()
            })
            .map_err(crate::eval_err)?
        };
        {
            let mut k = self.intrinsics.bind(py).try_readwrite().map_err(err)?;
            let mut pose = self
                .world_from_camera
                .bind(py)
                .try_readwrite()
                .map_err(err)?;
            let mut gp = self.gripper_pixel.bind(py).try_readwrite().map_err(err)?;
            let (k, pose, gp) = (
                k.as_slice_mut().map_err(err)?,
                pose.as_slice_mut().map_err(err)?,
                gp.as_slice_mut().map_err(err)?,
            );
            for (((m, k), pose), gp) in metas
                .iter()
                .zip(k.chunks_exact_mut(9))
                .zip(pose.chunks_exact_mut(16))
                .zip(gp.chunks_exact_mut(2))
            {
                let [fx, fy, cx, cy] = m.intrinsics;
                k.copy_from_slice(&[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]);
                for (out, v) in pose.iter_mut().zip(m.world_from_camera.iter().flatten()) {
                    *out = *v;
                }
                let (r, c) = m
                    .gripper_pixel
                    .map_or((-1, -1), |(r, c)| (r as i64, c as i64));
                gp.copy_from_slice(&[r, c]);
            }
        }
        let d = self.dict.bind(py);
        if !copy {
            return Ok(d.clone());
        }
        let fresh = PyDict::new(py);
        for (k, v) in d.iter() {
            fresh.set_item(k, v.call_method0("copy")?)?;
        }
        Ok(fresh)
    }
}
