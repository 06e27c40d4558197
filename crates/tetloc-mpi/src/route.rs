//! Where a point may be answered: each rank's region (the bounding box of its cells and a
//! coarse occupancy grid over it), and the routing of a batch of points to the ranks whose
//! region holds them.
//!
//! The grid is conservative: a grid cell is marked when some mesh cell's bounding box (of all
//! its corners, so a warped face's outward bulge is inside it) touches it, and a point and a
//! box are mapped to grid cells by the same monotone rounding, so a point inside a mesh cell
//! always lands in a marked grid cell of the rank that holds the cell.

use tetloc_core::{Mesh, Vec3};

/// Grid cells per side of a rank's occupancy grid (32³ bits: 4 KiB a rank).
pub const GRID: usize = 32;
const WORDS: usize = GRID * GRID * GRID / 64;

/// One rank's region: where its cells are.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    pub lo: Vec3,
    pub hi: Vec3,
    /// Bit `(z·GRID + y)·GRID + x` set: some cell's box touches that grid cell.
    pub occupied: Vec<u64>,
}

impl Region {
    /// The region of a rank without cells: holds no point.
    pub fn empty() -> Region {
        Region { lo: [f32::INFINITY; 3], hi: [f32::NEG_INFINITY; 3], occupied: vec![0; WORDS] }
    }

    /// The region of `mesh`'s cells.
    /// In the file's coordinates (the points' own), boxes rounded outward to f32.
    pub fn of_mesh(mesh: &Mesh) -> Region {
        let (lo, hi) = mesh.file_box();
        let mut r = Region { lo: lo.map(f32_down), hi: hi.map(f32_up), occupied: vec![0; WORDS] };
        let mut mark = |corners: &mut dyn Iterator<Item = u32>| {
            let (mut a, mut b) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for i in corners {
                let p = mesh.vertex64(i);
                for k in 0..3 {
                    a[k] = a[k].min(p[k]);
                    b[k] = b[k].max(p[k]);
                }
            }
            let (ca, cb) = (r.cell(a.map(f32_down)), r.cell(b.map(f32_up)));
            for z in ca[2]..=cb[2] {
                for y in ca[1]..=cb[1] {
                    for x in ca[0]..=cb[0] {
                        let bit = (z * GRID + y) * GRID + x;
                        r.occupied[bit / 64] |= 1 << (bit % 64);
                    }
                }
            }
        };
        match &mesh.cells {
            Some(cells) => (0..cells.block.len()).for_each(|c| mark(&mut cells.block.corners(c).iter().copied())),
            None => mesh.tets.iter().for_each(|t| mark(&mut t.iter().copied())),
        }
        r
    }

    /// The grid cell of a point of the box (clamped): monotone in each coordinate.
    fn cell(&self, p: Vec3) -> [usize; 3] {
        std::array::from_fn(|k| {
            let ext = self.hi[k] - self.lo[k];
            let t = if ext > 0.0 { (p[k] - self.lo[k]) / ext * GRID as f32 } else { 0.0 };
            (t.max(0.0) as usize).min(GRID - 1)
        })
    }

    /// Whether a point may be in one of the region's cells (false for NaN coordinates).
    #[inline]
    pub fn may_hold(&self, p: Vec3) -> bool {
        if !(0..3).all(|k| p[k] >= self.lo[k] && p[k] <= self.hi[k]) {
            return false;
        }
        let c = self.cell(p);
        let bit = (c[2] * GRID + c[1]) * GRID + c[0];
        self.occupied[bit / 64] & (1 << (bit % 64)) != 0
    }

    /// The region as words, for an allgather (fixed length: [`Region::WORDS`]).
    pub fn to_words(&self) -> Vec<u64> {
        let mut w = Vec::with_capacity(Self::WORDS);
        w.extend(self.lo.iter().chain(&self.hi).map(|&x| u64::from(x.to_bits())));
        w.extend_from_slice(&self.occupied);
        w
    }

    pub const WORDS: usize = 6 + WORDS;

    pub fn from_words(w: &[u64]) -> Region {
        let f = |i: usize| f32::from_bits(w[i] as u32);
        Region { lo: [f(0), f(1), f(2)], hi: [f(3), f(4), f(5)], occupied: w[6..Self::WORDS].to_vec() }
    }

    /// Fraction of the grid's cells that are marked (how tight the region is).
    pub fn occupancy(&self) -> f64 {
        self.occupied.iter().map(|w| w.count_ones() as f64).sum::<f64>() / (GRID * GRID * GRID) as f64
    }
}

/// A batch's routes: for each rank, the points sent to it, in the batch's order.
#[derive(Debug, Default)]
pub struct Routes {
    /// Points per rank.
    pub counts: Vec<usize>,
    /// The batch index of each sent point, rank after rank.
    pub index: Vec<u32>,
}

impl Routes {
    /// Routes every point to each rank whose region may hold it. Blocks of points are
    /// routed in parallel and their lists joined rank after rank, so each rank's points stay
    /// in the batch's order (the reduction relies on it).
    pub fn plan(points: &[Vec3], regions: &[Region]) -> Routes {
        use rayon::prelude::*;
        let blocks: Vec<Vec<Vec<u32>>> = points
            .par_chunks(BLOCK)
            .enumerate()
            .map(|(b, block)| {
                let base = (b * BLOCK) as u32;
                regions
                    .iter()
                    .map(|r| {
                        (0..block.len() as u32).filter(|&i| r.may_hold(block[i as usize])).map(|i| base + i).collect()
                    })
                    .collect()
            })
            .collect();
        let counts: Vec<usize> = (0..regions.len()).map(|r| blocks.iter().map(|b| b[r].len()).sum()).collect();
        // Each (rank, block) list to its place in `index`, in parallel.
        let mut index = vec![0u32; counts.iter().sum()];
        let mut slots: Vec<(&[u32], &mut [u32])> = Vec::with_capacity(regions.len() * blocks.len());
        let mut rest = &mut index[..];
        for r in 0..regions.len() {
            for b in &blocks {
                let (head, tail) = rest.split_at_mut(b[r].len());
                slots.push((&b[r], head));
                rest = tail;
            }
        }
        slots.into_par_iter().for_each(|(from, to)| to.copy_from_slice(from));
        Routes { counts, index }
    }

