//! umpnet-sim: the articulated-object simulator behind umpnet.
//!
//! URDF (PartNet-Mobility or generated) -> [`model::ObjectModel`] ->
//! [`physics::Articulation`] (the suction gripper on the `reference` solver,
//! by default, or on a rapier3d multibody with the `ideal` profile).
#![warn(missing_docs)]
/// [`SimError`]: what can go wrong, naming the file, element or value.
pub mod error;
pub mod fsio;
pub mod math;
pub mod mesh;
pub mod model;
pub mod physics;
pub mod urdf;

pub use error::{Result, SimError};
pub mod camera;
pub mod env;
pub mod fields;
pub mod labels;
pub mod objects;
pub mod render;
pub mod scene;
