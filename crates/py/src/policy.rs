//! `umpnet.Policy`: the Rust policy runtime on a model package, its two
//! decisions for any caller, and `decide` with an episode's memory (the one
//! `umpnet eval`'s learned policy keeps) for `Policy.act`.
#![allow(
    clippy::indexing_slicing,
    reason = "every index follows a shape check of the array it indexes, which raises ValueError otherwise"
)]
use crate::arrays::{Arr2, Arr3, Arr4};
use crate::{MAX_THREADS, policy_err, runtime_err};
use numpy::{
    IntoPyArray, PyArrayMethods, PyReadonlyArray3, PyReadonlyArray4, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::SeedableRng;
use std::path::PathBuf;
use std::sync::Arc;
use umpnet_policy::axis::JointEstimate;
use umpnet_policy::cem::CemResult;
use umpnet_policy::cem::Mode;
use umpnet_policy::frame_joint::{
    FrameJoint, JOINT_CHANNELS, joint_from_fields as joint_from_fields_rs,
};
use umpnet_policy::memory::EpisodeMemory;
use umpnet_policy::{DecisionInput, ModelPackage, UmpnetPolicy};

/// The ONNX Runtime library of the `onnxruntime` package installed in the
/// `site` folder, by the runtime's own rule, or None.
#[pyfunction]
pub(crate) fn onnxruntime_in_site_packages(site: PathBuf) -> Option<PathBuf> {
    umpnet_policy::runtime::library_in_site_packages(&site)
}

/// The Rust policy runtime on a model package.
#[pyclass(module = "umpnet", subclass, name = "Policy")]
pub(crate) struct Policy {
    inner: UmpnetPolicy,
    rng: rand_chacha::ChaCha8Rng,
    memory: EpisodeMemory,
    /// The last direction `decide` returned: the move `moved` reports on.
    last: Option<nalgebra::Vector3<f32>>,
    /// The grasped part's joint, read by `position` where the filter uses it
    /// (`joint45`, `onward45`), as `umpnet eval` reads it at the grasp.
    joint: Option<JointEstimate>,
}

#[pymethods]
impl Policy {
    #[new]
    #[pyo3(signature = (model_dir, seed=0, threads=1, onnxruntime=None, direction_filter=None, grasp_rule=None, mirror_average=false))]
    fn new(
        model_dir: PathBuf,
        seed: u64,
        threads: usize,
        onnxruntime: Option<PathBuf>,
        direction_filter: Option<&str>,
        grasp_rule: Option<&str>,
        mirror_average: bool,
    ) -> PyResult<Self> {
        if !(1..=MAX_THREADS).contains(&threads) {
            return Err(PyValueError::new_err(format!(
                "threads = {threads}: expected 1 to {MAX_THREADS}"
            )));
        }
        // Named before the package loads: a misspelt filter is the caller's
        // error whatever the package holds.
        let filter = direction_filter
            .map(|f| {
                f.parse::<umpnet_policy::policy::DirectionFilter>()
                    .map_err(|e| PyValueError::new_err(format!("direction_filter: {e}")))
            })
            .transpose()?;
        let grasp = grasp_rule
            .map(|g| {
                g.parse::<umpnet_policy::policy::GraspRule>()
                    .map_err(|e| PyValueError::new_err(format!("grasp_rule: {e}")))
            })
            .transpose()?;
        let pkg = ModelPackage::load(&model_dir, 1, threads, onnxruntime.as_deref())
            .map_err(policy_err)?;
        let mut inner = UmpnetPolicy::new(Arc::new(pkg)).with_mirror_average(mirror_average);
        if let Some(f) = filter {
            inner = inner.with_direction_filter(f);
        }
        if let Some(g) = grasp {
            inner = inner
                .with_grasp(g)
                .map_err(|e| PyValueError::new_err(format!("grasp_rule: {e}")))?;
        }
        Ok(Self {
            inner,
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed),
            memory: EpisodeMemory::default(),
            last: None,
            joint: None,
        })
    }

    /// (height, width) the model takes.
    #[getter]
    fn resolution(&self) -> (usize, usize) {
        self.inner.resolution()
    }

    /// The grasp pixel (row, col) for an H x W x 10 observation (masked by a
    /// goal observation if given). Under the `joint45` and `onward45`
    /// filters it also reads the grasped part's joint there, which `decide`
    /// uses until `reset`.
    #[pyo3(signature = (image, goal=None))]
    fn position(
        &mut self,
        image: Arr3<'_, f32>,
        goal: Option<Arr3<'_, f32>>,
    ) -> PyResult<(usize, usize)> {
        let image = image.0;
        let img = to_array3(&image)?;
        let g = goal.as_ref().map(|g| to_array3(g)).transpose()?;
        let c = self
            .inner
            .position(img.view(), g.as_ref().map(|g| g.view()))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        if self.inner.direction_filter.reads_joint() {
            self.joint = self
                .inner
                .joint_at_grasp(img.view(), &c)
                .map_err(policy_err)?
                .map(|j| j.estimate);
        }
        Ok(c.pixel)
    }

    /// Directions for a batch: images/references B x H x W x 10, pixels B x 2.
    /// Returns a list of dicts (direction or None to stop, candidates, distance, aot).
    /// The joint of the part at `pixel` (row, col) read from this one
    /// observation (H x W x 10) by the package's JointNet: a dict with
    /// `type` ("revolute" or "prismatic"), `axis`, `point` (on a hinge's axis,
    /// None for a slide; world frame), `hinge_probability` and `voting_pixels`.
    /// None when the package has no JointNet or too few part pixels voted.
    fn frame_joint<'py>(
        &self,
        py: Python<'py>,
        image: Arr3<'_, f32>,
        pixel: (i64, i64),
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        let img = to_array3(&image.0)?;
        let (h, w, _) = img.dim();
        let px = check_pixel("pixel", pixel, (h, w))?;
        match self.inner.frame_joint(img.view(), px).map_err(policy_err)? {
            Some(j) => frame_joint_dict(py, &j).map(Some),
            None => Ok(None),
        }
    }

    #[pyo3(signature = (images, references, pixels, mode="explore"))]
    fn direction_batch<'py>(
        &mut self,
        py: Python<'py>,
        images: Arr4<'py, f32>,
        references: Arr4<'py, f32>,
        pixels: Arr2<'py, i64>,
        mode: &str,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let images = images.0;
        let references = references.0;
        let pixels = pixels.0;
        let mode = parse_mode(mode)?;
        let b = images.shape()[0];
        if references.shape() != images.shape() || pixels.shape() != [b, 2] {
            return Err(PyValueError::new_err(format!(
                "shapes: images {:?}, references {:?}, pixels {:?}; expected equal image shapes and pixels ({b}, 2)",
                images.shape(),
                references.shape(),
                pixels.shape()
            )));
        }
        let imgs: Vec<ndarray::Array3<f32>> = (0..b).map(|i| slice3(&images, i)).collect();
        let refs: Vec<ndarray::Array3<f32>> = (0..b).map(|i| slice3(&references, i)).collect();
        let px = pixels.as_array();
        let (h, w) = (images.shape()[1], images.shape()[2]);
        let mut grasp_pixels = Vec::with_capacity(b);
        for i in 0..b {
            grasp_pixels.push(check_pixel(
                &format!("pixels[{i}]"),
                (px[[i, 0]], px[[i, 1]]),
                (h, w),
            )?);
        }
        let inputs: Vec<DecisionInput<'_>> = (0..b)
            .map(|i| DecisionInput {
                observation: imgs[i].view(),
                reference: refs[i].view(),
                pixel: grasp_pixels[i],
                banned: &[],
                previous: None,
                mode,
                joint: None,
                motion: None,
                long_motion: None,
            })
            .collect();
        let mut rngs: Vec<rand_chacha::ChaCha8Rng> = (0..b)
            .map(|i| {
                rand_chacha::ChaCha8Rng::seed_from_u64(
                    rand::Rng::random::<u64>(&mut self.rng) ^ i as u64,
                )
            })
            .collect();
        let inner = &self.inner;
        let results = py
            .detach(|| inner.directions(&inputs, &mut rngs))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        results.iter().map(|r| decision_dict(py, r)).collect()
    }

    /// Starts an episode: forgets the moves that moved nothing and the
    /// previous move, and with `seed` restarts the random stream (as `umpnet
    /// eval` seeds each episode's policy).
    #[pyo3(signature = (seed=None))]
    fn reset(&mut self, seed: Option<u64>) {
        if let Some(seed) = seed {
            self.rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        }
        self.memory.clear();
        self.last = None;
        self.joint = None;
    }

    /// The next direction for one H x W x 10 observation, with the episode's
    /// memory, as `umpnet eval`'s learned policy decides: `moved` says whether
    /// the move this last returned moved the part (a move that did not is
    /// not tried again until one does); `gripper` is where the gripper is now
    /// (world x, y, z, from its own pose), from which the `goal45` and
    /// `onward45` filters read how it went over the last move (`goal45`,
    /// after moves that stalled, over the last one that carried it). A dict as
    /// `direction_batch` gives.
    #[pyo3(signature = (image, reference, pixel, mode="explore", moved=None, gripper=None))]
    #[expect(clippy::too_many_arguments, reason = "Python keyword arguments")]
    fn decide<'py>(
        &mut self,
        py: Python<'py>,
        image: Arr3<'py, f32>,
        reference: Arr3<'py, f32>,
        pixel: (i64, i64),
        mode: &str,
        moved: Option<bool>,
        gripper: Option<Vec<f32>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mode = parse_mode(mode)?;
        let gripper = match gripper.as_deref() {
            None => None,
            Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
                Some(nalgebra::Vector3::new(x, y, z))
            }
            Some(g) => {
                return Err(PyValueError::new_err(format!(
                    "gripper = {g:?}: expected the gripper's world position, three finite numbers (x, y, z)"
                )));
            }
        };
        let (image, reference) = (to_array3(&image.0)?, to_array3(&reference.0)?);
        if image.shape() != reference.shape() {
            return Err(PyValueError::new_err(format!(
                "shapes: image {:?}, reference {:?}; expected equal",
                image.shape(),
                reference.shape()
            )));
        }
        let (h, w) = (image.shape()[0], image.shape()[1]);
        let pixel = check_pixel("pixel", pixel, (h, w))?;
        if let (Some(last), Some(moved)) = (self.last, moved) {
            self.memory.record(last, moved);
        }
        if let Some(g) = gripper {
            self.memory.gripper_at(g);
        }
        let input = self.memory.decision_input(
            image.view(),
            reference.view(),
            pixel,
            mode,
            self.joint.as_ref(),
        );
        let (inner, rng) = (&self.inner, &mut self.rng);
        let mut out = py
            .detach(|| inner.directions(std::slice::from_ref(&input), std::slice::from_mut(rng)))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let r = out.pop().ok_or_else(|| runtime_err("no decision"))?;
        self.last = r.direction;
        decision_dict(py, &r)
    }
}

