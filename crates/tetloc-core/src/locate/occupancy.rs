//! A coarse grid over the mesh's box marking the cells that some box meets (each tet's, or
//! each boundary tet's grown one): a point in an unmarked cell is in none of the boxes, known
//! from one bit instead of a BVH traversal (points of a grid in a torus' hole, particles
//! leaving the mesh). Cell indices are monotone in the coordinate (a subtraction, a product
//! and a floor, each rounding monotonically; clamped to the grid), so a point inside a box
//! (working coordinates) has its cell index within the box's on each axis: the test never
//! refuses a point a box holds.

use crate::geom::{self, Vec3};
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

pub(super) struct Occupancy {
    lo: Vec3,
    scale: Vec3,
    n: [usize; 3],
    bits: Vec<u64>,
}

impl Occupancy {
    /// The cells the tets' boxes meet.
    pub(super) fn of_tets(mesh: &Mesh) -> Occupancy {
        Self::of_boxes(mesh, mesh.tets.len(), |i| geom::tet_bounds(mesh.tets[i], &mesh.points))
    }

    /// The cells that boxes `0..n` (`box_of`, working coordinates) meet: about one cell per
    /// mean edge length of the mesh a side, over the mesh's box, at most 2^24 cells.
    pub(super) fn of_boxes(mesh: &Mesh, n_boxes: usize, box_of: impl Fn(usize) -> (Vec3, Vec3) + Sync) -> Occupancy {
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let edge = (mesh.info.mean_edge_length as f64).max(1e-30);
        let ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]) as f64);
        let mut cell = edge;
        let count = |cell: f64| -> [usize; 3] { ext.map(|e| ((e / cell).ceil() as usize).clamp(1, 1 << 12)) };
        while count(cell).iter().product::<usize>() > 1 << 24 {
            cell *= 1.25;
        }
        let n = count(cell);
        let scale = std::array::from_fn(|k| if ext[k] > 0.0 { (n[k] as f64 / ext[k]) as f32 } else { 0.0 });
        let mut occ = Occupancy { lo, scale, n, bits: Vec::new() };
        let words: Vec<AtomicU64> = (0..(n[0] * n[1] * n[2]).div_ceil(64)).map(|_| AtomicU64::new(0)).collect();
        (0..n_boxes).into_par_iter().for_each(|i| {
            let (a, b) = box_of(i);
            let (a, b) = (occ.index(a), occ.index(b));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        let i = (z * n[1] + y) * n[0] + x;
                        words[i / 64].fetch_or(1 << (i % 64), Ordering::Relaxed);
                    }
                }
            }
        });
        occ.bits = words.into_iter().map(AtomicU64::into_inner).collect();
        occ
    }

    /// The cell of a point, clamped to the grid on each axis (also monotone; on values
    /// clamped at 0 the cast's truncation is the floor). NaN goes to cell 0.
    #[inline]
    fn index(&self, p: Vec3) -> [usize; 3] {
        std::array::from_fn(|k| (((p[k] - self.lo[k]) * self.scale[k]).max(0.0) as usize).min(self.n[k] - 1))
    }

    /// False only when no box holds `p`.
    #[inline]
    pub(super) fn may_hold(&self, p: Vec3) -> bool {
        let [x, y, z] = self.index(p);
        let i = (z * self.n[1] + y) * self.n[0] + x;
        self.bits[i / 64] >> (i % 64) & 1 != 0
    }
}
