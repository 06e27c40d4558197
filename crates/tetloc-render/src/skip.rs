//! Empty-space skipping: a coarse occupancy grid over the mesh bounds.
//!
//! A cell is occupied when the bounding box of some tet overlaps it, found with the same
//! floor-of-scaled-coordinate formula ([`OccupancyGrid::cell_of`]) that later classifies
//! sample points. That formula is monotonic in each coordinate, so a point inside a tet —
//! inside its box — always lands in a cell marked for that tet: skipping a sample whose
//! cell is empty never skips a sample that some tet contains.
//!
//! Cells are grouped into blocks of 8³; a ray in an empty block jumps over the whole block,
//! so large empty regions (a sheet in a big box) cost a few steps, not one per cell.

use crate::camera::Ray;
use crate::vec::{at, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use tetloc_core::{geom, Mesh};

/// At most this many cells along an axis (256³ bytes = 16 MiB).
pub const MAX_DIM: u32 = 256;

/// Cells a block is wide along each axis.
pub const BLOCK: u32 = 8;

#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    pub(crate) lo: Vec3,
    pub(crate) hi: Vec3,
    pub(crate) cell: Vec3,
    pub(crate) inv_cell: Vec3,
    pub dims: [u32; 3],
    pub(crate) occupied: Vec<bool>,
    /// Blocks of `BLOCK³` cells: occupied if any of their cells is.
    pub(crate) block_dims: [u32; 3],
    pub(crate) blocks: Vec<bool>,
    /// How far before a cell's exit a jump lands, so that rounding in the sample positions
    /// can never carry a skipped sample into the next cell.
    pub(crate) margin: f32,
}

