//! Answers of a backend that decides on the working f32 copy (the GPU kernels), made exact on
//! the file's f64 data: each tet found is tested again with the exact test
//! (`geom::test_point_with`); when the exact test puts the point outside it, the tets around
//! it (face neighbours, three rings: 52 at most) are tested, and the one that holds the point
//! is the answer, or none when the exact test puts the point outside the mesh's boundary there.
//!
//! The working copy differs from the file's data by rounding only, so a wrong answer is one
//! for a point within rounding of a face, and the tet that holds it shares a vertex with the
//! one found: the cost is one tet test per point, a few more for the rare corrected ones. A
//! point that the backend put outside is left outside: the working copy is watertight, so only
//! points within rounding of the mesh's boundary can be affected.

use crate::geom::{self, Bary, TetTest};
use crate::mesh::Mesh;
use crate::OUTSIDE;
use rayon::prelude::*;

/// Rings of face neighbours searched around a wrong answer.
const RINGS: usize = 3;

/// Whether the working copy's answers for `points` can differ from exact arithmetic on the
/// file's data: the mesh or some point does not survive the rounding to the working copy.
pub fn needs_certifying(mesh: &Mesh, points: &[[f64; 3]]) -> bool {
    let frame = &mesh.info.frame;
    mesh.points64.is_some()
        || !frame.is_identity()
        || points.par_iter().any(|p| p.iter().all(|c| c.is_finite()) && frame.to_working(*p).map(f64::from) != *p)
}

/// Corrects `tets` (tet ids, -1 outside) for `points` in place; returns the indices changed,
/// each with the barycentrics of its point in its new tet (`None`: now outside).
pub fn certify(mesh: &Mesh, points: &[[f64; 3]], tets: &mut [i32]) -> Vec<(usize, Option<Bary>)> {
    let exact = mesh.exact();
    let neighbors = mesh.neighbors();
    tets.par_iter_mut()
        .enumerate()
        .filter_map(|(i, t)| {
            if *t < 0 {
                return None;
            }
            let q = exact.query(points[i]);
            let holds = |t: i32| match geom::test_point_with(mesh.tets[t as usize], &mesh.points, &exact, &q) {
                TetTest::Inside(b) => Some(b),
                TetTest::Outside { .. } => None,
            };
            if holds(*t).is_some() {
                return None;
            }
            // Breadth first through face neighbours; a boundary face crossed means the point
            // may be outside.
            let (mut ring, mut seen, mut boundary) = (vec![*t], vec![*t], false);
            for _ in 0..RINGS {
                let mut next = Vec::new();
                for &c in &ring {
                    for &n in &neighbors[c as usize] {
                        if n < 0 {
                            boundary = true;
                        } else if !seen.contains(&n) {
                            if let Some(b) = holds(n) {
                                *t = n;
                                return Some((i, Some(b)));
                            }
                            seen.push(n);
                            next.push(n);
                        }
                    }
                }
                ring = next;
            }
            // No tet near the one found holds the point: outside, if it is near the boundary
            // (else the search was too short: keep the backend's answer).
            boundary.then(|| {
                *t = OUTSIDE;
                (i, None)
            })
        })
        .collect()
}
