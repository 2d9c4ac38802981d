//! `umpnet.Articulation`: the physics of one object without camera or task,
//! for scripted experiments and the differential suite against PyBullet.
#![allow(
    clippy::indexing_slicing,
    reason = "joint and link indices come from name lookups in the same model"
)]
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;
use umpnet_sim::math::{Pose3, Quat, Vec3};
use umpnet_sim::model::ObjectModel;
use umpnet_sim::physics::{Articulation as SimArticulation, PhysicsConfig, PhysicsProfile};
use umpnet_sim::urdf::load_urdf;

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn finite3(name: &str, v: [f32; 3]) -> PyResult<Vec3> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vec3::from(v))
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be three finite numbers, got {v:?}"
        )))
    }
}

#[pyclass(module = "umpnet")]
pub struct Articulation {
    model: Arc<ObjectModel>,
    art: SimArticulation,
}

impl Articulation {
    fn link_id(&self, name: &str) -> PyResult<usize> {
        self.model
            .links
            .iter()
            .position(|l| l.name == name)
            .ok_or_else(|| PyValueError::new_err(format!("no link named `{name}`")))
    }
    fn joint_id(&self, name: &str) -> PyResult<usize> {
        self.model
            .joint_by_name(name)
            .ok_or_else(|| PyValueError::new_err(format!("no joint named `{name}`")))
    }
}

#[pymethods]
impl Articulation {
    /// An object from a URDF with a fixed base at `position` / `orientation`
    /// (quaternion x, y, z, w), uniformly scaled by `scale`, under the
    /// `physics` profile ("reference" or "ideal").
    #[new]
    ///
    /// `steps_per_update` and `solver_iterations` tune the reference solver
    /// (defaults: 1 reference step per update, as PyBullet steps, and 50 sweeps).
    #[pyo3(signature = (urdf, position=[0.0, -0.5, 0.0], orientation=[0.0, 0.0, 0.0, 1.0], scale=1.0, physics="reference", steps_per_update=None, solver_iterations=None))]
    fn new(
        urdf: PathBuf,
        position: [f32; 3],
        orientation: [f32; 4],
        scale: f32,
        physics: &str,
        steps_per_update: Option<usize>,
        solver_iterations: Option<usize>,
    ) -> PyResult<Self> {
        let profile: PhysicsProfile = physics.parse().map_err(value_err)?;
        let position = finite3("position", position)?;
        let q = Quat::from_xyzw(
            orientation[0],
            orientation[1],
            orientation[2],
            orientation[3],
        );
        if !q.is_finite() || q.length() < 1e-6 {
            return Err(PyValueError::new_err(format!(
                "orientation must be a non-zero finite quaternion (x, y, z, w), got {orientation:?}"
            )));
        }
        let model = load_urdf(&urdf).map_err(value_err)?;
        let model = Arc::new(model.scaled(scale).map_err(value_err)?);
        let mut config = PhysicsConfig::with_profile(profile);
        for (name, value, field) in [
            (
                "steps_per_update",
                steps_per_update,
                &mut config.reference.steps_per_update,
            ),
            (
                "solver_iterations",
                solver_iterations,
                &mut config.reference.solver_iterations,
            ),
        ] {
            if let Some(v) = value {
                if !(1..=1000).contains(&v) {
                    return Err(PyValueError::new_err(format!(
                        "{name} must be in 1..=1000, got {v}"
                    )));
                }
                *field = v;
            }
        }
        let art = SimArticulation::new(
            model.clone(),
            Pose3::from_parts(position, q.normalize()),
            config,
        );
        Ok(Self { model, art })
    }

    #[getter]
    fn physics(&self) -> &'static str {
        self.art.profile().name()
    }

    fn joint_names(&self) -> Vec<String> {
        self.model.joints.iter().map(|j| j.name.clone()).collect()
    }

    fn link_names(&self) -> Vec<String> {
        self.model.links.iter().map(|l| l.name.clone()).collect()
    }

    /// The joint's value (rad or m).
    fn joint(&self, name: &str) -> PyResult<f32> {
        Ok(self.art.joint_position(self.joint_id(name)?))
    }

    /// Sets joints by name (others keep their values); lets go of any grasp.
    fn set_joints(&mut self, values: &Bound<'_, PyDict>) -> PyResult<()> {
        let mut q = self.art.joint_positions();
        for (k, v) in values.iter() {
            let name: String = k.extract()?;
            let value: f32 = v.extract()?;
            let j = self.joint_id(&name)?;
            q[j] = value;
        }
        self.art.set_joint_positions(&q).map_err(value_err)
    }

    /// The joint's child link and the joint's axis and origin in world.
    fn joint_axis(&self, name: &str) -> PyResult<(String, [f32; 3], [f32; 3])> {
        let j = self.joint_id(name)?;
        let (axis, origin) = self.art.joint_axis_in_world(j);
        let child = self.model.joints[j].child;
        Ok((
            self.model.links[child].name.clone(),
            axis.to_array(),
            origin.to_array(),
        ))
    }

    /// The link's visual mesh vertices in world (n x 3).
    fn link_vertices(&self, name: &str) -> PyResult<Vec<[f32; 3]>> {
        let l = self.link_id(name)?;
        let pose = self.art.world_from_link(l);
        Ok(self.model.links[l]
            .visuals
            .iter()
            .flat_map(|v| v.mesh_in_link.positions.iter())
            .map(|p| pose.transform_point(*p).to_array())
            .collect())
    }

    /// The gripper's position in world, None before a grasp.
    fn gripper_position(&self) -> Option<[f32; 3]> {
        self.art.gripper_position().map(|p| p.to_array())
    }

    /// The position action at a world point on a link.
    fn grasp(&mut self, point: [f32; 3], link: &str) -> PyResult<()> {
        let l = self.link_id(link)?;
        let p = finite3("point", point)?;
        self.art.attach(p, l).map_err(value_err)
    }

    /// One direction action (a non-zero world vector, normalised here);
    /// returns the named joint before and after, and the steps taken.
    fn move_gripper<'py>(
        &mut self,
        py: Python<'py>,
        direction: [f32; 3],
        joint: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let j = self.joint_id(joint)?;
        let d = finite3("direction", direction)?;
        if d.length() < 1e-6 {
            return Err(PyValueError::new_err("direction must be non-zero"));
        }
        if self.art.grasped_link().is_none() {
            return Err(PyRuntimeError::new_err("no grasp: call grasp() first"));
        }
        let t = std::time::Instant::now();
        let o = self.art.move_gripper(d.normalize(), j).map_err(value_err)?;
        // The physics alone, without the Python call around it: benches set it beside PyBullet's.
        let seconds = t.elapsed().as_secs_f64();
        let out = PyDict::new(py);
        out.set_item("seconds", seconds)?;
        out.set_item("joint_before", o.joint_before)?;
        out.set_item("joint_after", o.joint_after)?;
        out.set_item("gripper_moved", o.gripper_moved)?;
        out.set_item("steps", o.steps)?;
        out.set_item("suction_lost", o.suction_lost)?;
        Ok(out)
    }
}