impl OccupancyGrid {
    /// A grid over the mesh bounds with cells of about `cell_size` (capped at [`MAX_DIM`]
    /// cells per axis), each marked when a tet's bounding box overlaps it.
    pub fn build(mesh: &Mesh, cell_size: f32) -> OccupancyGrid {
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let dims: [u32; 3] = std::array::from_fn(|k| {
            let cells = ((hi[k] - lo[k]) / cell_size).ceil();
            if cells.is_finite() {
                (cells as u32).clamp(1, MAX_DIM)
            } else {
                MAX_DIM
            }
        });
        let cell: Vec3 = std::array::from_fn(|k| (hi[k] - lo[k]) / dims[k] as f32);
        // A flat axis has one cell and everything maps into it.
        let inv_cell: Vec3 = std::array::from_fn(|k| if cell[k] > 0.0 { 1.0 / cell[k] } else { 0.0 });
        let max_abs = lo.iter().chain(hi.iter()).fold(0f32, |m, &x| m.max(x.abs()));
        let min_cell = cell.iter().copied().filter(|&c| c > 0.0).fold(f32::INFINITY, f32::min);
        let margin = if min_cell.is_finite() { 1e-3 * min_cell } else { 0.0 } + 1e-5 * max_abs;
        let block_dims = dims.map(|d| d.div_ceil(BLOCK));
        let mut grid = OccupancyGrid {
            lo,
            hi,
            cell,
            inv_cell,
            dims,
            occupied: Vec::new(),
            block_dims,
            blocks: Vec::new(),
            margin,
        };

        let n = dims.iter().map(|&d| d as usize).product();
        let flags: Vec<AtomicBool> = (0..n).map(|_| AtomicBool::new(false)).collect();
        mesh.tets.par_iter().for_each(|&t| {
            let (a, b) = geom::tet_bounds(t, &mesh.points);
            let (Some(ca), Some(cb)) = (grid.cell_of(a), grid.cell_of(b)) else { return };
            for z in ca[2]..=cb[2] {
                for y in ca[1]..=cb[1] {
                    for x in ca[0]..=cb[0] {
                        flags[grid.index([x, y, z])].store(true, Ordering::Relaxed);
                    }
                }
            }
        });
        grid.occupied = flags.into_iter().map(AtomicBool::into_inner).collect();
        let mut blocks = vec![false; block_dims.iter().map(|&d| d as usize).product()];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    if grid.occupied[grid.index([x, y, z])] {
                        blocks[grid.block_index([x, y, z])] = true;
                    }
                }
            }
        }
        grid.blocks = blocks;
        grid
    }

    /// The cell holding `p`, or `None` outside the bounds (where no tet is).
    #[inline]
    pub fn cell_of(&self, p: Vec3) -> Option<[u32; 3]> {
        if (0..3).any(|k| !(p[k] >= self.lo[k] && p[k] <= self.hi[k])) {
            return None;
        }
        // Truncation is floor here (the scaled coordinate is ≥ 0) and, unlike `floor`, needs no
        // libm call on baseline x86-64: this runs for every sample.
        Some(std::array::from_fn(|k| (((p[k] - self.lo[k]) * self.inv_cell[k]) as u32).min(self.dims[k] - 1)))
    }

    #[inline]
    fn index(&self, c: [u32; 3]) -> usize {
        (c[2] as usize * self.dims[1] as usize + c[1] as usize) * self.dims[0] as usize + c[0] as usize
    }

    /// The index of the block holding cell `c`.
    #[inline]
    fn block_index(&self, c: [u32; 3]) -> usize {
        let [x, y, z] = c.map(|i| (i / BLOCK) as usize);
        (z * self.block_dims[1] as usize + y) * self.block_dims[0] as usize + x
    }

    /// Whether some tet may contain `p`.
    #[inline]
    pub fn may_contain(&self, p: Vec3) -> bool {
        self.cell_of(p).is_some_and(|c| self.occupied[self.index(c)])
    }

    /// The fraction of cells that are occupied.
    pub fn occupancy(&self) -> f64 {
        self.occupied.iter().filter(|&&o| o).count() as f64 / self.occupied.len() as f64
    }

    /// For a point `p = ray(t)` in an empty cell, a parameter before which every point of the
    /// ray past `t` is in that same empty region: a little before where the ray leaves the
    /// cell, or its whole block when the block is empty. The caller re-tests the first sample
    /// past it, so this is one step of a 3-D DDA that never trusts the geometry for a sample
    /// it keeps.
    #[inline]
    pub fn skip_to(&self, ray: &Ray, t: f32, p: Vec3) -> f32 {
        // Outside the bounds the ray is clipped to: nothing to skip to.
        let Some(c) = self.cell_of(p) else { return t };
        let (first, width) =
            if self.blocks[self.block_index(c)] { (c, 1) } else { (c.map(|i| i / BLOCK * BLOCK), BLOCK) };
        // The region's box; a block may reach past the bounds, where there are no tets either.
        let lo: Vec3 = std::array::from_fn(|k| self.lo[k] + first[k] as f32 * self.cell[k]);
        let hi: Vec3 = std::array::from_fn(|k| lo[k] + width as f32 * self.cell[k]);
        let mut t_exit = f32::INFINITY;
        for k in 0..3 {
            let d = ray.dir[k];
            if d != 0.0 {
                let plane = if d > 0.0 { hi[k] } else { lo[k] };
                t_exit = t_exit.min((plane - ray.origin[k]) / d);
            }
        }
        let end = at(ray.origin, ray.dir, t_exit);
        let scale = end.iter().fold(t_exit.abs(), |m, x| m.max(x.abs()));
        t_exit - self.margin - 1e-5 * scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_testdata::testmesh;

    #[test]
    fn every_tet_point_is_in_an_occupied_cell() {
        let mesh = testmesh::two_blobs(6, 3);
        let grid = OccupancyGrid::build(&mesh, 0.05);
        assert!(grid.occupancy() < 0.5, "two blobs leave most of the box empty ({})", grid.occupancy());
        // Corners and centroids of every tet.
        for (i, t) in mesh.tets.iter().enumerate() {
            for &v in t {
                assert!(grid.may_contain(mesh.points[v as usize]));
            }
            assert!(grid.may_contain(mesh.tet_center(i)));
        }
        assert!(!grid.may_contain([1e6, 0.0, 0.0]));
        // Every occupied cell is in an occupied block, and some blocks are empty.
        for (i, &o) in grid.occupied.iter().enumerate() {
            let d = grid.dims.map(|d| d as usize);
            let c = [(i % d[0]) as u32, ((i / d[0]) % d[1]) as u32, (i / (d[0] * d[1])) as u32];
            assert!(!o || grid.blocks[grid.block_index(c)]);
        }
        assert!(grid.blocks.iter().any(|b| !b));
    }

    /// Skipping from an empty cell lands before the next occupied one, along random rays.
    #[test]
    fn skips_never_pass_an_occupied_cell() {
        use rand::{Rng, SeedableRng};
        let mesh = testmesh::two_blobs(16, 4);
        let grid = OccupancyGrid::build(&mesh, 0.02);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut jumps = 0;
        for _ in 0..300 {
            let origin: Vec3 = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
            let Some(dir) = crate::vec::normalize(std::array::from_fn(|_| rng.gen_range(-1.0..1.0))) else { continue };
            let ray = Ray { origin, dir };
            let mut t = 0.0;
            while t < 2.0 {
                let p = at(origin, dir, t);
                if grid.cell_of(p).is_some() && !grid.may_contain(p) {
                    let to = grid.skip_to(&ray, t, p);
                    // Fine steps over the skipped stretch find nothing occupied.
                    let n = 200;
                    for i in 0..n {
                        let s = t + (to - t) * i as f32 / n as f32;
                        assert!(!grid.may_contain(at(origin, dir, s)), "skipped an occupied cell at t={s}");
                    }
                    jumps += 1;
                    t = to.max(t) + 1e-3;
                } else {
                    t += 1e-3;
                }
            }
        }
        assert!(jumps > 100, "{jumps}");
    }

    #[test]
    fn dims_are_capped_and_flat_axes_have_one_cell() {
        let mesh = testmesh::cube(2, 1.0, 1.0);
        assert_eq!(OccupancyGrid::build(&mesh, 1e-6).dims, [MAX_DIM; 3]);
        assert_eq!(OccupancyGrid::build(&mesh, 0.3).dims, [4, 4, 4]);
        assert_eq!(OccupancyGrid::build(&mesh, 10.0).dims, [1, 1, 1]);
    }
}
