//! The seam every backend plugs into: a batch locator takes points and returns tet ids, or
//! values of a field. The CPU implementation lives here; the Vulkan backend implements the
//! same trait in `tetloc-vulkan`. Three wrappers add what is the same for every backend:
//! [`FiniteOnly`] answers points with NaN or infinite coordinates, [`CellLocator`] turns
//! answers in a mixed mesh's tet decomposition into answers on its cells, and
//! [`WithTolerance`] assigns points just outside the boundary to the nearest boundary cell.

mod bins;
mod cells;
pub mod certify;
mod cpu;
mod grid_raster;
pub mod precision;
mod tet_map;
#[cfg(test)]
use cpu::is_coherent;
#[cfg(test)]
mod tests;
pub mod tolerance;

pub(crate) use cells::cell_weights;
pub use cells::CellLocator;
pub use cpu::CpuLocator;
pub use precision::{with_precision, F64Values, Precision};
pub use tolerance::{Tolerance, WithTolerance};

use crate::error::{Error, Result};
use crate::geom::ImageGrid;
use crate::geom::Vec3;
use crate::ops::trace::{Line, TraceOptions};
use rayon::prelude::*;
use std::ops::Range;

/// Id returned for a point outside every tet.
pub const OUTSIDE: i32 = -1;

/// A backend that locates batches of points in one mesh.
///
/// `locate` writes the containing tet id (0-based, file order) or [`OUTSIDE`] for each
/// point; `sample` writes the field's value there: per-vertex fields are interpolated
/// barycentrically, per-cell fields looked up, NaN outside. A point on a face shared by two
/// tets may go to either, but always to the same one for the same backend.
pub trait BatchLocator {
    /// The backend's name as used on the command line (`cpu`, `soft-bvh`, ...).
    fn name(&self) -> &str;
    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()>;
    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()>;
    /// Ids and values together; backends that can do both in one pass override this.
    fn locate_and_sample(&mut self, points: &[Vec3], field: &str, ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        self.locate(points, ids)?;
        self.sample(points, field, values)
    }
    /// Ids and several fields at once (each field one component: a vector is its `NAME[i]`
    /// fields): `values` holds `fields.len()` values per point, point after point (VTK's tuple
    /// order), NaN outside. The default locates, then samples each field; backends that
    /// interpolate every field from one lookup override it.
    fn sample_many(&mut self, points: &[Vec3], fields: &[&str], ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        self.locate(points, ids)?;
        let mut one = vec![0f32; points.len()];
        for (j, f) in fields.iter().enumerate() {
            self.sample(points, f, &mut one)?;
            values.iter_mut().skip(j).step_by(fields.len()).zip(&one).for_each(|(v, &x)| *v = x);
        }
        Ok(())
    }
    /// [`Self::sample_many`] of points given in the file's coordinates at f64 precision
    /// (points far from the origin keep their precision), with f64 values. The CPU backend
    /// decides exactly on them and on the mesh's f64 coordinates, and interpolates the file's
    /// values in f64 ([`crate::mesh::Mesh::values_at_ids64`]); the GPU backends search them
    /// in the mesh's working frame (`mesh::Frame`) and give their f32 values widened, or the
    /// CPU's f64 values with their f64 precision option. Backends without f64 input say so.
    fn sample_many64(
        &mut self,
        points: &[[f64; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f64],
    ) -> Result<()> {
        let _ = (points, fields, ids, values);
        Err(Error::Invalid(format!("the {} backend takes f32 points only", self.name())))
    }

    /// [`Self::sample_many`] at points `range` of `grid` (x fastest, [`ImageGrid::point`]):
    /// `resample`'s chunks. Backends that make the points themselves (the GPU kernels' grid
    /// set) override it.
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()> {
        self.sample_many(&grid_points(grid, range), fields, ids, values)
    }

    /// Whole streamlines traced by the backend itself (a GPU kernel that runs every particle
    /// to its end), or `None` where it has no tracer of its own for these options: then
    /// [`crate::ops::trace::trace_with`] drives it one Runge–Kutta stage at a time.
    /// `progress` gets the number of lines done so far.
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        progress: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Option<Vec<Line>>> {
        let _ = (seeds, o, vector, progress);
        Ok(None)
    }
}

impl<L: BatchLocator + ?Sized> BatchLocator for Box<L> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()> {
        (**self).locate(points, ids)
    }
    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()> {
        (**self).sample(points, field, values)
    }
    fn locate_and_sample(&mut self, points: &[Vec3], field: &str, ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        (**self).locate_and_sample(points, field, ids, values)
    }
    fn sample_many(&mut self, points: &[Vec3], fields: &[&str], ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        (**self).sample_many(points, fields, ids, values)
    }
    fn sample_many64(
        &mut self,
        points: &[[f64; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f64],
    ) -> Result<()> {
        (**self).sample_many64(points, fields, ids, values)
    }
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()> {
        (**self).sample_grid(grid, range, fields, ids, values)
    }
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        progress: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Option<Vec<Line>>> {
        (**self).trace_lines(seeds, o, vector, progress)
    }
}

/// Points `range` of `grid`, as [`BatchLocator::sample_grid`] samples them.
pub fn grid_points(grid: &ImageGrid, range: Range<usize>) -> Vec<Vec3> {
    range.into_par_iter().map(|i| grid.point(i)).collect()
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

    /// Spreads the answers for the compacted points back; the others get `none`.
    fn scatter<T: Copy>(&self, answers: &[T], out: &mut [T], none: T) {
        self.scatter_k(1, answers, out, none);
    }

    /// [`Self::scatter`] for `k` answers per point.
    fn scatter_k<T: Copy>(&self, k: usize, answers: &[T], out: &mut [T], none: T) {
        out.fill(none);
        for (&i, a) in self.index.iter().zip(answers.chunks_exact(k.max(1))) {
            out[i * k..(i + 1) * k].copy_from_slice(&a[..k]);
        }
    }
}

impl<L: BatchLocator> BatchLocator for FiniteOnly<L> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()> {
        check_lengths(points.len(), ids.len())?;
        let Some(c) = Compacted::of(points, |p| is_finite(*p)) else { return self.inner.locate(points, ids) };
        let mut sub = vec![OUTSIDE; c.points.len()];
        self.inner.locate(&c.points, &mut sub)?;
        c.scatter(&sub, ids, OUTSIDE);
        Ok(())
    }

    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()> {
        check_lengths(points.len(), values.len())?;
        let Some(c) = Compacted::of(points, |p| is_finite(*p)) else { return self.inner.sample(points, field, values) };
        let mut sub = vec![f32::NAN; c.points.len()];
        self.inner.sample(&c.points, field, &mut sub)?;
        c.scatter(&sub, values, f32::NAN);
        Ok(())
    }

