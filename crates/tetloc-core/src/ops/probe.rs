//! Probing (vtkResampleWithDataSet): a source mesh's fields sampled at a target's points.
//! The result is the target (a mesh with its cells and data, or a point set) plus one
//! array per source field (cell fields become point data, as VTK's probe makes them) and
//! `vtkValidPointMask`.

use super::{FieldGroup, CHUNK};
use crate::error::Result;
use crate::geom::Vec3;
use crate::locate::{BatchLocator, Points};
use rayon::prelude::*;

/// The source's fields at the target's points.
#[derive(Default)]
pub struct Probed {
    /// The containing source tet of each point (-1: no value).
    pub ids: Vec<i32>,
    /// Each field with its values, k per point (NaN where the point got none).
    pub arrays: Vec<(FieldGroup, Vec<f32>)>,
    /// One entry for each of `arrays`: its f64 values when the field has f64 data and the
    /// backend takes f64 points (`None` otherwise): what the writers write, as Float64.
    pub arrays64: Vec<Option<Vec<f64>>>,
}

impl Probed {
    /// `vtkValidPointMask`: 1 where a point got values.
    pub fn mask(&self) -> Vec<u8> {
        self.ids.iter().map(|&i| u8::from(i >= 0)).collect()
    }

    pub fn n_valid(&self) -> usize {
        self.ids.iter().filter(|&&i| i >= 0).count()
    }
}

/// Samples `fields` (of the mesh `loc` locates in) at `points`, in the backend's batches;
/// `progress` gets the number of points done so far (an error from it stops the probe: an
/// interruption).
pub fn probe(
    loc: &mut dyn BatchLocator,
    points: &[Vec3],
    fields: &[FieldGroup],
    progress: impl FnMut(usize) -> Result<()>,
) -> Result<Probed> {
    probe_points(loc, Points::F32(points), fields, progress)
}

/// [`probe`] at points of either precision: f64 points (a target's coordinates as its file
/// has them) keep a target far from the origin precise, on backends that take f64 points.
pub fn probe_points(
    loc: &mut dyn BatchLocator,
    points: Points,
    fields: &[FieldGroup],
    mut progress: impl FnMut(usize) -> Result<()>,
) -> Result<Probed> {
    let names: Vec<&str> = fields.iter().flat_map(|g| g.component_refs()).collect();
    let n = points.len();
    let mut ids = vec![0i32; n];
    // Batches as the backend takes them best: the CPU's values stay in cache until each
    // batch's columns are copied to the fields' arrays.
    let batch = loc.preferred_batch().unwrap_or(CHUNK).clamp(1, CHUNK);
    // Fields of f64 data, and points f32 cannot hold, go through the f64 path (its exact
    // ids and f64 values) where the backend takes f64 points (an empty batch says whether
    // it does): every field in one pass.
    let wide =
        (fields.iter().any(|g| g.f64) || points.need_f64()) && loc.sample_many64(&[], &names, &mut [], &mut []).is_ok();
    if wide {
        let arrays64 = in_batches(n, batch, fields, &mut ids, &mut progress, |r, ids, values| {
            loc.sample_many64(&points.wide(r), &names, ids, values)
        })?;
        let arrays =
            fields.iter().zip(&arrays64).map(|(g, v)| (g.clone(), v.par_iter().map(|&v| v as f32).collect())).collect();
        let arrays64 = fields.iter().zip(arrays64).map(|(g, v)| g.f64.then_some(v)).collect();
        return Ok(Probed { ids, arrays, arrays64 });
    }
    let arrays = in_batches(n, batch, fields, &mut ids, &mut progress, |r, ids, values| {
        loc.sample_many(&points.narrow(r), &names, ids, values)
    })?;
    Ok(Probed { ids, arrays: fields.iter().cloned().zip(arrays).collect(), arrays64: vec![None; fields.len()] })
}

