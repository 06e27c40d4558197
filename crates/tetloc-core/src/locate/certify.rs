//! Answers of a backend that decides on the working f32 copy (the GPU kernels), made exact on
//! the file's f64 data: each tet found is tested again with the exact test
//! (`geom::test_point_with`); when the exact test puts the point outside it, the tets around
//! it (face neighbours, three rings: 52 at most) are tested, and the one that holds the point
//! is the answer. Where they hold it on a face, edge or vertex, or none of them holds it (a
//! point within rounding of a vertex shared by many tets, whose holder lies further off), the
//! complete search decides: a BVH over every tet, exact, with the tie rule (the lowest tet
//! that holds the point), built on the first such point. So the answers are the CPU's.
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
    /// Every tet: the complete search, where the rings and the shell do not decide.
    whole: OnceLock<Bvh>,
}

/// A tet that holds the point, with its weights; `None`: outside.
type Found = Option<(i32, Bary)>;

/// What the parallel pass makes of one answer.
enum Verdict {
    Stands(Bary),
    Moves(i32, Bary),
    /// The complete search decides.
    Search,
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
        let verdicts: Vec<(usize, Verdict)> = tets
            .par_iter()
            .enumerate()
            .filter_map(|(i, &t)| {
                let q = exact.query(points[i]);
                let holds = |t: i32| match geom::test_point_with(mesh.tets[t as usize], &mesh.points, &exact, &q) {
                    TetTest::Inside(b) => Some(b),
                    TetTest::Outside { .. } => None,
                };
                // A holder that holds the point strictly inside is the only one; on its boundary
                // the tie rule needs every holder.
                let settle =
                    |(t, b): (i32, Bary)| if b.contains(&0.0) { Verdict::Search } else { Verdict::Moves(t, b) };
                let verdict = if t < 0 {
                    // Inside only if within rounding of a boundary face: try the tets there.
                    if !finite(&points[i]) {
                        return None;
                    }
                    let shell = self.shell.get().expect("built before the loop");
                    match shell.find(frame.to_working(points[i]), |start| search(start, neighbors, &holds)) {
                        Some(found) => settle(found),
                        None if shell.near(frame.to_working(points[i])) => Verdict::Search,
                        None => return None,
                    }
                } else if let Some(b) = holds(t) {
                    match b.contains(&0.0) {
                        true => Verdict::Search,
                        false if every => Verdict::Stands(b),
                        false => return None,
                    }
                } else {
                    match search(t, neighbors, &holds) {
                        Some(found) => settle(found),
                        None => Verdict::Search,
                    }
                };
                Some((i, verdict))
            })
            .collect();
        // The complete search, built here and not inside the parallel loop (see the shell).
        if verdicts.iter().any(|(_, v)| matches!(v, Verdict::Search)) {
            self.whole.get_or_init(|| Bvh::build(&mesh.points, &mesh.tets, BuildPreset::Fast));
        }
        let whole = self.whole.get();
        // (index, answer, whether it may differ from the backend's)
        let decided: Vec<(usize, Found, bool)> = verdicts
            .into_par_iter()
            .map(|(i, v)| match v {
                Verdict::Stands(b) => (i, Some((tets[i], b)), false),
                Verdict::Moves(t, b) => (i, Some((t, b)), true),
                Verdict::Search => {
                    let found = lowest_holder(
                        whole.expect("built above"),
                        mesh,
                        &exact.query(points[i]),
                        frame.to_working(points[i]),
                    );
                    (i, found, true)
                }
            })
            .collect();
        decided
            .into_iter()
            .filter_map(|(i, found, changes)| {
                let t = found.map_or(OUTSIDE, |(t, _)| t);
                let moved = changes && t != tets[i];
                tets[i] = t;
                (moved || every).then_some((i, found.map(|(_, b)| b)))
            })
            .collect()
    }
}

