//! Answers of a backend that decides on the working f32 copy (the GPU kernels), made exact on
//! the file's f64 data: each tet found is tested again with the exact test
//! (`geom::test_point_with`); when the exact test puts the point outside it, the tets around
//! it (face neighbours, three rings: 52 at most) are tested, and the one that holds the point
//! is the answer, or none when the exact test puts the point outside the mesh's boundary there.
//! An answer that holds the point on its boundary follows the tie rule
//! (`geom::lowest_holder`): the lowest tet that holds it.
//!
//! The working copy differs from the file's data by rounding only, so a wrong answer is one
//! for a point within rounding of a face, and the tet that holds it shares a vertex with the
//! one found: the cost is one tet test per point, a few more for the rare corrected ones.
//!
//! A point the backend put outside can be inside only within rounding of the mesh's boundary
//! (the working copy is watertight): such points are looked up in a BVH over the boxes of the
//! tets with a boundary face, grown by that rounding ([`Certifier`] builds it once), and the
//! tets around each one whose box holds the point are tested exactly. Points away from the boundary cost one
//! box test.

use crate::bvh::{Aabb, BuildPreset, Bvh, Visitor};
use crate::geom::{self, Bary, TetTest, Vec3};
use crate::mesh::Mesh;
use crate::OUTSIDE;
use rayon::prelude::*;
use std::sync::OnceLock;

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

/// Certification of one mesh's answers, keeping what it builds between batches: the
/// boundary tets' grown boxes, on the first point a backend puts outside.
#[derive(Default)]
pub struct Certifier {
    shell: OnceLock<Shell>,
}

impl Certifier {
    /// Corrects `tets` (tet ids, -1 outside) for `points` in place; returns the indices
    /// changed, each with the barycentrics of its point in its new tet (`None`: now outside),
    /// and with `every` also each point whose tet stands, with its barycentrics there: those
    /// of the exact test, on the file's coordinates and the point as given (a backend's
    /// values are of the point rounded to the working copy).
    pub fn certify(
        &self,
        mesh: &Mesh,
        points: &[[f64; 3]],
        tets: &mut [i32],
        every: bool,
    ) -> Vec<(usize, Option<Bary>)> {
        let exact = mesh.exact();
        let neighbors = mesh.neighbors();
        let frame = &mesh.info.frame;
        let finite = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
        // The shell is built here, not inside the parallel loop: its build runs on rayon
        // too, and a worker waiting in it could be handed another item of the loop and
        // re-enter the OnceLock it is initialising (a deadlock).
        if tets.par_iter().zip(points).any(|(&t, p)| t < 0 && finite(p)) {
            self.shell.get_or_init(|| Shell::build(mesh));
        }
        tets.par_iter_mut()
            .enumerate()
            .filter_map(|(i, t)| {
                let q = exact.query(points[i]);
                let holds = |t: i32| match geom::test_point_with(mesh.tets[t as usize], &mesh.points, &exact, &q) {
                    TetTest::Inside(b) => Some(b),
                    TetTest::Outside { .. } => None,
                };
                // The tie rule for an answer that holds the point on its boundary.
                let settle = |(t, b): (i32, Bary)| {
                    if b.contains(&0.0) {
                        geom::lowest_holder(t, b, neighbors, holds)
                    } else {
                        (t, b)
                    }
                };
                if *t < 0 {
                    // Inside only if within rounding of a boundary face: try the tets there.
                    if !finite(&points[i]) {
                        return None;
                    }
                    let shell = self.shell.get().expect("built before the loop");
                    let found = shell.find(frame.to_working(points[i]), |start| search(start, neighbors, &holds).0);
                    return found.map(settle).map(|(n, b)| {
                        *t = n;
                        (i, Some(b))
                    });
                }
                if let Some(b) = holds(*t) {
                    let (n, b) = settle((*t, b));
                    if n != *t {
                        *t = n;
                        return Some((i, Some(b)));
                    }
                    return every.then_some((i, Some(b)));
                }
                match search(*t, neighbors, &holds) {
                    (Some(found), _) => {
                        let (n, b) = settle(found);
                        *t = n;
                        Some((i, Some(b)))
                    }
                    // No tet near the one found holds the point: outside, if it is near the
                    // boundary (else the search was too short: keep the backend's answer).
                    (None, boundary) => boundary.then(|| {
                        *t = OUTSIDE;
                        (i, None)
                    }),
                }
            })
            .collect()
    }
}

/// The tet that holds the point among `start` and its face neighbours up to [`RINGS`] rings
/// (breadth first, each tet once), and whether a boundary face was crossed on the way.
fn search(start: i32, neighbors: &[[i32; 4]], holds: &impl Fn(i32) -> Option<Bary>) -> (Option<(i32, Bary)>, bool) {
    if let Some(b) = holds(start) {
        return (Some((start, b)), false);
    }
    let (mut ring, mut seen, mut boundary) = (vec![start], vec![start], false);
    for _ in 0..RINGS {
        let mut next = Vec::new();
        for &c in &ring {
            for &n in &neighbors[c as usize] {
                if n < 0 {
                    boundary = true;
                } else if !seen.contains(&n) {
                    if let Some(b) = holds(n) {
                        return (Some((n, b)), boundary);
                    }
                    seen.push(n);
                    next.push(n);
                }
            }
        }
        ring = next;
    }
    (None, boundary)
}

/// The tets with a boundary face, by their boxes in the working copy grown by more than the
/// rounding between it and the file's data (vertices and points alike).
struct Shell {
    tets: Vec<i32>,
    bvh: Bvh,
}

impl Shell {
    fn build(mesh: &Mesh) -> Shell {
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let big = (0..3).map(|k| lo[k].abs().max(hi[k].abs())).fold(0f32, f32::max);
        // Rounding to f32 moves a coordinate by half an ulp of its magnitude: 2^-21 of the
        // largest is 8 of those, plus the frame's bound on rounding the file's data.
        let grow = big * (1.0 / (1u32 << 21) as f32) + 4.0 * mesh.info.frame.delta;
        let tets: Vec<i32> = mesh
            .neighbors()
            .par_iter()
            .enumerate()
            .filter(|(_, n)| n.iter().any(|&n| n < 0))
            .map(|(t, _)| t as i32)
            .collect();
        let boxes: Vec<Aabb> = tets
            .par_iter()
            .map(|&t| {
                let b = Aabb::of_tet(mesh.tets[t as usize], &mesh.points);
                Aabb { min: b.min.map(|c| c - grow), max: b.max.map(|c| c + grow) }
            })
            .collect();
        Shell { tets, bvh: Bvh::build_boxes(&boxes, BuildPreset::Fast) }
    }

    /// The first answer of `search` from a boundary tet whose grown box holds `p`.
    fn find(&self, p: Vec3, search: impl Fn(i32) -> Option<(i32, Bary)>) -> Option<(i32, Bary)> {
        struct Find<'a, S> {
            shell: &'a Shell,
            p: Vec3,
            search: S,
            found: Option<(i32, Bary)>,
        }
        impl<S: Fn(i32) -> Option<(i32, Bary)>> Visitor for Find<'_, S> {
            fn enter(&mut self, b: &Aabb) -> bool {
                b.contains(self.p)
            }
            fn prim(&mut self, id: u32) -> bool {
                self.found = (self.search)(self.shell.tets[id as usize]);
                self.found.is_some()
            }
        }
        let mut f = Find { shell: self, p, search, found: None };
        self.bvh.traverse(&mut f);
        f.found
    }
}
