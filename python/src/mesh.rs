//! `_Mesh`: a validated core mesh shared (`Arc`) with the locators built on it, made from
//! arrays or read from a file. The public `tetloc.Mesh` (python/tetloc/_mesh.py) wraps it.

use crate::background;
use crate::cells;
use crate::errors::to_py;
use numpy::{
    PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use tetloc_core::mesh::TimeSteps;
use tetloc_core::{Field, FieldLocation, Mesh, Vec3};
use tetloc_io::vtk::{from_cell_list, Extracted};
use tetloc_io::{self as io, MeshFormat};

/// A VTK cell list: types, offsets, connectivity.
type CellArrays<'py> = (Bound<'py, PyArray1<u8>>, Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<i64>>);

#[pyclass(name = "_Mesh", module = "tetloc._tetloc", frozen)]
pub struct PyMesh {
    pub mesh: Arc<Mesh>,
    /// The file's time steps (`None`: one snapshot); the mesh holds the first step's fields.
    pub steps: Option<Arc<TimeSteps>>,
}

fn location_name(l: FieldLocation) -> &'static str {
    match l {
        FieldLocation::Vertex => "point",
        FieldLocation::Cell => "cell",
    }
}

/// A C-contiguous array's data, or a `ValueError` naming the argument.
pub fn contiguous<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    a: &'a PyReadonlyArray<'_, T, D>,
    arg: &str,
) -> PyResult<&'a [T]> {
    a.as_slice().map_err(|_| PyValueError::new_err(format!("{arg}: expected a C-contiguous array")))
}