/// Samples `n` points in batches of `batch` (`sample(range, ids, values)`, every field's
/// components a point), each batch's values in one buffer, reused, and copied out to one
/// array per field (its components together).
fn in_batches<T: Copy + Default + Send + Sync>(
    n: usize,
    batch: usize,
    fields: &[FieldGroup],
    ids: &mut [i32],
    progress: &mut impl FnMut(usize) -> Result<()>,
    mut sample: impl FnMut(std::ops::Range<usize>, &mut [i32], &mut [T]) -> Result<()>,
) -> Result<Vec<Vec<T>>> {
    let width: usize = fields.iter().map(FieldGroup::n_components).sum();
    let mut arrays: Vec<Vec<T>> = fields.iter().map(|g| vec![T::default(); n * g.n_components()]).collect();
    let mut buffer = vec![T::default(); batch.min(n) * width];
    for start in (0..n).step_by(batch) {
        let r = start..(start + batch).min(n);
        let values = &mut buffer[..r.len() * width];
        sample(r.clone(), &mut ids[r.clone()], values)?;
        let mut at = 0;
        for (g, out) in fields.iter().zip(&mut arrays) {
            let k = g.n_components();
            super::copy_components(values, width, at..at + k, &mut out[r.start * k..r.end * k]);
            at += k;
        }
        progress(r.end)?;
    }
    Ok(arrays)
}

impl Probed {
    /// [`Self::from_values`] of f64 values: rounded to f32 for `arrays`, kept in `arrays64`
    /// for the fields of f64 data.
    pub(crate) fn from_values64(ids: Vec<i32>, fields: &[FieldGroup], values: &[f64]) -> Probed {
        let width: usize = fields.iter().map(FieldGroup::n_components).sum();
        let narrow: Vec<f32> = values.par_iter().map(|&v| v as f32).collect();
        let mut probed = Probed::from_values(ids, fields, &narrow);
        let mut at = 0;
        probed.arrays64 = fields
            .iter()
            .map(|g| {
                let k = g.n_components();
                let v = g.f64.then(|| components(values, width, at, k));
                at += k;
                v
            })
            .collect();
        probed
    }

    /// One array per field, its components together, from `values` (every field's components
    /// per point, fields in order).
    pub(crate) fn from_values(ids: Vec<i32>, fields: &[FieldGroup], values: &[f32]) -> Probed {
        let width: usize = fields.iter().map(FieldGroup::n_components).sum();
        let mut at = 0;
        let arrays = fields
            .iter()
            .map(|g| {
                let k = g.n_components();
                let v = components(values, width, at, k);
                at += k;
                (g.clone(), v)
            })
            .collect();
        Probed { ids, arrays, arrays64: vec![None; fields.len()] }
    }
}

