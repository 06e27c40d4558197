//! `_StepWeights`: the interpolation weights of fixed points, applied to many time steps of
//! a point field (issue 32: locate once, interpolate many). A GPU locator's weights go up to
//! its device once and each batch of steps runs there (`tetloc_vulkan::GpuWeights`); a cpu
//! locator's apply on the host (`Weights::apply`, rayon over the points). Both sum in f64 and
//! round to f32, so on a device with shaderFloat64 the two give the same bits.

use crate::errors::to_py;
use crate::mesh::contiguous;
use numpy::ndarray::Array3;
use numpy::{PyArray1, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::sync::Mutex;
use tetloc_core::ops::weights::Weights;
use tetloc_vulkan::GpuWeights;

/// A CSR matrix's indptr (int64), indices (int32) and data (float64).
pub type CsrArrays<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<i32>>, Bound<'py, PyArray1<f64>>);

/// `w`'s CSR arrays over the mesh's vertices, as numpy arrays (scipy's index types).
pub fn csr<'py>(py: Python<'py>, w: &Weights) -> CsrArrays<'py> {
    let indptr: Vec<i64> = w.offsets.iter().map(|&o| o as i64).collect();
    let indices: Vec<i32> = w.vertices.iter().map(|&v| v as i32).collect();
    (PyArray1::from_vec(py, indptr), PyArray1::from_vec(py, indices), PyArray1::from_slice(py, &w.weights))
}

#[pyclass(name = "_StepWeights", module = "tetloc._tetloc", frozen)]
pub struct PyStepWeights {
    weights: Weights,
    /// `None`: applied on the host.
    gpu: Option<Mutex<GpuWeights>>,
    device: String,
}

impl PyStepWeights {
    /// `weights` applied on the host (`device` `None`) or on the Vulkan device `device`
    /// (`Some(None)`: the best one, as the locator chose it).
    pub fn new(py: Python<'_>, weights: Weights, device: Option<Option<usize>>) -> PyResult<PyStepWeights> {
        let Some(index) = device else { return Ok(PyStepWeights { weights, gpu: None, device: "cpu".into() }) };
        let ctx = tetloc_locator::context(index).map_err(|e| PyRuntimeError::new_err(e.msg))?;
        let gpu = py.detach(|| GpuWeights::new(&ctx, &weights)).map_err(|e| to_py(e.into()))?;
        Ok(PyStepWeights { weights, gpu: Some(Mutex::new(gpu)), device: ctx.info().name.clone() })
    }
}

#[pymethods]
impl PyStepWeights {
    /// Where `apply` runs: "cpu" or the Vulkan device's name.
    #[getter]
    fn device(&self) -> &str {
        &self.device
    }

    #[getter]
    fn n_points(&self) -> usize {
        self.weights.n_points()
    }

    #[getter]
    fn n_vertices(&self) -> usize {
        self.weights.n_vertices
    }

    /// Each point's cell (-1 outside).
    fn cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        PyArray1::from_slice(py, &self.weights.cells)
    }

    /// The CSR arrays: indptr (K + 1,) int64, indices int32, data float64.
    fn csr<'py>(&self, py: Python<'py>) -> CsrArrays<'py> {
        csr(py, &self.weights)
    }

    /// S steps of a k-component point field, (S, n_vertices, k) float32 C-contiguous, at the
    /// points: (S, n_points, k) float32, NaN outside.
    fn apply<'py>(&self, py: Python<'py>, values: PyReadonlyArray3<'_, f32>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let &[s, nv, k] = values.shape() else { unreachable!("a 3-d array") };
        let n = self.weights.n_points();
        if nv != self.weights.n_vertices || k == 0 {
            return Err(PyValueError::new_err(format!(
                "values: shape {:?}; expected (steps, {}, components >= 1): a point field of the mesh's vertices",
                values.shape(),
                self.weights.n_vertices
            )));
        }
        let values = contiguous(&values, "values")?;
        let mut out = vec![0f32; s * n * k];
        if s > 0 && n > 0 {
            let steps: Vec<&[f32]> = values.chunks(nv * k).collect();
            py.detach(|| match &self.gpu {
                Some(gpu) => gpu.lock().unwrap_or_else(|p| p.into_inner()).apply_steps(&steps, k, &mut out),
                None => {
                    steps.iter().zip(out.chunks_mut(n * k)).try_for_each(|(step, o)| self.weights.apply(step, k, o))
                }
            })
            .map_err(to_py)?;
        }
        let out = Array3::from_shape_vec((s, n, k), out).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(PyArray3::from_owned_array(py, out))
    }
}
