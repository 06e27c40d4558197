//! `CudaLocator`: the zero-copy path of `tetloc.torch` for CUDA tensors
//! (`tetloc_vulkan::cuda_interop`): points and ids stay on the GPU, handed between CUDA and
//! Vulkan through shared memory and semaphores on the caller's stream. `tetloc.torch` passes
//! the tensors' device addresses (`data_ptr()`) and the stream (`cuda_stream`); it checks
//! their device, dtype, shape and contiguity first, so addresses here are trusted.

use crate::errors::{guarded, DeviceError};
use crate::mesh::PyMesh;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::sync::Mutex;
use tetloc_vulkan::cuda_interop::{self, CudaError, CudaLocator, WeightsOut};

fn to_py(e: CudaError) -> PyErr {
    DeviceError::new_err(e.to_string())
}

/// A soft-bvh locator on the Vulkan device of one CUDA device, for CUDA tensors.
#[pyclass(name = "CudaLocator", module = "tetloc._tetloc")]
pub struct PyCudaLocator {
    inner: Mutex<CudaLocator>,
}

#[pymethods]
impl PyCudaLocator {
    /// Builds the locator of `mesh` on CUDA device `cuda_device` (the Vulkan device of the same
    /// GPU, found by UUID, or `vulkan_device`, which must be it). Raises `tetloc.DeviceError`
    /// without a CUDA driver, on another GPU, or without the Vulkan extensions the sharing
    /// needs, and for meshes the path does not take (then the host path serves them).
    /// `validation`: the Vulkan validation layer (default: `TETLOC_VK_VALIDATION`).
    #[new]
    #[pyo3(signature = (mesh, cuda_device, vulkan_device=None, validation=None))]
    fn new(
        py: Python<'_>,
        mesh: &PyMesh,
        cuda_device: i32,
        vulkan_device: Option<usize>,
        validation: Option<bool>,
    ) -> PyResult<Self> {
        let mesh = mesh.mesh.clone();
        let validation = validation.unwrap_or_else(|| tetloc_vulkan::ContextOptions::default().validation);
        let loc = py.detach(|| {
            guarded("building the CUDA locator", || {
                CudaLocator::new(mesh, cuda_device, vulkan_device, validation).map_err(to_py)
            })
        })?;
        Ok(PyCudaLocator { inner: Mutex::new(loc) })
    }

    /// Locates `n` float32 points (x, y, z interleaved) at CUDA address `points` into `n`
    /// int32 ids at CUDA address `ids`, ordered on CUDA stream `stream` (its handle; 0: the
    /// default stream). The caller guarantees both addresses are contiguous memory of this
    /// CUDA device of 12 n and 4 n bytes.
    fn locate(&self, py: Python<'_>, points: u64, n: usize, ids: u64, stream: u64) -> PyResult<()> {
        check_call(points, n, &[ids])?;
        // SAFETY: `tetloc.torch` passes the addresses of live, contiguous CUDA tensors of the
        // right sizes on this device, and the stream of that device.
        self.call(py, |loc| unsafe { loc.locate(points, n, ids, stream) })
    }

    /// Locates as `locate` and writes how each point's values are interpolated in its tet:
    /// its four vertex ids at `nodes` (int32, 0 outside) and their weights at `weights`
    /// (float32 barycentrics, 0 outside), four a point. The caller guarantees `nodes` and
    /// `weights` are contiguous memory of this CUDA device of 16 n bytes each, besides what
    /// `locate` asks.
    #[allow(clippy::too_many_arguments)] // the addresses of four tensors, their length and the stream
    fn weights(
        &self,
        py: Python<'_>,
        points: u64,
        n: usize,
        ids: u64,
        nodes: u64,
        weights: u64,
        stream: u64,
    ) -> PyResult<()> {
        check_call(points, n, &[ids, nodes, weights])?;
        // SAFETY: as in `locate`.
        self.call(py, |loc| unsafe { loc.weights(points, n, WeightsOut { ids, nodes, weights }, stream) })
    }

    /// The CUDA device this locator serves.
    #[getter]
    fn cuda_device(&self) -> i32 {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).cuda_device()
    }

    /// How CUDA and Vulkan hand over work: "timeline" or "binary" semaphores.
    #[getter]
    fn semaphores(&self) -> &'static str {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).semaphores()
    }

    /// Points a call may take before the shared buffers grow (0 before the first call).
    #[getter]
    fn capacity(&self) -> usize {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).capacity()
    }

    /// Validation-layer errors of this locator's Vulkan context so far.
    fn validation_errors(&self) -> usize {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).vulkan().context().validation_errors()
    }
}

impl PyCudaLocator {
    /// Runs `f` on the locator without the GIL, its errors as `DeviceError`.
    fn call(&self, py: Python<'_>, f: impl FnOnce(&mut CudaLocator) -> Result<(), CudaError> + Send) -> PyResult<()> {
        py.detach(|| {
            guarded("locating CUDA points", || {
                let mut loc = self.inner.lock().unwrap_or_else(|e| e.into_inner());
                f(&mut loc).map_err(to_py)
            })
        })
    }
}

/// Refuses null addresses for a call of `n > 0` points, and more than `i32::MAX` points.
fn check_call(points: u64, n: usize, outputs: &[u64]) -> PyResult<()> {
    if n > 0 && (points == 0 || outputs.contains(&0)) {
        return Err(PyValueError::new_err("null device addresses"));
    }
    if n > i32::MAX as usize {
        return Err(PyValueError::new_err(format!("{n} points: at most 2^31 - 1 a call")));
    }
    Ok(())
}

/// Whether the CUDA driver can be loaded in this process (the zero-copy path needs it).
#[pyfunction]
pub fn cuda_driver_available() -> bool {
    cuda_interop::driver_available()
}
