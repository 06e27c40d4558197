//! The seam every backend plugs into: one query ([`BatchLocator::query`]) takes points in
//! f32 or f64 and writes, for each, its tet id and the values of any number of fields. The
//! CPU implementation lives here; the Vulkan backend implements the same trait in
//! `tetloc-vulkan`. Two capabilities go beyond the query ([`GridSampler`], [`LineTracer`]):
//! a backend that has one says so through a hook, and the operations fall back to queries
//! where it has none. Wrappers add what is the same for every backend: [`FiniteOnly`]
//! answers points with NaN or infinite coordinates, [`CellLocator`] turns answers in a mixed
//! mesh's tet decomposition into answers on its cells, [`F64Values`] gives the f64 path the
//! CPU's values, and [`WithTolerance`] assigns points just outside the boundary to the
//! nearest boundary cell. Each implements the query and the two hooks, nothing else.

mod bins;
mod capability;
mod cells;
pub mod certify;
mod cpu;
mod grid_raster;
mod hint;
mod occupancy;
pub mod precision;
mod tet_map;
#[cfg(test)]
use cpu::is_coherent;
#[cfg(test)]
mod tests;
pub mod tolerance;

pub use capability::{locate_from, sample_grid, trace_lines, GridSampler, HintedLocator, LineTracer};
pub(crate) use cells::cell_weights;
pub use cells::CellLocator;
pub use cpu::CpuLocator;
pub use hint::Hint;
pub use precision::{with_precision, F64Values, Precision};
pub use tolerance::{Tolerance, WithTolerance};

use crate::error::Result;
use crate::geom::{ImageGrid, Real, Vec3};
use crate::Mesh;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Arc;

/// Id returned for a point outside every tet.
pub const OUTSIDE: i32 = -1;

/// A backend that locates batches of points in one mesh.
///
/// [`Self::query`] is all a backend must answer; the other methods are conveniences over it.
/// A point on a face shared by two tets may go to either, but always to the same one for the
/// same backend.
pub trait BatchLocator {
    /// The backend's name as used on the command line (`cpu`, `soft-bvh`, ...).
    fn name(&self) -> &str;

    /// For each point, the containing tet's id (0-based, file order) or [`OUTSIDE`] into
    /// `ids`, and the values of `fields` there into `values`: `fields.len()` a point, point
    /// after point (VTK's tuple order; a vector is its `NAME[i]` fields), NaN outside.
    /// Per-vertex fields are interpolated, per-cell fields looked up.
    ///
    /// f64 points are the file's coordinates at full precision (points far from the origin
    /// keep it): the CPU decides exactly on them and the mesh's f64 coordinates; the GPU
    /// kernels search the mesh's working frame (`mesh::Frame`) and their answers are certified
    /// on the host. Values come in the precision `values` asks for: f64 ones are the file's
    /// values interpolated in f64 ([`crate::mesh::Mesh::values_at_ids64`]) where the backend
    /// computes them so, else its f32 values widened ([`Precision`]).
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()>;

    /// The backend's own way to sample a grid's points (a GPU kernel makes them itself, the
    /// CPU rasterizes its tets), or `None`: then [`sample_grid`] queries the grid's points.
    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        None
    }

    /// The backend's own streamline tracer (a GPU kernel that runs every particle to its
    /// end), or `None`: then `ops::trace::trace_with` drives the queries one Runge–Kutta stage
    /// at a time.
    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        None
    }

    /// The backend's own way to locate points from a tet near each (a GPU kernel's walk), or
    /// `None`: then [`locate_from`] runs `locate`.
    fn hinted_locator(&mut self) -> Option<&mut dyn HintedLocator> {
        None
    }

    /// The most points a batch of queries should hold for this backend's best rate, or
    /// `None` for any (`ops` cuts larger jobs into such batches). The CPU's is small enough
    /// for a batch's values to stay in cache; a GPU's launches want them large.
    fn preferred_batch(&self) -> Option<usize> {
        None
    }

    /// Takes `mesh`'s fields in place of its own mesh's, keeping what it built: `mesh` has
    /// the geometry of the mesh it locates in ([`Mesh::same_geometry`]: another time step,
    /// made by [`Mesh::with_fields`]). False, with nothing changed, where the geometry is not
    /// the same or the locator cannot (the default): build a new one then.
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        let _ = mesh;
        false
    }

    /// Ids only.
    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()> {
        self.query(Points::F32(points), &[], ids, Values::none())
    }

    /// One field's values only.
    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()> {
        // `query` writes every id. Zeroed memory comes from the allocator untouched (a fill
        // with -1 wrote 48 MB on one core for 12M points: a third of a GPU call's time).
        let mut ids = vec![0; points.len()];
        self.query(Points::F32(points), &[field], &mut ids, Values::F32(values))
    }

    /// Ids and one field's values.
    fn locate_and_sample(&mut self, points: &[Vec3], field: &str, ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        self.query(Points::F32(points), &[field], ids, Values::F32(values))
    }

    /// Ids and several fields' values of f32 points.
    fn sample_many(&mut self, points: &[Vec3], fields: &[&str], ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        self.query(Points::F32(points), fields, ids, Values::F32(values))
    }

    /// Ids and several fields' f64 values of f64 points (the file's coordinates).
    fn sample_many64(
        &mut self,
        points: &[[f64; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f64],
    ) -> Result<()> {
        self.query(Points::F64(points), fields, ids, Values::F64(values))
    }
}

