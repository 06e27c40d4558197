//! The pieces of a partitioned input, whatever holds them, for the MPI path (`tetloc-mpi`
//! gives each rank some of them and joins its own with [`pieces::join`]): the `.vtu` files of
//! a `.pvtu`/`.vtm` listing, or the `processorN/` folders of a decomposed OpenFOAM case
//! (`NAME.foam` or the case folder), each a piece with its addressing as global ids.

use crate::openfoam;
use crate::vtk::pieces::{self, Piece};
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};

/// Whether `path` is partitioned: a listing, or an OpenFOAM case with processor folders.
pub fn is_partitioned(path: &Path) -> bool {
    pieces::is_listing(path) || is_decomposed_case(path)
}

fn is_decomposed_case(path: &Path) -> bool {
    let foam = crate::output::extension(path) == "foam" || (path.is_dir() && openfoam::is_case(path));
    foam && openfoam::is_decomposed(path)
}

/// The pieces of `path`, in order: a listing's `.vtu` files, or a case's processor folders.
pub fn list(path: &Path) -> Result<Vec<PathBuf>> {
    if pieces::is_listing(path) {
        pieces::list(path)
    } else if is_decomposed_case(path) {
        openfoam::processors(path)
    } else {
        Err(Error::format(
            path,
            "not partitioned: a .pvtu or .vtm listing (see `tetloc partition`), or a decomposed OpenFOAM case (processor*/)",
        ))
    }
}

/// Piece `index` (`piece`, as [`list`] gave it) of `path`; errors name both.
pub fn read_piece(path: &Path, index: usize, piece: &Path) -> Result<Piece> {
    if pieces::is_listing(path) {
        return pieces::read_piece(path, index, piece);
    }
    let (raw, global_ids, global_point_ids) = openfoam::read_processor(piece)
        .map_err(|e| Error::format(path, format!("processor {index} ({}): {e}", piece.display())))?;
    Ok(Piece { path: piece.to_path_buf(), raw, global_ids, global_point_ids })
}
