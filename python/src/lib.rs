//! `tetloc._tetloc`, the extension module under the `tetloc` Python package: meshes
//! (`mesh`, VTK cell lists in and out: `cells`), locators on every backend (`locator`, `backend`), errors as Python
//! exceptions (`errors`). The public API, vector fields and pyvista/meshio conversion are
//! Python (`python/tetloc`).

mod alloc;
mod backend;
mod background;
mod cells;
mod cuda;
mod errors;
mod locator;
mod mesh;
mod ops;
mod steps;
mod weights;

use pyo3::prelude::*;

#[global_allocator]
static ALLOC: alloc::Counting = alloc::Counting;

/// Validation-layer errors reported so far by the Vulkan contexts of this process.
#[pyfunction]
fn validation_errors() -> usize {
    backend::validation_errors()
}

/// Every VTK cell type tetloc reads: (code, points, name).
#[pyfunction]
fn vtk_cell_types() -> Vec<(u8, usize, &'static str)> {
    cells::vtk_cell_types()
}

/// The VTK cell type of a Gmsh element type, if tetloc reads it: (VTK code, Gmsh nodes,
/// VTK node i = Gmsh node vtk_from_gmsh[i]).
#[pyfunction]
fn gmsh_cell_type(code: u8) -> Option<(u8, usize, Vec<u16>)> {
    cells::gmsh_cell_type(code)
}

#[pymodule]
fn _tetloc(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<mesh::PyMesh>()?;
    m.add_class::<locator::PyLocator>()?;
    m.add_class::<cuda::PyCudaLocator>()?;
    m.add_class::<steps::PyStepWeights>()?;
    m.add_function(wrap_pyfunction!(cuda::cuda_driver_available, m)?)?;
    m.add_function(wrap_pyfunction!(mesh::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(backend::devices, m)?)?;
    m.add_function(wrap_pyfunction!(validation_errors, m)?)?;
    m.add_function(wrap_pyfunction!(vtk_cell_types, m)?)?;
    m.add_function(wrap_pyfunction!(gmsh_cell_type, m)?)?;
    m.add_function(wrap_pyfunction!(ops::resample_to_image, m)?)?;
    m.add_function(wrap_pyfunction!(ops::probe_fields, m)?)?;
    m.add_function(wrap_pyfunction!(ops::trace_lines, m)?)?;
    m.add_function(wrap_pyfunction!(backend::resolve, m)?)?;
    m.add_function(wrap_pyfunction!(weights::interpolation_weights, m)?)?;
    m.add("DeviceError", m.py().get_type::<errors::DeviceError>())?;
    m.add("BACKENDS", backend::names())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
