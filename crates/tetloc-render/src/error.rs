//! The renderer's typed errors. An error about a file names that file.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A command-line style option string that does not parse or is out of range.
    #[error("{option} '{value}': {msg}")]
    BadOption { option: &'static str, value: String, msg: String },

    /// A transfer-function or surface file that is not what its format says it should be.
    #[error("{path}: {msg}")]
    BadFile { path: PathBuf, msg: String },

    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },

    /// Options that parse on their own but cannot be used together or with this mesh.
    #[error("{0}")]
    Invalid(String),

    /// Errors from the core library: unknown fields, locator failures.
    #[error(transparent)]
    Core(#[from] tetloc_core::Error),
}

impl RenderError {
    pub(crate) fn file(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        RenderError::BadFile { path: path.into(), msg: msg.into() }
    }
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        RenderError::Io { path: path.into(), source }
    }
    pub(crate) fn option(option: &'static str, value: &str, msg: impl Into<String>) -> Self {
        RenderError::BadOption { option, value: value.to_string(), msg: msg.into() }
    }
}

pub type Result<T, E = RenderError> = std::result::Result<T, E>;
