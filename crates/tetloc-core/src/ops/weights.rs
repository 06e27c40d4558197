//! Locate once, interpolate many: the sparse map from a mesh's vertices to query points.
//!
//! A simulation writes many steps (and many fields) on one mesh. Locating the same points
//! again for each is the expensive part; the interpolation is a fixed linear map. [`Weights`]
//! holds that map in CSR form, row `i` holding the weights of point `i`'s cell (the tet's
//! barycentrics, or the cell type's shape functions on all its nodes), so that applying it to a
//! per-vertex field gives what `sample` gives there, to rounding. A point outside the mesh has
//! an empty row (its value is NaN, as `sample`'s). Per-cell fields need only the cell ids
//! ([`Weights::cells`]). The weights are those of the located point itself: with a boundary
//! tolerance, a point assigned from just outside extrapolates from its cell.

use crate::error::{Error, Result};
use crate::geom::Real;
use crate::locate::{cell_weights, BatchLocator, OUTSIDE};
use crate::mesh::{Field, FieldLocation, Mesh};
use rayon::prelude::*;

/// Interpolation weights of a set of points in a mesh, one CSR row per point.
#[derive(Clone, Debug, PartialEq)]
pub struct Weights {
    /// The mesh's vertices (the matrix's columns).
    pub n_vertices: usize,
    /// Row `i` is `offsets[i]..offsets[i + 1]` of `vertices` and `weights` (`n_points + 1` entries).
    pub offsets: Vec<u64>,
    pub vertices: Vec<u32>,
    pub weights: Vec<f64>,
    /// Each point's cell (file order; -1 outside): what per-cell fields need.
    pub cells: Vec<i32>,
}

impl Weights {
    /// Locates `points` (the file's coordinates, f64) with `locator` (built on `mesh`) in
    /// batches of [`super::CHUNK`], then computes their weights.
    pub fn locate(locator: &mut dyn BatchLocator, mesh: &Mesh, points: &[[f64; 3]]) -> Result<Weights> {
        // Refused before the points are located, not after.
        refuse_polyhedra(mesh)?;
        let mut cells = vec![OUTSIDE; points.len()];
        for (p, ids) in points.chunks(super::CHUNK).zip(cells.chunks_mut(super::CHUNK)) {
            locator.sample_many64(p, &[], ids, &mut [])?;
        }
        Weights::from_cells(mesh, points, cells)
    }

    /// The weights of `points` (file coordinates) in the cells a locator found for them
    /// (`cells[i]`: a cell id of `mesh`, or -1).
    pub fn from_cells(mesh: &Mesh, points: &[[f64; 3]], cells: Vec<i32>) -> Result<Weights> {
        if points.len() != cells.len() {
            return Err(Error::Invalid(format!("{} points but {} cell ids", points.len(), cells.len())));
        }
        let n_cells = mesh.n_cells();
        if let Some(c) = cells.par_iter().find_any(|&&c| c < OUTSIDE || c >= 0 && c as usize >= n_cells) {
            return Err(Error::Invalid(format!("cell id {c} is not a cell of a mesh of {n_cells}")));
        }
        refuse_polyhedra(mesh)?;
        let rows: Vec<Vec<(u32, f64)>> = points
            .par_iter()
            .zip(&cells)
            .map(|(&p, &c)| {
                let mut row = Vec::new();
                if c >= 0 {
                    row_of(mesh, c as usize, p, |v, w| row.push((v, w)));
                }
                row
            })
            .collect();
        let lens: Vec<usize> = rows.iter().map(Vec::len).collect();
        let mut offsets = Vec::with_capacity(points.len() + 1);
        offsets.push(0u64);
        for &n in &lens {
            offsets.push(offsets.last().unwrap() + n as u64);
        }
        let vertices =
            super::concat(&lens, |i, out: &mut [u32]| out.iter_mut().zip(&rows[i]).for_each(|(o, r)| *o = r.0));
        let weights =
            super::concat(&lens, |i, out: &mut [f64]| out.iter_mut().zip(&rows[i]).for_each(|(o, r)| *o = r.1));
        Ok(Weights { n_vertices: mesh.points.len(), offsets, vertices, weights, cells })
    }

    /// The number of points (rows).
    pub fn n_points(&self) -> usize {
        self.cells.len()
    }

