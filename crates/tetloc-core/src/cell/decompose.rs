//! The conforming tet decomposition of every cell, and which quad faces are warped.
//!
//! **The rule.** Each quad face splits along the diagonal through its vertex of smallest global
//! id; a cell is the cone from its corner of smallest global id (its *apex*) over the triangles
//! of the faces that do not contain that corner. Both halves depend on global ids only, so two
//! cells that share a face split it the same way: the decomposition of a conforming mesh is a
//! conforming tet mesh. A face that contains the apex needs no tets: its diagonal already runs
//! through the apex (the apex is its smallest id too), so the cone's tets fill it. This gives
//! 1 tet per tet, 2 per pyramid, 3 per wedge and 6 per hex, with no new points: the result of
//! Dompierre et al. (1999), who split hexes with no diagonal through the corner opposite the
//! apex into 5 tets instead; tetloc keeps 6 for one stride per type.
//!
//! For a cell whose faces are planar the decomposition covers exactly the cell (the convex
//! polytope, VTK's definition there). Across a warped (bilinear, non-planar) face it differs
//! from the cell by a thin sliver on either side of the face: there location refines with the
//! cell's own parametric coordinates.

use super::{Point, Shape};

/// A cell's tets as local corner indices, right-handed (positive volume) for a valid cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decomposition {
    tets: [[u8; 4]; 6],
    len: u8,
}

impl Decomposition {
    pub fn tets(&self) -> &[[u8; 4]] {
        &self.tets[..usize::from(self.len)]
    }
}

/// The triangles of a face (local corner indices, outward as the face is): a triangle itself,
/// or a quad split along the diagonal through its smallest global id (`ids` are the cell's
/// corner ids). Ties between equal ids (a degenerate cell) go to the first in face order.
pub fn face_split(face: &[u8], ids: &[u32]) -> Vec<[u8; 3]> {
    match *face {
        [a, b, c] => vec![[a, b, c]],
        [a, b, c, d] => {
            let smallest = (0..4).min_by_key(|&k| (ids[usize::from(face[k])], k)).unwrap();
            if smallest % 2 == 0 {
                vec![[a, b, c], [a, c, d]]
            } else {
                vec![[b, c, d], [b, d, a]]
            }
        }
        _ => unreachable!("faces have 3 or 4 corners"),
    }
}

/// The conforming decomposition of a cell of shape `shape` with corner ids `ids` (global,
/// `ids.len() == shape.n_corners()`).
pub fn decompose(shape: &Shape, ids: &[u32]) -> Decomposition {
    debug_assert_eq!(ids.len(), shape.n_corners());
    let apex = (0..ids.len()).min_by_key(|&k| (ids[k], k)).unwrap() as u8;
    let mut out = Decomposition { tets: [[0; 4]; 6], len: 0 };
    for face in shape.faces.iter().filter(|f| !f.contains(&apex)) {
        for [a, b, c] in face_split(face, ids) {
            // (a, b, c) faces outward, so the apex lies behind it: (a, c, b, apex) is right-handed.
            out.tets[usize::from(out.len)] = [a, c, b, apex];
            out.len += 1;
        }
    }
    out
}

/// For each face of a decomposition tet (face `i` is opposite tet vertex `i`), the cell face it
/// lies on, or `None` inside the cell.
pub fn tet_faces(shape: &Shape, tet: [u8; 4]) -> [Option<u8>; 4] {
    std::array::from_fn(|i| {
        let tri = (0..4).filter(|&k| k != i).map(|k| tet[k]);
        shape.faces.iter().position(|f| tri.clone().all(|v| f.contains(&v))).map(|f| f as u8)
    })
}

/// The shape of a face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaceKind {
    Triangle,
    /// A quad whose four corners are coplanar, exactly: its two triangles are the cell's face.
    Planar,
    /// A quad that is not (or not provably) planar: the cell's face is the bilinear patch.
    Warped,
}

/// Shewchuk's orient3d error bound (7 + 56ε)ε for f64, ε = 2⁻⁵³.
const ORIENT_BOUND_F64: f64 = (7.0 + 56.0 * f64::EPSILON / 2.0) * f64::EPSILON / 2.0;

/// Whether the quad `q` (in face order) is planar, exactly in f64: first with Shewchuk's
/// stage-A filter (a determinant above its error bound is certainly non-zero), and where that
/// cannot tell, exactly with expansion arithmetic.
pub fn classify_quad(q: [Point; 4]) -> FaceKind {
    let d = |u: Point| [u[0] - q[3][0], u[1] - q[3][1], u[2] - q[3][2]];
    let (a, b, c) = (d(q[0]), d(q[1]), d(q[2]));
    let (bc, cb) = (b[1] * c[2], c[1] * b[2]);
    let (ca, ac) = (c[1] * a[2], a[1] * c[2]);
    let (ab, ba) = (a[1] * b[2], b[1] * a[2]);
    let det = a[0] * (bc - cb) + b[0] * (ca - ac) + c[0] * (ab - ba);
    let permanent =
        (bc.abs() + cb.abs()) * a[0].abs() + (ca.abs() + ac.abs()) * b[0].abs() + (ab.abs() + ba.abs()) * c[0].abs();
    if det.abs() > ORIENT_BOUND_F64 * permanent || !exact::orient_is_zero(q) {
        FaceKind::Warped
    } else {
        FaceKind::Planar
    }
}

