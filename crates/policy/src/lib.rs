//! umpnet-policy: the UMPNet policy runtime. Inputs are RGB-D frames,
//! intrinsics and a camera pose — from the simulator or a real camera; this
//! crate never depends on the simulator.
#![warn(missing_docs)]
pub mod axis;
pub mod cem;
/// Errors of the runtime: bad input, a bad package, ONNX Runtime failing.
pub mod error;
mod filters;
pub mod frame_joint;
pub mod goal_shift;
pub mod memory;
pub mod observation;

pub use error::{PolicyError, Result};
pub use observation::{
    CHANNELS, CameraFrame, MIRRORED_CHANNELS, build_observation, build_observation_into,
    mirrored_observations,
};
pub mod package;
pub mod policy;
pub mod runtime;

pub use package::{Branches, DirectionScores, ModelMeta, ModelPackage};
pub use policy::{DecisionInput, PositionChoice, UmpnetPolicy};
