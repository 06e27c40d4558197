//! `tetloc.resample_to_image`, `tetloc.probe` and `tetloc.trace` (python/tetloc/_ops.py) on
//! the core's operations (`tetloc_core::ops`, what the CLI runs): each runs on a worker
//! thread without the GIL while the calling thread checks for Ctrl-C and reports progress.

use crate::errors::{internal_error, to_py};
use crate::locator::{Backend, PyLocator};
use crate::mesh::{contiguous, PyMesh};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::PyDict;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use tetloc_core::locate::Points;
use tetloc_core::ops::trace::{self, Integrator, LineArrays, TraceOptions};
use tetloc_core::ops::{fields, probe, resample, FieldGroup, ImageGrid};
use tetloc_core::{BatchLocator, Vec3};
use tetloc_locator::{BareLocator, Locator};

/// Points per batch between two progress ticks (and chances to stop).
const TICK_POINTS: usize = 1 << 20;

/// What a job and the waiting thread share: work done so far, and the request to stop.
#[derive(Default)]
struct Ticker {
    done: AtomicUsize,
    cancel: AtomicBool,
}

impl Ticker {
    /// Records progress; an error (ending the job) once the caller asked to stop.
    fn tick(&self, done: usize) -> tetloc_core::Result<()> {
        self.done.store(done, Ordering::Relaxed);
        if self.cancel.load(Ordering::Relaxed) {
            return Err(tetloc_core::Error::Invalid("interrupted".into()));
        }
        Ok(())
    }
}

/// Runs `job` on a scoped worker thread while this thread, every 100 ms, checks for Ctrl-C
/// (which stops the job at its next tick and raises `KeyboardInterrupt`) and calls
/// `progress(stage, done / total, seconds)`.
fn run_job<T: Send>(
    py: Python<'_>,
    stage: &str,
    total: usize,
    progress: Option<&Bound<'_, PyAny>>,
    job: impl FnOnce(&Ticker) -> tetloc_core::Result<T> + Send,
) -> PyResult<T> {
    let ticker = Ticker::default();
    let t0 = Instant::now();
    std::thread::scope(|scope| {
        let handle = scope.spawn(|| catch_unwind(AssertUnwindSafe(|| job(&ticker))));
        let mut stop: Option<PyErr> = None;
        while !handle.is_finished() {
            py.detach(|| {
                let until = Instant::now() + Duration::from_millis(100);
                while !handle.is_finished() && Instant::now() < until {
                    std::thread::sleep(Duration::from_millis(2));
                }
            });
            if stop.is_some() || handle.is_finished() {
                continue;
            }
            let fraction = ticker.done.load(Ordering::Relaxed) as f64 / total.max(1) as f64;
            let ticked = py.check_signals().and_then(|()| {
                progress.map(|p| p.call1((stage, fraction.min(1.0), t0.elapsed().as_secs_f64()))).transpose()
            });
            if let Err(e) = ticked {
                ticker.cancel.store(true, Ordering::Relaxed);
                stop = Some(e);
            }
        }
        let result = py.detach(|| handle.join());
        if let Some(e) = stop {
            return Err(e);
        }
        if let Some(p) = progress {
            p.call1(("done", 1.0, t0.elapsed().as_secs_f64()))?;
        }
        match result {
            Ok(Ok(r)) => r.map_err(to_py),
            Ok(Err(panic)) | Err(panic) => Err(internal_error(stage, &*panic)),
        }
    })
}

/// The locator's backend for one call (waiting for another thread's call without the GIL).
fn with_backend<T>(
    py: Python<'_>,
    locator: &PyLocator,
    f: impl FnOnce(&mut (dyn BatchLocator + Send)) -> PyResult<T>,
) -> PyResult<T> {
    let mut guard = locator.backend.lock_py_attached(py).unwrap_or_else(|p| p.into_inner());
    let Some(loc) = guard.as_mut() else {
        return Err(PyRuntimeError::new_err(format!(
            "this {} Locator is unusable after an internal error; build a new one",
            locator.name
        )));
    };
    let loc: &mut Backend = loc;
    f(&mut **loc)
}

/// The named fields of `mesh` (all when `names` is empty), as the core groups them.
fn field_groups(mesh: &tetloc_core::Mesh, names: &[String]) -> PyResult<Vec<FieldGroup>> {
    if names.is_empty() {
        return Ok(fields::groups(mesh));
    }
    names.iter().map(|n| fields::resolve(mesh, n).map_err(to_py)).collect()
}

