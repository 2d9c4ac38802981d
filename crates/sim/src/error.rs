use std::path::PathBuf;

/// Everything that can go wrong in the simulator, each naming what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("{file}: cannot read: {source}")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: cannot write: {source}")]
    Write {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: {what}")]
    Urdf { file: PathBuf, what: String },
    #[error("{file}:{line}: {what}")]
    Mesh {
        file: PathBuf,
        line: usize,
        what: String,
    },
    #[error("invalid action: {0}")]
    InvalidAction(String),
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    #[error("renderer: {0}")]
    Render(String),
    #[error("{0}")]
    Other(String),
}

pub type Result<T, E = SimError> = std::result::Result<T, E>;
