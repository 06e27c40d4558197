//! A brute-force reference of the location design for tests: the conforming decomposition
//! located exactly, refined with the cells' parametric coordinates across warped faces. Cells
//! are found by a grid of their boxes; no BVH, no walk.

use super::*;
use crate::geom::{self, Vec3};
use crate::test_support::QuerySet;
use std::collections::HashMap;
use std::path::Path;

/// A mixed mesh as the reader hands it over, with f64 copies of its (f32) vertices.
pub(crate) struct Mixed {
    pub points32: Vec<Vec3>,
    pub points: Vec<Point>,
    pub cells: CellBlock,
    /// The point field `f`.
    pub f: Vec<f32>,
}

impl Mixed {
    pub fn load(path: &Path) -> Mixed {
        let raw = crate::test_support::read_raw(path, None).unwrap_or_else(|e| panic!("{e}"));
        let f = raw.fields.iter().find(|f| f.name == "f").expect("point field f").values.clone();
        let cells = raw.cells.expect("a mixed mesh has a cell block");
        let points = raw.points.iter().map(|p| p.map(f64::from)).collect();
        Mixed { points32: raw.points, points, cells, f }
    }

    /// An `n`³ grid of hexes on [0,1]³ whose interior vertices move by up to `jitter` cell widths
    /// (warping every interior face) and whose boundary vertices move only within the boundary
    /// (which stays the flat cube), with shuffled vertex ids so that the diagonals vary.
    pub fn warped_hex_grid(n: usize, jitter: f64, seed: u64) -> Mixed {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let h = 1.0 / n as f64;
        let mut ids: Vec<u32> = (0..(n + 1).pow(3) as u32).collect();
        for i in (1..ids.len()).rev() {
            ids.swap(i, rng.gen_range(0..=i));
        }
        let mut points32 = vec![[0.0f32; 3]; ids.len()];
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    let g = [i, j, k];
                    let v = ids[i + (n + 1) * (j + (n + 1) * k)] as usize;
                    points32[v] = std::array::from_fn(|a| {
                        let inner = g[a] > 0 && g[a] < n;
                        let d = if inner { rng.gen_range(-jitter..=jitter) } else { 0.0 };
                        ((g[a] as f64 + d) * h) as f32
                    });
                }
            }
        }
        let mut cells = CellBlock::default();
        let hex = CellType::from_vtk(12, 8).unwrap();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let corner =
                        |di: usize, dj: usize, dk: usize| ids[i + di + (n + 1) * (j + dj + (n + 1) * (k + dk))];
                    let c = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)];
                    cells.push(hex, &c.map(|(a, b, d)| corner(a, b, d)));
                }
            }
        }
        let points = points32.iter().map(|p| p.map(f64::from)).collect();
        Mixed { f: points32.iter().map(|p| p[0]).collect(), points32, points, cells }
    }

    pub fn corners(&self, c: usize) -> Vec<Point> {
        self.cells.corners(c).iter().map(|&i| self.points[i as usize]).collect()
    }

    /// The parametric coordinates of `p` in cell `c`, located by its corners.
    pub fn pcoords(&self, c: usize, p: Point) -> Result<PCoords, InverseError> {
        invert(self.cells.types[c].shape().linear, &self.corners(c), p)
    }

    /// VTK's definition: `p`'s parametric coordinates lie in `c`'s domain.
    pub fn holds(&self, c: usize, p: Point) -> bool {
        self.pcoords(c, p).is_ok_and(|pc| self.cells.types[c].shape().contains(pc))
    }

    pub fn value(&self, c: usize, pc: PCoords) -> f64 {
        let nodes = self.cells.nodes(c);
        interpolate(self.cells.types[c].def(), pc, |k| f64::from(self.f[nodes[k] as usize]))
    }
}

/// The location design on the CPU, by brute force: each cell's conforming decomposition (global
/// tet ids, canonical, tested with the one point-in-tet definition), then, in cells with a
/// warped face, the cell's parametric coordinates decide, stepping across a violated warped
/// face to the neighbour, and to outside across a warped boundary face; points outside every
/// decomposition tet are tested in the cells with a warped boundary face whose box holds them.
pub(crate) struct Design {
    /// The decomposition's tets, canonical, cell by cell: cell c has tets[first[c]..first[c + 1]].
    tets: Vec<[u32; 4]>,
    first: Vec<usize>,
    /// Bit f: face f of the cell is a warped quad.
    pub warped: Vec<u8>,
    /// The cell across each face, or -1 on the boundary.
    neighbours: Vec<[i32; 6]>,
    boxes: Vec<(Vec3, Vec3)>,
    grid: Grid,
}