type FieldArrays<'py> = Vec<(String, usize, Bound<'py, PyArray1<f32>>)>;

/// `(arrays, vtkValidPointMask, origin, spacing)`: every field sampled at the grid points of
/// `dims` over `bounds` (x0, x1, y0, y1, z0, z1; the mesh's, nudged inwards as
/// vtkResampleToImage does, when `None`), x fastest; each array holds k values per point.
#[pyfunction]
#[pyo3(signature = (locator, names, dims, bounds=None, progress=None))]
#[allow(clippy::type_complexity)]
pub fn resample_to_image<'py>(
    py: Python<'py>,
    locator: &PyLocator,
    names: Vec<String>,
    dims: [usize; 3],
    bounds: Option<[f64; 6]>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(FieldArrays<'py>, Bound<'py, PyArray1<u8>>, [f64; 3], [f64; 3])> {
    let mesh = locator.mesh.clone();
    let groups = field_groups(&mesh, &names)?;
    let grid = match bounds {
        Some(b) => ImageGrid::spanning([b[0], b[2], b[4]], [b[1], b[3], b[5]], dims),
        None => {
            let (lo, hi) = mesh.file_bounds();
            ImageGrid::over_bounds(lo, hi, dims)
        }
    }
    .map_err(to_py)?;
    let n = grid.n_points();
    let widths: Vec<usize> = groups.iter().map(FieldGroup::n_components).collect();
    let width: usize = widths.iter().sum();
    let size = |k: usize| {
        n.checked_mul(k).ok_or_else(|| PyValueError::new_err(format!("dims {dims:?}: too many points for memory")))
    };
    size(width.max(1))?;
    // The image is held whole (a mask byte and 4 bytes a component a point): refused before
    // allocating where memory cannot hold it (an allocation that fails aborts the interpreter).
    let need = n as u128 * (1 + 4 * width as u128);
    tetloc_core::memory::check(need, || format!("dims {dims:?}: the image's {n} points")).map_err(to_py)?;
    let mut mask = vec![0u8; n];
    let mut values: Vec<Vec<f32>> = widths.iter().map(|&k| vec![0f32; n * k]).collect();
    with_backend(py, locator, |loc| {
        let grid = resample::grid_for(grid.clone(), &mesh, loc);
        run_job(py, "resampling", n, progress.as_ref(), |ticker| {
            let mut at = 0;
            resample::resample(loc, &grid, &groups, TICK_POINTS, |ids, vals| {
                use rayon::prelude::*;
                let n = ids.len();
                mask[at..at + n].par_iter_mut().zip(ids).for_each(|(m, &id)| *m = u8::from(id >= 0));
                // Each field's components out of the chunk's rows (all fields a point).
                let mut offset = 0;
                for (out, &k) in values.iter_mut().zip(&widths) {
                    tetloc_core::ops::copy_components(vals, width, offset..offset + k, &mut out[at * k..(at + n) * k]);
                    offset += k;
                }
                at += ids.len();
                ticker.tick(at)
            })
        })
    })?;
    let arrays = groups.iter().zip(values).map(|(g, v)| (g.name.clone(), g.n_components(), PyArray1::from_vec(py, v)));
    Ok((arrays.collect(), PyArray1::from_vec(py, mask), grid.origin, grid.spacing))
}

/// `(arrays, vtkValidPointMask)`: the fields of the locator's mesh at `points`, (K, 3)
/// float32 or float64 (located at that precision). Each array is float64 for a field of f64
/// data sampled on the f64 path (as the CLI's probe writes it), else float32.
#[pyfunction(name = "probe")]
#[pyo3(signature = (locator, points, names, progress=None))]
pub fn probe_fields<'py>(
    py: Python<'py>,
    locator: &PyLocator,
    points: Bound<'py, PyAny>,
    names: Vec<String>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(ProbedArrays<'py>, Bound<'py, PyArray1<u8>>)> {
    let groups = field_groups(&locator.mesh, &names)?;
    // The points at the precision given (float64: the f64 path where it matters).
    let (p64, p32);
    let pts = if let Ok(a) = points.extract::<PyReadonlyArray2<'_, f64>>() {
        p64 = a;
        Points::F64(points_of(&p64)?)
    } else {
        p32 = points
            .extract::<PyReadonlyArray2<'_, f32>>()
            .map_err(|_| PyValueError::new_err("points: expected a (K, 3) float32 or float64 array".to_string()))?;
        Points::F32(points_of(&p32)?)
    };
    let probed = with_backend(py, locator, |loc| {
        run_job(py, "probing", pts.len(), progress.as_ref(), |ticker| {
            probe::probe_points(loc, pts, &groups, |d| ticker.tick(d))
        })
    })?;
    let mask = PyArray1::from_vec(py, probed.mask());
    let arrays = probed.arrays.into_iter().zip(probed.arrays64).map(|((g, v), v64)| {
        let values = match v64 {
            Some(v64) => PyArray1::from_vec(py, v64).into_any(),
            None => PyArray1::from_vec(py, v).into_any(),
        };
        (g.name.clone(), g.n_components(), values)
    });
    Ok((arrays.collect(), mask))
}

