//! `interpolation_weights`: the weights of points in the cells they were located in, and the
//! weights' spatial gradients (`tetloc_core::ops::gradients`), for `tetloc.torch`'s
//! differentiable `sample`.

use crate::mesh::{contiguous, PyMesh};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use tetloc_core::ops::gradients::weights;

/// (nodes (K, W) int64, weights (K, W) float64, gradients (K, W, 3) float64, found (K,) bool).
type WeightArrays<'py> =
    (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray3<f64>>, Bound<'py, PyArray1<bool>>);

/// The interpolation weights of (K, 3) float64 points (the file's coordinates) in the cells
/// `ids` (what `locate` answered, -1 outside): W = the most nodes a cell of the mesh has,
/// padded with the cell's first node and weight 0; points outside (or in a cell that could not be inverted)
/// have `found` False and zero weights.
#[pyfunction]
pub fn interpolation_weights<'py>(
    py: Python<'py>,
    mesh: &PyMesh,
    points: PyReadonlyArray2<'_, f64>,
    ids: PyReadonlyArray1<'_, i32>,
) -> PyResult<WeightArrays<'py>> {
    if points.shape()[1] != 3 || points.shape()[0] != ids.len() {
        return Err(PyValueError::new_err(format!(
            "points: shape {:?} for {} ids; expected (K, 3) with K = len(ids)",
            points.shape(),
            ids.len()
        )));
    }
    let pts: &[[f64; 3]] = bytemuck::cast_slice(contiguous(&points, "points")?);
    let ids = contiguous(&ids, "ids")?;
    let limit = mesh.mesh.cells.as_ref().map_or(mesh.mesh.n_tets(), |c| c.len());
    if let Some(bad) = ids.iter().find(|&&i| i >= 0 && i as usize >= limit) {
        return Err(PyValueError::new_err(format!("ids: {bad} is beyond the mesh's {limit} cells")));
    }
    let m = &mesh.mesh;
    let w = py.detach(|| weights(m, pts, ids));
    let (k, width) = (pts.len(), w.width);
    let shape_err = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
    let nodes = Array2::from_shape_vec((k, width), w.nodes.into_iter().map(i64::from).collect()).map_err(shape_err)?;
    let weights = Array2::from_shape_vec((k, width), w.weights).map_err(shape_err)?;
    let gradients =
        Array3::from_shape_vec((k, width, 3), w.gradients.into_iter().flatten().collect()).map_err(shape_err)?;
    Ok((
        PyArray2::from_owned_array(py, nodes),
        PyArray2::from_owned_array(py, weights),
        PyArray3::from_owned_array(py, gradients),
        PyArray1::from_owned_array(py, Array1::from_vec(w.found)),
    ))
}
