//! Reader stub: replaced by the real reader.

use crate::error::{Error, Result};
use crate::mesh::RawMesh;
use std::path::Path;

pub fn read(path: &Path) -> Result<RawMesh> {
    Err(Error::format(path, "reader not implemented yet"))
}
