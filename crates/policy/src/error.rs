use std::path::PathBuf;

/// What can go wrong in the runtime.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// The caller's input is wrong: a shape, a value, a pixel.
    #[error("invalid input: {0}")]
    Input(String),
    /// A model package is wrong or unreadable.
    #[error("{path}: {what}")]
    Package {
        /// The file (or folder) at fault.
        path: PathBuf,
        /// What is wrong with it, and what was expected.
        what: String,
    },
    /// ONNX Runtime is missing, or failed.
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
}

/// The runtime's result type.
pub type Result<T, E = PolicyError> = std::result::Result<T, E>;