/// The same vote from JointNet outputs computed elsewhere (a training
/// checkpoint): `fields` is 11 x H x W (the JointNet's channels), `image`
/// H x W x 10. What `Policy.frame_joint` returns.
#[pyfunction]
pub(crate) fn joint_from_fields<'py>(
    py: Python<'py>,
    image: Arr3<'_, f32>,
    fields: Arr3<'_, f32>,
    pixel: (i64, i64),
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let (img, f) = (to_array3(&image.0)?, to_array3(&fields.0)?);
    let (h, w, c) = img.dim();
    if c != umpnet_policy::CHANNELS || f.dim() != (JOINT_CHANNELS, h, w) {
        return Err(PyValueError::new_err(format!(
            "image {:?} and fields {:?}: expected (H, W, {}) and ({JOINT_CHANNELS}, H, W)",
            img.dim(),
            f.dim(),
            umpnet_policy::CHANNELS
        )));
    }
    let px = check_pixel("pixel", pixel, (h, w))?;
    match joint_from_fields_rs(img.view(), f.view(), px) {
        Some(j) => frame_joint_dict(py, &j).map(Some),
        None => Ok(None),
    }
}

/// Observations (N x H x W x 10) mirrored left-right by the runtime's own
/// rule: columns reversed and the world's x (point and normal) negated.
/// Training's mirrors (`train --mirror`, the fine-tune's `--mirror`) call it,
/// so training and `--mirror-average` see the same mirror.
#[pyfunction]
pub(crate) fn mirrored_observations<'py>(
    py: Python<'py>,
    images: Arr4<'_, f32>,
) -> PyResult<Bound<'py, numpy::PyArray4<f32>>> {
    let m = umpnet_policy::mirrored_observations(to_array4(&images)?.view()).map_err(policy_err)?;
    let (n, h, w, c) = m.dim();
    let (m, _) = m.into_raw_vec_and_offset();
    m.into_pyarray(py).reshape([n, h, w, c])
}

