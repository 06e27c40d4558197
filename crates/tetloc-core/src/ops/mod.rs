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
    /// Rows a task copies.
    const BLOCK: usize = 1 << 13;
    /// One block with `K` columns known when compiling: plain loads and stores (a slice copy
    /// a row was a call to `memcpy` for one to three values).
    fn block<T: Copy, const K: usize>(rows: &[T], width: usize, first: usize, out: &mut [T]) {
        for (o, r) in out.chunks_exact_mut(K).zip(rows.chunks_exact(width)) {
            let o: &mut [T; K] = o.try_into().expect("K values a row");
            *o = std::array::from_fn(|j| r[first + j]);
        }
    }
    let (k, width, first) = (columns.len(), width.max(1), columns.start);
    if k == 0 {
        return;
    }
    assert!(columns.end <= width, "columns {columns:?} of rows of {width}");
    out.par_chunks_mut(k * BLOCK).zip(rows.par_chunks(width * BLOCK)).for_each(|(o, r)| match k {
        1 => block::<T, 1>(r, width, first, o),
        2 => block::<T, 2>(r, width, first, o),
        3 => block::<T, 3>(r, width, first, o),
        _ => o.chunks_exact_mut(k).zip(r.chunks_exact(width)).for_each(|(o, r)| o.copy_from_slice(&r[columns.clone()])),
    });
}

#[cfg(test)]
mod tests {
    /// Every column range of rows of several widths, over more rows than a task's block and
    /// not a multiple of it: the columns row after row.
    #[test]
    fn components_are_the_columns_row_after_row() {
        for width in [1usize, 3, 5, 7] {
            let n = 3 * 8192 + 17;
            let rows: Vec<u32> = (0..(n * width) as u32).collect();
            for first in 0..width {
                for end in first..=width {
                    let want: Vec<u32> = rows.chunks(width).flat_map(|r| r[first..end].to_vec()).collect();
                    let mut out = vec![0u32; n * (end - first)];
                    super::copy_components(&rows, width, first..end, &mut out);
                    assert_eq!(out, want, "width {width}, columns {first}..{end}");
                }
            }
        }
    }
}
