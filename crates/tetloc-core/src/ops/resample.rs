//! Resampling to an image (vtkResampleToImage): every grid point of an [`ImageGrid`] is
//! located and the chosen fields sampled there, chunk by chunk in grid order, so the
//! result streams into a file of any size with bounded memory.

use super::{FieldGroup, ImageGrid};
use crate::error::Result;
use crate::locate::BatchLocator;
use crate::Mesh;

/// `grid` with the points `resample` locates for `mesh` through `loc`: its f64 points
/// ([`ImageGrid::f64_points`]) where the mesh's file coordinates are not its f32 copy (f64
/// data, or far from the origin: [`Mesh::wants_f64_points`], the rule for a query's points)
/// and the backend takes f64 points (an empty batch says whether it does); else their f32
/// rounding, which on a mesh that is its own f32 copy near the origin moves a point by at
/// most half an f32 step of its coordinates, the data's own precision.
pub fn grid_for(grid: ImageGrid, mesh: &Mesh, loc: &mut dyn BatchLocator) -> ImageGrid {
    let wide = mesh.wants_f64_points() && loc.sample_many64(&[], &[], &mut [], &mut []).is_ok();
    grid.with_f64_points(wide)
}

/// Samples `fields` at every point of `grid`, `chunk` points at a time in grid order (x
/// fastest), and hands each chunk's ids (-1: no value) and values (every field's components
/// per point, fields in order; NaN outside) to `sink`.
pub fn resample(
    loc: &mut dyn BatchLocator,
    grid: &ImageGrid,
    fields: &[FieldGroup],
    chunk: usize,
    mut sink: impl FnMut(&[i32], &[f32]) -> Result<()>,
) -> Result<()> {
    let names: Vec<&str> = fields.iter().flat_map(|g| g.component_refs()).collect();
    let n = grid.n_points();
    let chunk = chunk.clamp(1, n.max(1));
    let mut ids = Vec::with_capacity(chunk);
    let mut values = Vec::with_capacity(chunk * names.len());
    for start in (0..n).step_by(chunk) {
        let len = chunk.min(n - start);
        ids.resize(len, 0);
        values.resize(len * names.len(), 0.0);
        crate::locate::sample_grid(loc, grid, start..start + len, &names, &mut ids, &mut values)?;
        sink(&ids, &values)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::fields;
    use crate::test_support::KuhnGrid;
    use crate::{CpuLocator, Field, FieldLocation, Mesh};
    use std::sync::Arc;

    /// A unit cube of tets with a vector field v = (x, 2y, 3z) and its scalar f.
    fn cube_with_vector() -> Arc<Mesh> {
        let m = KuhnGrid::new(4).mesh("cube");
        let mut fields = m.fields.clone();
        for c in 0..3 {
            let values = m.points.iter().map(|p| (c + 1) as f32 * p[c]).collect();
            fields.push(Field { values64: None, name: format!("v[{c}]"), location: FieldLocation::Vertex, values });
        }
        let raw = crate::RawMesh { points: m.points.to_vec(), tets: m.tets.to_vec(), fields, ..Default::default() };
        Arc::new(Mesh::new(raw, "cube+v").unwrap())
    }

    /// Linear fields are reproduced exactly at every grid point; points beyond the mesh get
    /// -1 and NaN; chunks do not change the answers; the default `sample_many` (one pass per
    /// component) agrees with the CPU locator's single lookup.
    #[test]
    fn resampling_a_linear_vector_field() {
        let m = cube_with_vector();
        let v = fields::resolve(&m, "v").unwrap();
        let grid = ImageGrid::spanning([0.0; 3], [1.25, 1.0, 1.0], [6, 5, 4]).unwrap();
        let mut loc = CpuLocator::new(m.clone());
        let collect = |loc: &mut dyn BatchLocator, chunk| {
            let (mut ids, mut vals) = (Vec::new(), Vec::new());
            resample(loc, &grid, std::slice::from_ref(&v), chunk, |i, x| {
                ids.extend_from_slice(i);
                vals.extend_from_slice(x);
                Ok(())
            })
            .unwrap();
            (ids, vals)
        };
        let (ids, vals) = collect(&mut loc, 7);
        assert_eq!(ids.len(), grid.n_points());
        for i in 0..grid.n_points() {
            let p = grid.point(i);
            let got = &vals[3 * i..3 * i + 3];
            if p[0] > 1.0 {
                assert!(ids[i] < 0 && got.iter().all(|x| x.is_nan()), "{p:?}");
            } else {
                assert!(ids[i] >= 0, "{p:?}");
                for c in 0..3 {
                    assert!((got[c] - (c + 1) as f32 * p[c]).abs() < 1e-5, "{p:?}: {got:?}");
                }
            }
        }
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (ids1, vals1) = collect(&mut loc, 1 << 20);
        assert_eq!((ids1, bits(&vals1)), (ids.clone(), bits(&vals)));

        /// A backend without a grid sampler of its own: resample queries the grid's points.
        struct Plain(CpuLocator);
        impl BatchLocator for Plain {
            fn name(&self) -> &str {
                "plain"
            }
            fn query(
                &mut self,
                points: crate::locate::Points<'_>,
                fields: &[&str],
                ids: &mut [i32],
                values: crate::locate::Values<'_>,
            ) -> Result<()> {
                self.0.query(points, fields, ids, values)
            }
        }
        let (ids2, vals2) = collect(&mut Plain(CpuLocator::new(m.clone())), 11);
        assert_eq!((ids2, bits(&vals2)), (ids, bits(&vals)));
    }
}