fn frame_joint_dict<'py>(py: Python<'py>, j: &FrameJoint) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let (kind, axis, point) = match j.estimate {
        JointEstimate::Prismatic { axis } => ("prismatic", axis, None),
        JointEstimate::Revolute { axis, point } => ("revolute", axis, Some(point)),
    };
    d.set_item("type", kind)?;
    d.set_item("axis", axis.to_vec())?;
    d.set_item("point", point.map(|p| p.to_vec()))?;
    d.set_item("hinge_probability", j.hinge_probability)?;
    d.set_item("voting_pixels", j.voting_pixels)?;
    Ok(d)
}

fn parse_mode(mode: &str) -> PyResult<Mode> {
    match mode {
        "explore" | "exploration" => Ok(Mode::Explore),
        "goal" => Ok(Mode::Goal),
        m => Err(PyValueError::new_err(format!(
            "mode `{m}`: expected explore or goal"
        ))),
    }
}

/// A grasp pixel inside an h x w image, or a ValueError naming `what`.
fn check_pixel(
    what: &str,
    (row, col): (i64, i64),
    (h, w): (usize, usize),
) -> PyResult<(usize, usize)> {
    match (usize::try_from(row), usize::try_from(col)) {
        (Ok(r), Ok(c)) if r < h && c < w => Ok((r, c)),
        _ => Err(PyValueError::new_err(format!(
            "{what} = ({row}, {col}) is outside the {h} x {w} image: expected 0 <= row < {h} and 0 <= col < {w}"
        ))),
    }
}

