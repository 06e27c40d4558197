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
use crate::geom::predicates::expansion::{two_sum, Expansion};
use crate::geom::predicates::orient::{orient3d_exact, orient3d_stage_a};

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

/// Whether the quad `q` (in face order) is planar, exactly in f64: orient3d of its corners is
/// exactly zero. The f64 filter proves most warped quads warped; every planar quad needs an
/// exact answer, so the cheap exact ones go first (planar faces are most faces of most meshes;
/// reading a 200k-cell hybrid spent most of its time here, issue 30):
/// 1. the four corners share a coordinate (an axis-aligned face: structured grids, layers);
/// 2. their differences from `q[3]` are exact in f64 (coordinates of like magnitude, as in most
///    generated meshes): the 3×3 determinant of those, summed exactly from 24 terms;
/// 3. else [`orient3d_exact`], the full exact sum (96 terms).
pub fn classify_quad(q: [Point; 4]) -> FaceKind {
    /// The six permutations of three axes with their signs: a 3×3 determinant's terms.
    const PERMUTATIONS_3: [(f64, [usize; 3]); 6] =
        [(1.0, [0, 1, 2]), (-1.0, [0, 2, 1]), (-1.0, [1, 0, 2]), (1.0, [1, 2, 0]), (1.0, [2, 0, 1]), (-1.0, [2, 1, 0])];
    let planar = |zero: bool| if zero { FaceKind::Planar } else { FaceKind::Warped };
    let (det, bound) = orient3d_stage_a(q[0], q[1], q[2], q[3]);
    if det.abs() > bound {
        return FaceKind::Warped;
    }
    if (0..3).any(|k| q[0][k] == q[3][k] && q[1][k] == q[3][k] && q[2][k] == q[3][k]) {
        return FaceKind::Planar;
    }
    let mut d = [[0.0; 3]; 3];
    let mut exact = true;
    for (row, p) in d.iter_mut().zip(&q[..3]) {
        for k in 0..3 {
            let (diff, round_off) = two_sum(p[k], -q[3][k]);
            row[k] = diff;
            exact &= round_off == 0.0;
        }
    }
    if exact {
        let mut sum = Expansion::<24>::new();
        for (sign, [i, j, k]) in PERMUTATIONS_3 {
            sum.add_triple_product(sign, d[0][i], d[1][j], d[2][k]);
        }
        return planar(sum.sign() == 0.0);
    }
    planar(orient3d_exact(q[0], q[1], q[2], q[3]).sign() == 0.0)
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
        // Each exact path: a shared coordinate; exact differences (a vertical, not axis-aligned
        // face); differences that round (coordinates of very different magnitudes).
        let vertical = [[0.0, 0.0, 0.0], [3.0, 1.0, 0.0], [3.0, 1.0, 2.0], [0.0, 0.0, 2.0]];
        assert_eq!(classify_quad(vertical), FaceKind::Planar);
        let mut leaning = vertical;
        leaning[2][0] = 3.0 + 2.0f64.powi(-40);
        assert_eq!(classify_quad(leaning), FaceKind::Warped);
        let mixed_scales = [[1e-20, 0.0, 1e-20], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [1e-20, 1.0, 1e-20]]; // z = x
        assert_eq!(classify_quad(mixed_scales), FaceKind::Planar);
        let mut off = mixed_scales;
        off[3][2] = 2e-20;
        assert_eq!(classify_quad(off), FaceKind::Warped);
        assert_eq!(classify_face(&pyramid::SHAPE, 1, pyramid::SHAPE.corners), FaceKind::Triangle);
    }
}
