//! Backends through the front door ([`tetloc_locator`]: names, `auto`, the process' Vulkan
//! contexts), its errors as Python exceptions, and `tetloc.devices()`.

use crate::errors::{to_py, DeviceError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use tetloc_locator::{Backend, Error, Kernel, LocatorOptions};

/// A backend name as a [`Backend`]; an unknown one is a `ValueError`.
pub fn parse(name: &str) -> PyResult<Backend> {
    name.parse().map_err(py_error)
}

/// The front door's error as a Python exception: `tetloc.DeviceError` for the GPU,
/// `ValueError` for a bad name, the core's mapping for the rest.
pub fn py_error(e: Error) -> PyErr {
    match e {
        Error::Core(e) => to_py(e),
        e if e.is_device() => DeviceError::new_err(e.to_string()),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// Every backend name besides `auto`.
pub fn names() -> Vec<&'static str> {
    tetloc_locator::names()
}

/// Validation-layer errors reported so far on every open context (the tests check for 0).
pub fn validation_errors() -> usize {
    tetloc_locator::validation_errors()
}

/// The backend name a choice runs on: "auto" resolved as a Locator would (measured on a GPU
/// the first time, then cached), other names checked.
#[pyfunction]
#[pyo3(signature = (name, device=None))]
pub fn resolve(py: Python<'_>, name: &str, device: Option<usize>) -> PyResult<String> {
    let backend = parse(name)?;
    let choice = match backend {
        Backend::Auto => {
            py.detach(|| tetloc_locator::auto::choose(device, &LocatorOptions::default(), true))
                .map_err(py_error)?
                .backend
        }
        b => b,
    };
    Ok(choice.name().to_string())
}

/// `tetloc.devices()`: one dict per Vulkan device; empty when there is no Vulkan loader.
#[pyfunction]
pub fn devices(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    let list = match py.detach(tetloc_vulkan::devices) {
        Ok(l) => l,
        Err(e) if tetloc_locator::is_no_vulkan(&e) => Vec::new(),
        Err(e) => return Err(DeviceError::new_err(e.to_string())),
    };
    list.into_iter()
        .map(|d| {
            let kernels: Vec<&str> = tetloc_locator::kernels_on(&d).into_iter().map(Kernel::name).collect();
            let dict = PyDict::new(py);
            dict.set_item("index", d.index)?;
            dict.set_item("name", d.name)?;
            dict.set_item("driver", d.driver)?;
            dict.set_item("device_type", d.device_type)?;
            dict.set_item("api_version", d.api_version)?;
            dict.set_item("ray_tracing", d.ray_tracing)?;
            dict.set_item("memory_bytes", d.memory_bytes)?;
            dict.set_item("float64", d.float64)?;
            dict.set_item("backends", kernels)?;
            Ok(dict)
        })
        .collect()
}