    /// Row `i`: its vertices and weights.
    pub fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.offsets[i] as usize..self.offsets[i + 1] as usize;
        (&self.vertices[r.clone()], &self.weights[r])
    }

    /// A per-vertex field of `k` components (`values`: `k` per vertex, vertex after vertex)
    /// at the points: `out` gets `k` values per point, NaN for points outside. In f32 or f64;
    /// the sums run in f64 either way.
    pub fn apply<T: Real>(&self, values: &[T], k: usize, out: &mut [T]) -> Result<()> {
        if k == 0 || values.len() != self.n_vertices * k || out.len() != self.n_points() * k {
            return Err(Error::Invalid(format!(
                "weights of {} points over {} vertices applied to {} values of {k} components into {}",
                self.n_points(),
                self.n_vertices,
                values.len(),
                out.len()
            )));
        }
        // Blocks of points a task: one task a point costs more than its few products.
        const POINTS_A_TASK: usize = 4096;
        out.par_chunks_mut(k * POINTS_A_TASK).enumerate().for_each(|(b, block)| {
            for (i, o) in block.chunks_mut(k).enumerate() {
                let (ids, ws) = self.row(b * POINTS_A_TASK + i);
                if ids.is_empty() {
                    o.fill(T::NAN);
                    continue;
                }
                for (j, o) in o.iter_mut().enumerate() {
                    let sum: f64 = ids.iter().zip(ws).map(|(&v, &w)| w * values[v as usize * k + j].to_f64()).sum();
                    *o = T::from_f64(sum);
                }
            }
        });
        Ok(())
    }

    /// A per-cell field of `k` components at the points (its value in each point's cell, NaN
    /// outside).
    pub fn apply_cells<T: Real>(&self, values: &[T], k: usize, out: &mut [T]) -> Result<()> {
        if k == 0 || !values.len().is_multiple_of(k) || out.len() != self.n_points() * k {
            return Err(Error::Invalid(format!(
                "cell ids of {} points applied to {} values of {k} components into {}",
                self.n_points(),
                values.len(),
                out.len()
            )));
        }
        let n_cells = values.len() / k;
        if let Some(&c) = self.cells.iter().find(|&&c| c >= 0 && c as usize >= n_cells) {
            return Err(Error::Invalid(format!("cell {c} of a point but a cell field of {n_cells} cells")));
        }
        out.par_chunks_mut(k).zip(&self.cells).for_each(|(o, &c)| match c {
            OUTSIDE => o.fill(T::NAN),
            c => o.copy_from_slice(&values[c as usize * k..(c as usize + 1) * k]),
        });
        Ok(())
    }

    /// A mesh field (one component) at the points, in f64 on the file's values: per vertex
    /// through the weights, per cell by id.
    pub fn apply_field(&self, field: &Field, out: &mut [f64]) -> Result<()> {
        let values: Vec<f64> = (0..field.values.len()).into_par_iter().map(|i| field.value64(i)).collect();
        match field.location {
            FieldLocation::Vertex => self.apply(&values, 1, out),
            FieldLocation::Cell => self.apply_cells(&values, 1, out),
        }
    }
}

/// A polyhedron's values come through the centroids of its decomposition, which are not the
/// file's points: their weights would need folding onto the centroids' sources, which the mesh
/// does not keep. Refused rather than given in columns no file has.
fn refuse_polyhedra(mesh: &Mesh) -> Result<()> {
    if mesh.info.n_centroids == 0 {
        return Ok(());
    }
    Err(Error::Invalid(format!(
        "{}: interpolation weights of meshes with polyhedral cells are not supported yet (sample and locate are)",
        mesh.info.source
    )))
}

/// The (vertex, weight) pairs of point `p` (file coordinates) in cell `c`: the same
/// definitions as the values every backend computes (`Mesh::value_at64` for tets, the
/// mixed-cell wrapper's shape functions for other cells).
fn row_of(mesh: &Mesh, c: usize, p: [f64; 3], push: impl FnMut(u32, f64)) {
    match &mesh.cells {
        None => {
            if let Some(b) = mesh.bary64(c, p) {
                mesh.tet_weights(c, b, push);
            }
        }
        Some(cells) => cell_weights(mesh, cells, c, p, push),
    }
}

#[cfg(test)]
mod tests;