/// The complete search on the file's data: the tet that holds the point strictly inside, or
/// the lowest that holds it (the tie rule), as `CpuLocator::find` (boxes of the working copy
/// hold the point's working coordinates wherever the file's boxes hold the point).
fn lowest_holder(bvh: &Bvh, mesh: &Mesh, q: &geom::predicates::Query, p: Vec3) -> Found {
    struct Lowest<'a> {
        mesh: &'a Mesh,
        q: &'a geom::predicates::Query,
        p: Vec3,
        tie: Option<(u32, Bary)>,
        strict: Option<(u32, Bary)>,
    }
    impl Visitor for Lowest<'_> {
        fn enter(&mut self, b: &Aabb) -> bool {
            b.contains(self.p)
        }
        fn prim(&mut self, id: u32) -> bool {
            let m = self.mesh;
            match geom::test_point_with(m.tets[id as usize], &m.points, &m.exact(), self.q) {
                TetTest::Inside(b) if !b.contains(&0.0) => {
                    self.strict = Some((id, b));
                    true
                }
                TetTest::Inside(b) => {
                    geom::lowest_claim(&mut self.tie, (id, b));
                    false
                }
                TetTest::Outside { .. } => false,
            }
        }
    }
    let mut l = Lowest { mesh, q, p, tie: None, strict: None };
    bvh.traverse(&mut l);
    l.strict.or(l.tie).map(|(t, b)| (t as i32, b))
}

/// The tet that holds the point among `start` and its face neighbours up to [`RINGS`] rings
/// (breadth first, each tet once).
fn search(start: i32, neighbors: &[[i32; 4]], holds: &impl Fn(i32) -> Option<Bary>) -> Option<(i32, Bary)> {
    if let Some(b) = holds(start) {
        return Some((start, b));
    }
    let (mut ring, mut seen) = (vec![start], vec![start]);
    for _ in 0..RINGS {
        let mut next = Vec::new();
        for &c in &ring {
            for &n in &neighbors[c as usize] {
                if n >= 0 && !seen.contains(&n) {
                    if let Some(b) = holds(n) {
                        return Some((n, b));
                    }
                    seen.push(n);
                    next.push(n);
                }
            }
        }
        ring = next;
    }
    None
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

    /// Whether some boundary tet's grown box holds `p` (the point is within rounding of the
    /// boundary).
    fn near(&self, p: Vec3) -> bool {
        self.find(p, |t| Some((t, [0.0; 4]))).is_some()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::locate::CpuLocator;
    use rand::{Rng, SeedableRng};
    use std::sync::Arc;

    /// A mesh stored in f64 (vertices moved by up to 4e-8 off the f32 grid), queried at its
    /// vertices rounded to f32 (within rounding of the vertex: held by one of the many tets
    /// around it, or by none), at its exact vertices (ties) and at random points: the answers
    /// of a backend that searches the working copy, certified, are the CPU's on the f64 data.
    #[test]
    fn certified_answers_are_the_searchs_on_f64_data() {
        let mut raw = crate::test_support::jittered_grid(6, 0.3, 2);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let p64: Vec<[f64; 3]> =
            raw.points.iter().map(|p| p.map(|c| f64::from(c) + rng.gen_range(-4e-8..4e-8))).collect();
        raw.points = p64.iter().map(|p| p.map(|c| c as f32)).collect();
        let working = Arc::new(Mesh::new(raw.clone(), "working copy").unwrap());
        raw.points64 = Some(p64.clone());
        let mesh = Arc::new(Mesh::new(raw, "f64").unwrap());
        assert!(working.points == mesh.points, "the working copy is the f64 mesh rounded");
        let mut points: Vec<[f64; 3]> = p64.iter().map(|p| p.map(|c| f64::from(c as f32))).collect();
        points.extend(&p64);
        points.extend((0..3000).map(|_| -> [f64; 3] { std::array::from_fn(|_| rng.gen_range(-0.05..1.05)) }));
        // The backend: the exact test on the working copy (as the GPU kernels), tie rule included.
        let backend = CpuLocator::new(working);
        let mut ids: Vec<i32> = points
            .iter()
            .map(|p| backend.locate_point(p.map(|c| c as f32)).map_or(OUTSIDE, |(t, _)| t as i32))
            .collect();
        let before = ids.clone();
        Certifier::default().certify(&mesh, &points, &mut ids, false);
        let cpu = CpuLocator::new(mesh.clone());
        for (i, p) in points.iter().enumerate() {
            let want = cpu.locate_point64(*p).map_or(OUTSIDE, |(t, _)| t as i32);
            assert_eq!(ids[i], want, "point {i} {p:?} (backend {})", before[i]);
        }
        let corrected = ids.iter().zip(&before).filter(|(a, b)| a != b).count();
        assert!(corrected > 50, "only {corrected} answers corrected: the test does not reach the certifier");
    }
}