/// Components `at..at + k` of every point of `values` (`width` per point), on every core.
fn components<T: Copy + Default + Send + Sync>(values: &[T], width: usize, at: usize, k: usize) -> Vec<T> {
    let mut out = vec![T::default(); values.len() / width.max(1) * k];
    super::copy_components(values, width, at..at + k, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::ops::fields;
    use crate::test_support::KuhnGrid;
    use crate::CpuLocator;
    use std::sync::Arc;

    /// The CPU locator as another backend: one that takes f32 points only, or that prefers
    /// batches of `batch` points (and is never given more).
    struct Backend {
        cpu: CpuLocator,
        f32_only: bool,
        batch: Option<usize>,
    }

    impl BatchLocator for Backend {
        fn name(&self) -> &str {
            "backend"
        }
        fn query(
            &mut self,
            points: Points<'_>,
            fields: &[&str],
            ids: &mut [i32],
            values: crate::locate::Values<'_>,
        ) -> Result<()> {
            assert!(points.len() <= self.batch.unwrap_or(usize::MAX), "a batch of {}", points.len());
            match points {
                Points::F64(_) if self.f32_only => Err(crate::Error::Invalid("f32 points only".into())),
                _ => self.cpu.query(points, fields, ids, values),
            }
        }
        fn preferred_batch(&self) -> Option<usize> {
            self.batch
        }
    }

    /// Probing a mesh at its own vertices gives back its point field; points beyond it get
    /// NaN and mask 0; a cell field becomes point data. (How the result is written:
    /// `tetloc_io::ops_output`.)
    #[test]
    fn probing_a_mesh_onto_itself_and_beyond() {
        let m = Arc::new(KuhnGrid::new(3).mesh("cube"));
        let groups = fields::groups(&m);
        let mut points = m.points.to_vec();
        points.push([2.0, 0.5, 0.5]);
        let mut loc = CpuLocator::new(m.clone());
        let mut last = 0;
        let p = probe(&mut loc, &points, &groups, |d| {
            last = d;
            Ok(())
        })
        .unwrap();
        assert_eq!(last, points.len());
        assert_eq!(p.n_valid(), m.points.len());
        let (g, f) = &p.arrays[0];
        assert_eq!(g.name, "f");
        let want = &m.field("f").unwrap().values;
        assert!(want.iter().zip(f).all(|(a, b)| (a - b).abs() <= 1e-6 * (1.0 + a.abs())));
        assert!(f.last().unwrap().is_nan() && *p.mask().last().unwrap() == 0);
        // Every field has its (here empty) f64 entry: the Python binding pairs them up, and
        // dropped every field where this list was empty.
        assert_eq!(p.arrays64.len(), p.arrays.len());
        assert!(p.arrays64.iter().all(Option::is_none));
        let width: usize = groups.iter().map(FieldGroup::n_components).sum();
        let lines = Probed::from_values(p.ids.clone(), &groups, &vec![0.0; p.ids.len() * width]);
        assert_eq!(lines.arrays64.len(), groups.len());
    }

    /// A field of f64 data is probed in f64 (as VTK's probe keeps the source array's type): at
    /// the mesh's own vertices it comes back exactly; with a backend that takes f32 points only
    /// it is f32 as before.
    #[test]
    fn f64_fields_are_probed_in_f64() {
        use crate::locate::{Tolerance, WithTolerance};
        use crate::mesh::{Field, FieldLocation};
        let mut m = KuhnGrid::new(3).mesh("cube");
        let g: Vec<f64> = m.points.iter().map(|p| 1e-9 + p[0] as f64 * 1e-12 + 1e-17).collect();
        m.fields.push(Field::from_f64("g", FieldLocation::Vertex, g.clone()));
        let m = Arc::new(m);
        let groups = fields::groups_of(&m.fields);
        assert!(groups.iter().any(|g| g.f64) && groups.iter().any(|g| !g.f64));
        let p = probe(&mut CpuLocator::new(m.clone()), &m.points, &groups, |_| Ok(())).unwrap();
        let i = groups.iter().position(|gr| gr.name == "g").unwrap();
        let got = p.arrays64[i].as_ref().expect("probed in f64");
        assert!(got.iter().zip(&g).all(|(a, b)| a.to_bits() == b.to_bits()));
        // Through the boundary tolerance too.
        let mut tol = WithTolerance::new(CpuLocator::new(m.clone()), m.clone(), "1%".parse::<Tolerance>().unwrap());
        let p = probe(&mut tol, &m.points, &groups, |_| Ok(())).unwrap();
        let got = p.arrays64[i].as_ref().expect("probed in f64 with a tolerance");
        assert!(got.iter().zip(&g).all(|(a, b)| a.to_bits() == b.to_bits()));
        // A backend that takes f32 points only gives f32 values.
        let narrow = &mut Backend { cpu: CpuLocator::new(m.clone()), f32_only: true, batch: None };
        let p = probe(narrow, &m.points, &groups, |_| Ok(())).unwrap();
        assert!(p.arrays64.iter().all(Option::is_none));
    }

    /// A target far from the origin is probed at its f64 coordinates: a source vertex of a
    /// UTM-like mesh gets the source's value there, as at the origin (its f32 rounding would
    /// move it by up to a quarter of a unit).
    #[test]
    fn far_targets_are_probed_at_their_f64_coordinates() {
        let grid = KuhnGrid::new(3).jitter(0.2, 9);
        let raw = crate::test_support::mixed::moved(grid.raw(), [512_345.0, 4_123_456.0, 1_000.0]);
        let p64 = raw.points64.clone().expect("moved meshes have f64 coordinates");
        let far = Arc::new(Mesh::new(raw, "far cube").unwrap());
        let near = grid.mesh("cube");
        let groups = fields::groups_of(&far.fields);
        let p = probe_points(&mut CpuLocator::new(far.clone()), Points::F64(&p64), &groups, |_| Ok(())).unwrap();
        assert_eq!(p.n_valid(), p64.len(), "every vertex is in the mesh");
        let (g, f) = &p.arrays[0];
        assert_eq!(g.name, "f");
        let want = &near.field("f").unwrap().values;
        assert!(want.iter().zip(f).all(|(a, b)| (a - b).abs() <= 1e-6 * (1.0 + a.abs())), "{want:?} {f:?}");
        // Rounded to f32 the same targets miss: some land outside or off their values.
        let p32: Vec<Vec3> = p64.iter().map(|q| q.map(|c| c as f32)).collect();
        let q = probe(&mut CpuLocator::new(far.clone()), &p32, &groups, |_| Ok(())).unwrap();
        let off = want.iter().zip(&q.arrays[0].1).filter(|(a, b)| (*a - *b).abs() > 1e-3 || b.is_nan()).count();
        assert!(off > 0, "f32 targets this far out lose precision");
    }

    /// A probe in the backend's batches (here 7 points, the last batch short) is the probe
    /// in one: the same ids, every field's values bit for bit, the progress at each batch's
    /// end; in f32 and in f64 (a field of f64 data).
    #[test]
    fn batches_give_the_one_batch_answers() {
        use crate::mesh::{Field, FieldLocation};
        let mut m = KuhnGrid::new(3).jitter(0.2, 4).mesh("cube");
        let g: Vec<f64> = m.points.iter().map(|p| 1e-9 + p[1] as f64 * 1e-12).collect();
        for k in 0..3 {
            let v = m.points.iter().map(|p| p[k] * (k as f32 - 1.5)).collect();
            m.fields.push(Field::new(format!("v[{k}]"), FieldLocation::Vertex, v));
        }
        m.fields.push(Field::new("h", FieldLocation::Cell, (0..m.n_tets()).map(|t| t as f32).collect()));
        m.fields.push(Field::from_f64("g", FieldLocation::Vertex, g));
        let m = Arc::new(m);
        let mut points: Vec<Vec3> = (0..60).map(|i| [0.017 * i as f32, 0.4 + 0.009 * i as f32, 0.5]).collect();
        points.push([1.5, 0.5, 0.5]);
        let bits = |p: &Probed| {
            let f32s =
                p.arrays.iter().map(|(_, v)| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>();
            let f64s = p.arrays64.iter().map(|v| v.as_ref().map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()));
            (p.ids.clone(), f32s, f64s.collect::<Vec<_>>())
        };
        let all = fields::groups_of(&m.fields);
        assert!(all.iter().any(|g| g.f64) && all.iter().any(|g| g.n_components() == 3), "f64 and vector fields");
        for groups in [fields::groups_of(&m.fields[..1]), all] {
            let one = probe(&mut CpuLocator::new(m.clone()), &points, &groups, |_| Ok(())).unwrap();
            let mut done = Vec::new();
            let batched = &mut Backend { cpu: CpuLocator::new(m.clone()), f32_only: false, batch: Some(7) };
            let batched = probe(batched, &points, &groups, |d| {
                done.push(d);
                Ok(())
            })
            .unwrap();
            assert!(bits(&one) == bits(&batched), "{} fields", groups.len());
            assert_eq!(one.arrays.len(), groups.len());
            assert_eq!(done, (1..=9).map(|k| (7 * k).min(61)).collect::<Vec<_>>());
            assert!(one.n_valid() > 50 && one.n_valid() < 61);
        }
    }
}
