//! VTK_POLYHEDRON (42): a cell given by its faces, each a polygon of point ids (OpenFOAM's
//! cells, VTK's polyhedra). Unlike the other types it has no reference shape: it is *defined*
//! by its conforming tet decomposition, and located and interpolated on it.
//!
//! **The decomposition.** Each face is split into triangles: a triangle is itself; a quad
//! splits along the diagonal through its smallest global id (the rule of every cell's quads,
//! [`super::face_split`], so a polyhedron and a hex that share a quad split it alike); a face
//! of 5 or more points is fanned from its centroid (the mean of its points, a new point shared
//! by every cell that has the face). The cell is the cone from its centroid (the mean of its
//! points, a new point) over those triangles. Shared faces split the same way from both
//! sides, so the decomposition of a conforming mesh is a conforming tet mesh: no cracks.
//!
//! For planar faces and a cell that is star-shaped from its centroid (every convex cell)
//! this is exactly the cell. For warped faces it is one watertight definition: the triangles
//! above, through the rounded f64 centroids. The centroids join the mesh's points after the
//! file's (`Mesh::points[n_file_points..]`).
//!
//! **Values.** Point data at a new point is the mean of the values at the points it is the
//! mean of; inside a tet it is linear. An affine field is therefore reproduced to rounding
//! (linear precision), and values are continuous across faces. (vtkPolyhedron uses mean value
//! coordinates, which also have linear precision; the two agree on affine fields.)

use super::{CellDef, PCoords, Shape};
use std::collections::HashMap;

/// A polyhedron has no reference shape: no corners, faces or domain. Nothing evaluates it
/// (the decomposition is the cell; see the module documentation).
pub static SHAPE: Shape =
    Shape { name: "polyhedron", corners: &[], faces: &[], center: [0.0; 3], domain: &[], linear: &Polyhedron };

/// VTK's code for polyhedra.
pub const VTK_POLYHEDRON: u8 = 42;

pub struct Polyhedron;

impl CellDef for Polyhedron {
    fn name(&self) -> &'static str {
        "polyhedron"
    }
    fn vtk_type(&self) -> u8 {
        VTK_POLYHEDRON
    }
    fn shape(&self) -> &'static Shape {
        &SHAPE
    }
    fn order(&self) -> u8 {
        1
    }
    fn node_pcoords(&self) -> &[PCoords] {
        &[]
    }
    fn shape_functions(&self, _: PCoords, _: &mut [f64]) {}
    fn shape_derivatives(&self, _: PCoords, _: &mut [[f64; 3]]) {}
}

/// The faces of a block's polyhedra, in the block's cell order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PolyFaces {
    /// The block's cells that are polyhedra, ascending.
    pub cells: Vec<u32>,
    /// Polyhedron `k`'s faces are `face_ends` entries `cell_ends[k − 1]..cell_ends[k]`.
    pub cell_ends: Vec<u64>,
    /// Face `j`'s points are `points[face_ends[j − 1]..face_ends[j]]`.
    pub face_ends: Vec<u64>,
    pub points: Vec<u32>,
}

impl PolyFaces {
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The number of faces, over all polyhedra (a shared face counted once per cell).
    pub fn n_faces(&self) -> usize {
        self.face_ends.len()
    }

    /// Which polyhedron (index into `cells`) cell `c` of the block is.
    pub fn index_of(&self, c: usize) -> Option<usize> {
        self.cells.binary_search(&(c as u32)).ok()
    }

    /// The faces of polyhedron `k` (index into `cells`).
    pub fn faces(&self, k: usize) -> impl Iterator<Item = &[u32]> + Clone + '_ {
        let start = if k == 0 { 0 } else { self.cell_ends[k - 1] as usize };
        (start..self.cell_ends[k] as usize).map(move |j| {
            let s = if j == 0 { 0 } else { self.face_ends[j - 1] as usize };
            &self.points[s..self.face_ends[j] as usize]
        })
    }

    /// Appends the polyhedron that is cell `cell` with faces `faces`.
    pub fn push<'a>(&mut self, cell: u32, faces: impl IntoIterator<Item = &'a [u32]>) {
        debug_assert!(self.cells.last().is_none_or(|&l| l < cell));
        for f in faces {
            self.points.extend_from_slice(f);
            self.face_ends.push(self.points.len() as u64);
        }
        self.cells.push(cell);
        self.cell_ends.push(self.face_ends.len() as u64);
    }

    /// Appends `other`'s polyhedra, their cell ids shifted by `cell_offset` and point ids by
    /// `id_offset`.
    pub fn append(&mut self, other: &PolyFaces, cell_offset: u32, id_offset: u32) {
        let (faces, points) = (self.face_ends.len() as u64, self.points.len() as u64);
        self.cells.extend(other.cells.iter().map(|c| c + cell_offset));
        self.cell_ends.extend(other.cell_ends.iter().map(|e| e + faces));
        self.face_ends.extend(other.face_ends.iter().map(|e| e + points));
        self.points.extend(other.points.iter().map(|p| p + id_offset));
    }
}

