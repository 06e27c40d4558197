//! `SHAPE-octree`: a grid of `n³` hexahedra refined once (each into 8) inside a ball, as
//! snappyHexMesh and OpenFOAM's `refineMesh` leave it: the coarse cells beside refined ones
//! become polyhedra, their faces split where the fine cells meet them and with the hanging
//! nodes of their edges in their faces (so both cells of every face list the same points, as
//! OpenFOAM's meshes do). Under an affine map (chosen by the shape and the seed), every face
//! stays planar and every cell convex: the true cell of a point is known exactly (the grid
//! coordinates of its preimage), which is what the tests check against.
//!
//! The shape names only the map and the ball: its curved geometry is not kept (its jittered,
//! warped hexes would give warped polyhedron faces, whose cells are a definition rather than
//! a fact). Fields: `f` = 1 + 2x − 3y + 0.5z at the vertices (affine: interpolation must
//! reproduce it) and `cellval` per cell.

use super::Shape;
use crate::cell::{CellBlock, CellType};
use crate::mesh::{Field, FieldLocation, RawMesh};

/// Cells per coarse cube on average: a quarter of the cubes (about) are refined into 8.
pub(super) const CELLS_PER_CUBE: f64 = 1.0 + 7.0 * REFINED_SHARE;

/// The share of cubes inside the ball (radius 0.39 of the box: 4/3·π·0.39³ ≈ 0.248).
const REFINED_SHARE: f64 = 0.248;
const RADIUS: f64 = 0.39;

/// The affine field `f` (what the generated octree's `f` is, exactly).
pub fn field_f(p: [f64; 3]) -> f64 {
    1.0 + 2.0 * p[0] - 3.0 * p[1] + 0.5 * p[2]
}

/// The grid behind an octree mesh: `n` cubes a side, which are refined, and the map.
#[derive(Clone, Debug)]
pub struct Octree {
    pub n: usize,
    /// Row-major (`i` fastest): whether cube `(i, j, k)` is split into 8.
    pub refined: Vec<bool>,
    /// Point = `a · (grid coordinates / n) + offset`.
    pub a: [[f64; 3]; 3],
    pub offset: [f64; 3],
    /// For each cube, its first cell id (a refined cube's 8 cells follow in `(di, dj, dk)`
    /// order, `di` fastest).
    pub first_cell: Vec<u32>,
}

impl Octree {
    /// The grid for about `target_cells` cells.
    pub fn new(shape: Shape, target_cells: usize, seed: u64) -> Octree {
        let n = ((target_cells as f64 / CELLS_PER_CUBE).cbrt().round() as usize).max(2);
        let h = |x: usize| (x as f64 + 0.5) / n as f64 - 0.5;
        let refined: Vec<bool> = (0..n * n * n)
            .map(|c| {
                let (i, j, k) = (c % n, (c / n) % n, c / (n * n));
                h(i) * h(i) + h(j) * h(j) + h(k) * h(k) < RADIUS * RADIUS
            })
            .collect();
        // A shear and a stretch that depend on the shape and the seed: no face is axis-aligned.
        let s = (seed as f64 * 0.618_033_988_75 + shape as usize as f64 * 0.25).fract();
        let a = [[1.1 + 0.2 * s, -0.25, 0.05], [0.6 - 0.2 * s, 0.9, 0.2], [0.0, 0.1 * s, 1.1]];
        let mut first_cell = Vec::with_capacity(refined.len());
        let mut next = 0u32;
        for &r in &refined {
            first_cell.push(next);
            next += if r { 8 } else { 1 };
        }
        Octree { n, refined, a, offset: [3.0, -1.5, 0.75], first_cell }
    }

    fn cube(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.n * (j + self.n * k)
    }

    fn is_refined(&self, i: isize, j: isize, k: isize) -> bool {
        let n = self.n as isize;
        (0..n).contains(&i)
            && (0..n).contains(&j)
            && (0..n).contains(&k)
            && self.refined[self.cube(i as usize, j as usize, k as usize)]
    }