impl Design {
    pub fn build(m: &Mixed) -> Design {
        let n = m.cells.len();
        let (mut tets, mut first, mut warped) = (Vec::new(), vec![0], Vec::with_capacity(n));
        let mut neighbours = vec![[-1i32; 6]; n];
        let mut faces: HashMap<Vec<u32>, (usize, usize)> = HashMap::new();
        let mut boxes = Vec::with_capacity(n);
        for c in 0..n {
            let shape = m.cells.types[c].shape();
            let ids = m.cells.corners(c);
            for t in decompose(shape, ids).tets() {
                tets.push(geom::canonical_tet(t.map(|k| ids[usize::from(k)]), &m.points32).0);
            }
            first.push(tets.len());
            warped.push(warped_faces(shape, &m.corners(c)));
            for (f, face) in shape.faces.iter().enumerate() {
                let mut key: Vec<u32> = face.iter().map(|&k| ids[usize::from(k)]).collect();
                key.sort_unstable();
                if let Some((d, g)) = faces.remove(&key) {
                    neighbours[c][f] = d as i32;
                    neighbours[d][g] = c as i32;
                } else {
                    faces.insert(key, (c, f));
                }
            }
            let corner = |k: usize| ids.iter().map(move |&i| m.points32[i as usize][k]);
            let lo = std::array::from_fn(|k| corner(k).fold(f32::INFINITY, f32::min));
            let hi = std::array::from_fn(|k| corner(k).fold(f32::NEG_INFINITY, f32::max));
            boxes.push((lo, hi));
        }
        let grid = Grid::new(&boxes);
        Design { tets, first, warped, neighbours, boxes, grid }
    }

    /// The cells whose box holds `p`, ascending.
    fn candidates(&self, p: Vec3) -> impl Iterator<Item = usize> + '_ {
        self.grid.bin(p).iter().map(|&c| c as usize).filter(move |&c| {
            let (lo, hi) = self.boxes[c];
            (0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k])
        })
    }

    /// The decomposition's answer: the first cell (by id) with a tet holding `p`.
    pub fn partition(&self, m: &Mixed, p: Vec3) -> Option<usize> {
        self.candidates(p).find(|&c| {
            self.tets[self.first[c]..self.first[c + 1]].iter().any(|t| geom::point_in_tet(*t, &m.points32, p).is_some())
        })
    }

    fn warped_boundary(&self, c: usize) -> bool {
        (0..6).any(|f| self.warped[c] & (1 << f) != 0 && self.neighbours[c][f] < 0)
    }

    /// The design's answer: -1 outside.
    pub fn locate(&self, m: &Mixed, p: Vec3) -> i32 {
        let p64 = p.map(f64::from);
        let Some(c) = self.partition(m, p) else {
            // Outside the decomposition, maybe inside a warped boundary face that bulges out.
            return self.candidates(p).find(|&c| self.warped_boundary(c) && m.holds(c, p64)).map_or(-1, |c| c as i32);
        };
        if self.warped[c] == 0 {
            return c as i32;
        }
        let shape = m.cells.types[c].shape();
        let Ok(pc) = m.pcoords(c, p64) else { return c as i32 };
        if shape.contains(pc) {
            return c as i32;
        }
        let mut through_boundary = false;
        for (face, _) in shape.violated(pc) {
            let Some(f) = face.map(usize::from) else { continue };
            if self.warped[c] & (1 << f) == 0 {
                continue;
            }
            match self.neighbours[c][f] {
                n if n >= 0 && m.holds(n as usize, p64) => return n,
                n if n >= 0 => {}
                _ => through_boundary = true,
            }
        }
        // Outside through a warped boundary face: VTK says outside. Otherwise keep the cell:
        // a point inside the mesh is never "outside".
        if through_boundary {
            -1
        } else {
            c as i32
        }
    }
}

/// A uniform grid over the cells' boxes: each bin lists the cells whose box meets it.
struct Grid {
    lo: Vec3,
    size: Vec3,
    dims: [usize; 3],
    bins: Vec<Vec<u32>>,
}