/// Exact arithmetic for the rare quads the filter cannot decide: every rounding error is kept
/// as a term (Knuth's two-sum, and the product's error by a fused multiply-add), then the terms
/// are summed exactly into a non-overlapping expansion (Shewchuk's Grow-Expansion), whose
/// largest term has the sign of the sum. Slow, and needed only within rounding of planar.
mod exact {
    use super::Point;

    fn two_sum(a: f64, b: f64) -> (f64, f64) {
        let s = a + b;
        let bb = s - a;
        (s, (a - (s - bb)) + (b - bb))
    }

    /// `a · b` as the sum of all the exact products of their terms.
    fn product(a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(2 * a.len() * b.len());
        for &x in a {
            for &y in b {
                let p = x * y;
                out.extend([p, x.mul_add(y, -p)]);
            }
        }
        out
    }

    /// Whether orient3d(q0, q1, q2, q3) is exactly zero.
    pub(super) fn orient_is_zero(q: [Point; 4]) -> bool {
        // Each difference exactly, as two terms.
        let d = |u: Point, k: usize| {
            let (s, e) = two_sum(u[k], -q[3][k]);
            [s, e]
        };
        let (a, b, c) = ([0, 1, 2].map(|k| d(q[0], k)), [0, 1, 2].map(|k| d(q[1], k)), [0, 1, 2].map(|k| d(q[2], k)));
        let mut terms = Vec::new();
        // det = Σ over the permutations (i, j, k) of sign · a_i · b_j · c_k.
        for (i, j, k, sign) in
            [(0, 1, 2, 1.0), (0, 2, 1, -1.0), (1, 0, 2, -1.0), (1, 2, 0, 1.0), (2, 0, 1, 1.0), (2, 1, 0, -1.0)]
        {
            terms.extend(product(&product(&a[i], &b[j]), &c[k]).into_iter().map(|t| sign * t));
        }
        // Grow-Expansion: add each term into a non-overlapping expansion, exactly.
        let mut expansion: Vec<f64> = Vec::new();
        for t in terms {
            let mut q = t;
            for e in expansion.iter_mut() {
                let (s, err) = two_sum(q, *e);
                *e = err;
                q = s;
            }
            expansion.push(q);
        }
        expansion.iter().all(|&e| e == 0.0)
    }
}

/// The kind of face `f` of a cell with corner points `corners`.
pub fn classify_face(shape: &Shape, f: usize, corners: &[Point]) -> FaceKind {
    match *shape.faces[f] {
        [_, _, _] => FaceKind::Triangle,
        [a, b, c, d] => classify_quad([a, b, c, d].map(|k| corners[usize::from(k)])),
        _ => unreachable!("faces have 3 or 4 corners"),
    }
}

/// The warped faces of a cell, as a bit set (bit `f` for face `f`).
pub fn warped_faces(shape: &Shape, corners: &[Point]) -> u8 {
    (0..shape.faces.len()).filter(|&f| classify_face(shape, f, corners) == FaceKind::Warped).fold(0, |m, f| m | 1 << f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::{hex, pyramid, tet, wedge};

    #[test]
    fn counts_per_shape() {
        for (shape, n) in [(&tet::SHAPE, 1), (&pyramid::SHAPE, 2), (&wedge::SHAPE, 3), (&hex::SHAPE, 6)] {
            let ids: Vec<u32> = (0..shape.n_corners() as u32).map(|i| 7 * i % 11 + 3).collect();
            assert_eq!(decompose(shape, &ids).tets().len(), n, "{}", shape.name);
        }
    }

    #[test]
    fn quad_split_follows_the_smallest_id() {
        assert_eq!(face_split(&[0, 1, 2, 3], &[5, 9, 7, 8]), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(face_split(&[0, 1, 2, 3], &[5, 4, 7, 8]), vec![[1, 2, 3], [1, 3, 0]]);
        assert_eq!(face_split(&[0, 1, 2, 3], &[5, 6, 7, 1]), vec![[1, 2, 3], [1, 3, 0]]);
    }

    #[test]
    fn planar_and_warped_quads() {
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(classify_quad(flat), FaceKind::Planar);
        // Tilted but exactly planar in f64: z = x + 2y on small integers.
        let tilted = [[0.0, 0.0, 0.0], [2.0, 0.0, 2.0], [2.0, 1.0, 4.0], [0.0, 1.0, 2.0]];
        assert_eq!(classify_quad(tilted), FaceKind::Planar);
        let mut warped = flat;
        warped[2][2] = 1e-9;
        assert_eq!(classify_quad(warped), FaceKind::Warped);
        // Planar in the reals but not in f64: 0.1 and 0.3 round, and z = x + y no longer holds
        // exactly; the filter cannot tell, the exact stage can.
        let rounded = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.1], [0.1, 0.2, 0.1 + 0.2], [0.0, 0.2, 0.2]];
        let exact_zero = [[0.0, 0.0, 0.0], [0.5, 0.0, 0.5], [0.5, 0.25, 0.75], [0.0, 0.25, 0.25]];
        assert_eq!(classify_quad(exact_zero), FaceKind::Planar);
        assert_eq!(classify_quad(rounded), FaceKind::Warped, "0.1 + 0.2 != 0.3 in f64");
        assert_eq!(classify_face(&hex::SHAPE, 4, hex::SHAPE.corners), FaceKind::Planar);
        assert_eq!(classify_face(&pyramid::SHAPE, 1, pyramid::SHAPE.corners), FaceKind::Triangle);
    }
}
