//! `_Locator`: one backend's search structure over a `_Mesh`, and the batch calls. Builds run
//! on a worker thread (interruptible, with progress); batches run in chunks with the GIL
//! released and a check for Ctrl-C between chunks. The public `tetloc.Locator`
//! (python/tetloc/_locator.py) wraps it.

use crate::alloc::PeakMeter;
use crate::backend;
use crate::background;
use crate::errors::{internal_error, to_py};
use crate::mesh::{contiguous, PyMesh};
use crate::steps::PyStepWeights;
use numpy::{PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::PyDict;
use std::ops::Range;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tetloc_core::locate::{count_non_finite, Precision, Tolerance};
use tetloc_core::ops::weights::Weights;
use tetloc_core::{BatchLocator, Mesh, Vec3};
use tetloc_locator::{AutoReason, Layer, Locator, LocatorOptions, Memory};

/// Points per call into the backend between two checks for Ctrl-C: about 0.2 s on two cores.
const CPU_CHUNK: usize = 1 << 20;

/// Every keyword `tetloc.Locator` takes (its named arguments, then the `**options` this
/// version knows), listed when an option is misspelt; and the options that are planned.
const KNOWN_OPTIONS: &str = "backend, device, progress, tolerance, split, compact, precision, deferred";
const PLANNED_OPTIONS: [&str; 0] = [];

pub(crate) type Backend = Box<dyn BatchLocator + Send>;
type IdsAndValues<'py> = (Bound<'py, PyArray1<i32>>, Bound<'py, PyArray1<f32>>);
/// Ids, and one row of field values per point.
type IdsAndRows<'py> = (Bound<'py, PyArray1<i32>>, Bound<'py, PyArray2<f64>>);
/// A CSR matrix's indptr, indices and data, and each row's cell.
type CsrRows<'py> =
    (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<i32>>, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<i32>>);

#[pyclass(name = "_Locator", module = "tetloc._tetloc", frozen)]
pub struct PyLocator {
    /// `None` after a panic inside the backend: its state is unknown, so it is not used again.
    pub(crate) backend: Mutex<Option<Backend>>,
    pub(crate) name: String,
    pub(crate) mesh: Arc<Mesh>,
    chunk: usize,
    memory: Memory,
    build_seconds: f64,
    note: Option<String>,
    /// The backend and its layers, innermost first (the front door's `Built::describe`).
    stack: Vec<String>,
    progress: Option<Py<PyAny>>,
    /// float64 points go through `sample_many64` when the mesh's data is f64 or far from the
    /// origin (`Mesh::wants_f64_points`), and not with a tolerance, whose rescue of points near
    /// the boundary works in float32; also on a mesh with f64 field data, or with
    /// `precision="f64"`, for f64 values.
    takes_f64: bool,
    precision: Precision,
    /// The Vulkan device asked for (`None`: the best one), for `step_weights` on a GPU backend.
    device: Option<usize>,
}

/// What `**options` asks for, past the backend's name.
#[derive(Default)]
struct Options {
    vulkan: LocatorOptions,
    tolerance: Tolerance,
    precision: Precision,
    /// cpu: the search is built on first need (a resample's grid may need none).
    deferred: bool,
}

/// The options from `**options`; unknown names are a `TypeError` as for any keyword.
fn parse_options(options: Option<&Bound<'_, PyDict>>) -> PyResult<Options> {
    let mut o = Options::default();
    let Some(options) = options else { return Ok(o) };
    let flag = |name: &str, value: &Bound<'_, PyAny>| {
        value
            .extract::<bool>()
            .map_err(|_| PyTypeError::new_err(format!("{name}: expected True or False, got {value}")))
    };
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        match key.as_str() {
            "split" => {
                o.vulkan.rt.split = if value.is_none() {
                    None
                } else {
                    match value.extract::<usize>() {
                        Ok(n) if n > 0 => Some(n),
                        _ => {
                            return Err(PyValueError::new_err(format!(
                                "split: expected a positive number of primitives per structure, or None for one \
                                 structure; got {value}"
                            )))
                        }
                    }
                }
            }
            "tolerance" => {
                // A distance in mesh units, or a string such as "1%" (of the mean edge length).
                let text = match value.extract::<f64>() {
                    Ok(d) => d.to_string(),
                    Err(_) => value.extract::<String>().map_err(|_| {
                        PyTypeError::new_err(format!("tolerance: expected a number or a string like '1%', got {value}"))
                    })?,
                };
                o.tolerance = text.parse().map_err(|e: tetloc_core::Error| PyValueError::new_err(e.to_string()))?;
            }
            "precision" => {
                let text = value
                    .extract::<String>()
                    .map_err(|_| PyValueError::new_err(format!("precision: expected 'f32' or 'f64', got {value}")))?;
                o.precision = text.parse().map_err(|e: tetloc_core::Error| PyValueError::new_err(e.to_string()))?;
            }
            "deferred" => o.deferred = flag("deferred", &value)?,
            "compact" => o.vulkan.rt.compact = flag("compact", &value)?,
            k if PLANNED_OPTIONS.contains(&k) => {
                return Err(PyTypeError::new_err(format!(
                    "Locator(): option '{k}' is planned but not supported by this version (known: {KNOWN_OPTIONS})"
                )))
            }
            k => {
                return Err(PyTypeError::new_err(format!(
                    "Locator() got an unexpected option '{k}' (known: {KNOWN_OPTIONS})"
                )))
            }
        }
    }
    Ok(o)
}