type ProbedArrays<'py> = Vec<(String, usize, Bound<'py, PyAny>)>;

/// (K, 3) C-contiguous points of either precision, without a copy.
fn points_of<'a, T: numpy::Element + bytemuck::Pod>(points: &'a PyReadonlyArray2<'_, T>) -> PyResult<&'a [[T; 3]]> {
    if points.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!("points: shape {:?}; expected (K, 3)", points.shape())));
    }
    Ok(bytemuck::cast_slice(contiguous(points, "points")?))
}

/// Streamlines of the vector field `vector` of `mesh` from `seeds` (K, 3): on the CPU with
/// each particle walking from its last tet when `locator` is `None`, else step-synchronous
/// through the locator's backend. Returns a dict: `points` (P, 3) float32, `offsets` (L + 1)
/// int64, `IntegrationTime` (P) float64, `ReasonForTermination` and `SeedIds` (L) int32,
/// and `fields`: (name, k, values) of the fields sampled at the points. With `unsteady`,
/// pathlines through the mesh's time steps from `start_time` to `end_time` (`step` a time;
/// `IntegrationTime` the simulation time, `SeedIds` each particle's seed), the seeds injected
/// again every `reinject_every` output times (0: once); `streaklines`: one line a seed through
/// its particles at the end time, `ParticleAge` instead of `IntegrationTime`;
/// `every_output_time`: `frames`, a list of (time, dict) at each output time after the start
/// (the lines as a run ending there gives them) in place of the arrays. `vorticity`: the
/// lines also carry `Vorticity`, `Rotation`, `AngularVelocity` and, streamlines, `Normals`
/// (float64).
#[pyfunction(name = "trace")]
#[pyo3(signature = (mesh, locator, vector, seeds, step, max_steps, max_length, max_time, direction, integrator,
    max_error, min_step, max_step, terminal_speed, progress=None, unsteady=false, start_time=None, end_time=None, reinject_every=0, streaklines=false,
    every_output_time=false, vorticity=false))]