/// A polyhedron's distinct points, in the order its faces first list them: its node list.
pub fn distinct_points<'a>(faces: impl IntoIterator<Item = &'a [u32]>) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::new();
    for f in faces {
        for &p in f {
            if !out.contains(&p) {
                out.push(p);
            }
        }
    }
    out
}

/// Checks one polyhedron: every face has at least 3 distinct points, and the surface is
/// closed: every edge is on exactly two of its faces, or on one face and, on the other side,
/// split by hanging nodes (points on the edge, within 1e-9 of its length) into edges of other
/// faces (an octree's coarse cell beside refined ones). Errors name the cell.
pub fn validate<'a>(
    cell: usize,
    faces: impl IntoIterator<Item = &'a [u32]>,
    file: &dyn Fn(u32) -> [f64; 3],
) -> Result<(), String> {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    let mut n_faces = 0;
    for (j, f) in faces.into_iter().enumerate() {
        n_faces += 1;
        if f.len() < 3 {
            return Err(format!("polyhedron (cell {cell}): face {j} has {} points; a face needs at least 3", f.len()));
        }
        for (k, &a) in f.iter().enumerate() {
            if f[k + 1..].contains(&a) {
                return Err(format!("polyhedron (cell {cell}): face {j} lists point {a} twice"));
            }
            let b = f[(k + 1) % f.len()];
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    if n_faces < 4 {
        return Err(format!("polyhedron (cell {cell}) has {n_faces} faces; a closed polyhedron needs at least 4"));
    }
    let not_closed = |(a, b): (u32, u32), n: u32, count: usize| {
        format!(
            "polyhedron (cell {cell}) is not closed: its edge {a}-{b} is on {n} of its faces (every edge must be on 2, or be split by hanging nodes on the other side; {count} such edges)"
        )
    };
    if let Some((&e, &n)) = edges.iter().filter(|(_, &n)| n > 2).min() {
        return Err(not_closed(e, n, edges.values().filter(|&&n| n > 2).count()));
    }
    // Edges on one face only: each must be matched by a chain of others along it (longest
    // first: a chain's pieces are shorter than the edge they split).
    let length2 = |(a, b): (u32, u32)| dist2(file(a), file(b));
    let mut open: Vec<(u32, u32)> = edges.into_iter().filter(|&(_, n)| n == 1).map(|(e, _)| e).collect();
    open.sort_by(|&x, &y| length2(y).total_cmp(&length2(x)).then(x.cmp(&y)));
    let mut used = vec![false; open.len()];
    for i in 0..open.len() {
        if used[i] {
            continue;
        }
        let (a, b) = open[i];
        let (pa, pb) = (file(a), file(b));
        let on_edge = |m: u32| {
            let (u, v) = (sub(file(m), pa), sub(pb, pa));
            let (l2, t) = (dot(v, v), dot(u, v));
            t > 0.0 && t < l2 && dist2(cross(u, v), [0.0; 3]) <= 1e-18 * l2 * l2
        };
        // Walk from a to b through unused open edges whose points lie on a-b.
        let (mut at, mut path) = (a, Vec::new());
        while at != b {
            let next = (0..open.len()).find(|&j| {
                let (x, y) = open[j];
                let far = if x == at {
                    y
                } else if y == at {
                    x
                } else {
                    return false;
                };
                j != i && !used[j] && !path.contains(&j) && (far == b || on_edge(far))
            });
            match next {
                Some(j) => {
                    path.push(j);
                    at = if open[j].0 == at { open[j].1 } else { open[j].0 };
                }
                None => return Err(not_closed(open[i], 1, open.len() - used.iter().filter(|&&u| u).count())),
            }
        }
        used[i] = true;
        path.into_iter().for_each(|j| used[j] = true);
    }
    Ok(())
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// The decomposition of every polyhedron of a block: the new points (face and cell centroids)
/// and each polyhedron's tets (global ids, new points numbered from the file's count).
#[derive(Clone, Debug, Default)]
pub struct Decomposed {
    /// How many points the file has: new point `i` is vertex `n_file_points + i`.
    pub n_file_points: usize,
    /// The file points each new point is the mean of.
    pub means: Means,
    /// The new points' coordinates (the means, in f64).
    pub points: Vec<[f64; 3]>,
    /// Polyhedron `k`'s tets are `tets[tet_ends[k − 1]..tet_ends[k]]` (in no particular
    /// orientation: `Mesh::new` puts them in canonical order).
    pub tet_ends: Vec<u64>,
    pub tets: Vec<[u32; 4]>,
}

impl Decomposed {
    /// The tets of polyhedron `k`.
    pub fn tets_of(&self, k: usize) -> &[[u32; 4]] {
        let start = if k == 0 { 0 } else { self.tet_ends[k - 1] as usize };
        &self.tets[start..self.tet_ends[k] as usize]
    }

    /// Adds a new point, the mean of `of` (file point ids), and returns its vertex id.
    fn add_mean(&mut self, of: &[u32], file: &dyn Fn(u32) -> [f64; 3]) -> u32 {
        let mut sum = [0.0f64; 3];
        for &p in of {
            let x = file(p);
            (0..3).for_each(|k| sum[k] += x[k]);
        }
        self.points.push(sum.map(|s| s / of.len() as f64));
        self.means.sources.extend_from_slice(of);
        self.means.source_ends.push(self.means.sources.len() as u64);
        (self.n_file_points + self.points.len() - 1) as u32
    }
}

/// The file points each new point of a decomposition is the mean of: a per-vertex field's
/// values there (kept by the mesh, for every time step's fields).
#[derive(Clone, Debug, Default)]
pub struct Means {
    /// New point `i` is the mean of `sources[source_ends[i − 1]..source_ends[i]]`.
    source_ends: Vec<u64>,
    sources: Vec<u32>,
}

impl Means {
    /// The values of a per-vertex field at the new points: the means of its values at their
    /// sources.
    pub fn extend_values(&self, values: &[f64]) -> Vec<f64> {
        (0..self.source_ends.len())
            .map(|i| {
                let start = if i == 0 { 0 } else { self.source_ends[i - 1] as usize };
                let s = &self.sources[start..self.source_ends[i] as usize];
                s.iter().map(|&p| values[p as usize]).sum::<f64>() / s.len() as f64
            })
            .collect()
    }
}

/// Validates and decomposes `polys` (see the module documentation) over the file's points
/// (`file(i)`: point `i` in f64; `n_file_points` of them). Errors are messages naming the cell.
pub fn decompose_all(
    polys: &PolyFaces,
    n_file_points: usize,
    file: &dyn Fn(u32) -> [f64; 3],
) -> Result<Decomposed, String> {
    let mut out = Decomposed { n_file_points, ..Decomposed::default() };
    // A face of 5+ points has one centroid, whichever cell lists it (in whichever direction).
    let mut face_centroids: HashMap<Vec<u32>, u32> = HashMap::new();
    for (k, &cell) in polys.cells.iter().enumerate() {
        if let Some(&p) = polys.faces(k).flatten().find(|&&p| p as usize >= n_file_points) {
            return Err(format!(
                "polyhedron (cell {cell}) references vertex {p} but the mesh has only {n_file_points} vertices"
            ));
        }
        validate(cell as usize, polys.faces(k), file)?;
        let nodes = distinct_points(polys.faces(k));
        let apex = out.add_mean(&nodes, file);
        for f in polys.faces(k) {
            let triangles: Vec<[u32; 3]> = match *f {
                [a, b, c] => vec![[a, b, c]],
                [a, b, c, d] => {
                    let smallest = (0..4).min_by_key(|&i| f[i]).unwrap();
                    if smallest % 2 == 0 {
                        vec![[a, b, c], [a, c, d]]
                    } else {
                        vec![[b, c, d], [b, d, a]]
                    }
                }
                _ => {
                    let mut key = f.to_vec();
                    key.sort_unstable();
                    let centre = match face_centroids.get(&key) {
                        Some(&c) => c,
                        None => {
                            let c = out.add_mean(f, file);
                            face_centroids.insert(key, c);
                            c
                        }
                    };
                    (0..f.len()).map(|i| [centre, f[i], f[(i + 1) % f.len()]]).collect()
                }
            };
            out.tets.extend(triangles.into_iter().map(|[a, b, c]| [a, b, c, apex]));
        }
        out.tet_ends.push(out.tets.len() as u64);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube as a polyhedron (points 0..8 as the hex's corners), its top face split in
    /// two by an extra edge midpoint pair (points 8, 9) to give 5-point faces.
    fn cube() -> (Vec<[f64; 3]>, Vec<Vec<u32>>) {
        let mut pts = super::super::hex::SHAPE.corners.to_vec();
        pts.extend([[0.5, 0.0, 1.0], [0.5, 1.0, 1.0]]);
        let faces = vec![
            vec![0, 3, 2, 1],
            vec![4, 8, 9, 7],
            vec![8, 5, 6, 9],
            vec![0, 1, 5, 8, 4],
            vec![3, 7, 9, 6, 2],
            vec![0, 4, 7, 3],
            vec![1, 2, 6, 5],
        ];
        (pts, faces)
    }

    fn poly_faces(faces: &[Vec<u32>]) -> PolyFaces {
        let mut p = PolyFaces::default();
        p.push(0, faces.iter().map(Vec::as_slice));
        p
    }

    #[test]
    fn a_cube_with_split_faces_decomposes_into_its_volume() {
        let (pts, faces) = cube();
        let d = decompose_all(&poly_faces(&faces), pts.len(), &|i| pts[i as usize]).unwrap();
        // 1 cell centroid + 2 face centroids (the two 5-point faces).
        assert_eq!(d.points.len(), 3);
        assert_eq!(d.points[0], [0.5, 0.5, 0.6]);
        let all: Vec<[f64; 3]> = pts.iter().chain(&d.points).copied().collect();
        let vol: f64 = d
            .tets_of(0)
            .iter()
            .map(|t| {
                let [a, b, c, e] = t.map(|i| all[i as usize]);
                let s = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
                let (u, v, w) = (s(b, a), s(c, a), s(e, a));
                (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                    + u[2] * (v[0] * w[1] - v[1] * w[0]))
                    .abs()
                    / 6.0
            })
            .sum();
        assert!((vol - 1.0).abs() < 1e-12, "volume {vol}");
        // Five quads of 2 triangles and two pentagons fanned into 5.
        assert_eq!(d.tets_of(0).len(), 2 * 5 + 5 * 2);
        // Linear precision: an affine field's mean at each new point is its value there.
        let f = |p: [f64; 3]| 1.0 + 2.0 * p[0] - 3.0 * p[1] + 0.5 * p[2];
        let values: Vec<f64> = pts.iter().map(|&p| f(p)).collect();
        for (v, p) in d.means.extend_values(&values).iter().zip(&d.points) {
            assert!((v - f(*p)).abs() < 1e-14);
        }
    }

    #[test]
    fn shared_faces_get_one_centroid() {
        let (pts, faces) = cube();
        let mut polys = poly_faces(&faces);
        // The same cube again, its pentagon listed the other way round and from another start.
        let mut again = faces.clone();
        again[3] = vec![4, 8, 5, 1, 0];
        polys.push(1, again.iter().map(Vec::as_slice));
        let d = decompose_all(&polys, pts.len(), &|i| pts[i as usize]).unwrap();
        assert_eq!(d.points.len(), 2 + 2, "two cell centroids; the two pentagons' centroids once each");
    }

    #[test]
    fn hanging_nodes_close_a_polyhedron() {
        // The cube with its top split by the edge 8-9 but its front and back faces plain quads:
        // their top edges 4-5 and 7-6 are split by 8 and 9 on the top's side.
        let (pts, mut faces) = cube();
        faces[3] = vec![0, 1, 5, 4];
        faces[4] = vec![3, 7, 6, 2];
        let file = |i: u32| pts[i as usize];
        let d = decompose_all(&poly_faces(&faces), pts.len(), &file).unwrap();
        assert_eq!(d.points.len(), 1, "the cell centroid only: every face is a quad");
        // A hanging node off the edge's line is a hole, not a split edge.
        let mut off = pts.clone();
        off[8][2] = 1.1;
        let e = decompose_all(&poly_faces(&faces), off.len(), &|i| off[i as usize]).unwrap_err();
        assert!(e.contains("not closed"), "{e}");
    }

    #[test]
    fn bad_polyhedra_are_named() {
        let (pts, faces) = cube();
        let file = |i: u32| pts[i as usize];
        let mut open = faces.clone();
        open.pop();
        let e = decompose_all(&poly_faces(&open), pts.len(), &file).unwrap_err();
        assert!(e.contains("cell 0") && e.contains("not closed"), "{e}");
        let mut two = faces.clone();
        two[0] = vec![0, 3];
        let e = decompose_all(&poly_faces(&two), pts.len(), &file).unwrap_err();
        assert!(e.contains("face 0 has 2 points"), "{e}");
        let e = decompose_all(&poly_faces(&faces), 5, &file).unwrap_err();
        assert!(e.contains("references vertex"), "{e}");
        let mut twice = faces.clone();
        twice[0] = vec![0, 3, 0, 1];
        assert!(decompose_all(&poly_faces(&twice), pts.len(), &file).unwrap_err().contains("twice"));
    }
}
