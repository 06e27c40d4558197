//! Mixed meshes (see ARCHITECTURE.md, "Mixed cells"): the file's volume cells of any type, kept
//! with all their nodes, and their conforming tet decomposition, which becomes the mesh's tets.
//! Every tet kernel (CPU and GPU) locates in the decomposition unchanged; the answers map to
//! cells through [`Cells::tet_parent`] and are refined with the cells' own parametric
//! coordinates by [`crate::locate::CellLocator`].
//!
//! Meshes of tets only (of any order) have no `Cells` and pay nothing for it.

use crate::cell::polyhedron::Decomposed;
use crate::cell::{decompose, warped_faces, CellBlock, Point, Shape};
use crate::geom::{self, Vec3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::OnceLock;

/// The volume cells of a mixed mesh and the map from its decomposition tets to them.
#[derive(Debug)]
pub struct Cells {
    /// The file's volume cells, in file order (cell ids), with all their nodes in VTK's order.
    pub block: CellBlock,
    /// For each tet of [`super::Mesh::tets`], the cell it belongs to (ascending: a cell's tets
    /// are consecutive).
    pub tet_parent: Vec<u32>,
    /// Per cell, bit `f` set when face `f` is a warped (non-planar, bilinear) quad (never for
    /// polyhedra: their decomposition is the cell).
    pub warped: Vec<u8>,
    /// The file's points are the mesh's first `n_file_points`; the rest are the polyhedra's
    /// centroids ([`crate::cell::polyhedron`]).
    pub n_file_points: usize,
    neighbors: OnceLock<Vec<[i32; 6]>>,
}

/// What [`Cells::build`] hands back to `Mesh::new`.
pub(super) struct Built {
    pub cells: Cells,
    /// The decomposition, canonical.
    pub tets: Vec<[u32; 4]>,
    /// Cells listed inverted (every decomposition tet negative): located as they are.
    pub reoriented: usize,
    /// Cells of zero volume (repeated or coplanar corners): they hold no point.
    pub degenerate: usize,
    /// Cells that fold over themselves (decomposition tets of both signs).
    pub tangled: usize,
}

/// Tets per cell of a shape (1, 2, 3, 6): the decomposition's count does not depend on ids.
pub fn tets_per_cell(shape: &Shape) -> usize {
    let ids: Vec<u32> = (0..shape.n_corners() as u32).collect();
    decompose(shape, &ids).tets().len()
}

impl Cells {
    /// Decomposes `block` over `points` and validates it; its polyhedra are already
    /// decomposed (`poly`, whose new points `points` ends with). Errors are messages for
    /// `Error::Mesh` (the caller names the file).
    pub(super) fn build(block: CellBlock, points: &[Vec3], poly: Option<&Decomposed>) -> Result<Built, String> {
        let n = points.len() as u32;
        let n_file_points = poly.map_or(points.len(), |d| d.n_file_points);
        let poly_tets = |c: usize| -> Option<&[[u32; 4]]> { Some(poly?.tets_of(block.polyhedra.index_of(c)?)) };
        if let Some(k) = crate::par::first_position(&block.conn, |&id| id >= n) {
            let c = block.ends.partition_point(|&e| e <= k as u64);
            return Err(format!("cell {c} references vertex {} but the mesh has only {n} vertices", block.conn[k]));
        }
        if block.len() >= u32::MAX as usize {
            return Err(format!("{} cells: more than 32-bit ids can name", block.len()));
        }
        let counts: Vec<usize> = (0..block.len())
            .into_par_iter()
            .map(|c| match poly_tets(c) {
                Some(t) => t.len(),
                None => tets_per_cell(block.types[c].shape()),
            })
            .collect();
        let total: usize = counts.iter().sum();
        if total >= i32::MAX as usize {
            return Err(format!(
                "{} cells decompose into {total} tets: more than 32-bit signed ids can name",
                block.len()
            ));
        }
        // Each cell's tets, canonical, with the signs of their volumes as the cell lists them.
        let per_cell = |c: usize| {
            if let Some(tets) = poly_tets(c) {
                // A polyhedron's faces may face either way: its tets' signs say nothing.
                return tets.iter().map(|&t| geom::canonical_tet(t, points)).map(|(t, v)| (t, v.abs())).collect();
            }
            let ids = block.corners(c);
            decompose(block.types[c].shape(), ids)
                .tets()
                .iter()
                .map(|t| geom::canonical_tet(t.map(|k| ids[usize::from(k)]), points))
                .collect::<Vec<_>>()
        };
        // Signs of the decomposition tets' volumes, as the cell lists its corners.
        let signs: Vec<(usize, usize)> = (0..block.len())
            .into_par_iter()
            .map(|c| {
                let tets = per_cell(c);
                (tets.iter().filter(|t| t.1 > 0.0).count(), tets.iter().filter(|t| t.1 < 0.0).count())
            })
            .collect();
        // Tangled cells (tets of both signs: the cell folds over itself, as in crushed meshes)
        // are kept, located by their decomposition, and counted.
        let tangled = signs.par_iter().filter(|&&(pos, neg)| pos > 0 && neg > 0).count();
        let reoriented = signs.par_iter().filter(|&&(pos, neg)| neg > 0 && pos == 0).count();
        let degenerate = signs.par_iter().filter(|&&(pos, neg)| pos == 0 && neg == 0).count();
        let tets: Vec<[u32; 4]> =
            (0..block.len()).into_par_iter().flat_map_iter(|c| per_cell(c).into_iter().map(|t| t.0)).collect();
        let tet_parent: Vec<u32> =
            (0..block.len()).into_par_iter().flat_map_iter(|c| std::iter::repeat_n(c as u32, counts[c])).collect();
        debug_assert_eq!(tets.len(), total);
        let warped = (0..block.len())
            .into_par_iter()
            .map(|c| {
                if block.types[c].is_polyhedron() {
                    return 0;
                }
                let corners: Vec<Point> = block.corners(c).iter().map(|&i| points[i as usize].map(f64::from)).collect();
                warped_faces(block.types[c].shape(), &corners)
            })
            .collect();
        let cells = Cells { block, tet_parent, warped, n_file_points, neighbors: OnceLock::new() };
        Ok(Built { cells, tets, reoriented, degenerate, tangled })
    }

    pub fn len(&self) -> usize {
        self.block.len()
    }

    pub fn is_empty(&self) -> bool {
        self.block.is_empty()
    }

    /// The cell that decomposition tet `t` belongs to.
    #[inline]
    pub fn cell_of(&self, t: usize) -> usize {
        self.tet_parent[t] as usize
    }

    /// The range of decomposition tets of cell `c`.
    pub fn tets_of(&self, c: usize) -> std::ops::Range<usize> {
        let c = c as u32;
        self.tet_parent.partition_point(|&p| p < c)..self.tet_parent.partition_point(|&p| p <= c)
    }

    /// Each cell's first decomposition tet, and the number of tets last (`len() + 1` entries):
    /// cell `c`'s tets are `first_tets[c]..first_tets[c + 1]`. What the GPU kernels that take
    /// one box a cell (soft-bvh, rt-bvh) read to test a cell's tets.
    pub fn first_tets(&self) -> Vec<u32> {
        // Every cell has at least one tet, and a cell's tets are consecutive.
        let mut first = vec![0u32; self.len() + 1];
        for (t, pair) in self.tet_parent.windows(2).enumerate() {
            if pair[0] != pair[1] {
                first[pair[1] as usize] = t as u32 + 1;
            }
        }
        first[self.len()] = self.tet_parent.len() as u32;
        first
    }

    /// Cell counts by type name (VTK's names).
    pub fn type_counts(&self) -> BTreeMap<String, usize> {
        let mut by_type = BTreeMap::new();
        for t in &self.block.types {
            *by_type.entry(*t).or_insert(0usize) += 1;
        }
        by_type.into_iter().map(|(t, n)| (t.def().name().to_string(), n)).collect()
    }

    /// How many cells are polyhedra, and their faces (a shared face counted once per cell).
    pub fn polyhedra(&self) -> (usize, usize) {
        (self.block.polyhedra.len(), self.block.polyhedra.n_faces())
    }

    /// Cells with at least one warped face.
    pub fn n_warped(&self) -> usize {
        self.warped.par_iter().filter(|&&w| w != 0).count()
    }

    /// For each cell and face (VTK's face order), the cell across it, or -1 on the boundary.
    /// Computed on first use, for faces that some cell has as a warped quad only (the only
    /// faces the refinement crosses); every other entry is -1.
    pub fn warped_neighbors(&self) -> &[[i32; 6]] {
        self.neighbors.get_or_init(|| {
            // (sorted corner ids, cell, face) of every warped face, sorted: shared faces pair up.
            let mut faces: Vec<([u32; 4], u32, u8)> = (0..self.len())
                .into_par_iter()
                .filter(|&c| self.warped[c] != 0)
                .flat_map_iter(|c| {
                    let shape = self.block.types[c].shape();
                    let ids = self.block.corners(c);
                    (0..shape.faces.len()).filter(move |&f| self.warped[c] & (1 << f) != 0).map(move |f| {
                        let mut key = [u32::MAX; 4];
                        for (k, &v) in shape.faces[f].iter().enumerate() {
                            key[k] = ids[usize::from(v)];
                        }
                        key.sort_unstable();
                        (key, c as u32, f as u8)
                    })
                })
                .collect();
            faces.par_sort_unstable();
            let mut out = vec![[-1i32; 6]; self.len()];
            for w in faces.windows(2) {
                if w[0].0 == w[1].0 {
                    out[w[0].1 as usize][usize::from(w[0].2)] = w[1].1 as i32;
                    out[w[1].1 as usize][usize::from(w[1].2)] = w[0].1 as i32;
                }
            }
            out
        })
    }

    /// Whether cell `c` has a warped face on the mesh's boundary (it may bulge out of the
    /// decomposition there).
    pub fn has_warped_boundary(&self, c: usize) -> bool {
        let n = &self.warped_neighbors()[c];
        (0..6).any(|f| self.warped[c] & (1 << f) != 0 && n[f] < 0)
    }

    /// Bytes held (the decomposition tets are counted with the mesh's tets).
    pub fn memory_bytes(&self) -> usize {
        self.block.types.len()
            + std::mem::size_of_val(self.block.ends.as_slice())
            + std::mem::size_of_val(self.block.conn.as_slice())
            + std::mem::size_of_val(self.block.polyhedra.face_ends.as_slice())
            + std::mem::size_of_val(self.block.polyhedra.points.as_slice())
            + std::mem::size_of_val(self.tet_parent.as_slice())
            + self.warped.len()
            + self.neighbors.get().map_or(0, |n| std::mem::size_of_val(n.as_slice()))
    }
}