impl PyLocator {
    /// The weights of (K, 3) float64 points in the cells `locate` finds them in (at float64
    /// precision when `takes_f64`, else rounded to float32 as `locate` rounds them).
    fn located_weights(&self, py: Python<'_>, points: &PyReadonlyArray2<'_, f64>) -> PyResult<Weights> {
        if points.shape()[1] != 3 {
            return Err(PyValueError::new_err(format!("points: shape {:?}; expected (K, 3)", points.shape())));
        }
        let pts: &[[f64; 3]] = bytemuck::cast_slice(contiguous(points, "points")?);
        let mut cells = vec![tetloc_core::OUTSIDE; pts.len()];
        let out = &mut cells;
        let located: Vec<[f64; 3]> = if self.takes_f64 {
            self.chunked(py, pts.len(), |loc, r| loc.sample_many64(&pts[r.clone()], &[], &mut out[r], &mut []))?;
            pts.to_vec()
        } else {
            let narrow: Vec<Vec3> = pts.iter().map(|p| p.map(|c| c as f32)).collect();
            self.chunked(py, pts.len(), |loc, r| loc.locate(&narrow[r.clone()], &mut out[r]))?;
            narrow.iter().map(|p| p.map(f64::from)).collect()
        };
        let mesh = &self.mesh;
        py.detach(|| Weights::from_cells(mesh, &located, cells)).map_err(to_py)
    }

    /// Runs `f` over `n` points in chunks, with the GIL released during each chunk and a
    /// check for Ctrl-C (and a progress tick) between chunks.
    fn chunked(
        &self,
        py: Python<'_>,
        n: usize,
        mut f: impl FnMut(&mut (dyn BatchLocator + Send), Range<usize>) -> tetloc_core::Result<()> + Send,
    ) -> PyResult<()> {
        // Waits for another thread's call on this locator without holding the GIL.
        let mut guard = self.backend.lock_py_attached(py).unwrap_or_else(|p| p.into_inner());
        let t0 = Instant::now();
        let mut start = 0;
        while start < n {
            let Some(loc) = guard.as_mut() else {
                return Err(PyRuntimeError::new_err(format!(
                    "this {} Locator is unusable after an internal error; build a new one",
                    self.name
                )));
            };
            let range = start..n.min(start + self.chunk);
            start = range.end;
            let loc: &mut (dyn BatchLocator + Send) = &mut **loc;
            match py.detach(|| catch_unwind(AssertUnwindSafe(|| f(loc, range)))) {
                Ok(result) => result.map_err(to_py)?,
                Err(panic) => {
                    *guard = None;
                    return Err(internal_error(&format!("locating on {}", self.name), &*panic));
                }
            }
            if start < n {
                py.check_signals()?;
                if let Some(p) = &self.progress {
                    let stage = format!("locating on {}", self.name);
                    p.call1(py, (stage, start as f64 / n as f64, t0.elapsed().as_secs_f64()))?;
                }
            }
        }
        if let (Some(p), true) = (&self.progress, n > self.chunk) {
            p.call1(py, ("done", 1.0, t0.elapsed().as_secs_f64()))?;
        }
        Ok(())
    }
}

/// The points of a (K, 3) float32 C-contiguous array, without a copy. Points with a NaN or
/// infinite coordinate (also float64 values beyond float32's range) are answered -1 / NaN, with
/// a `RuntimeWarning` that counts them.
fn points_of<'a>(py: Python<'_>, points: &'a PyReadonlyArray2<'_, f32>) -> PyResult<&'a [Vec3]> {
    if points.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!("points: shape {:?}; expected (K, 3)", points.shape())));
    }
    let pts: &[Vec3] = bytemuck::cast_slice(contiguous(points, "points")?);
    let bad = py.detach(|| count_non_finite(pts));
    if bad > 0 {
        let msg = format!(
            "points: {bad} of {} points have a NaN or infinite coordinate (or one beyond float32 range); \
             they are answered -1 (and NaN values)",
            pts.len()
        );
        let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
        PyErr::warn(py, &category, &std::ffi::CString::new(msg).unwrap_or_default(), 1)?;
    }
    Ok(pts)
}