    /// The point of fine-lattice coordinates `l` (twice the grid coordinates).
    pub fn point(&self, l: [usize; 3]) -> [f64; 3] {
        let u = l.map(|x| x as f64 / (2 * self.n) as f64);
        std::array::from_fn(|r| self.offset[r] + (0..3).map(|c| self.a[r][c] * u[c]).sum::<f64>())
    }

    /// The grid coordinates (in cubes) of a point: the inverse map.
    pub fn grid_coords(&self, p: [f64; 3]) -> [f64; 3] {
        let a = &self.a;
        let d: [f64; 3] = std::array::from_fn(|r| p[r] - self.offset[r]);
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        // Cramer's rule, column by column.
        std::array::from_fn(|c| {
            let mut m = *a;
            (0..3).for_each(|r| m[r][c] = d[r]);
            let dc = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
            dc / det * self.n as f64
        })
    }

    /// The cell that holds grid coordinates `g` (in cubes), or `None` outside the grid.
    pub fn cell_at(&self, g: [f64; 3]) -> Option<usize> {
        let n = self.n as f64;
        if g.iter().any(|&x| !(0.0..n).contains(&x)) {
            return None;
        }
        let [i, j, k] = g.map(|x| x.floor() as usize);
        let c = self.cube(i, j, k);
        let first = self.first_cell[c] as usize;
        if !self.refined[c] {
            return Some(first);
        }
        let [di, dj, dk] = g.map(|x| usize::from(x.fract() >= 0.5));
        Some(first + di + 2 * dj + 4 * dk)
    }
}

/// The corners (cube corner codes `dx | dy << 1 | dz << 2`) of a cube's faces, outward, in
/// VTK's hexahedron face order.
const CUBE_FACES: [[usize; 4]; 6] =
    [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
/// The face neighbour across each of [`CUBE_FACES`].
const FACE_STEP: [[isize; 3]; 6] = [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]];
/// VTK's hexahedron node order as cube corner codes.
const HEX_ORDER: [usize; 8] = [0, 1, 3, 2, 4, 5, 7, 6];

