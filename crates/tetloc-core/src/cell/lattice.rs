//! Cells whose nodes lie on an equispaced lattice and whose shape functions are the Lagrange
//! (or Bernstein) polynomials of that lattice: the complete tets, wedges and hexes of any
//! order. VTK's quadratic tet (24), triquadratic hex (29) and biquadratic-quadratic wedge (32)
//! are the order-2 members; the Lagrange (71–73) and Bezier (78) types are all of them. Each
//! cell module gives only its node order (a lattice point per node) and its codes.

use super::scalar::{self, Scalar};
use super::{CellDef, GmshType, PCoords, Shape};

/// How the lattice's polynomials are built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Family {
    /// Simplex Lagrange in the barycentrics (r, s, t, 1 − r − s − t).
    Tet,
    /// Triangle Lagrange in (r, s, 1 − r − s) times line Lagrange in t.
    Wedge,
    /// Line Lagrange in r, s and t.
    Hex,
    /// Bernstein polynomials in the tet's barycentrics (Bezier tets: control points, not nodes).
    BezierTet,
}

/// A cell defined by its lattice: node `i` sits at `lattice[i] / order` in (r, s, t).
pub(crate) struct LatticeCell {
    pub name: &'static str,
    pub vtk: u8,
    pub gmsh: Vec<GmshType>,
    pub shape: &'static Shape,
    pub family: Family,
    pub order: u8,
    pub lattice: Vec<[u8; 3]>,
    pub pcoords: Vec<PCoords>,
}

impl LatticeCell {
    pub fn new(
        name: &'static str,
        vtk: u8,
        shape: &'static Shape,
        family: Family,
        order: u8,
        lattice: Vec<[u8; 3]>,
    ) -> LatticeCell {
        let p = f64::from(order);
        let pcoords = lattice.iter().map(|l| l.map(|x| f64::from(x) / p)).collect();
        LatticeCell { name, vtk, gmsh: Vec::new(), shape, family, order, lattice, pcoords }
    }

    /// Adds the Gmsh element type whose nodes sit on the lattice points `gmsh_lattice`, in
    /// Gmsh's order: the node permutation follows by matching the points.
    pub fn with_gmsh(mut self, code: u8, gmsh_lattice: &[[u8; 3]]) -> LatticeCell {
        assert_eq!(gmsh_lattice.len(), self.lattice.len(), "{}: Gmsh type {code} has another node count", self.name);
        let vtk_from_gmsh = self
            .lattice
            .iter()
            .map(|l| {
                let g = gmsh_lattice.iter().position(|g| g == l);
                u16::try_from(g.expect("every VTK node is a Gmsh node")).expect("node counts fit u16")
            })
            .collect::<Vec<_>>();
        self.gmsh.push(GmshType { code, n_nodes: gmsh_lattice.len(), vtk_from_gmsh: vtk_from_gmsh.into() });
        self
    }

    fn eval<T: Scalar>(&self, pc: [T; 3], w: &mut [T]) {
        let p = self.order;
        let one = T::from(1.0);
        match self.family {
            Family::Tet => {
                let u = one - pc[0] - pc[1] - pc[2];
                for (wi, l) in w.iter_mut().zip(&self.lattice) {
                    let b = p - l[0] - l[1] - l[2];
                    *wi =
                        simplex(p, l[0], pc[0]) * simplex(p, l[1], pc[1]) * simplex(p, l[2], pc[2]) * simplex(p, b, u);
                }
            }
            Family::Wedge => {
                let u = one - pc[0] - pc[1];
                for (wi, l) in w.iter_mut().zip(&self.lattice) {
                    let b = p - l[0] - l[1];
                    *wi = simplex(p, l[0], pc[0]) * simplex(p, l[1], pc[1]) * simplex(p, b, u) * line(p, l[2], pc[2]);
                }
            }
            Family::Hex => {
                for (wi, l) in w.iter_mut().zip(&self.lattice) {
                    *wi = line(p, l[0], pc[0]) * line(p, l[1], pc[1]) * line(p, l[2], pc[2]);
                }
            }
            Family::BezierTet => {
                let u = one - pc[0] - pc[1] - pc[2];
                for (wi, l) in w.iter_mut().zip(&self.lattice) {
                    let b = [l[0], l[1], l[2], p - l[0] - l[1] - l[2]];
                    let multinomial = factorial(p) / b.iter().map(|&k| factorial(k)).product::<f64>();
                    *wi = pow(pc[0], b[0]) * pow(pc[1], b[1]) * pow(pc[2], b[2]) * pow(u, b[3]) * multinomial;
                }
            }
        }
    }
}

