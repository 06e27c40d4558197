//! The library's typed errors. Every error that comes from a file names that file.

use std::path::PathBuf;

/// Everything that can go wrong in the core library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },

    /// The file is not what its format says it should be (truncated, malformed, bad values).
    #[error("{path}: {msg}")]
    Format { path: PathBuf, msg: String },

    /// The extension (or `--format`) names no format we read or write.
    #[error("{path}: unknown file format (known: {known})")]
    UnknownFormat { path: PathBuf, known: &'static str },

    /// Volume cells tetloc does not read: we count them by type instead of dropping them.
    #[error("{path}: the mesh has volume cells that tetloc does not read ({}); tetloc reads tetrahedra, pyramids, wedges and hexahedra (linear, quadratic and Lagrange)", fmt_counts(.counts))]
    NonTetCells { path: PathBuf, counts: Vec<(String, usize)> },

    /// The mesh itself is unusable (empty, indices out of range, NaN coordinates, ...).
    #[error("{source_name}: {msg}")]
    Mesh { source_name: String, msg: String },

    /// A field name that the mesh does not carry.
    #[error("no field named '{name}' (the mesh has: {available})")]
    NoSuchField { name: String, available: String },

    /// Input arrays that do not fit together (query points vs output buffer, ...).
    #[error("{0}")]
    Invalid(String),

    /// An error from a GPU or other pluggable backend.
    #[error("{backend}: {source}")]
    Backend { backend: String, source: Box<dyn std::error::Error + Send + Sync> },
}

fn fmt_counts(counts: &[(String, usize)]) -> String {
    counts.iter().map(|(k, n)| format!("{n} {k}")).collect::<Vec<_>>().join(", ")
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
    pub fn format(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Format { path: path.into(), msg: msg.into() }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
