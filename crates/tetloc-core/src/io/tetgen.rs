//! Reader stub: replaced by the real reader.

use crate::error::{Error, Result};
use crate::mesh::RawMesh;
use std::path::Path;

/// Reads `NAME.node` and `NAME.ele` (either may be named).
pub fn read(path: &Path) -> Result<RawMesh> {
    Err(Error::format(path, "reader not implemented yet"))
}

/// Parses a .node and a .ele file held in memory; `path` only names them in errors.
pub fn parse(_node: &[u8], _ele: &[u8], path: &Path) -> Result<RawMesh> {
    Err(Error::format(path, "reader not implemented yet"))
}