impl<L: BatchLocator + ?Sized> BatchLocator for Box<L> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
        (**self).query(points, fields, ids, values)
    }
    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        (**self).grid_sampler()
    }
    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        (**self).line_tracer()
    }
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        (**self).take_fields(mesh)
    }

    fn preferred_batch(&self) -> Option<usize> {
        (**self).preferred_batch()
    }
}

/// [`BatchLocator::take_fields`] of a layer that holds its own `mesh` over `inner`: the inner
/// locator takes the step's fields, then the layer's mesh is the step's (what the layer built
/// from the mesh, its bulges or boundary, is the geometry's and stays).
pub(crate) fn layer_takes_fields(own: &mut Arc<Mesh>, inner: &mut impl BatchLocator, mesh: &Arc<Mesh>) -> bool {
    let taken = own.same_geometry(mesh) && inner.take_fields(mesh);
    if taken {
        *own = mesh.clone();
    }
    taken
}

/// Points `range` of `grid`, rounded to f32 ([`ImageGrid::point`]).
pub fn grid_points(grid: &ImageGrid, range: Range<usize>) -> Vec<Vec3> {
    range.into_par_iter().map(|i| grid.point(i)).collect()
}

/// Points `range` of `grid` in f64 as the samplers locate them ([`ImageGrid::point64`]).
pub fn grid_points64(grid: &ImageGrid, range: Range<usize>) -> Vec<[f64; 3]> {
    range.into_par_iter().map(|i| grid.point64(i)).collect()
}

/// What every [`GridSampler`] answers: a query of `grid`'s points `range`, the f64 points
/// where the grid asks for them ([`ImageGrid::f64_points`]), else their f32 rounding.
pub fn query_grid_points(
    loc: &mut (impl BatchLocator + ?Sized),
    grid: &ImageGrid,
    range: Range<usize>,
    fields: &[&str],
    ids: &mut [i32],
    values: &mut [f32],
) -> Result<()> {
    if grid.f64_points {
        let points = grid_points64(grid, range);
        loc.query(Points::F64(&points), fields, ids, Values::F32(values))
    } else {
        loc.sample_many(&grid_points(grid, range), fields, ids, values)
    }
}

/// Whether all three coordinates are finite (not NaN, not infinite).
#[inline]
pub fn is_finite(p: Vec3) -> bool {
    p.iter().all(|c| c.is_finite())
}

/// How many points have a NaN or infinite coordinate.
pub fn count_non_finite(points: &[Vec3]) -> usize {
    points.par_iter().filter(|&&p| !is_finite(p)).count()
}

/// Any backend, with points that have a NaN or infinite coordinate answered here: they are
/// in no tet ([`OUTSIDE`], NaN). They are compacted out of the batch before the backend sees
/// it, so GPU kernels never get one; batches without such points pass through as they are.
pub struct FiniteOnly<L> {
    inner: L,
}

impl<L: BatchLocator> FiniteOnly<L> {
    pub fn new(inner: L) -> Self {
        FiniteOnly { inner }
    }
    pub fn inner(&self) -> &L {
        &self.inner
    }
    pub fn into_inner(self) -> L {
        self.inner
    }

