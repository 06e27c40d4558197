//! What users do with point location, as ParaView's filters do it: [`resample`] a mesh's
//! fields onto a regular image (vtkResampleToImage), [`probe`] one mesh's fields at another's
//! points (vtkResampleWithDataSet), and trace particles through a vector field
//! (vtkStreamTracer). Each works over any [`crate::BatchLocator`], so on every backend.

pub mod gradients;
pub mod probe;
pub mod resample;
pub mod trace;
pub mod weights;

// The field groups and the image grid live below the locators (the locators take them);
// the operations' callers keep finding them here.
pub use crate::geom::ImageGrid;
pub use crate::mesh::field_groups as fields;
pub use fields::FieldGroup;

/// Points per batch handed to a locator: large enough to keep a GPU busy, small enough to
/// bound memory (a batch's points, ids and values) for any output size.
pub const CHUNK: usize = 1 << 22;

/// Parts of known lengths concatenated on every core: part `i` has `lens[i]` values, written
/// by `fill(i, its slice)`. Collecting a `flat_map` instead goes through a list of buffers and
/// copies every value once more on one core, into memory that faults in page by page on that
/// core: most of a second for a trace's 9M points and their fields.
pub(crate) fn concat<T: Copy + Default + Send + Sync>(lens: &[usize], fill: impl Fn(usize, &mut [T]) + Sync) -> Vec<T> {
    use rayon::prelude::*;
    let mut out = vec![T::default(); lens.iter().sum()];
    let mut parts = Vec::with_capacity(lens.len());
    let mut rest = &mut out[..];
    for &n in lens {
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(n);
        parts.push(part);
        rest = tail;
    }
    parts.into_par_iter().enumerate().for_each(|(i, part)| fill(i, part));
    out
}

/// Components `columns` of every row of `rows` (`width` values a row: every field's
/// components of a point, fields in order) into `out`, row after row, on every core: one
/// field's array out of a batch's interleaved values.
pub fn copy_components<T: Copy + Send + Sync>(
    rows: &[T],
    width: usize,
    columns: std::ops::Range<usize>,
    out: &mut [T],
) {
    use rayon::prelude::*;
    out.par_chunks_mut(columns.len().max(1))
        .zip(rows.par_chunks_exact(width.max(1)))
        .for_each(|(o, r)| o.copy_from_slice(&r[columns.clone()]));
}
