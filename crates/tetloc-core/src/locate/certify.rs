//! Answers of a backend that decides on the working f32 copy (the GPU kernels), made exact on
//! the file's f64 data: each tet found is checked on the file's data, first by the signs of
//! the f32 filter alone (`geom::holds_strictly_by_filter`: strictly inside, proved, for almost
//! every point), else by the exact test (`geom::test_point_with`); when that puts the point
//! outside, the tets around it (face neighbours, three rings: 52 at most) are tested, and the
//! one that holds the point is the answer. Where they hold it on a face, edge or vertex, or
//! none of them holds it (a point within rounding of a vertex shared by many tets, whose
//! holder lies further off), the complete search decides: every tet whose box holds the
//! point (uniform bins of every tet, `bins.rs`), exact, with the tie rule (the lowest tet
//! that holds the point), built on the first such point. So the answers are the CPU's.
//! A backend that proves its own answers (the kernels' f32 filter with the copy's rounding,
//! CERTIFY_DELTA) marks the others (`-2 - tet`, [`unmarked`]), and only those are checked.
//!
//! The working copy differs from the file's data by rounding only, so a wrong answer is one
//! for a point within rounding of a face, and the tet that holds it shares a vertex with the
//! one found.
//!
//! A point the backend put outside can be inside only within rounding of the mesh's boundary
//! (the working copy is watertight; see `Shell`): a coarse grid of the cells that the
//! boundary tets' grown boxes meet rejects most such points with one bit, a BVH over those
//! boxes finds the tets near the rest, and those with a boundary face within the rounding's
//! reach are searched from (their rings), the complete search deciding what they do not.
use super::bins::Bins;
use super::cpu::BIN_EDGES;
use super::occupancy::Occupancy;
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
    mesh.wants_f64_points()
        || points.par_iter().any(|p| p.iter().all(|c| c.is_finite()) && frame.to_working(*p).map(f64::from) != *p)
}