    /// The query of the points that `keep` keeps, when it drops some; the others get
    /// [`OUTSIDE`] and NaN.
    fn query_kept<P: Point>(
        &mut self,
        points: &[P],
        keep: impl Fn(&P) -> bool + Sync,
        fields: &[&str],
        ids: &mut [i32],
        values: Values<'_>,
    ) -> Result<()> {
        let Some(c) = Compacted::of(points, keep) else {
            return self.inner.query(P::batch(points), fields, ids, values);
        };
        let (k, n) = (fields.len(), c.points.len());
        let mut sub_ids = vec![OUTSIDE; n];
        match values {
            Values::F32(v) => {
                self.query_sub(&c, P::batch(&c.points), fields, &mut sub_ids, vec![f32::NAN; n * k], v)?
            }
            Values::F64(v) => {
                self.query_sub(&c, P::batch(&c.points), fields, &mut sub_ids, vec![f64::NAN; n * k], v)?
            }
        }
        c.scatter_k(1, &sub_ids, ids, OUTSIDE);
        Ok(())
    }

    /// The inner query of the compacted points, its values spread back into `out`.
    fn query_sub<P, T: Real>(
        &mut self,
        c: &Compacted<P>,
        points: Points<'_>,
        fields: &[&str],
        ids: &mut [i32],
        mut sub: Vec<T>,
        out: &mut [T],
    ) -> Result<()>
    where
        for<'v> Values<'v>: From<&'v mut [T]>,
    {
        self.inner.query(points, fields, ids, Values::from(&mut sub[..]))?;
        c.scatter_k(fields.len(), &sub, out, T::NAN);
        Ok(())
    }
}

/// A query point in either precision.
trait Point: Copy + Send + Sync {
    fn batch(points: &[Self]) -> Points<'_>;
}

impl Point for Vec3 {
    fn batch(points: &[Self]) -> Points<'_> {
        Points::F32(points)
    }
}

impl Point for [f64; 3] {
    fn batch(points: &[Self]) -> Points<'_> {
        Points::F64(points)
    }
}

/// The points of a batch to hand to the backend (finite ones) when it has others, and the
/// batch index of each.
struct Compacted<P> {
    index: Vec<usize>,
    points: Vec<P>,
}

impl<P: Copy + Send + Sync> Compacted<P> {
    /// `None` when every point is kept (nothing to compact).
    fn of(points: &[P], keep: impl Fn(&P) -> bool + Sync) -> Option<Compacted<P>> {
        if points.par_iter().all(&keep) {
            return None;
        }
        let index: Vec<usize> = (0..points.len()).into_par_iter().filter(|&i| keep(&points[i])).collect();
        let points = index.par_iter().map(|&i| points[i]).collect();
        Some(Compacted { index, points })
    }
}

impl<P> Compacted<P> {
    /// Spreads the answers for the compacted points back, `k` a point; the others get `none`.
    fn scatter_k<T: Copy>(&self, k: usize, answers: &[T], out: &mut [T], none: T) {
        out.fill(none);
        if k == 0 {
            return;
        }
        for (&i, a) in self.index.iter().zip(answers.chunks_exact(k)) {
            out[i * k..(i + 1) * k].copy_from_slice(a);
        }
    }
}

impl<L: BatchLocator> BatchLocator for FiniteOnly<L> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        match points {
            Points::F32(p) => self.query_kept(p, |p| is_finite(*p), fields, ids, values),
            // Beyond f32's range is beyond every mesh (whose f32 copy is finite), like NaN.
            Points::F64(p) => {
                let in_range = |p: &[f64; 3]| p.iter().all(|c| c.abs() <= f32::MAX as f64);
                self.query_kept(p, in_range, fields, ids, values)
            }
        }
    }

    /// A grid's points are finite (its bounds are).
    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        self.inner.grid_sampler()
    }

    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        self.inner.take_fields(mesh)
    }

    fn preferred_batch(&self) -> Option<usize> {
        self.inner.preferred_batch()
    }

    /// The backend's own tracer gets only the finite seeds ([`LineTracer`] below).
    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        self.inner.line_tracer()?;
        Some(self)
    }

    /// The backend's own hinted locator gets only the finite points ([`HintedLocator`] below).
    fn hinted_locator(&mut self) -> Option<&mut dyn HintedLocator> {
        self.inner.hinted_locator()?;
        Some(self)
    }
}

impl<L: BatchLocator> HintedLocator for FiniteOnly<L> {
    /// Only the finite points, with their hints; the others are outside.
    fn locate_from(&mut self, points: &[Vec3], hints: &[i32], ids: &mut [i32]) -> Result<()> {
        if hints.len() != points.len() || ids.len() != points.len() {
            return Err(crate::Error::Invalid(format!(
                "locate_from: {} points, {} hints, {} ids",
                points.len(),
                hints.len(),
                ids.len()
            )));
        }
        let Some(h) = self.inner.hinted_locator() else { return self.locate(points, ids) };
        let Some(c) = Compacted::of(points, |p| is_finite(*p)) else {
            return h.locate_from(points, hints, ids);
        };
        let kept_hints: Vec<i32> = c.index.iter().map(|&i| hints[i]).collect();
        let mut kept = vec![OUTSIDE; c.points.len()];
        h.locate_from(&c.points, &kept_hints, &mut kept)?;
        c.scatter_k(1, &kept, ids, OUTSIDE);
        Ok(())
    }
}

