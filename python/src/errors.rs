//! Rust errors and panics as Python exceptions: `OSError` subclasses (`FileNotFoundError`,
//! ...) for files that cannot be opened, `ValueError` for bad files and bad arguments,
//! `tetloc.DeviceError` for the GPU. No panic crosses into the interpreter.

use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::panic::{catch_unwind, AssertUnwindSafe};

pyo3::create_exception!(
    tetloc,
    DeviceError,
    PyRuntimeError,
    "A GPU (Vulkan) backend cannot be used: no Vulkan loader or device, a device without the \
     features the backend needs, or a Vulkan call that failed."
);

/// The Python exception for a core error.
pub fn to_py(e: tetloc_core::Error) -> PyErr {
    use tetloc_core::Error;
    match e {
        // OSError(errno, strerror, filename) is raised as its subclass (FileNotFoundError,
        // PermissionError, IsADirectoryError, ...), with `.filename` set.
        Error::Io { ref path, ref source } => match source.raw_os_error() {
            Some(errno) => PyOSError::new_err((errno, source.to_string(), path.display().to_string())),
            None => PyValueError::new_err(e.to_string()),
        },
        Error::Backend { .. } => DeviceError::new_err(e.to_string()),
        Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// The message of a caught panic.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// The `RuntimeError` raised for a panic: a bug in tetloc, never the caller's fault.
pub fn internal_error(what: &str, payload: &(dyn std::any::Any + Send)) -> PyErr {
    PyRuntimeError::new_err(format!(
        "internal error in tetloc while {what}: {} (please report this as a bug)",
        panic_message(payload)
    ))
}

/// Runs `f`, turning a panic into a `RuntimeError` instead of unwinding into Python.
pub fn guarded<T>(what: &str, f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| Err(internal_error(what, &*p)))
}