impl CellDef for LatticeCell {
    fn name(&self) -> &'static str {
        self.name
    }
    fn vtk_type(&self) -> u8 {
        self.vtk
    }
    fn gmsh_types(&self) -> &[GmshType] {
        &self.gmsh
    }
    fn shape(&self) -> &'static Shape {
        self.shape
    }
    fn order(&self) -> u8 {
        self.order
    }
    fn node_pcoords(&self) -> &[PCoords] {
        &self.pcoords
    }
    fn interpolates_nodes(&self) -> bool {
        self.family != Family::BezierTet
    }
    fn shape_functions(&self, pc: PCoords, w: &mut [f64]) {
        self.eval(pc, w);
    }
    fn shape_derivatives(&self, pc: PCoords, d: &mut [[f64; 3]]) {
        scalar::derivatives(pc, d, |pc, w| self.eval(pc, w));
    }
}

/// The 1-D Lagrange polynomial of node `a` on the nodes 0, 1/p, …, 1.
fn line<T: Scalar>(p: u8, a: u8, x: T) -> T {
    let mut v = T::from(1.0);
    for m in (0..=p).filter(|&m| m != a) {
        v = (x * f64::from(p) - T::from(f64::from(m))) * v * (1.0 / (f64::from(a) - f64::from(m)));
    }
    v
}

/// The simplex factor ∏_{m<a} (pλ − m)/(m + 1): 1 at λ = a/p, 0 at λ = m/p for every m < a.
/// A node's shape function is the product of these over its barycentric lattice indices.
fn simplex<T: Scalar>(p: u8, a: u8, lambda: T) -> T {
    let mut v = T::from(1.0);
    for m in 0..a {
        v = (lambda * f64::from(p) - T::from(f64::from(m))) * v * (1.0 / f64::from(m + 1));
    }
    v
}

fn pow<T: Scalar>(x: T, k: u8) -> T {
    (0..k).fold(T::from(1.0), |acc, _| acc * x)
}

fn factorial(k: u8) -> f64 {
    (1..=k).map(f64::from).product()
}

// ---------------------------------------------------------------------------------------------
// Node orders. Lattice points are (i, j, k) = p · (r, s, t).

/// VTK's node order of a Lagrange (or Bezier) tet of order `p` (vtkHigherOrderTetra): corners,
/// edge nodes, face nodes (each face a smaller triangle, recursively), then the interior as a
/// tet of order p − 4, recursively.
pub(crate) fn vtk_tet(p: u8) -> Vec<[u8; 3]> {
    let p = usize::from(p);
    let n = (p + 1) * (p + 2) * (p + 3) / 6;
    (0..n)
        .map(|index| {
            let b = vtk_tet_barycentric(index, p as i64);
            [b[0], b[1], b[2]].map(|x| u8::try_from(x).expect("lattice indices fit u8"))
        })
        .collect()
}