    /// The points to send (as `plan` was given them, or in another precision), rank after
    /// rank.
    pub fn gather<P: Copy + Send + Sync>(&self, points: &[P]) -> Vec<P> {
        use rayon::prelude::*;
        self.index.par_iter().map(|&i| points[i as usize]).collect()
    }
}

/// Points a task routes at once.
const BLOCK: usize = 1 << 16;

/// The largest f32 not above `x`.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}

/// The smallest f32 not below `x`.
fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_core::{partition, RawMesh};
    use tetloc_testdata::KuhnGrid;

    /// Every point inside a piece's cell is routed to that piece, and most of the box's empty
    /// space is not.
    #[test]
    fn regions_hold_every_point_of_their_cells() {
        // An L-shaped block: the pieces' boxes hold empty space.
        let m = KuhnGrid::new(8).jitter(0.3, 1).keep(|c| !(c[0] > 0.5 && c[1] > 0.5)).mesh("L");
        let parts = partition::rcb(&partition::cell_centroids(&m), 3);
        let regions: Vec<Region> = (0..3)
            .map(|k| {
                let cells: Vec<u32> = (0..m.n_cells() as u32).filter(|&c| parts[c as usize] == k).collect();
                let r = Region::of_mesh(&partition::piece(&m, &cells, "p").unwrap());
                assert_eq!(Region::from_words(&r.to_words()), r);
                r
            })
            .collect();
        // Corners and centroids of every cell, and points on the faces between pieces.
        let mut pts = partition::cell_centroids(&m);
        pts.extend(m.points.iter().copied());
        let routes = Routes::plan(&pts, &regions);
        for (c, &k) in parts.iter().enumerate() {
            let start: usize = routes.counts[..k as usize].iter().sum();
            let sent = &routes.index[start..start + routes.counts[k as usize]];
            assert!(sent.contains(&(c as u32)), "cell {c}'s centroid is not routed to its piece {k}");
            for &v in &m.tets[c] {
                let i = (m.n_cells() + v as usize) as u32;
                assert!(sent.contains(&i), "a corner of cell {c} is not routed to piece {k}");
            }
        }
        let whole = Region::of_mesh(&m);
        assert!(whole.occupancy() < 0.85 && !whole.may_hold([0.9, 0.9, 0.5]), "{}", whole.occupancy());
        assert!(!Region::empty().may_hold([0.0; 3]));
        assert!(!regions[0].may_hold([f32::NAN, 0.5, 0.5]));
    }

    /// A mesh far from the origin (its working copy is centred): the region is in the file's
    /// coordinates, the points' own, and holds every vertex and centroid there.
    #[test]
    fn far_from_the_origin_regions_are_in_file_coordinates() {
        let raw = KuhnGrid::new(4).jitter(0.25, 2).raw();
        let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
        let file: Vec<[f64; 3]> =
            raw.points.iter().map(|p| std::array::from_fn(|k| p[k] as f64 * 1000.0 + shift[k] + 1e-7)).collect();
        let raw = RawMesh { points: file.iter().map(|p| p.map(|c| c as f32)).collect(), points64: Some(file), ..raw };
        let m = Mesh::new(raw, "far").unwrap();
        assert!(!m.info.frame.is_identity());
        let r = Region::of_mesh(&m);
        for i in 0..m.points.len() as u32 {
            let p = m.vertex64(i).map(|c| c as f32);
            assert!(r.may_hold(p), "vertex {i} at {p:?}");
        }
        for t in m.tets.iter() {
            let c: [f64; 3] = std::array::from_fn(|k| t.iter().map(|&v| m.vertex64(v)[k]).sum::<f64>() / 4.0);
            assert!(r.may_hold(c.map(|x| x as f32)));
        }
        assert!(!r.may_hold(m.points[0]), "a working-frame point is far from the file's mesh");
    }

    /// Routed in parallel blocks, the plan is the serial one: each rank's points in order.
    #[test]
    fn plans_of_many_blocks_keep_the_order() {
        let m = KuhnGrid::new(4).mesh("cube");
        let parts = partition::rcb(&partition::cell_centroids(&m), 2);
        let regions: Vec<Region> = (0..2)
            .map(|k| {
                let cells: Vec<u32> = (0..m.n_cells() as u32).filter(|&c| parts[c as usize] == k).collect();
                Region::of_mesh(&partition::piece(&m, &cells, "p").unwrap())
            })
            .collect();
        let pts: Vec<Vec3> = (0..3 * BLOCK + 5)
            .map(|i| std::array::from_fn(|k| ((i * 7919 + k * 104_729) % 1013) as f32 / 1000.0))
            .collect();
        let routes = Routes::plan(&pts, &regions);
        let serial: Vec<u32> = regions
            .iter()
            .flat_map(|r| (0..pts.len() as u32).filter(|&i| r.may_hold(pts[i as usize])).collect::<Vec<_>>())
            .collect();
        assert_eq!(routes.index, serial);
        assert_eq!(routes.counts.iter().sum::<usize>(), serial.len());
        assert_eq!(routes.gather(&pts)[5], pts[serial[5] as usize]);
    }
}