#[allow(clippy::too_many_arguments)]
pub fn trace_lines<'py>(
    py: Python<'py>,
    mesh: &PyMesh,
    locator: Option<&PyLocator>,
    vector: &str,
    seeds: PyReadonlyArray2<'_, f32>,
    step: Option<f64>,
    max_steps: usize,
    max_length: Option<f64>,
    max_time: Option<f64>,
    direction: &str,
    integrator: &str,
    max_error: f64,
    min_step: Option<f64>,
    max_step: Option<f64>,
    terminal_speed: f64,
    progress: Option<Bound<'py, PyAny>>,
    unsteady: bool,
    start_time: Option<f64>,
    end_time: Option<f64>,
    reinject_every: usize,
    streaklines: bool,
    every_output_time: bool,
    vorticity: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let m = mesh.mesh.clone();
    let seeds = points_of(&seeds)?;
    if unsteady {
        let o = trace::PathOptions {
            integrator: integrator.parse::<Integrator>().map_err(to_py)?,
            step,
            max_error,
            min_step,
            max_step,
            terminal_speed,
            start_time,
            end_time,
            reinject_every,
            streaklines,
            vorticity,
        };
        o.check().map_err(to_py)?;
        let Some(steps) = mesh.steps.clone() else {
            return Err(PyValueError::new_err(format!(
                "{}: unsteady=True needs a time series (an Exodus file with time steps, or a .pvd); this mesh is a single snapshot",
                m.info.source
            )));
        };
        let legs = o.legs(&steps.source, &steps.times).map_err(to_py)?;
        let injections = o.injections(&legs);
        let legs = legs.len();
        let vector = trace::vector_field(&m, vector).map_err(to_py)?;
        let c = vector.component_refs();
        let xyz = [c[0], c[1], c[2]];
        let out_fields = trace::line_fields(&m, &vector);
        let job = trace::PathJob { seeds, options: &o, steps: &steps, vector: xyz, fields: &out_fields };
        // The lines at the end time, or at every output time: made on the job's thread.
        let outputs = |run: trace::PathRun| match every_output_time {
            true => run.frame_times().into_iter().enumerate().map(|(k, t)| (t, run.frame(k))).collect(),
            false => vec![(0.0, run.output())],
        };
        let mut made: Vec<(f64, LineArrays)> = match locator {
            None if m.cells.is_none() => {
                let cpu = cpu_locator(py, &m)?;
                run_job(py, "pathlines", legs, progress.as_ref(), |ticker| {
                    Ok(outputs(trace::pathline_run(job, &cpu, |d| ticker.tick(d))?))
                })?
            }
            // The per-particle walk runs on tets: a mixed mesh goes through the CPU's stack,
            // whose answers are cells, interpolated with the cells' shape functions.
            None => {
                let mut built = cpu_stack(py, &m)?;
                let loc = built.locator.as_mut();
                run_job(py, "pathlines", legs, progress.as_ref(), |ticker| {
                    Ok(outputs(trace::pathline_run_batch(job, &mut *loc, &m, |d| ticker.tick(d))?))
                })?
            }
            Some(locator) => with_backend(py, locator, |loc| {
                run_job(py, "pathlines", legs, progress.as_ref(), |ticker| {
                    Ok(outputs(trace::pathline_run_batch(job, &mut *loc, &m, |d| ticker.tick(d))?))
                })
            })?,
        };
        let out = match every_output_time {
            true => {
                let out = PyDict::new(py);
                let frames = made.into_iter().map(|(t, a)| Ok((t, line_dict(py, a)?))).collect::<PyResult<Vec<_>>>()?;
                out.set_item("frames", frames)?;
                out
            }
            false => line_dict(py, made.pop().expect("one output").1)?,
        };
        out.set_item("injections", injections)?;
        return Ok(out);
    }
    let vector = trace::vector_field(&m, vector).map_err(to_py)?;
    let o = TraceOptions {
        step: step.unwrap_or(0.1 * m.info.mean_edge_length as f64),
        max_steps,
        max_length: max_length.unwrap_or(f64::INFINITY),
        max_time: max_time.unwrap_or(f64::INFINITY),
        terminal_speed,
        direction: direction.parse().map_err(to_py)?,
        integrator: integrator.parse::<Integrator>().map_err(to_py)?,
        max_error,
        min_step,
        max_step,
    };
    o.check().map_err(to_py)?;
    // As the CLI: a step f64 cannot tell from none at the mesh's coordinates is refused.
    let (lo, hi) = m.file_bounds();
    o.check_scale(lo.iter().chain(&hi).fold(0.0, |s, c| s.max(c.abs()))).map_err(to_py)?;
    let c = vector.component_refs();
    let xyz = [c[0], c[1], c[2]];
    let n_lines = seeds.len() * if o.direction == trace::Direction::Both { 2 } else { 1 };
    let out_fields = trace::line_fields(&m, &vector);
    // Step-synchronous through a locator's batches, its answers (cells, on a mixed mesh) kept.
    let batched = |loc: &mut (dyn BatchLocator + Send)| -> PyResult<LineArrays> {
        let lines = run_job(py, "tracing", n_lines, progress.as_ref(), |ticker| {
            trace::trace_with(seeds, &o, &mut *loc, xyz, &out_fields, |d| ticker.tick(d))
        })?;
        py.detach(|| LineArrays::sample(&lines, &m, &mut *loc, &out_fields)).map_err(to_py)
    };
    let arrays = match locator {
        None if m.cells.is_none() => {
            // The line arrays come from the integrator's own lookups (no second pass), through
            // the CPU's locator itself (each particle walks from its last tet).
            let cpu = cpu_locator(py, &m)?;
            run_job(py, "tracing", n_lines, progress.as_ref(), |ticker| {
                trace::trace_sampled(seeds, &o, &cpu, xyz, &out_fields, &|d| ticker.tick(d))
            })?
        }
        // The per-particle walk runs on tets: mixed meshes take the batch tracer (as the CLI),
        // through the CPU's stack, which maps answers to cells and interpolates with the
        // cells' shape functions.
        None => {
            let mut built = cpu_stack(py, &m)?;
            batched(built.locator.as_mut())?
        }
        Some(locator) => with_backend(py, locator, |loc| batched(loc))?,
    };
    let arrays = py.detach(|| arrays.with_vorticity(vorticity.then_some((&*m, &vector)))).map_err(to_py)?;
    line_dict(py, arrays)
}

