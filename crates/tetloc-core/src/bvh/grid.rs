//! The entry grid of a wide BVH: a uniform grid over the bounding box whose cells name where
//! a search for a point of the cell may start. Each cell names the lowest common ancestor of
//! the nodes holding every primitive whose box overlaps the cell (so that subtree holds every
//! primitive that can contain a point of the cell), or `EMPTY`; optionally also a start
//! primitive for a walk (the one holding the cell's centre). soft-bvh uploads it as
//! [`EntryGrid::words`]; [`EntryGrid::locate`] is the CPU reference of the shader's `tl_locate`.

use super::wide::{WideBvh, EMPTY};
use super::Aabb;
use crate::geom::Vec3;
use rayon::prelude::*;

/// Cell coordinate of `p` on one axis, computed exactly as the shader does (one f32
/// subtraction and one multiplication, no FMA), so that the CPU and the GPU agree on which
/// cell a point is in, and cell(lo) <= cell(p) <= cell(hi) whenever lo <= p <= hi.
#[inline]
pub fn cell_coord(p: f32, lo: f32, inv: f32, dim: u32) -> u32 {
    ((p - lo) * inv).floor().clamp(0.0, (dim - 1) as f32) as u32
}

/// See the module's documentation.
#[derive(Clone, Debug)]
pub struct EntryGrid {
    /// The grid's origin: the bounding box's minimum.
    pub lo: Vec3,
    pub dims: [u32; 3],
    /// Cells per unit length on each axis (0 on a flat axis).
    pub inv: [f32; 3],
    /// Per cell (x fastest), the node a traversal starts from, or `EMPTY`.
    pub cells: Vec<u32>,
    /// Per cell, the primitive a walk starts from: the one holding the cell's centre, else one
    /// whose box overlaps the cell, else `EMPTY`. Empty when built without starts.
    pub starts: Vec<u32>,
}

impl EntryGrid {
    /// The grid over [lo, hi] with about one cell per `prims_per_cell` of the `n_prims`
    /// primitives of `wide`, whose boxes `bounds` gives. With `claim` (does primitive `id`
    /// hold point `p`: `Some(strictly inside)`, as [`WideBvh::locate`] takes it), each cell
    /// also names a walk start.
    pub fn new(
        wide: &WideBvh,
        n_prims: usize,
        bounds: impl Fn(u32) -> Aabb + Sync,
        (lo, hi): (Vec3, Vec3),
        prims_per_cell: usize,
        claim: Option<&(dyn Fn(u32, Vec3) -> Option<bool> + Sync)>,
    ) -> EntryGrid {
        let (dims, inv) = EntryGrid::shape(n_prims, (lo, hi), prims_per_cell);
        let n_cells = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = EntryGrid { lo, dims, inv, cells: vec![EMPTY; n_cells], starts: vec![] };
        // Per cell, some primitive whose box overlaps it (the first in id order): the walk
        // start when the cell's centre lies in no primitive.
        let mut any = vec![EMPTY; n_cells];
        // Parallel over slabs of z layers: each slab scans every primitive and rasterizes only
        // its own layers (the LCA is order-free and `any` keeps the first primitive, so the
        // result does not depend on the slabs).
        let layer = (dims[0] * dims[1]) as usize;
        let per = (dims[2] as usize).div_ceil(rayon::current_num_threads() * 2).max(1);
        grid.cells.par_chunks_mut(per * layer).zip(any.par_chunks_mut(per * layer)).enumerate().for_each(
            |(s, (cells, any))| {
                let (z_first, z_last) = ((s * per) as u32, (s * per + cells.len() / layer - 1) as u32);
                for t in 0..n_prims {
                    let b = bounds(t as u32);
                    let c0: [u32; 3] = std::array::from_fn(|a| cell_coord(b.min[a], lo[a], inv[a], dims[a]));
                    let c1: [u32; 3] = std::array::from_fn(|a| cell_coord(b.max[a], lo[a], inv[a], dims[a]));
                    if c1[2] < z_first || c0[2] > z_last {
                        continue;
                    }
                    let home = wide.home[t];
                    for z in c0[2].max(z_first)..=c1[2].min(z_last) {
                        for y in c0[1]..=c1[1] {
                            for x in c0[0]..=c1[0] {
                                let i = (((z - z_first) * dims[1] + y) * dims[0] + x) as usize;
                                cells[i] = if cells[i] == EMPTY { home } else { wide.lca(cells[i], home) };
                                if any[i] == EMPTY {
                                    any[i] = t as u32;
                                }
                            }
                        }
                    }
                }
            },
        );
        if let Some(claim) = claim {
            // Locate each cell's centre with the reference search from the cell's node (the
            // tie rule included, as the GPU build's grid_starts.comp).
            let starts = (0..n_cells)
                .into_par_iter()
                .map_init(Vec::new, |stack, i| match grid.cells[i] {
                    EMPTY => EMPTY,
                    node => {
                        let centre = grid.centre(i);
                        wide.locate(centre, node, stack, |t| claim(t, centre)).prim.unwrap_or(any[i])
                    }
                })
                .collect();
            grid.starts = starts;
        }
        grid
    }

