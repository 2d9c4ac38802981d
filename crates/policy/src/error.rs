use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    #[error("invalid input: {0}")]
    Input(String),
    #[error("{path}: {what}")]
    Package { path: PathBuf, what: String },
    #[error("ONNX Runtime: {0}")]
    Runtime(String),
}

pub type Result<T, E = PolicyError> = std::result::Result<T, E>;