impl<L: BatchLocator> LineTracer for FiniteOnly<L> {
    /// Only the finite seeds (the others give no line, as a seed outside the mesh), with the
    /// lines' seed indices mapped back.
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &crate::streamline::TraceOptions,
        vector: [&str; 3],
        fields: &[&str],
        progress: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Option<Vec<crate::streamline::Line>>> {
        let Some(tracer) = self.inner.line_tracer() else { return Ok(None) };
        let Some(c) = Compacted::of(seeds, |p| is_finite(*p)) else {
            return tracer.trace_lines(seeds, o, vector, fields, progress);
        };
        let Some(mut lines) = tracer.trace_lines(&c.points, o, vector, fields, progress)? else { return Ok(None) };
        for l in &mut lines {
            l.seed = c.index[l.seed as usize] as u32;
        }
        // VTK's order: by direction, then by seed.
        lines.sort_by_key(|l| (l.backward, l.seed));
        Ok(Some(lines))
    }
}

/// The values a query writes, in f32 or f64 (see [`BatchLocator::query`]).
pub enum Values<'a> {
    F32(&'a mut [f32]),
    F64(&'a mut [f64]),
}

impl<'a> From<&'a mut [f32]> for Values<'a> {
    fn from(v: &'a mut [f32]) -> Self {
        Values::F32(v)
    }
}

impl<'a> From<&'a mut [f64]> for Values<'a> {
    fn from(v: &'a mut [f64]) -> Self {
        Values::F64(v)
    }
}

impl Values<'_> {
    /// No values: a query of ids only.
    pub fn none() -> Values<'static> {
        Values::F32(&mut [])
    }

    pub fn len(&self) -> usize {
        match self {
            Values::F32(v) => v.len(),
            Values::F64(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The same values, borrowed again (to pass on and write into afterwards).
    pub fn reborrow(&mut self) -> Values<'_> {
        match self {
            Values::F32(v) => Values::F32(v),
            Values::F64(v) => Values::F64(v),
        }
    }

    /// Value `i` set from an f64 one (rounded for f32 values).
    pub fn set(&mut self, i: usize, v: f64) {
        match self {
            Values::F32(out) => out[i] = v as f32,
            Values::F64(out) => out[i] = v,
        }
    }

    /// Runs `f` on f32 values: these, or a temporary widened into these afterwards (a
    /// backend whose values are f32).
    pub fn via_f32(self, f: impl FnOnce(&mut [f32]) -> Result<()>) -> Result<()> {
        match self {
            Values::F32(v) => f(v),
            Values::F64(v) => via_temporary(v, f, f64::from),
        }
    }

    /// Runs `f` on f64 values: these, or a temporary rounded into these afterwards.
    pub fn via_f64(self, f: impl FnOnce(&mut [f64]) -> Result<()>) -> Result<()> {
        match self {
            Values::F64(v) => f(v),
            Values::F32(v) => via_temporary(v, f, |x| x as f32),
        }
    }
}

/// Runs `f` on a temporary of the other precision, then converts it into `out`: what
/// [`Values::via_f32`] and [`Values::via_f64`] do when the values are not of theirs.
fn via_temporary<T: Copy + Default + Sync, U: Send>(
    out: &mut [U],
    f: impl FnOnce(&mut [T]) -> Result<()>,
    convert: impl Fn(T) -> U + Sync + Send,
) -> Result<()> {
    let mut tmp = vec![T::default(); out.len()];
    f(&mut tmp)?;
    out.par_iter_mut().zip(&tmp).for_each(|(o, &x)| *o = convert(x));
    Ok(())
}

/// A batch's query points in the precision the caller has them: f32, or the file's f64.
#[derive(Clone, Copy)]
pub enum Points<'a> {
    F32(&'a [Vec3]),
    F64(&'a [[f64; 3]]),
}

impl<'a> Points<'a> {
    pub fn len(self) -> usize {
        match self {
            Points::F32(p) => p.len(),
            Points::F64(p) => p.len(),
        }
    }

    pub fn is_empty(self) -> bool {
        self.len() == 0
    }

    /// Points `r` in f64 (f32 ones widen exactly).
    pub fn wide(self, r: Range<usize>) -> std::borrow::Cow<'a, [[f64; 3]]> {
        match self {
            Points::F32(p) => std::borrow::Cow::Owned(p[r].par_iter().map(|q| q.map(f64::from)).collect()),
            Points::F64(p) => std::borrow::Cow::Borrowed(&p[r]),
        }
    }

    /// Points `r` rounded to f32.
    pub fn narrow(self, r: Range<usize>) -> std::borrow::Cow<'a, [Vec3]> {
        match self {
            Points::F32(p) => std::borrow::Cow::Borrowed(&p[r]),
            Points::F64(p) => std::borrow::Cow::Owned(p[r].par_iter().map(|q| q.map(|c| c as f32)).collect()),
        }
    }

    /// Whether rounding them to f32 would change some (finite) point.
    pub fn need_f64(self) -> bool {
        match self {
            Points::F32(_) => false,
            Points::F64(p) => crate::mesh::needs_f64(p),
        }
    }
}

