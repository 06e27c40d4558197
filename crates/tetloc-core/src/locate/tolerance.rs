//! The boundary tolerance: a point outside the mesh but within a distance `D` of its boundary
//! is assigned to the nearest boundary cell, with the value interpolated at the closest point
//! of the boundary, so that samples on (or rounded just off) the boundary get an answer, as
//! with VTK's probe filter and its tolerance.
//!
//! It is a post-pass over the points a backend answered [`OUTSIDE`] for, so it works the same
//! over every backend; points inside are never changed, and tolerance 0 (the default) is the
//! exact answer. Ties: the nearest boundary triangle, and among equally near ones the first
//! in the mesh's face order (faces sorted by vertex ids), whatever the traversal order.
//!
//! The search runs in the mesh's working frame (`mesh::Frame`: centred and scaled for a mesh
//! far from the origin), on query points taken there in f64; values are the file's, in f64
//! for f64 values and rounded to f32 for f32 ones.

use super::{check_sample_lengths, BatchLocator, Points, Values, OUTSIDE};
use crate::bvh::{Aabb, BuildPreset, Bvh, Visitor};
use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// A boundary tolerance: an absolute distance, or a percentage of the mesh's mean edge length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tolerance {
    /// In mesh units.
    Absolute(f64),
    /// Percent of [`crate::MeshInfo::mean_edge_length`].
    PercentOfMeanEdge(f64),
}

impl Default for Tolerance {
    fn default() -> Self {
        Tolerance::Absolute(0.0)
    }
}

impl std::str::FromStr for Tolerance {
    type Err = Error;
    /// `0.01` (mesh units) or `5%` (of the mean edge length); finite and not negative.
    fn from_str(s: &str) -> Result<Tolerance> {
        let t = s.trim();
        let (num, percent) = match t.strip_suffix('%') {
            Some(n) => (n.trim(), true),
            None => (t, false),
        };
        match num.parse::<f64>() {
            Ok(v) if v.is_finite() && v >= 0.0 => {
                Ok(if percent { Tolerance::PercentOfMeanEdge(v) } else { Tolerance::Absolute(v) })
            }
            _ => Err(Error::Invalid(format!(
                "tolerance '{s}': expected a distance that is not negative (e.g. 0.001) or a percentage of the mean edge length (e.g. 1%)"
            ))),
        }
    }
}

impl std::fmt::Display for Tolerance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Tolerance::Absolute(d) => write!(f, "{d}"),
            Tolerance::PercentOfMeanEdge(p) => write!(f, "{p}%"),
        }
    }
}

impl Tolerance {
    /// The distance in mesh units.
    pub fn distance(self, mesh: &Mesh) -> f64 {
        match self {
            Tolerance::Absolute(d) => d,
            Tolerance::PercentOfMeanEdge(p) => p / 100.0 * mesh.info.mean_edge_length as f64,
        }
    }
}

/// The mesh's boundary triangles, each with the tet it bounds, and a BVH over them.
pub struct Boundary {
    /// Vertex ids of each boundary triangle, in the mesh's face order.
    pub triangles: Vec<[u32; 3]>,
    /// The tet each triangle bounds.
    pub tets: Vec<u32>,
    bvh: Bvh,
}

/// Builds the boundary search structure: the one place that does, with the one BVH builder
/// over the triangles' boxes.
pub fn build_boundary(mesh: &Mesh) -> Boundary {
    let (triangles, tets): (Vec<[u32; 3]>, Vec<u32>) = mesh
        .faces()
        .faces
        .par_iter()
        .filter_map(|f| match (f.front, f.back) {
            (t, -1) | (-1, t) if t >= 0 => Some((f.v, t as u32)),
            _ => None,
        })
        .unzip();
    let boxes: Vec<Aabb> = triangles.par_iter().map(|t| Aabb::of_points(&t.map(|i| mesh.points[i as usize]))).collect();
    let bvh = Bvh::build_boxes(&boxes, BuildPreset::Fast);
    Boundary { triangles, tets, bvh }
}

/// The boundary point nearest to a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Index into [`Boundary::triangles`].
    pub triangle: usize,
    /// The tet the triangle bounds.
    pub tet: u32,
    /// Weights of the triangle's three vertices at the closest point (they sum to 1).
    pub weights: [f64; 3],
    /// Squared distance from the query to the closest point.
    pub dist2: f64,
}

