//! Writing a mesh cut into pieces (`tetloc partition`): [`tetloc_core::partition`] cuts it,
//! [`crate::vtk::write_pieces`] writes the `.pvtu` and its pieces.

use crate::vtk::write_pieces;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::Mesh;
use tetloc_core::partition::{cell_centroids, piece_with_points, rcb};

/// Cuts `mesh` into `parts` pieces by [`rcb`] of its cell centroids and writes them as the
/// partitioned mesh `path` (`.pvtu` and its pieces folder, complete or absent); `done(k)`
/// after piece `k`.
pub fn write_pvtu(mesh: &Mesh, parts: usize, path: &std::path::Path, zlib: bool, done: impl Fn(usize)) -> Result<()> {
    let n = mesh.n_cells();
    if parts == 0 || parts > n {
        return Err(Error::Invalid(format!("cannot cut {n} cells into {parts} pieces")));
    }
    let part = rcb(&cell_centroids(mesh), parts);
    let mut cells: Vec<Vec<u32>> = vec![Vec::new(); parts];
    part.iter().enumerate().for_each(|(c, &k)| cells[k as usize].push(c as u32));
    let name = path.display().to_string();
    let pieces = cells.into_iter().enumerate().map(|(k, cells)| {
        let (piece, points) = piece_with_points(mesh, &cells, format!("{name} piece {k}").as_str())?;
        Ok((piece, cells.into_iter().map(u64::from).collect(), points))
    });
    write_pieces::write_pvtu(path, pieces, zlib, done)
}
