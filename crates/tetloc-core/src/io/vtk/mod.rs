//! The VTK family: the XML reader ([`vtu`]), the legacy reader ([`legacy`]), the VTU writers
//! ([`write`]), and what they share: element types, cell types, XML and binary blocks.

pub(crate) mod blocks;
pub(crate) mod cells;
pub(crate) mod num;
pub(crate) mod xml;

pub mod legacy;
pub mod vtu;
pub mod write;

#[cfg(test)]
mod tests;

use crate::error::{Error, Result};
use std::path::Path;

/// Reads a whole file. Large files are read by all threads at once: copying from the page
/// cache is a good part of loading a big mesh, and it parallelises.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>> {
    #[cfg(unix)]
    {
        use rayon::prelude::*;
        use std::os::unix::fs::FileExt;
        const PART: usize = 8 << 20;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        if len > 4 * PART as u64 && rayon::current_num_threads() > 1 {
            let len = usize::try_from(len).map_err(|_| Error::format(path, "file too large for this machine"))?;
            let mut buf = vec![0u8; len];
            buf.par_chunks_mut(PART)
                .enumerate()
                .try_for_each(|(i, part)| file.read_exact_at(part, (i * PART) as u64))
                .map_err(|e| Error::io(path, e))?;
            return Ok(buf);
        }
    }
    std::fs::read(path).map_err(|e| Error::io(path, e))
}