/// The nearest-triangle search as a BVH visitor: boxes farther than the best distance so far
/// are skipped, so the bound shrinks as the search goes.
struct NearestSearch<'a> {
    boundary: &'a Boundary,
    points: &'a [Vec3],
    p: [f64; 3],
    bound: f64,
    best: Option<Nearest>,
}

impl Visitor for NearestSearch<'_> {
    fn enter(&mut self, b: &Aabb) -> bool {
        box_dist2(b.min, b.max, self.p) <= self.bound
    }

    fn prim(&mut self, id: u32) -> bool {
        let k = id as usize;
        let v = self.boundary.triangles[k].map(|i| self.points[i as usize].map(f64::from));
        let weights = closest_on_triangle(self.p, v);
        let q: [f64; 3] = std::array::from_fn(|a| (0..3).map(|j| weights[j] * v[j][a]).sum());
        let dist2 = (0..3).map(|a| (self.p[a] - q[a]).powi(2)).sum::<f64>();
        let better = match &self.best {
            None => dist2 <= self.bound,
            Some(b) => dist2 < b.dist2 || (dist2 == b.dist2 && k < b.triangle),
        };
        if better {
            self.best = Some(Nearest { triangle: k, tet: self.boundary.tets[k], weights, dist2 });
            self.bound = dist2;
        }
        false // never stop early: a nearer triangle may follow
    }
}

impl Boundary {
    /// The nearest boundary point within `max_dist` of `p`, if any (`points`, `p` and
    /// `max_dist` in the same coordinates: the mesh's working frame).
    pub fn nearest(&self, points: &[Vec3], p: [f64; 3], max_dist: f64) -> Option<Nearest> {
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut search = NearestSearch { boundary: self, points, p, bound: max_dist * max_dist, best: None };
        self.bvh.traverse(&mut search);
        search.best
    }
}

/// Squared distance from `p` to the box `lo..hi` (0 inside).
fn box_dist2(lo: Vec3, hi: Vec3, p: [f64; 3]) -> f64 {
    (0..3).map(|a| (lo[a] as f64 - p[a]).max(p[a] - hi[a] as f64).max(0.0).powi(2)).sum()
}

/// Weights `(u, v, w)` of the point of triangle `abc` closest to `p` (`u·a + v·b + w·c`), by
/// the Voronoi regions of its vertices and edges (Ericson, Real-Time Collision Detection 5.1.5).
pub fn closest_on_triangle(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    let sub = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        // A degenerate (zero-area) triangle that no region above claimed: its nearest vertex.
        let d = [ap, bp, cp].map(|x| dot(x, x));
        let k = (0..3).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap();
        return std::array::from_fn(|i| if i == k { 1.0 } else { 0.0 });
    }
    let (v, w) = (vb / sum, vc / sum);
    [1.0 - v - w, v, w]
}

/// Any backend with a boundary tolerance: points it answers [`OUTSIDE`] that lie within
/// `distance` of the boundary get the nearest boundary tet and the field's value at the
/// closest boundary point (per-cell fields: that tet's value). The boundary structure is
/// built on the first batch that needs it.
pub struct WithTolerance<L> {
    inner: L,
    mesh: Arc<Mesh>,
    distance: f64,
    boundary: OnceLock<Boundary>,
}

impl<L: BatchLocator> WithTolerance<L> {
    /// `inner` must locate in `mesh`.
    pub fn new(inner: L, mesh: Arc<Mesh>, tolerance: Tolerance) -> Self {
        let distance = tolerance.distance(&mesh);
        WithTolerance { inner, mesh, distance, boundary: OnceLock::new() }
    }

    /// The tolerance in mesh units.
    pub fn distance(&self) -> f64 {
        self.distance
    }

    pub fn into_inner(self) -> L {
        self.inner
    }