/// One decision as Python sees it: direction (None to stop), candidates, distance, aot.
fn decision_dict<'py>(py: Python<'py>, r: &CemResult) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("direction", r.direction.map(|v| vec![v.x, v.y, v.z]))?;
    d.set_item(
        "candidates",
        r.candidates
            .iter()
            .map(|v| vec![v.x, v.y, v.z])
            .collect::<Vec<_>>(),
    )?;
    d.set_item(
        "distance",
        r.scores.iter().map(|s| s.distance).collect::<Vec<_>>(),
    )?;
    d.set_item("aot", r.scores.iter().map(|s| s.aot).collect::<Vec<_>>())?;
    Ok(d)
}

// numpy's ndarray is another version than the workspace's: these copy.
fn to_array3(a: &PyReadonlyArray3<'_, f32>) -> PyResult<ndarray::Array3<f32>> {
    let s = a.shape();
    let v: Vec<f32> = a.as_array().iter().copied().collect();
    ndarray::Array3::from_shape_vec((s[0], s[1], s[2]), v).map_err(runtime_err)
}

fn to_array4(a: &PyReadonlyArray4<'_, f32>) -> PyResult<ndarray::Array4<f32>> {
    let s = a.shape();
    let v: Vec<f32> = a.as_array().iter().copied().collect();
    ndarray::Array4::from_shape_vec((s[0], s[1], s[2], s[3]), v).map_err(runtime_err)
}

fn slice3(a: &PyReadonlyArray4<'_, f32>, i: usize) -> ndarray::Array3<f32> {
    let s = a.shape();
    let v: Vec<f32> = a
        .as_array()
        .index_axis(numpy::ndarray::Axis(0), i)
        .iter()
        .copied()
        .collect();
    ndarray::Array3::from_shape_vec((s[1], s[2], s[3]), v)
        .unwrap_or_else(|_| ndarray::Array3::zeros((s[1], s[2], s[3])))
}