    /// Cells per axis and cells per unit length of the grid over [lo, hi] with about one
    /// cell per `prims_per_cell` of `n_prims` primitives (the GPU build uses it too).
    pub fn shape(n_prims: usize, (lo, hi): (Vec3, Vec3), prims_per_cell: usize) -> ([u32; 3], [f32; 3]) {
        let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0) as f64);
        let cells_wanted = (n_prims / prims_per_cell.max(1)).max(1) as f64;
        let used: Vec<f64> = extent.iter().copied().filter(|&e| e > 0.0).collect();
        let h = if used.is_empty() {
            1.0
        } else {
            (used.iter().product::<f64>() / cells_wanted).powf(1.0 / used.len() as f64)
        };
        let dims: [u32; 3] = std::array::from_fn(|a| ((extent[a] / h).round() as u32).clamp(1, 1024));
        let inv: [f32; 3] =
            std::array::from_fn(|a| if extent[a] > 0.0 { dims[a] as f32 / (hi[a] - lo[a]) } else { 0.0 });
        (dims, inv)
    }

    /// As uploaded: header (dims, number of cells if walk starts follow else 0, inv as bits,
    /// 0), the cells' entry nodes, then the walk starts if any.
    pub fn words(&self) -> Vec<u32> {
        let starts_at = if self.starts.is_empty() { 0 } else { self.cells.len() as u32 };
        let mut w = vec![self.dims[0], self.dims[1], self.dims[2], starts_at];
        w.extend(self.inv.map(f32::to_bits));
        w.push(0);
        w.extend_from_slice(&self.cells);
        w.extend_from_slice(&self.starts);
        w
    }

    /// The cell of `p` (the shader's arithmetic, see [`cell_coord`]).
    pub fn cell_of(&self, p: Vec3) -> usize {
        let c: [u32; 3] = std::array::from_fn(|a| cell_coord(p[a], self.lo[a], self.inv[a], self.dims[a]));
        ((c[2] as usize * self.dims[1] as usize) + c[1] as usize) * self.dims[0] as usize + c[0] as usize
    }

    /// The centre of cell `i` (only a hint for where a walk starts: no exactness needed).
    pub fn centre(&self, i: usize) -> Vec3 {
        let (nx, ny) = (self.dims[0] as usize, self.dims[1] as usize);
        let c = [i % nx, (i / nx) % ny, i / (nx * ny)];
        std::array::from_fn(|a| EntryGrid::centre_coord(self.lo[a], self.inv[a], c[a] as u32))
    }

    /// On one axis (origin `lo`, `inv` cells per unit length), the centre of the cells at
    /// index `c` (the GPU build uses it too).
    pub fn centre_coord(lo: f32, inv: f32, c: u32) -> f32 {
        if inv > 0.0 {
            lo + (c as f32 + 0.5) / inv
        } else {
            lo
        }
    }

    /// The CPU reference of soft-bvh's `tl_locate` (shaders/common/soft_bvh.glsl): in `p`'s
    /// cell, `walk` from the cell's start primitive (when the grid has starts) may settle the
    /// point (it must answer only a primitive that holds `p` strictly inside, the one any
    /// search finds); else [`WideBvh::locate`] from the cell's node with `claim` deciding the
    /// primitives. `None` in a cell no primitive's box overlaps.
    pub fn locate(
        &self,
        wide: &WideBvh,
        p: Vec3,
        stack: &mut Vec<u32>,
        walk: impl FnOnce(u32) -> Option<u32>,
        claim: impl FnMut(u32) -> Option<bool>,
    ) -> Option<u32> {
        let cell = self.cell_of(p);
        let node = self.cells[cell];
        if node == EMPTY {
            return None;
        }
        if let Some(&start) = self.starts.get(cell) {
            if let Some(t) = walk(start) {
                return Some(t);
            }
        }
        wide.locate(p, node, stack, claim).prim
    }
}