/// VTK's barycentric index (r, s, t, u) of node `index` of a tet of order `order`.
fn vtk_tet_barycentric(mut index: usize, mut order: i64) -> [i64; 4] {
    // The barycentric index of each corner has its maximum in this coordinate.
    const CORNER_MAX: [usize; 4] = [3, 0, 1, 2];
    const CORNERS: [[i64; 4]; 4] = [[0, 0, 0, 1], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
    const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];
    // Per face: the coordinates its triangle's barycentric index fills, and the one held at its minimum.
    const FACE_COORDS: [[usize; 3]; 4] = [[0, 2, 3], [2, 0, 1], [2, 1, 3], [1, 0, 3]];
    const FACE_MIN: [usize; 4] = [1, 3, 0, 2];
    let (mut max, mut min) = (order, 0);
    // Skip the boundary shells of 2(p² + 1) nodes each, down to the nested tet holding the node.
    while index != 0 && order > 3 && index >= usize::try_from(2 * (order * order + 1)).unwrap() {
        index -= usize::try_from(2 * (order * order + 1)).unwrap();
        max -= 3;
        min += 1;
        order -= 4;
    }
    let mut b = [min; 4];
    let per_edge = usize::try_from(order - 1).unwrap_or(0);
    if index < 4 {
        b[CORNER_MAX[index]] = max;
    } else if index - 4 < 6 * per_edge {
        let (edge, along) = ((index - 4) / per_edge, ((index - 4) % per_edge) as i64);
        let [e0, e1] = EDGES[edge];
        for (k, bk) in b.iter_mut().enumerate() {
            *bk = min + CORNERS[e0][k] * (max - min - 1 - along) + CORNERS[e1][k] * (1 + along);
        }
    } else {
        let per_face = (per_edge - 1) * per_edge / 2;
        let (face, within) = ((index - 4 - 6 * per_edge) / per_face, (index - 4 - 6 * per_edge) % per_face);
        let projected = if order == 3 { [0; 3] } else { vtk_triangle_barycentric(within, order - 3) };
        for (i, &c) in FACE_COORDS[face].iter().enumerate() {
            b[c] = min + 1 + projected[i];
        }
        b[FACE_MIN[face]] = min;
    }
    b
}

/// VTK's barycentric index of node `index` of a triangle of order `order` (vtkHigherOrderTriangle).
fn vtk_triangle_barycentric(mut index: usize, mut order: i64) -> [i64; 3] {
    let (mut max, mut min) = (order, 0);
    while index != 0 && index >= usize::try_from(3 * order).unwrap() {
        index -= usize::try_from(3 * order).unwrap();
        max -= 2;
        min += 1;
        order -= 3;
    }
    let mut b = [0; 3];
    if index < 3 {
        b[index] = min;
        b[(index + 1) % 3] = min;
        b[(index + 2) % 3] = max;
    } else {
        let per_edge = usize::try_from(order - 1).unwrap();
        let (dim, offset) = ((index - 3) / per_edge, ((index - 3) % per_edge) as i64);
        b[(dim + 1) % 3] = min;
        b[(dim + 2) % 3] = max - 1 - offset;
        b[dim] = min + 1 + offset;
    }
    b
}

/// VTK's node order of a Lagrange hex of order `p` in every direction
/// (vtkHigherOrderHexahedron::PointIndexFromIJK, inverted).
pub(crate) fn vtk_hex(p: u8) -> Vec<[u8; 3]> {
    let n = (usize::from(p) + 1).pow(3);
    let mut out = vec![[u8::MAX; 3]; n];
    for k in 0..=p {
        for j in 0..=p {
            for i in 0..=p {
                out[vtk_hex_index(i.into(), j.into(), k.into(), p.into())] = [i, j, k];
            }
        }
    }
    out
}

fn vtk_hex_index(i: usize, j: usize, k: usize, p: usize) -> usize {
    let on = |x: usize| x == 0 || x == p;
    let corner = |i: usize, j: usize| match (i > 0, j > 0) {
        (false, false) => 0,
        (true, false) => 1,
        (true, true) => 2,
        (false, true) => 3,
    };
    let (q, mut offset) = (p - 1, 8);
    match (on(i), on(j), on(k)) {
        (true, true, true) => corner(i, j) + if k > 0 { 4 } else { 0 },
        // Edges: the 4 bottom ones (along r at s = 0, along s at r = 1, along r at s = 1, along
        // s at r = 0), the 4 top ones, then the 4 vertical ones; each runs in +r, +s or +t.
        (false, true, true) => offset + (i - 1) + if j > 0 { 2 * q } else { 0 } + if k > 0 { 4 * q } else { 0 },
        (true, false, true) => offset + (j - 1) + if i > 0 { q } else { 3 * q } + if k > 0 { 4 * q } else { 0 },
        (true, true, false) => offset + 8 * q + (k - 1) + q * corner(i, j),
        (ibdy, jbdy, kbdy) => {
            offset += 12 * q;
            let face = q * q;
            if ibdy {
                return offset + (j - 1) + q * (k - 1) + if i > 0 { face } else { 0 };
            }
            offset += 2 * face;
            if jbdy {
                return offset + (i - 1) + q * (k - 1) + if j > 0 { face } else { 0 };
            }
            offset += 2 * face;
            if kbdy {
                return offset + (i - 1) + q * (j - 1) + if k > 0 { face } else { 0 };
            }
            offset += 2 * face;
            offset + (i - 1) + q * ((j - 1) + q * (k - 1))
        }
    }
}