#[pymethods]
impl PyMesh {
    /// Validates and builds a mesh. `points`: (N, 3) float32; `points64`: the same points in
    /// float64 when the caller has them (kept where float32 rounds them); `connectivity`: the
    /// cells' vertex ids, flat: linear tets, 4 per cell, when `celltypes` is `None`, else a VTK
    /// cell list (`celltypes` (M,) VTK codes, `offsets` (M + 1,): cell `i` has the ids
    /// `connectivity[offsets[i]..offsets[i + 1]]`), of any volume cells tetloc reads; `fields`:
    /// (name, "point" or "cell", float32 or float64 values). `source` names the mesh in error
    /// messages.
    #[new]
    #[pyo3(signature = (points, connectivity, fields, source, points64=None, celltypes=None, offsets=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        points: PyReadonlyArray2<'_, f32>,
        connectivity: PyReadonlyArray1<'_, u32>,
        fields: Vec<(String, String, Bound<'_, PyAny>)>,
        source: String,
        points64: Option<PyReadonlyArray2<'_, f64>>,
        celltypes: Option<PyReadonlyArray1<'_, u8>>,
        offsets: Option<PyReadonlyArray1<'_, i64>>,
    ) -> PyResult<PyMesh> {
        if points.shape()[1] != 3 {
            return Err(PyValueError::new_err(format!("points: shape {:?}; expected (N, 3)", points.shape())));
        }
        let points: Vec<Vec3> = bytemuck::cast_slice(contiguous(&points, "points")?).to_vec();
        let conn = contiguous(&connectivity, "cells")?;
        let volume = match (&celltypes, &offsets) {
            (None, None) if conn.len() % 4 == 0 => Extracted::all_tets(conn.to_vec()),
            (None, None) => {
                return Err(PyValueError::new_err(format!("cells: {} ids are not 4 per tet", conn.len())));
            }
            (Some(types), Some(offsets)) => {
                let (types, offsets) = (contiguous(types, "celltypes")?, contiguous(offsets, "offsets")?);
                py.detach(|| from_cell_list(types, offsets, conn))
                    .map_err(|e| PyValueError::new_err(format!("cells: {e}")))?
            }
            _ => return Err(PyValueError::new_err("cells: celltypes and offsets go together")),
        };
        let fields = fields
            .iter()
            .map(|(name, location, values)| {
                let location = match location.as_str() {
                    "point" => FieldLocation::Vertex,
                    "cell" => FieldLocation::Cell,
                    other => return Err(PyValueError::new_err(format!("field '{name}': unknown location '{other}'"))),
                };
                // float64 values are kept where float32 would round them (Field::from_f64).
                if let Ok(v) = values.extract::<PyReadonlyArray1<'_, f64>>() {
                    return Ok(Field::from_f64(name.clone(), location, contiguous(&v, name)?.to_vec()));
                }
                let v = values.extract::<PyReadonlyArray1<'_, f32>>().map_err(|_| {
                    PyValueError::new_err(format!("field '{name}': expected a 1-D float32 or float64 array"))
                })?;
                Ok(Field::new(name.clone(), location, contiguous(&v, name)?.to_vec()))
            })
            .collect::<PyResult<Vec<_>>>()?;
        let points64 = match &points64 {
            Some(p) if p.shape() == [points.len(), 3] => {
                let p: &[[f64; 3]] = bytemuck::cast_slice(contiguous(p, "points64")?);
                tetloc_core::mesh::points64_if_needed(p.to_vec())
            }
            Some(p) => return Err(PyValueError::new_err(format!("points64: shape {:?}; expected (N, 3)", p.shape()))),
            None => None,
        };
        // The readers' path: `Mesh::new` decomposes mixed cells and keeps higher-order nodes.
        let raw = volume.into_mesh(points, points64, fields);
        let mesh = py.detach(|| Mesh::new(raw, source)).map_err(to_py)?;
        Ok(PyMesh { mesh: Arc::new(mesh), steps: None })
    }

    #[getter]
    fn n_points(&self) -> usize {
        self.mesh.points.len()
    }

    /// The file's volume cells (a mixed mesh's cells, not their tet decomposition).
    #[getter]
    fn n_cells(&self) -> usize {
        self.mesh.n_cells()
    }

    /// The tets located in: the cells, or a mixed mesh's decomposition.
    #[getter]
    fn n_tets(&self) -> usize {
        self.mesh.n_tets()
    }

    /// (min, max) corners of the box around the vertices that cells use.
    #[getter]
    fn bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.mesh.file_bounds();
        (lo.map(|x| x as f32), hi.map(|x| x as f32))
    }

    /// The file (or description) the mesh came from.
    #[getter]
    fn source(&self) -> &str {
        &self.mesh.info.source
    }

    /// (name, "point" or "cell") of every scalar field, in the mesh's order.
    fn fields(&self) -> Vec<(String, &'static str)> {
        self.mesh.fields.iter().map(|f| (f.name.clone(), location_name(f.location))).collect()
    }

    /// A copy of a scalar field's values as the file has them: float64 where it stored
    /// them so (and they do not all round to f32 exactly), else float32.
    fn field<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let f = self.mesh.field(name).map_err(to_py)?;
        Ok(match &f.values64 {
            Some(v) => PyArray1::from_slice(py, v).into_any(),
            None => PyArray1::from_slice(py, &f.values).into_any(),
        })
    }

    /// The time of each step (empty for a single snapshot).
    #[getter]
    fn times(&self) -> Vec<f64> {
        self.steps.as_ref().map_or_else(Vec::new, |s| s.times.clone())
    }

    /// The mesh with the fields of time step `step` (its steps kept), as the CLI's
    /// `--time-step K` reads it: only that step's fields are read, and the mesh shares this
    /// one's geometry (`Mesh::with_fields`: its faces and neighbours computed once for every
    /// step).
    fn at_step(&self, py: Python<'_>, step: usize) -> PyResult<PyMesh> {
        let Some(s) = &self.steps else {
            return Err(to_py(tetloc_core::mesh::steps::check_step(&self.mesh.info.source, 0, step).unwrap_err()));
        };
        // Checked before anything is read.
        tetloc_core::mesh::steps::check_step(&s.source, s.times.len(), step).map_err(to_py)?;
        let (steps, shown) = (s.clone(), self.mesh.clone());
        let mesh = background::run(py, "reading a time step", None, move |_| {
            shown.with_fields(steps.fields(step).map_err(to_py)?).map_err(to_py)
        })?;
        Ok(PyMesh { mesh: Arc::new(mesh), steps: self.steps.clone() })
    }

    /// Scalar fields `names` at time step `step`, read from the file now in one pass (a
    /// vector's components together): float64 where the file stored them so (and they do not
    /// all round to f32 exactly), else float32.
    fn step_fields<'py>(&self, py: Python<'py>, names: Vec<String>, step: usize) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let fields = self.read_step_fields(py, &names, step)?;
        Ok(fields
            .into_iter()
            .map(|f| match f.values64 {
                Some(v) => PyArray1::from_vec(py, v).into_any(),
                None => PyArray1::from_vec(py, f.values).into_any(),
            })
            .collect())
    }

    /// A copy of the vertices, (N, 3) float32.
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let m = &self.mesh;
        let flat = if m.info.frame.is_identity() {
            PyArray1::from_slice(py, bytemuck::cast_slice::<Vec3, f32>(&m.points))
        } else {
            // The search's copy is centred (mesh::Frame): users get the file's coordinates.
            PyArray1::from_vec(py, (0..m.points.len() as u32).flat_map(|i| m.vertex64(i).map(|c| c as f32)).collect())
        };
        flat.reshape([m.points.len(), 3])
    }

    /// A copy of the vertices as the file has them, (N, 3) float64.
    fn points64<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let m = &self.mesh;
        let flat: Vec<f64> = (0..m.points.len() as u32).flat_map(|i| m.vertex64(i)).collect();
        PyArray1::from_vec(py, flat).reshape([m.points.len(), 3])
    }

    /// The cells as the input had them, as a VTK cell list: (types (M,) uint8 VTK codes,
    /// offsets (M + 1,) int64, connectivity int64) (`cells::to_vtk`).
    fn cell_list<'py>(&self, py: Python<'py>) -> CellArrays<'py> {
        let list = py.detach(|| cells::to_vtk(&self.mesh));
        (PyArray1::from_vec(py, list.types), PyArray1::from_vec(py, list.offsets), PyArray1::from_vec(py, list.conn))
    }

    /// Cell counts by VTK type name ("tetra", "hexahedron", "quadratic tetra", ...).
    fn cell_type_counts(&self) -> BTreeMap<String, usize> {
        self.mesh.info.cell_types.clone()
    }

    /// A copy of the tets located in, (T, 4) int64, canonical vertex order: the mesh's tets
    /// (their corners for higher-order ones), or a mixed mesh's conforming decomposition.
    fn tets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let flat: Vec<i64> = self.mesh.tets.iter().flatten().map(|&i| i64::from(i)).collect();
        PyArray1::from_vec(py, flat).reshape([self.mesh.n_tets(), 4])
    }

    /// The cell each tet of `tets()` is or belongs to, (T,) int64.
    fn tet_cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let m = &self.mesh;
        PyArray1::from_vec(py, (0..m.n_tets()).map(|t| m.cell_of_tet(t) as i64).collect())
    }

    /// The JSON of `tetloc info --json`: the mesh facts, face counts and fields with their
    /// value ranges (one definition: `Mesh::summary`). Computes
    /// the shared faces on first use (a sort of 4 faces per tet).
    fn info_json(&self, py: Python<'_>) -> PyResult<String> {
        let mesh = &self.mesh;
        let summary = py.detach(|| mesh.summary());
        serde_json::to_string(&summary).map_err(|e| PyValueError::new_err(e.to_string()))
    }
}

