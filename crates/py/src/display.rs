//! The scene drawn again at a display size (`Env.render_rgb`,
//! `VecEnv.render_rgb`, gymnasium's `render_size`): a second scene on its own
//! renderer, posed by the environment's parts at each call, remade when the
//! scene or the size changes.
use crate::{eval_err, runtime_err};
use numpy::ndarray::Array3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use umpnet_eval::train_env::TrainEnv;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::SimEnv;

/// (height, width) each in `IMAGE_SIDES`, or a ValueError naming them.
pub(crate) fn size(height: i64, width: i64) -> PyResult<(u32, u32)> {
    umpnet_sim::camera::image_size(height, width).ok_or_else(|| {
        PyValueError::new_err(format!(
            "render size ({height}, {width}): expected (height, width), each in {:?}",
            umpnet_sim::camera::IMAGE_SIDES
        ))
    })
}

/// `env`'s current state at `(h, w)` as H x W x 3 colour.
pub(crate) fn draw(
    display: &mut Option<SimEnv>,
    env: &TrainEnv,
    (h, w): (u32, u32),
) -> PyResult<Array3<u8>> {
    let Some(sim) = env.sim() else {
        return Err(PyValueError::new_err(
            "render_rgb: reset the environment first",
        ));
    };
    let stale = display.as_ref().is_none_or(|d| {
        d.scene() != sim.scene() || (d.camera().height, d.camera().width) != (h, w)
    });
    if stale {
        let renderer = umpnet_sim::render::create_renderer(env.config().renderer)
            .map_err(|e| eval_err(e.into()))?;
        *display = Some(
            SimEnv::new(sim.scene().clone(), Camera::reference(h, w), renderer)
                .map_err(|e| eval_err(e.into()))?,
        );
    }
    let parts = sim.part_transforms();
    let d = display
        .as_mut()
        .ok_or_else(|| runtime_err("no display scene"))?;
    let frame = d.render_parts(&parts).map_err(|e| eval_err(e.into()))?;
    Array3::from_shape_vec((h as usize, w as usize, 3), frame.rgb).map_err(runtime_err)
}