impl Grid {
    fn new(boxes: &[(Vec3, Vec3)]) -> Grid {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for b in boxes {
            for k in 0..3 {
                lo[k] = lo[k].min(b.0[k]);
                hi[k] = hi[k].max(b.1[k]);
            }
        }
        let side = (boxes.len() as f64).cbrt().ceil().max(1.0) as usize;
        let dims = [side; 3];
        let size: Vec3 = std::array::from_fn(|k| (hi[k] - lo[k]).max(f32::MIN_POSITIVE) / side as f32);
        let mut grid = Grid { lo, size, dims, bins: vec![Vec::new(); side * side * side] };
        for (c, b) in boxes.iter().enumerate() {
            let (a, z) = (grid.cell_of(b.0), grid.cell_of(b.1));
            for k in a[2]..=z[2] {
                for j in a[1]..=z[1] {
                    for i in a[0]..=z[0] {
                        let bin = i + dims[0] * (j + dims[1] * k);
                        grid.bins[bin].push(c as u32);
                    }
                }
            }
        }
        grid
    }

    fn cell_of(&self, p: Vec3) -> [usize; 3] {
        std::array::from_fn(|k| (((p[k] - self.lo[k]) / self.size[k]).max(0.0) as usize).min(self.dims[k] - 1))
    }

    fn bin(&self, p: Vec3) -> &[u32] {
        let c = self.cell_of(p);
        &self.bins[c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])]
    }
}

/// How a set's answers compare with the oracle's, outside the ambiguous points.
#[derive(Default, Debug, PartialEq)]
pub(crate) struct Mismatches {
    /// Oracle inside, answer outside: a crack.
    pub lost: usize,
    /// Oracle outside, answer inside.
    pub extra: usize,
    /// Both inside, different cells.
    pub other_cell: usize,
}

impl Mismatches {
    pub fn total(&self) -> usize {
        self.lost + self.extra + self.other_cell
    }
}

pub(crate) fn compare(set: &QuerySet, answer: impl Fn(Vec3) -> i32) -> Mismatches {
    let mut m = Mismatches::default();
    for (i, (&p, &want)) in set.points.iter().zip(&set.cell).enumerate() {
        let got = answer(p);
        if got == want || set.ambiguous(i) {
            continue;
        }
        match (want >= 0, got >= 0) {
            (true, false) => m.lost += 1,
            (false, true) => m.extra += 1,
            _ => m.other_cell += 1,
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]

        /// No cracks across warped faces: on random warped hex grids every point of the open
        /// cube (the mesh's domain) is in a cell, one that holds it by VTK's definition, and so
        /// is every point of the warped faces themselves; points outside the cube are outside.
        #[test]
        fn no_cracks_across_warped_faces(seed in any::<u64>()) {
            let m = Mixed::warped_hex_grid(4, 0.2, seed);
            let d = Design::build(&m);
            prop_assert!(d.warped.iter().filter(|&&w| w != 0).count() > 32, "the faces should be warped");
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let holds_nearly = |c: i32, p: Vec3| {
                let c = c as usize;
                m.pcoords(c, p.map(f64::from)).is_ok_and(|pc| m.cells.types[c].shape().margin(pc) >= -1e-6)
            };
            for _ in 0..2000 {
                let p: Vec3 = std::array::from_fn(|_| rng.gen_range(1e-4f32..1.0 - 1e-4));
                let c = d.locate(&m, p);
                prop_assert!(c >= 0, "a crack at {:?}", p);
                prop_assert!(holds_nearly(c, p), "cell {} does not hold {:?}", c, p);
            }
            // Points on the interior faces, through the faces' bilinear maps (then rounded).
            for c in 0..m.cells.len() {
                let shape = m.cells.types[c].shape();
                for (f, bound) in shape.domain.iter().enumerate() {
                    if d.neighbours[c][f] < 0 {
                        continue;
                    }
                    let mut pc: PCoords = std::array::from_fn(|_| rng.gen_range(0.0..1.0));
                    let k = bound.normal.iter().position(|&x| x != 0.0).unwrap();
                    pc[k] = bound.offset;
                    let p = forward(shape.linear, &m.corners(c), pc).map(|x| x as f32);
                    let got = d.locate(&m, p);
                    prop_assert!(got >= 0, "a crack on face {} of cell {} at {:?}", f, c, p);
                    prop_assert!(holds_nearly(got, p), "cell {} does not hold {:?}", got, p);
                }
            }
            for p in [[1.0001f32, 0.5, 0.5], [0.5, -1e-4, 0.5], [0.3, 0.6, 1.2]] {
                prop_assert_eq!(d.locate(&m, p), -1);
            }
        }
    }
}