/// VTK's node order of a Lagrange wedge of order `p` in every direction
/// (vtkHigherOrderWedge::PointIndexFromIJK, inverted).
pub(crate) fn vtk_wedge(p: u8) -> Vec<[u8; 3]> {
    let pu = usize::from(p);
    let n = (pu + 1) * (pu + 1) * (pu + 2) / 2;
    let mut out = vec![[u8::MAX; 3]; n];
    for k in 0..=p {
        for j in 0..=p {
            for i in 0..=(p - j) {
                out[vtk_wedge_index(i.into(), j.into(), k.into(), pu)] = [i, j, k];
            }
        }
    }
    out
}

fn vtk_wedge_index(i: usize, j: usize, k: usize, p: usize) -> usize {
    let q = p - 1;
    let (ibdy, jbdy, ijbdy, kbdy) = (i == 0, j == 0, i + j == p, k == 0 || k == p);
    let n_bdy = [ibdy, jbdy, ijbdy, kbdy].iter().filter(|&&b| b).count();
    // The triangle corner (0: r = s = 0, 1: r = 1, 2: s = 1) of a point on two triangle edges.
    let corner = || {
        if ibdy && jbdy {
            0
        } else if jbdy && ijbdy {
            1
        } else {
            2
        }
    };
    // Interior points of a triangle of order p, row by row (VTK's triangleDOFOffset).
    let tri_offset = |i: usize, j: usize| i + p * (j - 1) - j * (j + 1) / 2;
    let mut offset = 6;
    if n_bdy == 3 {
        return corner() + if k > 0 { 3 } else { 0 };
    }
    if n_bdy == 2 {
        if !kbdy {
            // A vertical edge.
            return offset + 6 * q + (k - 1) + corner() * (p - 1);
        }
        // A triangle edge: the bottom three (r-axis, hypotenuse, s-axis) then the top three.
        offset += if k == p { 3 * q } else { 0 };
        if jbdy {
            return offset + i - 1;
        }
        offset += q;
        if ijbdy {
            return offset + j - 1;
        }
        offset += q;
        return offset + (p - j - 1);
    }
    offset += 6 * q + 3 * q;
    let (tri_face, quad_face) = (q.saturating_sub(1) * q / 2, q * q);
    if n_bdy == 1 {
        if kbdy {
            return offset + if k > 0 { tri_face } else { 0 } + tri_offset(i, j);
        }
        offset += 2 * tri_face;
        if jbdy {
            return offset + (i - 1) + q * (k - 1);
        }
        offset += quad_face;
        if ijbdy {
            return offset + (j - 1) + q * (k - 1);
        }
        offset += quad_face;
        return offset + (p - j - 1) + q * (k - 1);
    }
    offset += 2 * tri_face + 3 * quad_face;
    offset + tri_offset(i, j) + tri_face * (k - 1)
}

/// Gmsh's node order of a complete tet of order `p` (gmshGenerateMonomialsTetrahedron): corners,
/// `p − 1` nodes per edge along the edges (0,1) (1,2) (2,0) (3,0) (3,2) (3,1), the face nodes of
/// the faces (0,2,1) (0,1,3) (0,3,2) (3,1,2) as triangles of order p − 3, then the interior as a
/// tet of order p − 4, recursively.
pub(crate) fn gmsh_tet(p: u8) -> Vec<[u8; 3]> {
    let p = i64::from(p);
    gmsh_tet_i64(p).into_iter().map(|v| v.map(|x| u8::try_from(x).expect("lattice fits u8"))).collect()
}