/// Certification of one mesh's answers, keeping what it builds between batches: the
/// boundary tets' grown boxes, on the first point a backend puts outside.
#[derive(Default)]
pub struct Certifier {
    /// The backend finds every point its copy of the mesh holds (a search over every tet:
    /// soft-bvh, rt-bvh), so a point it puts outside is within rounding of the boundary;
    /// a backend that can stop at a face with no tet behind it (the face kernels, at a
    /// boundary or at a face that only one side's cells list) may miss a point anywhere near
    /// such a face (`Shell::near`).
    complete: bool,
    shell: OnceLock<Shell>,
    /// Every tet, binned: the complete search, where the rings and the shell do not decide.
    whole: OnceLock<Bins>,
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
    /// A certifier for a backend that finds every point its copy holds (`complete`), or one
    /// that may miss points near faces with no tet behind them.
    pub fn new(complete: bool) -> Certifier {
        Certifier { complete, ..Default::default() }
    }

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
        assert_eq!(points.len(), tets.len(), "a tet a point");
        self.certify_at(mesh, |i| points[i], tets, every, false)
    }

    /// [`Self::certify`] of the points that `point` gives by index (`0..tets.len()`): points
    /// made on the fly (f32 points widened, a grid's points) need no array of their own. With
    /// `marked`, the backend proved its non-negative answers (they stand) and marked those it
    /// did not as `-2 - tet` ([`unmarked`]): only those and the points outside are checked.
    /// Either way every mark is gone from `tets` on return.
    pub fn certify_at(
        &self,
        mesh: &Mesh,
        point: impl Fn(usize) -> [f64; 3] + Sync,
        tets: &mut [i32],
        every: bool,
        marked: bool,
    ) -> Vec<(usize, Option<Bary>)> {
        let exact = mesh.exact();
        let neighbors = mesh.neighbors();
        let frame = &mesh.info.frame;
        let finite = |p: &[f64; 3]| p.iter().all(|c| c.is_finite());
        // The shell is built here, not inside the parallel loop: its build runs on rayon
        // too, and a worker waiting in it could be handed another item of the loop and
        // re-enter the OnceLock it is initialising (a deadlock).
        if tets.par_iter().enumerate().any(|(i, &t)| t == OUTSIDE && finite(&point(i))) {
            self.shell.get_or_init(|| Shell::build(mesh));
        }
        let verdicts: Vec<(usize, Verdict)> = tets
            .par_iter()
            .enumerate()
            .filter_map(|(i, &t)| {
                if marked && t >= 0 && !every {
                    return None; // proved by the backend
                }
                let t = unmarked(t);
                let p = point(i);
                let q = exact.query(p);
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
                    if !finite(&p) {
                        return None;
                    }
                    let shell = self.shell.get().expect("built before the loop");
                    let near = shell.near(mesh, frame.to_working(p), self.complete);
                    if near.is_empty() {
                        return None;
                    }
                    match near.iter().find_map(|&start| search(start, neighbors, &holds)) {
                        Some(found) => settle(found),
                        None => Verdict::Search,
                    }
                } else if !every && geom::holds_strictly_by_filter(mesh.tets[t as usize], &mesh.points, &exact, &q) {
                    // Strictly inside by signs alone (almost every answer): it stands.
                    return None;
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
        // Marks off every answer (a backend may mark its answers even where they are all checked).
        tets.par_iter_mut().for_each(|t| *t = unmarked(*t));
        // The complete search, built here and not inside the parallel loop (see the shell).
        if verdicts.iter().any(|(_, v)| matches!(v, Verdict::Search)) {
            self.whole.get_or_init(|| Bins::build(mesh, BIN_EDGES));
        }
        let whole = self.whole.get();
        // (index, answer, whether it may differ from the backend's)
        let decided: Vec<(usize, Found, bool)> = verdicts
            .into_par_iter()
            .map(|(i, v)| match v {
                Verdict::Stands(b) => (i, Some((tets[i], b)), false),
                Verdict::Moves(t, b) => (i, Some((t, b)), true),
                Verdict::Search => {
                    let p = point(i);
                    let found = lowest_holder(whole.expect("built above"), mesh, &exact.query(p));
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
/// the lowest that holds it (the tie rule), as `CpuLocator::find`. The bins list every tet
/// whose box (working copy) meets them, and a box of the working copy holds the point's
/// working coordinates wherever the file's box holds the point: every holder is among its
/// bin's tets. (Bins, not a BVH: a grouping pass instead of a tree, several times cheaper to
/// build on a mesh of millions of tets, for the few points that need it.)
fn lowest_holder(bins: &Bins, mesh: &Mesh, q: &geom::predicates::Query) -> Found {
    let p = q.local;
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    if !(0..3).all(|k| lo[k] <= p[k] && p[k] <= hi[k]) {
        return None;
    }
    let mut tie = None;
    for t in bins.boxes_holding(mesh, bins.bin_of(p).0, p) {
        match geom::test_point_with(mesh.tets[t as usize], &mesh.points, &mesh.exact(), q) {
            TetTest::Inside(b) if !b.contains(&0.0) => return Some((t as i32, b)),
            TetTest::Inside(b) => geom::lowest_claim(&mut tie, (t, b)),
            TetTest::Outside { .. } => {}
        }
    }
    tie.map(|(t, b)| (t as i32, b))
}

/// A backend's answer without its mark: `-2 - tet` marks an answer the backend did not
/// prove on the file's data ([`Certifier::certify_at`] with `marked`); -1 is outside.
#[inline]
pub fn unmarked(id: i32) -> i32 {
    if id < OUTSIDE {
        -2 - id
    } else {
        id
    }
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
///
/// A point outside every tet of the copy but inside a tet T of the file's data is within that
/// rounding (`grow`) of T's copy, so the segment between them crosses the copy's boundary
/// within `grow` of the point: some boundary face lies within `grow` of it, and its tet's
/// grown box holds it. [`Shell::near`] keeps the tets of such faces only.
struct Shell {
    tets: Vec<i32>,
    bvh: Bvh,
    /// The cells the grown boxes meet: most points outside the mesh are far from all of
    /// them, known from a bit.
    cells: Occupancy,
    /// How far the copy's boundary may be from the file's (each box's growth).
    grow: f32,
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
        let cells = Occupancy::of_boxes(mesh, boxes.len(), |i| (boxes[i].min, boxes[i].max));
        Shell { tets, bvh: Bvh::build_boxes(&boxes, BuildPreset::Fast), cells, grow }
    }

    /// The boundary tets whose grown boxes hold `p` (working coordinates), and with
    /// `complete` (the backend missed no point of the copy) only those with a boundary face
    /// within twice `grow` of it: none, the point is farther than the rounding from the
    /// boundary, outside the file's mesh as it is outside the copy. Distances to the faces'
    /// planes in f64 from the copy's f32 vertices (relative error near 2^-50, against the
    /// rounding's 2^-21: the factor of two covers it).
    fn near(&self, mesh: &Mesh, p: Vec3, complete: bool) -> Vec<i32> {
        struct Near<'a> {
            shell: &'a Shell,
            mesh: &'a Mesh,
            p: Vec3,
            complete: bool,
            found: Vec<i32>,
        }
        impl Visitor for Near<'_> {
            fn enter(&mut self, b: &Aabb) -> bool {
                b.contains(self.p)
            }
            fn prim(&mut self, id: u32) -> bool {
                let t = self.shell.tets[id as usize];
                if !self.complete || face_near(self.mesh, t, self.p, 2.0 * f64::from(self.shell.grow)) {
                    self.found.push(t);
                }
                false
            }
        }
        let mut n = Near { shell: self, mesh, p, complete, found: Vec::new() };
        if self.cells.may_hold(p) {
            self.bvh.traverse(&mut n);
        }
        n.found
    }
}

/// Whether a face of tet `t` without a neighbour has its plane within `reach` of `p`.
fn face_near(mesh: &Mesh, t: i32, p: Vec3, reach: f64) -> bool {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let v = mesh.tets[t as usize].map(|i| mesh.points[i as usize].map(f64::from));
    let p = p.map(f64::from);
    (0..4).any(|opposite| {
        if mesh.neighbors()[t as usize][opposite] >= 0 {
            return false;
        }
        let [a, b, c] = [1, 2, 3].map(|k| v[(opposite + k) % 4]);
        let (e1, e2, q) = (sub(b, a), sub(c, a), sub(p, a));
        let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        let along = n[0] * q[0] + n[1] * q[1] + n[2] * q[2];
        along.abs() <= reach * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
    })
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