/// The dict `trace` returns for `arrays`.
fn line_dict(py: Python<'_>, arrays: LineArrays) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    let flat = PyArray1::from_slice(py, bytemuck::cast_slice::<Vec3, f32>(&arrays.points));
    let points: Bound<'_, PyArray2<f32>> = flat.reshape([arrays.points.len(), 3])?;
    out.set_item("points", points)?;
    let offsets: Vec<i64> = std::iter::once(0).chain(arrays.ends.iter().map(|&e| e as i64)).collect();
    out.set_item("offsets", PyArray1::from_vec(py, offsets))?;
    // The other arrays move into numpy as they are (no copy: fresh pages cost more than
    // the copy itself here).
    out.set_item(arrays.time_name, PyArray1::from_vec(py, arrays.time))?;
    out.set_item("ReasonForTermination", PyArray1::from_vec(py, arrays.reasons))?;
    out.set_item("SeedIds", PyArray1::from_vec(py, arrays.seeds))?;
    if let Some(p) = arrays.particles {
        out.set_item("ParticleId", PyArray1::from_vec(py, p.particle_id))?;
        out.set_item("InjectedPointId", PyArray1::from_vec(py, p.injected_point_id))?;
        out.set_item("InjectionStepId", PyArray1::from_vec(py, p.injection_step_id))?;
        if let Some(age) = p.age {
            out.set_item("ParticleAge", PyArray1::from_vec(py, age))?;
        }
    }
    if let Some(v) = arrays.vorticity {
        let vectors = |v: Vec<[f64; 3]>| -> PyResult<Bound<'_, PyArray2<f64>>> {
            let n = v.len();
            PyArray1::from_vec(py, bytemuck::cast_vec::<[f64; 3], f64>(v)).reshape([n, 3])
        };
        out.set_item("Vorticity", vectors(v.vorticity)?)?;
        out.set_item("Rotation", PyArray1::from_vec(py, v.rotation))?;
        out.set_item("AngularVelocity", PyArray1::from_vec(py, v.angular_velocity))?;
        if let Some(normals) = v.normals {
            out.set_item("Normals", vectors(normals)?)?;
        }
    }
    let fields: FieldArrays = arrays
        .fields
        .arrays
        .into_iter()
        .map(|(g, v)| {
            let k = g.n_components();
            (g.name, k, PyArray1::from_vec(py, v))
        })
        .collect();
    out.set_item("fields", fields)?;
    Ok(out)
}

/// The CPU's whole stack over `m` (a mixed mesh's answers cells, interpolated with the cells'
/// shape functions), built without the GIL: the tracers of meshes the per-particle walk,
/// which runs on tets, does not take.
fn cpu_stack(py: Python<'_>, m: &std::sync::Arc<tetloc_core::Mesh>) -> PyResult<tetloc_locator::Built> {
    let build = || Locator::builder(m.clone()).backend(tetloc_locator::Backend::Cpu).build();
    py.detach(build).map_err(crate::backend::py_error)
}

/// The CPU's own locator (no wrappers) over `m`, built without the GIL: trace and pathlines
/// walk each particle from its last tet through it. Deferred: each tracer builds the search
/// it needs (`CpuLocator::ready_for_particles`: the bins for streamlines, the BVH for
/// pathlines).
fn cpu_locator(
    py: Python<'_>,
    m: &std::sync::Arc<tetloc_core::Mesh>,
) -> PyResult<Box<tetloc_core::locate::CpuLocator>> {
    let bare = py.detach(|| {
        Locator::builder(m.clone()).backend(tetloc_locator::Backend::Cpu).defer_cpu_build(true).build_bare()
    });
    match bare.map_err(crate::backend::py_error)?.locator {
        BareLocator::Cpu(cpu) => Ok(cpu),
        _ => Err(PyRuntimeError::new_err("cpu: not the CPU's locator")),
    }
}
