//! Reader stub: replaced by the real reader.

use crate::error::{Error, Result};
use crate::mesh::RawMesh;
use std::path::Path;

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, path)
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(_bytes: &[u8], path: &Path) -> Result<RawMesh> {
    Err(Error::format(path, "reader not implemented yet"))
}