#[pymethods]
impl PyLocator {
    /// Builds `backend` ("auto", "cpu", "soft-bvh", "rt-bvh", "rt-rep-faces",
    /// "rt-shared-faces") over `mesh`. `progress(stage, fraction or None, seconds)` is called
    /// during the build and between chunks of long batches.
    #[new]
    #[pyo3(signature = (mesh, backend="auto", device=None, options=None, progress=None))]
    fn new(
        py: Python<'_>,
        mesh: &PyMesh,
        backend: &str,
        device: Option<usize>,
        options: Option<&Bound<'_, PyDict>>,
        progress: Option<Bound<'_, PyAny>>,
    ) -> PyResult<PyLocator> {
        let choice = backend::parse(backend)?;
        let Options { vulkan: opts, tolerance, precision, deferred } = parse_options(options)?;
        let mesh_arc = mesh.mesh.clone();
        // The front door (tetloc_locator) builds the backend and its layers as for every front
        // end: points with a NaN or infinite coordinate answered -1 / NaN, answers in a mixed
        // mesh's tet decomposition turned into cells, precision="f64"'s values, the
        // tolerance's post-pass over them.
        let mesh = mesh_arc.clone();
        let mut built = background::run(py, "building a locator", progress.as_ref(), move |stages| {
            // The host's heap, measured while the CPU builds (the GPU's memory is tracked).
            let meter = PeakMeter::start();
            let stage = |name| stages.enter(name);
            let builder = Locator::builder(mesh)
                .backend(choice)
                .device(device)
                .precision(precision)
                .tolerance(tolerance)
                .vulkan_options(opts)
                .defer_cpu_build(deferred)
                .quiet(true)
                .stages(&stage);
            let mut built = builder.build().map_err(backend::py_error)?;
            let m = &mut built.memory;
            if m.on == "host" {
                let mesh_bytes = m.items["mesh points"] + m.items["mesh tets"];
                m.peak_bytes = m.final_bytes.max(mesh_bytes + meter.peak_since() as u64);
            }
            Ok(built)
        })?;
        let name = built.backend.name().to_string();
        // Why `auto` did not use a device that is there (no Vulkan at all is no news).
        let note = match built.auto.take().map(|c| c.reason) {
            Some(AutoReason::Unusable(e)) => {
                Some(format!("backend 'auto' uses cpu: the Vulkan device cannot be used ({e})"))
            }
            _ => None,
        };
        let stack =
            std::iter::once(name.clone()).chain(built.stack.iter().map(|l: &Layer| l.name().to_string())).collect();
        let backend: Backend = built.locator;
        // float64 points take the f64 path also for f64 values: with precision="f64", or on a
        // mesh with a field of f64 data.
        let f64_values = precision == Precision::F64 || mesh_arc.fields.iter().any(|f| f.values64.is_some());
        let takes_f64 = mesh_arc.wants_f64_points() || f64_values;
        let chunk = if name == tetloc_locator::CPU { CPU_CHUNK } else { LocatorOptions::default().chunk_points };
        Ok(PyLocator {
            backend: Mutex::new(Some(backend)),
            name,
            mesh: mesh_arc,
            chunk,
            memory: built.memory,
            device,
            build_seconds: built.build_seconds,
            note,
            stack,
            progress: progress.map(Bound::unbind),
            takes_f64,
            precision,
        })
    }

    /// The backend actually used ("cpu", "soft-bvh", ...).
    #[getter]
    fn backend(&self) -> &str {
        &self.name
    }

    /// Why `auto` chose `cpu` although a Vulkan device is there (`None` otherwise).
    #[getter]
    fn auto_note(&self) -> Option<&str> {
        self.note.as_deref()
    }

    /// The backend and the layers around it, innermost first: ["cpu", "FiniteOnly",
    /// "CellLocator", ...] (as `TETLOC_EXPLAIN=1 tetloc locate ...` says for the same options).
    #[getter]
    fn stack(&self) -> Vec<String> {
        self.stack.clone()
    }