    /// For the outside points of a batch (`point(i)`: point `i` in the file's coordinates),
    /// the nearest boundary point within the tolerance.
    fn rescue(&self, ids: &[i32], point: impl Fn(usize) -> [f64; 3] + Sync) -> Vec<(usize, Nearest)> {
        if self.distance <= 0.0 || !ids.par_iter().any(|&i| i == OUTSIDE) {
            return Vec::new();
        }
        let boundary = self.boundary.get_or_init(|| build_boundary(&self.mesh));
        let frame = &self.mesh.info.frame;
        let (mesh_points, distance) = (&self.mesh.points, self.distance * frame.scale);
        (0..ids.len())
            .into_par_iter()
            .filter(|&i| ids[i] == OUTSIDE)
            .filter_map(|i| Some((i, boundary.nearest(mesh_points, frame.to_working64(point(i)), distance)?)))
            .collect()
    }

    /// The field's value at a boundary point, from the file's values (in f64).
    fn value_at(&self, field: &crate::Field, n: &Nearest) -> f64 {
        let tri = self.boundary.get().expect("built by rescue").triangles[n.triangle];
        if self.mesh.cells.is_some() {
            // A mixed mesh: the cell's own shape functions at the boundary point.
            let cell = self.mesh.cell_of_tet(n.tet as usize);
            let q: [f64; 3] = std::array::from_fn(|a| {
                (0..3).map(|j| n.weights[j] * f64::from(self.mesh.points[tri[j] as usize][a])).sum()
            });
            return super::cells::value_in_cell(&self.mesh, cell, q, field).map_or(f64::NAN, f64::from);
        }
        // The boundary point's barycentrics in its tet (0 at the corner off the face), for
        // the one definition of a value in a tet.
        let corners = self.mesh.tets[n.tet as usize];
        let bary = corners.map(|c| tri.iter().position(|&v| v == c).map_or(0.0, |j| n.weights[j]));
        self.mesh.value_at64(field, Some((n.tet as usize, bary)))
    }
}