impl PyMesh {
    /// Fields `names` of step `step`, in that order, read in one pass (an error for a step out
    /// of range, a mesh without steps, or a field the step lacks).
    pub fn read_step_fields(&self, py: Python<'_>, names: &[String], step: usize) -> PyResult<Vec<Field>> {
        let Some(s) = &self.steps else {
            return Err(to_py(tetloc_core::mesh::steps::check_step(&self.mesh.info.source, 0, step).unwrap_err()));
        };
        py.detach(|| {
            let mut read: Vec<Option<Field>> = s.fields_named(step, names)?.into_iter().map(Some).collect();
            names
                .iter()
                .map(|n| {
                    match read.iter_mut().find(|f| f.as_ref().is_some_and(|f| f.name == *n)).and_then(Option::take) {
                        Some(f) => Ok(f),
                        // Not among them: the one-field read says which fields the step has.
                        None => s.field(n, step),
                    }
                })
                .collect::<tetloc_core::Result<Vec<Field>>>()
        })
        .map_err(to_py)
    }
}

/// Reads a mesh file in any format the CLI reads (by extension, or `format`: vtu, vtk, msh,
/// node). `allow_outside_pieces`: a .pvtu/.vtm may name pieces outside its folder tree (the
/// CLI's `--allow-outside-pieces`; refused by default). Interruptible with Ctrl-C.
#[pyfunction]
#[pyo3(signature = (path, format=None, allow_outside_pieces=false))]
pub fn read_mesh(py: Python<'_>, path: PathBuf, format: Option<&str>, allow_outside_pieces: bool) -> PyResult<PyMesh> {
    let format = format
        .map(|f| {
            MeshFormat::from_name(f).ok_or_else(|| {
                PyValueError::new_err(format!("format '{f}': unknown mesh format (known: {})", io::KNOWN_MESH_FORMATS))
            })
        })
        .transpose()?;
    let options = io::ReadOptions { allow_outside_pieces };
    // Without the GIL: the mesh and its steps.
    let (mesh, steps) = background::run(py, "reading a mesh", None, move |_| {
        let (raw, steps) = io::read_series_with(&path, format, options).map_err(to_py)?;
        Ok((Mesh::new(raw, path.display().to_string()).map_err(to_py)?, steps))
    })?;
    Ok(PyMesh { mesh: Arc::new(mesh), steps: steps.map(Arc::new) })
}