/// An error unless an output buffer holds one entry per point (`out == points`).
pub fn check_lengths(points: usize, out: usize) -> Result<()> {
    if points != out {
        return Err(crate::Error::Invalid(format!("{points} points but an output buffer for {out}")));
    }
    Ok(())
}

/// [`check_lengths`] of a `sample_many`'s outputs: an id a point, and `n_fields` values a point.
pub fn check_sample_lengths(points: usize, n_fields: usize, ids: usize, values: usize) -> Result<()> {
    check_lengths(points, ids)?;
    check_lengths(points * n_fields, values)
}

#[cfg(test)]
mod nan_tests {
    use super::*;
    use crate::test_support::KuhnGrid;
    use std::sync::Arc;

    /// A backend that fails the test if it is handed a non-finite point.
    struct NoNaN(CpuLocator);
    impl BatchLocator for NoNaN {
        fn name(&self) -> &str {
            "no-nan"
        }
        fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
            let Points::F32(p) = points else { panic!("f32 points only") };
            assert_eq!(count_non_finite(p), 0, "the backend saw a non-finite point");
            self.0.query(points, fields, ids, values)
        }
    }

    /// NaN and infinite points are answered -1 / NaN, the others as without them, and the
    /// backend never sees them; the CPU locator answers them the same way on its own.
    #[test]
    fn non_finite_points_get_no_answer_and_never_reach_the_backend() {
        let m = Arc::new(KuhnGrid::new(3).mesh("cube"));
        let pts = [
            [0.3, 0.4, 0.5],
            [f32::NAN, 0.5, 0.5],
            [0.5, f32::INFINITY, 0.5],
            [0.9, 0.1, 0.2],
            [0.5, 0.5, f32::NEG_INFINITY],
            [2.0, 0.5, 0.5],
        ];
        let finite: Vec<Vec3> = pts.iter().copied().filter(|&p| is_finite(p)).collect();
        assert_eq!(count_non_finite(&pts), 3);
        let mut plain = CpuLocator::new(m.clone());
        let (mut want_ids, mut want_vals) = (vec![0; 3], vec![0.0; 3]);
        plain.locate_and_sample(&finite, "f", &mut want_ids, &mut want_vals).unwrap();

        let mut loc = FiniteOnly::new(NoNaN(CpuLocator::new(m.clone())));
        let (mut ids, mut vals, mut both_ids, mut both_vals) = (vec![7; 6], vec![7.0; 6], vec![7; 6], vec![7.0; 6]);
        loc.locate(&pts, &mut ids).unwrap();
        loc.sample(&pts, "f", &mut vals).unwrap();
        loc.locate_and_sample(&pts, "f", &mut both_ids, &mut both_vals).unwrap();
        for (ids, vals) in [(&ids, &vals), (&both_ids, &both_vals)] {
            assert_eq!(*ids, [want_ids[0], OUTSIDE, OUTSIDE, want_ids[1], OUTSIDE, OUTSIDE]);
            assert_eq!([vals[0], vals[3]], [want_vals[0], want_vals[1]]);
            assert!([1, 2, 4, 5].iter().all(|&i| vals[i].is_nan()));
        }
        // The CPU locator by itself, in a batch large and incoherent enough to be sorted.
        let many: Vec<Vec3> = (0..10_000).map(|i| pts[i * 7 % pts.len()]).collect();
        let mut ids = vec![0; many.len()];
        plain.locate(&many, &mut ids).unwrap();
        for (p, id) in many.iter().zip(&ids) {
            assert_eq!(*id >= 0, is_finite(*p) && p[0] < 1.5, "{p:?}: {id}");
        }
    }
}
