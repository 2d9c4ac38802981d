//! `umpnet.EnvConfig`: what scenes an environment samples, declared once for
//! `Env` and `VecEnv` (which take it as `config=`, or its keyword arguments).
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;
use umpnet_eval::train_env;
use umpnet_sim::model::ObjectPose;
use umpnet_sim::objects::{Category, InstanceSplit};
use umpnet_sim::scene::{ObjectSource, Task};

/// `category=` takes one name or a list of names.
#[derive(FromPyObject)]
pub(crate) enum Categories {
    One(String),
    Many(Vec<String>),
}

impl Categories {
    fn names(self) -> Vec<String> {
        match self {
            Categories::One(c) => vec![c],
            Categories::Many(c) => c,
        }
    }
}

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// What scenes an environment samples: categories (one name or a list; all
/// of the split's by default) or one object file (`object_dir`: a folder
/// with `mobility.urdf`, or the URDF itself, placed by `scale` and `pose`
/// when given, else by its `object_meta_info.json`), the instance split,
/// the task, the observation size (height, width), the renderer, the
/// generated dataset's seed, the physics profile, and what the depth camera
/// reads on glass (`surface`, `through` or `missing`).
#[pyclass(module = "umpnet", name = "EnvConfig", frozen)]
pub(crate) struct EnvConfig {
    pub(crate) inner: train_env::EnvConfig,
}

#[pymethods]
impl EnvConfig {
    #[new]
    #[pyo3(signature = (category=None, split="train", resolution=(96, 128), task="exploration", object_dir=None, renderer="auto", dataset_seed=0, physics="reference", scale=None, pose=None, glass_depth="surface"))]
    #[expect(
        clippy::too_many_arguments,
        reason = "Python keyword arguments, each with a default; declared here once for Env and VecEnv"
    )]
    fn new(
        category: Option<Categories>,
        split: &str,
        resolution: (i64, i64),
        task: &str,
        object_dir: Option<PathBuf>,
        renderer: &str,
        dataset_seed: u64,
        physics: &str,
        scale: Option<f32>,
        pose: Option<Vec<f32>>,
        glass_depth: &str,
    ) -> PyResult<Self> {
        let task: Task = task.parse().map_err(value_err)?;
        let split = match split {
            "train" => InstanceSplit::Train,
            "test" => InstanceSplit::Test,
            s => {
                return Err(PyValueError::new_err(format!(
                    "split `{s}`: expected train or test"
                )));
            }
        };
        let Some((height, width)) = umpnet_sim::camera::image_size(resolution.0, resolution.1)
        else {
            return Err(PyValueError::new_err(format!(
                "resolution {resolution:?}: expected (height, width), each in {:?}",
                umpnet_sim::camera::IMAGE_SIDES
            )));
        };
        let mut cfg = train_env::EnvConfig::new(task, split);
        cfg.physics = physics.parse().map_err(value_err)?;
        cfg.resolution = (height, width);
        cfg.dataset_seed = dataset_seed;
        cfg.renderer = renderer.parse().map_err(value_err)?;
        cfg.glass_depth = glass_depth.parse().map_err(value_err)?;
        if let Some(names) = category.map(Categories::names) {
            if names.is_empty() {
                return Err(PyValueError::new_err(
                    "category: expected a category name or a non-empty list of names",
                ));
            }
            cfg.categories = names
                .iter()
                .map(|n| n.parse::<Category>().map_err(value_err))
                .collect::<PyResult<_>>()?;
        }
        cfg.object = match object_dir {
            Some(dir) => Some(object_source(dir, scale, pose)?),
            None if scale.is_some() || pose.is_some() => {
                return Err(PyValueError::new_err(
                    "scale and pose place an object file: give object_dir too",
                ));
            }
            None => None,
        };
        Ok(Self { inner: cfg })
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        let what = match &c.object {
            Some(ObjectSource::File { path, pose }) => format!(
                "object_dir={:?}{}",
                path.display().to_string(),
                pose.map_or(String::new(), |p| format!(
                    ", scale={}, pose={:?}",
                    p.scale,
                    [
                        p.orientation[0],
                        p.orientation[1],
                        p.orientation[2],
                        p.orientation[3],
                        p.offset_z
                    ]
                ))
            ),
            _ => format!(
                "category={:?}",
                c.categories.iter().map(|c| c.name()).collect::<Vec<_>>()
            ),
        };
        format!(
            "EnvConfig({what}, split={:?}, resolution={:?}, task={:?}, renderer={:?}, dataset_seed={}, physics={:?}, glass_depth={:?})",
            format!("{:?}", c.split).to_lowercase(),
            c.resolution,
            format!("{:?}", c.task).to_lowercase(),
            format!("{:?}", c.renderer).to_lowercase(),
            c.dataset_seed,
            format!("{:?}", c.physics).to_lowercase(),
            c.glass_depth.name(),
        )
    }
}

/// The object file, placed by `scale` and `pose` (QX, QY, QZ, QW[, OFFSET_Z])
/// over its own `object_meta_info.json`.
fn object_source(
    dir: PathBuf,
    scale: Option<f32>,
    pose: Option<Vec<f32>>,
) -> PyResult<ObjectSource> {
    let urdf = if dir.is_dir() {
        dir.join("mobility.urdf")
    } else {
        dir
    };
    if !urdf.is_file() {
        return Err(PyValueError::new_err(format!(
            "object_dir: {} not found (a folder with mobility.urdf, or a URDF file)",
            urdf.display()
        )));
    }
    let source = ObjectSource::file(urdf.clone());
    if scale.is_none() && pose.is_none() {
        return Ok(source);
    }
    let mut placed: ObjectPose = source.pose().map_err(value_err)?;
    if let Some(s) = scale {
        placed.scale = s;
    }
    if let Some(p) = pose {
        let (q, offset) = match p.as_slice() {
            [x, y, z, w] => ([*x, *y, *z, *w], None),
            [x, y, z, w, o] => ([*x, *y, *z, *w], Some(*o)),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "pose: expected (qx, qy, qz, qw) or (qx, qy, qz, qw, offset_z), got {} numbers",
                    p.len()
                )));
            }
        };
        placed.orientation = q;
        placed.offset_z = offset.unwrap_or(placed.offset_z);
    }
    placed.validate().map_err(value_err)?;
    Ok(ObjectSource::File {
        path: urdf,
        pose: Some(placed),
    })
}

/// The configuration an `Env` or `VecEnv` was given: `config=`, or built
/// from `category` and the other keyword arguments by `EnvConfig` itself.
pub(crate) fn resolve(
    py: Python<'_>,
    category: Option<Bound<'_, PyAny>>,
    config: Option<PyRef<'_, EnvConfig>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<train_env::EnvConfig> {
    let has_options = options.is_some_and(|o| !o.is_empty());
    if let Some(c) = config {
        if category.is_some() || has_options {
            return Err(PyValueError::new_err(
                "config= already says which scenes: give it, or category and EnvConfig's keyword arguments, not both",
            ));
        }
        return Ok(c.inner.clone());
    }
    let args = match category {
        Some(c) => PyTuple::new(py, [c])?,
        None => PyTuple::empty(py),
    };
    let made = py.get_type::<EnvConfig>().call(args, options)?;
    Ok(made.extract::<PyRef<'_, EnvConfig>>()?.inner.clone())
}