/// Builds the mesh of [`Octree::new`].
pub(super) fn build(shape: Shape, target_cells: usize, seed: u64) -> RawMesh {
    let g = Octree::new(shape, target_cells, seed);
    let n = g.n;
    let m = 2 * n + 1; // fine lattice points a side
    let lattice = |l: [usize; 3]| l[0] + m * (l[1] + m * l[2]);
    // Which fine-lattice points exist: every coarse corner, and every point of a refined cube.
    let mut used = vec![false; m * m * m];
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                used[lattice([2 * i, 2 * j, 2 * k])] = true;
            }
        }
    }
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                if g.refined[g.cube(i, j, k)] {
                    for d in 0..27 {
                        used[lattice([2 * i + d % 3, 2 * j + (d / 3) % 3, 2 * k + d / 9])] = true;
                    }
                }
            }
        }
    }
    let mut id = vec![u32::MAX; m * m * m];
    let mut points64 = Vec::new();
    for (x, _) in used.iter().enumerate().filter(|(_, &u)| u) {
        id[x] = points64.len() as u32;
        points64.push(g.point([x % m, (x / m) % m, x / (m * m)]));
    }
    let at = |l: [usize; 3]| id[lattice(l)];
    let corner = |base: [usize; 3], c: usize, scale: usize| -> [usize; 3] {
        [base[0] + scale * (c & 1), base[1] + scale * ((c >> 1) & 1), base[2] + scale * ((c >> 2) & 1)]
    };
    let mid = |a: [usize; 3], b: [usize; 3]| -> [usize; 3] { std::array::from_fn(|r| (a[r] + b[r]) / 2) };
    let hex = CellType::from_vtk(12, 8).expect("hexahedra are known");

    let mut block = CellBlock::default();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let base = [2 * i, 2 * j, 2 * k];
                if g.refined[g.cube(i, j, k)] {
                    for s in 0..8 {
                        let sub = corner(base, s, 1);
                        block.push(hex, &HEX_ORDER.map(|c| at(corner(sub, c, 1))));
                    }
                    continue;
                }
                // A coarse cube: its faces, split where a refined cube meets them, and with the
                // hanging nodes of their edges.
                let mut faces: Vec<Vec<u32>> = Vec::with_capacity(6);
                let mut plain = true;
                for (f, step) in CUBE_FACES.iter().zip(FACE_STEP) {
                    let q = f.map(|c| corner(base, c, 2));
                    if g.is_refined(i as isize + step[0], j as isize + step[1], k as isize + step[2]) {
                        plain = false;
                        let o = mid(mid(q[0], q[1]), mid(q[2], q[3]));
                        for r in 0..4 {
                            let (a, b, d) = (q[r], q[(r + 1) % 4], q[(r + 3) % 4]);
                            faces.push(vec![at(a), at(mid(a, b)), at(o), at(mid(d, a))]);
                        }
                    } else {
                        let mut poly = Vec::with_capacity(8);
                        for r in 0..4 {
                            let (a, b) = (q[r], q[(r + 1) % 4]);
                            poly.push(at(a));
                            let e = mid(a, b);
                            if used[lattice(e)] {
                                plain = false;
                                poly.push(at(e));
                            }
                        }
                        faces.push(poly);
                    }
                }
                if plain {
                    block.push(hex, &HEX_ORDER.map(|c| at(corner(base, c, 2))));
                } else {
                    block.push_polyhedron(faces.iter().map(Vec::as_slice));
                }
            }
        }
    }
    let n_cells = block.len();
    let f: Vec<f64> = points64.iter().map(|&p| field_f(p)).collect();
    let fields = vec![
        Field::from_f64("f", FieldLocation::Vertex, f),
        Field::new("cellval", FieldLocation::Cell, (0..n_cells).map(|c| (c % 97) as f32).collect()),
    ];
    RawMesh {
        points: points64.iter().map(|p| p.map(|x| x as f32)).collect(),
        points64: crate::mesh::points64_if_needed(points64),
        tets: Vec::new(),
        fields,
        higher_order: None,
        cells: Some(block),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::locate::{BatchLocator, CellLocator, CpuLocator};
    use crate::mesh::Mesh;
    use std::sync::Arc;

    fn octree(cells: usize) -> (Octree, Arc<Mesh>) {
        let raw = build(Shape::Jets, cells, 3);
        (Octree::new(Shape::Jets, cells, 3), Arc::new(Mesh::new(raw, "octree").unwrap()))
    }

    #[test]
    fn counts_and_types() {
        let (g, mesh) = octree(3_000);
        let refined = g.refined.iter().filter(|&&r| r).count();
        assert!(refined > 0 && refined < g.refined.len());
        assert_eq!(mesh.n_cells(), g.refined.len() + 7 * refined);
        let poly = mesh.info.cell_types.get("polyhedron").copied().unwrap_or(0);
        assert!(poly > 0, "coarse cells beside refined ones are polyhedra");
        assert!((mesh.n_cells() as f64 - 3_000.0).abs() < 0.35 * 3_000.0, "{} cells", mesh.n_cells());
    }

    /// Every cell's vertex centroid, and random points, are in the cell the grid says; `f` is
    /// reproduced (linear precision, to rounding) at all of them.
    #[test]
    fn every_point_is_in_its_cell_with_the_affine_value() {
        let (g, mesh) = octree(4_000);
        let block = &mesh.cells.as_ref().unwrap().block;
        let mut points: Vec<[f64; 3]> = (0..block.len())
            .map(|c| {
                let nodes = block.nodes(c);
                let mut s = [0.0; 3];
                nodes.iter().for_each(|&v| (0..3).for_each(|r| s[r] += mesh.vertex64(v)[r]));
                s.map(|x| x / nodes.len() as f64)
            })
            .collect();
        let n_centroids = points.len();
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut rand = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = g.n as f64;
        for _ in 0..20_000 {
            let u = [rand(), rand(), rand()].map(|x| x * (n + 0.4) - 0.2);
            points.push(std::array::from_fn(|r| g.offset[r] + (0..3).map(|c| g.a[r][c] * u[c] / n).sum::<f64>()));
        }
        let mut loc = CellLocator::new(CpuLocator::new(mesh.clone()), mesh.clone());
        let (mut ids, mut values) = (vec![0; points.len()], vec![0.0; points.len()]);
        loc.sample_many64(&points, &["f"], &mut ids, &mut values).unwrap();
        let (mut checked, mut wrong, mut off) = (0, 0, 0);
        for (i, &p) in points.iter().enumerate() {
            let gc = g.grid_coords(p);
            // Points within rounding of a grid plane (of the fine lattice) have two right answers.
            if gc.iter().any(|&x| ((2.0 * x) - (2.0 * x).round()).abs() < 1e-9) {
                continue;
            }
            checked += 1;
            let want = g.cell_at(gc).map_or(-1, |c| c as i32);
            if i < n_centroids {
                assert_eq!(want, i as i32, "the centroid of cell {i} is in it");
            }
            if ids[i] != want {
                wrong += 1;
            }
            if want >= 0 && (values[i] - field_f(p)).abs() > 1e-12 * field_f(p).abs().max(1.0) {
                off += 1;
            }
        }
        assert!(checked > 20_000, "{checked}");
        assert_eq!((wrong, off), (0, 0), "of {checked} points: wrong cells, wrong values");
    }

    /// A piece of the mesh (what `partition` writes) keeps its polyhedra and their faces.
    #[test]
    fn pieces_keep_their_polyhedra() {
        let (_, mesh) = octree(2_000);
        let block = &mesh.cells.as_ref().unwrap().block;
        let cells: Vec<u32> = (0..block.len() as u32).filter(|c| c % 3 != 0).collect();
        let piece = crate::partition::piece(&mesh, &cells, "piece").unwrap();
        let pb = &piece.cells.as_ref().unwrap().block;
        assert_eq!(pb.len(), cells.len());
        for (k, &c) in cells.iter().enumerate() {
            assert_eq!(pb.types[k], block.types[c as usize]);
            let faces = |b: &CellBlock, c: usize, m: &Mesh| -> Option<Vec<Vec<[f64; 3]>>> {
                b.faces_of(c).map(|f| f.map(|f| f.iter().map(|&v| m.vertex64(v)).collect()).collect())
            };
            assert_eq!(faces(pb, k, &piece), faces(block, c as usize, &mesh), "cell {c}");
        }
    }

    /// No cracks: every face of the decomposition is shared by two tets, except the box's
    /// outer faces (split faces and hanging nodes are listed alike by both their cells).
    #[test]
    fn the_decomposition_is_conforming() {
        let (g, mesh) = octree(3_000);
        let faces = mesh.faces();
        let n = g.n as f64;
        let mut boundary = 0;
        for f in &faces.faces {
            if f.front >= 0 && f.back >= 0 {
                continue;
            }
            boundary += 1;
            let gc: Vec<[f64; 3]> = f.v.iter().map(|&v| g.grid_coords(mesh.vertex64(v))).collect();
            let on_box_side =
                (0..3).any(|r| gc.iter().all(|c| c[r].abs() < 1e-9) || gc.iter().all(|c| (c[r] - n).abs() < 1e-9));
            assert!(on_box_side, "a boundary face inside the box: {gc:?}");
        }
        assert!(boundary > 0 && faces.stats.n_non_manifold == 0);
    }
}
