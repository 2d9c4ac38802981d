//! umpnet-eval: episodes, reference policies and the UMPNet benchmark. The
//! one crate that joins the simulator and the policy runtime.
#![warn(missing_docs)]
pub mod benchmark;
pub mod episode;
pub mod frame_joint;
pub mod learned;
pub mod partnet;
pub mod policy;
pub mod protocol;
pub mod rewards;
pub mod scripted;
pub mod shard;
pub mod stats;
pub mod train_env;

pub use policy::{Decision, Observation, Policy, StepRecord};
pub use protocol::Protocol;

/// What can go wrong in an episode or a benchmark.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The simulator refused (a bad scene or action, a file, the renderer).
    #[error(transparent)]
    Sim(#[from] umpnet_sim::SimError),
    /// The policy runtime refused (a package, an input, ONNX Runtime).
    #[error(transparent)]
    Policy(#[from] umpnet_policy::PolicyError),
    /// An episode or a benchmark could not run, and why.
    #[error("{0}")]
    Episode(String),
}

/// The crate's result type.
pub type Result<T, E = EvalError> = std::result::Result<T, E>;

/// The policies available by name without a model.
pub fn scripted_policy(name: &str) -> Option<Box<dyn Policy>> {
    match name {
        "random" => Some(Box::new(scripted::RandomPolicy::default())),
        "oracle" => Some(Box::new(scripted::OraclePolicy::default())),
        _ => None,
    }
}
