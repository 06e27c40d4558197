//! The point-in-tet test on the exact predicates, with the tie rule: the f32 local filter
//! first, the file's f64 coordinates where it cannot decide.
//!
//! Tets must be **right-handed** (`geom::tet_volume6 > 0`, i.e. exact orient3d(v0, v1, v2, v3)
//! < 0, as canonical order makes them): a left-handed tet contains nothing here. Face `i` is
//! the face opposite stored vertex `i`, listed in [`FACES`] in the order that makes orient3d
//! positive inside. With exact signs, the order of a face's vertices does not change any
//! answer, so neighbours agree without sharing an evaluation order.
//!
//! **Degenerate tets contain nothing, with no check**: the four faces, oriented as
//! [`FACES`] lists them, have normals that sum to zero (for any four points). In a flat
//! tet they are all parallel to one plane normal, so they point both ways (or vanish,
//! and a vanishing face never says inside): no point, perturbed or not, is on the inner
//! side of all four.

use super::local::{orient3d_local, Vec3, FILTER_DELTA};
use super::orient::{orient3d, orient3d_sos, Point};
use super::Sign;

/// Face `i` of a right-handed tet, opposite stored vertex `i`: its three stored indices,
/// ordered so that orient3d(face, p) > 0 for p strictly inside (on vertex `i`'s side).
pub const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Where a point is relative to a tet, under the tie rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Inside,
    /// Outside: the first face (in [`FACES`] order) that the perturbed point is beyond, the
    /// face across which a walk continues.
    Outside {
        face: usize,
    },
}

/// A query point in both representations: `local` is the tet mesh's
/// [`super::LocalFrame::to_local`] of `file`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Query {
    pub local: Vec3,
    pub file: Point,
}

/// The test on f64 coordinates alone (exact stages and the tie rule, no local filter).
pub fn side_of_tet(v: [Point; 4], p: Point) -> Side {
    for (i, f) in FACES.iter().enumerate() {
        if orient3d_sos(v[f[0]], v[f[1]], v[f[2]], p) != Sign::Positive {
            return Side::Outside { face: i };
        }
    }
    Side::Inside
}

/// The staged test for tet `ids`: each face in f32 on the local coordinates `local` when
/// the bound decides, else exactly on the file's coordinates `file` (read only then).
/// Gives the same answer as [`side_of_tet`] on the file's coordinates.
pub fn side_of_tet_staged(ids: [u32; 4], local: &[Vec3], file: &[Point], p: &Query) -> Side {
    let v = ids.map(|i| local[i as usize]);
    for (i, f) in FACES.iter().enumerate() {
        let (det, bound) = orient3d_local(v[f[0]], v[f[1]], v[f[2]], p.local, FILTER_DELTA);
        let inside = if det > bound {
            true
        } else if det < -bound {
            false
        } else {
            let w = |k: usize| file[ids[f[k]] as usize];
            orient3d_sos(w(0), w(1), w(2), p.file) == Sign::Positive
        };
        if !inside {
            return Side::Outside { face: i };
        }
    }
    Side::Inside
}

/// Barycentric weights (of v0..v3) of a point that is inside the tet under the tie rule, in
/// f64 on the file's coordinates: each weight is a face's orient3d over their sum, each with
/// its exact sign, so a point on a face gets a weight of exactly 0 there and none is
/// negative. Accurate to a few ulps times the tet's condition (permanent over volume).
pub fn barycentrics(v: [Point; 4], p: Point) -> [f64; 4] {
    let d = FACES.map(|f| orient3d(v[f[0]], v[f[1]], v[f[2]], p).max(0.0));
    let total: f64 = d.iter().sum();
    d.map(|x| x / total)
}

/// What the staged test found (the f64 counterpart of `geom::TetTest`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ExactTest {
    /// Inside under the tie rule: f64 weights of the stored vertices.
    Inside([f64; 4]),
    /// Outside: see [`Side::Outside`].
    Outside { face: usize },
}

/// [`side_of_tet_staged`] and, inside, [`barycentrics`].
pub fn test_point_exact(ids: [u32; 4], local: &[Vec3], file: &[Point], p: &Query) -> ExactTest {
    match side_of_tet_staged(ids, local, file, p) {
        Side::Inside => ExactTest::Inside(barycentrics(ids.map(|i| file[i as usize]), p.file)),
        Side::Outside { face } => ExactTest::Outside { face },
    }
}
