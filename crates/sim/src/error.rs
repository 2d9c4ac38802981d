use std::path::PathBuf;

/// Everything that can go wrong in the simulator, each naming what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file could not be written (nothing half-written is left).
    #[error("{file}: cannot write: {source}")]
    Write {
        /// The file.
        file: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A URDF (or an object's metadata) is wrong.
    #[error("{file}: {what}")]
    Urdf {
        /// The file.
        file: PathBuf,
        /// What is wrong, naming the element and what was expected.
        what: String,
    },
    /// A mesh file is wrong.
    #[error("{file}:{line}: {what}")]
    Mesh {
        /// The file.
        file: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What is wrong there.
        what: String,
    },
    /// An action the simulator cannot take (a pixel off the image, a zero direction).
    #[error("invalid action: {0}")]
    InvalidAction(String),
    /// A scene that cannot be (joint values off their limits, a bad pose).
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// The renderer failed.
    #[error("renderer: {0}")]
    Render(String),
    /// Anything else, said in words.
    #[error("{0}")]
    Other(String),
}

/// The simulator's result type.
pub type Result<T, E = SimError> = std::result::Result<T, E>;