fn gmsh_tet_i64(p: i64) -> Vec<[i64; 3]> {
    if p == 0 {
        return vec![[0; 3]];
    }
    let v = [[0, 0, 0], [p, 0, 0], [0, p, 0], [0, 0, p]];
    let mut out = v.to_vec();
    let along =
        |a: [i64; 3], b: [i64; 3], i: i64| -> [i64; 3] { std::array::from_fn(|c| a[c] + (b[c] - a[c]) / p * i) };
    if p > 1 {
        for [a, b] in [[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]] {
            out.extend((1..p).map(|i| along(v[a], v[b], i)));
        }
    }
    if p > 2 {
        let inner = gmsh_triangle(p - 3);
        for [a, b, c] in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [3, 1, 2]] {
            for &[x, y] in &inner {
                let (x, y) = (x + 1, y + 1);
                out.push(std::array::from_fn(|k| v[a][k] + (v[b][k] - v[a][k]) / p * x + (v[c][k] - v[a][k]) / p * y));
            }
        }
    }
    if p > 3 {
        out.extend(gmsh_tet_i64(p - 4).into_iter().map(|x| x.map(|c| c + 1)));
    }
    out
}

/// Gmsh's node order of a complete triangle of order `p` (gmshGenerateMonomialsTriangle).
fn gmsh_triangle(p: i64) -> Vec<[i64; 2]> {
    if p == 0 {
        return vec![[0, 0]];
    }
    let v = [[0, 0], [p, 0], [0, p]];
    let mut out = v.to_vec();
    if p > 1 {
        for [a, b] in [[0, 1], [1, 2], [2, 0]] {
            out.extend((1..p).map(|i| [v[a][0] + (v[b][0] - v[a][0]) / p * i, v[a][1] + (v[b][1] - v[a][1]) / p * i]));
        }
    }
    if p > 2 {
        out.extend(gmsh_triangle(p - 3).into_iter().map(|x| x.map(|c| c + 1)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    /// Every node order is a permutation of the whole lattice.
    #[test]
    fn node_orders_cover_their_lattices() {
        for p in 1..=8u8 {
            let in_tet = |l: &[u8; 3]| l.iter().map(|&x| u16::from(x)).sum::<u16>() <= u16::from(p);
            for (what, nodes, n, inside) in [
                (
                    "vtk tet",
                    vtk_tet(p),
                    (p as usize + 1) * (p as usize + 2) * (p as usize + 3) / 6,
                    &in_tet as &dyn Fn(&[u8; 3]) -> bool,
                ),
                ("gmsh tet", gmsh_tet(p), (p as usize + 1) * (p as usize + 2) * (p as usize + 3) / 6, &in_tet),
                ("vtk hex", vtk_hex(p), (p as usize + 1).pow(3), &|l: &[u8; 3]| l.iter().all(|&x| x <= p)),
                ("vtk wedge", vtk_wedge(p), (p as usize + 1).pow(2) * (p as usize + 2) / 2, &|l: &[u8; 3]| {
                    u16::from(l[0]) + u16::from(l[1]) <= u16::from(p) && l[2] <= p
                }),
            ] {
                assert_eq!(nodes.len(), n, "{what} order {p}");
                assert!(nodes.iter().all(inside), "{what} order {p}: {nodes:?}");
                assert_eq!(nodes.iter().collect::<HashSet<_>>().len(), n, "{what} order {p}: repeated nodes");
            }
        }
    }

    /// VTK's cubic Lagrange tet, written out in vtkHigherOrderTetra's terms: corners, two nodes
    /// per edge from its first vertex, then one node per face (faces 013, 123, 203, 021).
    #[test]
    fn cubic_tet_order() {
        let want: [[u8; 3]; 20] = [
            [0, 0, 0],
            [3, 0, 0],
            [0, 3, 0],
            [0, 0, 3],
            [1, 0, 0],
            [2, 0, 0],
            [2, 1, 0],
            [1, 2, 0],
            [0, 2, 0],
            [0, 1, 0],
            [0, 0, 1],
            [0, 0, 2],
            [2, 0, 1],
            [1, 0, 2],
            [0, 2, 1],
            [0, 1, 2],
            [1, 0, 1],
            [1, 1, 1],
            [0, 1, 1],
            [1, 1, 0],
        ];
        assert_eq!(vtk_tet(3), want);
    }
}