impl<L: BatchLocator> BatchLocator for WithTolerance<L> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    /// The boundary kept (it is the geometry's).
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        super::layer_takes_fields(&mut self.mesh, &mut self.inner, mesh)
    }

    fn preferred_batch(&self) -> Option<usize> {
        self.inner.preferred_batch()
    }

    /// The backend's answers, then the rescue of its outside points (values from the file's
    /// values in f64, rounded for f32 values). No grid sampler or tracer of the backend's
    /// own: they would skip the rescue.
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], mut values: Values<'_>) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        self.inner.query(points, fields, ids, values.reborrow())?;
        let fields = fields.iter().map(|f| self.mesh.field(f)).collect::<Result<Vec<_>>>()?;
        let point = |i: usize| match points {
            Points::F32(p) => p[i].map(f64::from),
            Points::F64(p) => p[i],
        };
        for (i, n) in self.rescue(ids, point) {
            ids[i] = self.mesh.cell_of_tet(n.tet as usize) as i32;
            for (j, f) in fields.iter().enumerate() {
                values.set(i * fields.len() + j, self.value_at(f, &n));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom;
    use crate::locate::{CpuLocator, FiniteOnly};
    use crate::test_support::mixed::moved;
    use crate::test_support::KuhnGrid;
    use proptest::prelude::*;

    #[test]
    fn tolerances_parse() {
        assert_eq!("0.01".parse::<Tolerance>().unwrap(), Tolerance::Absolute(0.01));
        assert_eq!(" 2.5 % ".parse::<Tolerance>().unwrap(), Tolerance::PercentOfMeanEdge(2.5));
        assert_eq!("0".parse::<Tolerance>().unwrap(), Tolerance::default());
        for bad in ["-1", "nan", "inf", "1e400", "x", "%", "1%%", ""] {
            let e = bad.parse::<Tolerance>().unwrap_err().to_string();
            assert!(e.contains(&format!("'{bad}'")), "{bad}: {e}");
        }
        let m = KuhnGrid::new(2).mesh("grid");
        let d = Tolerance::PercentOfMeanEdge(10.0).distance(&m);
        assert!((d - 0.1 * m.info.mean_edge_length as f64).abs() < 1e-12);
    }

    #[test]
    fn closest_points_on_a_triangle() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(closest_on_triangle([0.25, 0.25, 5.0], t), [0.5, 0.25, 0.25]);
        assert_eq!(closest_on_triangle([-1.0, -1.0, 0.0], t), [1.0, 0.0, 0.0]);
        assert_eq!(closest_on_triangle([3.0, -1.0, 1.0], t), [0.0, 1.0, 0.0]);
        assert_eq!(closest_on_triangle([0.5, -2.0, 0.0], t), [0.5, 0.5, 0.0]);
        assert_eq!(closest_on_triangle([1.0, 1.0, 0.0], t), [0.0, 0.5, 0.5]);
        // Degenerate: all three corners at one point, or on a line.
        assert_eq!(closest_on_triangle([1.0, 2.0, 3.0], [[0.0; 3]; 3]), [1.0, 0.0, 0.0]);
        let w = closest_on_triangle([0.5, 1.0, 0.0], [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        assert!((w[0] * 0.0 + w[1] * 1.0 + w[2] * 2.0 - 0.5).abs() < 1e-12, "{w:?}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// No point of the triangle is nearer than the one `closest_on_triangle` names.
        #[test]
        fn the_closest_point_is_closest(
            v in prop::array::uniform3(prop::array::uniform3(-1.0f64..1.0)),
            p in prop::array::uniform3(-2.0f64..2.0),
        ) {
            let w = closest_on_triangle(p, v);
            prop_assert!(w.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            let at = |w: [f64; 3]| -> [f64; 3] { std::array::from_fn(|a| (0..3).map(|j| w[j] * v[j][a]).sum()) };
            let d2 = |q: [f64; 3]| (0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f64>();
            let best = d2(at(w));
            let n = 40;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, s) = (i as f64 / n as f64, j as f64 / n as f64);
                    prop_assert!(best <= d2(at([u, s, 1.0 - u - s])) + 1e-9);
                }
            }
        }

        /// On the unit cube (a jittered grid with flat faces and the linear field
        /// f = x + 2y + 3z): an outside point gets an answer exactly when it is within the
        /// tolerance of the cube, in a tet holding its closest boundary point, with f there.
        #[test]
        fn points_within_the_tolerance_get_the_closest_boundary_point(
            n in 1usize..5,
            jitter in 0.0f32..0.3,
            seed in any::<u64>(),
            tol in 0.0f64..0.3,
            pts in prop::collection::vec(prop::array::uniform3(-0.4f32..1.4), 100),
        ) {
            let m = Arc::new(KuhnGrid::new(n).jitter(jitter, seed).mesh("cube"));
            let mut exact = CpuLocator::new(m.clone());
            let mut loc = WithTolerance::new(FiniteOnly::new(CpuLocator::new(m.clone())), m.clone(), Tolerance::Absolute(tol));
            let (mut ids0, mut ids, mut vals) = (vec![0; pts.len()], vec![0; pts.len()], vec![0.0; pts.len()]);
            exact.locate(&pts, &mut ids0).unwrap();
            loc.locate_and_sample(&pts, "f", &mut ids, &mut vals).unwrap();
            for (i, &p) in pts.iter().enumerate() {
                if ids0[i] >= 0 {
                    prop_assert_eq!(ids[i], ids0[i], "an inside answer changed");
                    continue;
                }
                let q: Vec3 = p.map(|c| c.clamp(0.0, 1.0));
                let dist = (0..3).map(|a| ((p[a] - q[a]) as f64).powi(2)).sum::<f64>().sqrt();
                if (dist - tol).abs() < 1e-6 {
                    continue; // on the edge of the tolerance, rounding decides
                }
                prop_assert_eq!(ids[i] >= 0, dist <= tol, "point {:?}, distance {} to the cube", p, dist);
                if ids[i] >= 0 {
                    prop_assert!(geom::point_in_tet(m.tets[ids[i] as usize], &m.points, q).is_some(), "tet {} does not hold {:?}", ids[i], q);
                    let f = q[0] as f64 + 2.0 * q[1] as f64 + 3.0 * q[2] as f64;
                    prop_assert!((vals[i] as f64 - f).abs() < 1e-5, "f({:?}) = {} but {}", q, f, vals[i]);
                } else {
                    prop_assert!(vals[i].is_nan());
                }
            }
        }
    }

    #[test]
    fn tolerance_zero_is_the_exact_answer_and_cell_fields_are_looked_up() {
        let m = Arc::new(KuhnGrid::new(3).mesh("cube"));
        let pts = [[0.5, 0.5, 1.0 + 1e-4], [0.5, 0.5, 0.5], [-0.01, 0.5, 0.5], [f32::NAN, 0.0, 0.0]];
        let mut exact = FiniteOnly::new(CpuLocator::new(m.clone()));
        let mut zero = WithTolerance::new(FiniteOnly::new(CpuLocator::new(m.clone())), m.clone(), Tolerance::default());
        let (mut a, mut b) = (vec![0; 4], vec![0; 4]);
        exact.locate(&pts, &mut a).unwrap();
        zero.locate(&pts, &mut b).unwrap();
        assert_eq!(a, b);
        assert_eq!(a, [OUTSIDE, a[1], OUTSIDE, OUTSIDE]);
        let mut loc = WithTolerance::new(FiniteOnly::new(CpuLocator::new(m.clone())), m.clone(), "1%".parse().unwrap());
        let mut ids = vec![0; 4];
        let mut c = vec![0.0; 4];
        loc.locate_and_sample(&pts, "c", &mut ids, &mut c).unwrap();
        assert!(ids[0] >= 0 && ids[2] == OUTSIDE && ids[3] == OUTSIDE, "{ids:?}");
        assert_eq!(c[0], ids[0] as f32, "the cell field of the boundary tet");
        assert!(c[2].is_nan() && c[3].is_nan());
        let mut v = vec![0.0; 4];
        loc.sample(&pts, "f", &mut v).unwrap();
        assert!((v[0] - 4.5).abs() < 1e-5, "f at (0.5, 0.5, 1) is 4.5, not {}", v[0]);
    }

    /// Far from the origin (UTM-like offsets, f64 coordinates) the tolerance answers as at
    /// the origin: the search runs in the mesh's working frame on the f64 points (it used to
    /// compare the file's coordinates with the working frame's, and had no f64 path).
    #[test]
    fn far_from_the_origin_the_tolerance_answers_as_at_the_origin() {
        let grid = KuhnGrid::new(3).jitter(0.2, 5);
        let near = Arc::new(grid.mesh("cube"));
        let offset = [512_345.0, 4_123_456.0, 1_000.0];
        let far = Arc::new(Mesh::new(moved(grid.raw(), offset), "far cube").unwrap());
        assert!(!far.info.frame.is_identity(), "the far mesh has its own working frame");
        let mut state = 7u64;
        let mut unit = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let pts: Vec<[f64; 3]> = (0..2000).map(|_| std::array::from_fn(|_| -0.1 + 1.2 * unit())).collect();
        let tol = 0.05;
        let run = |m: &Arc<Mesh>, shift: [f64; 3]| {
            let mut loc = WithTolerance::new(CpuLocator::new(m.clone()), m.clone(), Tolerance::Absolute(tol));
            let p: Vec<[f64; 3]> = pts.iter().map(|p| std::array::from_fn(|k| p[k] + shift[k])).collect();
            let (mut ids, mut v) = (vec![0; p.len()], vec![0.0; p.len()]);
            loc.sample_many64(&p, &["f"], &mut ids, &mut v).unwrap();
            (ids, v)
        };
        let ((ids0, v0), (ids1, v1)) = (run(&near, [0.0; 3]), run(&far, offset));
        let mut rescued = 0;
        for (i, p) in pts.iter().enumerate() {
            let outside: Vec<f64> = p.iter().map(|&c| (-c).max(c - 1.0).max(0.0)).collect();
            let dist = outside.iter().map(|d| d * d).sum::<f64>().sqrt();
            if (dist - tol).abs() < 1e-6 {
                continue; // on the edge of the tolerance, rounding decides
            }
            assert_eq!(ids1[i] >= 0, dist <= tol, "point {p:?} at {dist} from the cube");
            assert_eq!(ids0[i] >= 0, ids1[i] >= 0, "point {p:?}");
            if ids1[i] < 0 {
                assert!(v1[i].is_nan());
                continue;
            }
            rescued += usize::from(dist > 0.0);
            // Off one face only, the closest point is inside one boundary triangle; off an
            // edge or a corner, equally near triangles may tie within rounding.
            if outside.iter().filter(|&&d| d > 0.0).count() <= 1 {
                assert_eq!(ids0[i], ids1[i], "point {p:?}");
            }
            assert!((v0[i] - v1[i]).abs() < 1e-6, "point {p:?}: {} at the origin, {} far away", v0[i], v1[i]);
        }
        assert!(rescued > 100, "{rescued} points were within the tolerance outside the cube");
    }
}