    /// Seconds the build took.
    #[getter]
    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// {"on": "host" or "device", "final_bytes", "peak_bytes", "items": {name: bytes}}.
    fn memory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("on", self.memory.on)?;
        d.set_item("final_bytes", self.memory.final_bytes)?;
        d.set_item("peak_bytes", self.memory.peak_bytes)?;
        d.set_item("items", self.memory.items.clone())?;
        Ok(d)
    }

    /// Tet ids (-1 outside) of (K, 3) float32 C-contiguous points.
    fn locate<'py>(&self, py: Python<'py>, points: PyReadonlyArray2<'_, f32>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        let pts = points_of(py, &points)?;
        let mut ids = vec![0i32; pts.len()];
        let out = &mut ids;
        self.chunked(py, pts.len(), |loc, r| loc.locate(&pts[r.clone()], &mut out[r]))?;
        Ok(PyArray1::from_vec(py, ids))
    }

    /// Values of the scalar field `name` (NaN outside).
    fn sample<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'_, f32>,
        name: &str,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let pts = points_of(py, &points)?;
        let mut values = vec![0f32; pts.len()];
        let out = &mut values;
        self.chunked(py, pts.len(), |loc, r| loc.sample(&pts[r.clone()], name, &mut out[r]))?;
        Ok(PyArray1::from_vec(py, values))
    }

    /// Whether float64 points keep their precision (`sample_many64`).
    #[getter]
    fn takes_f64(&self) -> bool {
        self.takes_f64
    }

    /// "f32" or "f64": the `precision` option.
    #[getter]
    fn precision(&self) -> String {
        self.precision.to_string()
    }

    /// Whether float64 points' values of field `name` (one component) come back as float64:
    /// with `precision="f64"`, or when the field has f64 data.
    fn values_f64(&self, name: &str) -> PyResult<bool> {
        let f = self.mesh.field(name).map_err(to_py)?;
        Ok(self.precision == Precision::F64 || f.values64.is_some())
    }

    /// Ids and the values of every field of `names` (one component each) at (K, 3) float64
    /// C-contiguous points, located at that precision: ((K,) int32, (K, len(names)) float64:
    /// f64 interpolation of the file's values on the CPU and with `precision="f64"`, the
    /// kernels' f32 values widened otherwise).
    fn sample_many64<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'_, f64>,
        names: Vec<String>,
    ) -> PyResult<IdsAndRows<'py>> {
        if points.shape()[1] != 3 {
            return Err(PyValueError::new_err(format!("points: shape {:?}; expected (K, 3)", points.shape())));
        }
        let pts: &[[f64; 3]] = bytemuck::cast_slice(contiguous(&points, "points")?);
        let k = names.len();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let (mut ids, mut values) = (vec![0i32; pts.len()], vec![0f64; pts.len() * k]);
        let (ids_out, values_out) = (&mut ids, &mut values);
        self.chunked(py, pts.len(), |loc, r| {
            let v = &mut values_out[r.start * k..r.end * k];
            loc.sample_many64(&pts[r.clone()], &names, &mut ids_out[r], v)
        })?;
        let values = numpy::ndarray::Array2::from_shape_vec((pts.len(), k), values)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((PyArray1::from_vec(py, ids), PyArray2::from_owned_array(py, values)))
    }

    /// The interpolation weights of (K, 3) float64 C-contiguous points, located as `locate`
    /// locates them (at float64 precision when `takes_f64`, else rounded to float32): CSR
    /// arrays over the mesh's vertices (indptr (K + 1,) int64, indices int32, data float64)
    /// and each point's cell (K,) int32 (-1 outside: an empty row). `Weights` in the core.
    fn weights<'py>(&self, py: Python<'py>, points: PyReadonlyArray2<'_, f64>) -> PyResult<CsrRows<'py>> {
        let w = self.located_weights(py, &points)?;
        let (indptr, indices, data) = crate::steps::csr(py, &w);
        Ok((indptr, indices, data, PyArray1::from_vec(py, w.cells)))
    }

    /// `_StepWeights` of (K, 3) float64 points, located as `weights` locates them, applied on
    /// this locator's device for a GPU backend, on the host for cpu.
    fn step_weights(&self, py: Python<'_>, points: PyReadonlyArray2<'_, f64>) -> PyResult<PyStepWeights> {
        let w = self.located_weights(py, &points)?;
        PyStepWeights::new(py, w, (self.memory.on == "device").then_some(self.device))
    }

    /// Ids and values of the scalar field `name` in one pass.
    fn locate_and_sample<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'_, f32>,
        name: &str,
    ) -> PyResult<IdsAndValues<'py>> {
        let pts = points_of(py, &points)?;
        let (mut ids, mut values) = (vec![0i32; pts.len()], vec![0f32; pts.len()]);
        let (ids_out, values_out) = (&mut ids, &mut values);
        self.chunked(py, pts.len(), |loc, r| {
            loc.locate_and_sample(&pts[r.clone()], name, &mut ids_out[r.clone()], &mut values_out[r])
        })?;
        Ok((PyArray1::from_vec(py, ids), PyArray1::from_vec(py, values)))
    }
}
