//! umpnet-sim: the articulated-object simulator behind umpnet.
//!
//! URDF (PartNet-Mobility or generated) -> [`urdf::ObjectModel`] ->
//! [`physics::Articulation`] (rapier3d multibody + suction gripper).
pub mod error;
pub mod fsio;
pub mod math;
pub mod mesh;
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