    fn locate_and_sample(&mut self, points: &[Vec3], field: &str, ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        check_lengths(points.len(), ids.len())?;
        check_lengths(points.len(), values.len())?;
        let Some(c) = Compacted::of(points, |p| is_finite(*p)) else {
            return self.inner.locate_and_sample(points, field, ids, values);
        };
        let (mut sub_ids, mut sub_values) = (vec![OUTSIDE; c.points.len()], vec![f32::NAN; c.points.len()]);
        self.inner.locate_and_sample(&c.points, field, &mut sub_ids, &mut sub_values)?;
        c.scatter(&sub_ids, ids, OUTSIDE);
        c.scatter(&sub_values, values, f32::NAN);
        Ok(())
    }

    fn sample_many(&mut self, points: &[Vec3], fields: &[&str], ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        let Some(c) = Compacted::of(points, |p| is_finite(*p)) else {
            return self.inner.sample_many(points, fields, ids, values);
        };
        let k = fields.len();
        let (mut sub_ids, mut sub_values) = (vec![OUTSIDE; c.points.len()], vec![f32::NAN; c.points.len() * k]);
        self.inner.sample_many(&c.points, fields, &mut sub_ids, &mut sub_values)?;
        c.scatter(&sub_ids, ids, OUTSIDE);
        c.scatter_k(k, &sub_values, values, f32::NAN);
        Ok(())
    }

    fn sample_many64(
        &mut self,
        points: &[[f64; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f64],
    ) -> Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        // Beyond f32's range is beyond every mesh (whose f32 copy is finite), like NaN.
        let in_range = |p: &[f64; 3]| p.iter().all(|c| c.abs() <= f32::MAX as f64);
        let Some(c) = Compacted::of(points, in_range) else {
            return self.inner.sample_many64(points, fields, ids, values);
        };
        let k = fields.len();
        let (mut sub_ids, mut sub_values) = (vec![OUTSIDE; c.points.len()], vec![f64::NAN; c.points.len() * k]);
        self.inner.sample_many64(&c.points, fields, &mut sub_ids, &mut sub_values)?;
        c.scatter(&sub_ids, ids, OUTSIDE);
        c.scatter_k(k, &sub_values, values, f64::NAN);
        Ok(())
    }

    /// A grid's points are finite (its bounds are).
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()> {
        self.inner.sample_grid(grid, range, fields, ids, values)
    }

    /// The backend's own tracer gets only the finite seeds (the others give no line, as a
    /// seed outside the mesh), with the lines' seed indices mapped back.
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        progress: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Option<Vec<Line>>> {
        let Some(c) = Compacted::of(seeds, |p| is_finite(*p)) else {
            return self.inner.trace_lines(seeds, o, vector, progress);
        };
        let Some(mut lines) = self.inner.trace_lines(&c.points, o, vector, progress)? else { return Ok(None) };
        for l in &mut lines {
            l.seed = c.index[l.seed as usize] as u32;
        }
        // VTK's order: by direction, then by seed.
        lines.sort_by_key(|l| (l.backward, l.seed));
        Ok(Some(lines))
    }
}

/// A batch's query points in the precision the caller has them: f32 (the `BatchLocator`
/// methods' own) or the file's f64 (`sample_many64`).
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
        fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()> {
            assert_eq!(count_non_finite(points), 0, "the backend saw a non-finite point");
            self.0.locate(points, ids)
        }
        fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()> {
            assert_eq!(count_non_finite(points), 0, "the backend saw a non-finite point");
            self.0.sample(points, field, values)
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
