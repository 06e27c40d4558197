//! Backend choice (`cpu`, the four Vulkan kernels, `auto`), the process' Vulkan contexts
//! (one per device, opened on first use through the loader found at run time), and
//! `tetloc.devices()`.

use crate::errors::{device_error, DeviceError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tetloc_vulkan::{Context, ContextOptions, Kernel, VkError};

pub const CPU: &str = "cpu";
pub const AUTO: &str = "auto";

/// What a backend name asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    Cpu,
    Gpu(Kernel),
    Auto,
}

impl Choice {
    pub fn parse(name: &str) -> PyResult<Choice> {
        match name {
            CPU => Ok(Choice::Cpu),
            AUTO => Ok(Choice::Auto),
            _ => name.parse().map(Choice::Gpu).map_err(|_| {
                PyValueError::new_err(format!(
                    "backend '{name}': unknown (known: {})",
                    names().iter().chain([&AUTO]).copied().collect::<Vec<_>>().join(", ")
                ))
            }),
        }
    }
}

/// Every backend name besides `auto`.
pub fn names() -> Vec<&'static str> {
    std::iter::once(CPU).chain(Kernel::ALL.iter().map(|k| k.name())).collect()
}

/// Why there is no context: no Vulkan at all (loader or device missing), or a failure.
#[derive(Clone, Debug)]
pub struct NoContext {
    pub no_vulkan: bool,
    pub msg: String,
}

type Contexts = Mutex<HashMap<Option<usize>, Result<Arc<Context>, NoContext>>>;

fn contexts() -> &'static Contexts {
    static CONTEXTS: std::sync::OnceLock<Contexts> = std::sync::OnceLock::new();
    CONTEXTS.get_or_init(Default::default)
}

/// The process' context on `device` (the best device when `None`), opened once. Validation
/// is on when `TETLOC_VK_VALIDATION` is set (the tests set it).
pub fn context(device: Option<usize>) -> Result<Arc<Context>, NoContext> {
    let mut map = contexts().lock().unwrap_or_else(|p| p.into_inner());
    map.entry(device)
        .or_insert_with(|| {
            Context::with_options(ContextOptions { device_index: device, ..Default::default() })
                .map_err(|e| NoContext { no_vulkan: is_no_vulkan(&e), msg: e.to_string() })
        })
        .clone()
}

/// True when the error means this machine has no Vulkan: no loader, no driver (the loader
/// refuses to create an instance), or no device.
fn is_no_vulkan(e: &VkError) -> bool {
    matches!(
        e,
        VkError::NoLoader(_)
            | VkError::NoDevice
            | VkError::Vk { what: "vkCreateInstance", result: ash::vk::Result::ERROR_INCOMPATIBLE_DRIVER }
    )
}

/// Validation-layer errors reported so far on every open context (the tests check for 0).
pub fn validation_errors() -> usize {
    let map = contexts().lock().unwrap_or_else(|p| p.into_inner());
    map.values().filter_map(|c| c.as_ref().ok()).map(|c| c.validation_errors()).sum()
}

/// The backend `auto` resolves to: soft-bvh on a GPU, else `cpu` (also when Vulkan is
/// missing, and on a CPU Vulkan driver such as lavapipe, which is slower than `cpu`). The
/// returned note says why a device that exists was not used.
pub fn resolve_auto(device: Option<usize>) -> (Choice, Option<String>) {
    match context(device) {
        Ok(ctx) if ctx.info().device_type != "cpu" => (Choice::Gpu(Kernel::SoftBvh), None),
        Ok(_) => (Choice::Cpu, None),
        Err(e) if e.no_vulkan && device.is_none() => (Choice::Cpu, None),
        Err(e) => (Choice::Cpu, Some(format!("backend 'auto' uses cpu: the Vulkan device cannot be used ({})", e.msg))),
    }
}

/// The backend name a choice runs on: "auto" resolved as a Locator would (without building
/// anything), other names checked.
#[pyfunction]
#[pyo3(signature = (name, device=None))]
pub fn resolve(name: &str, device: Option<usize>) -> PyResult<String> {
    Ok(match Choice::parse(name)? {
        Choice::Auto => match resolve_auto(device).0 {
            Choice::Gpu(k) => k.name().to_string(),
            _ => CPU.to_string(),
        },
        _ => name.to_string(),
    })
}

/// The context for a GPU kernel, or `DeviceError` saying why there is none.
pub fn gpu_context(kernel: Kernel, device: Option<usize>) -> PyResult<Arc<Context>> {
    let ctx = context(device).map_err(|e| device_error(kernel.name(), format!("no Vulkan device: {}", e.msg)))?;
    if kernel.needs_ray_tracing() && !ctx.info().ray_tracing {
        return Err(DeviceError::new_err(format!(
            "{}: the device '{}' has no ray-tracing pipelines; use backend='soft-bvh' or 'cpu'",
            kernel.name(),
            ctx.info().name
        )));
    }
    Ok(ctx)
}

/// `tetloc.devices()`: one dict per Vulkan device; empty when there is no Vulkan loader.
#[pyfunction]
pub fn devices(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    let list = match py.detach(tetloc_vulkan::devices) {
        Ok(l) => l,
        Err(e) if is_no_vulkan(&e) => Vec::new(),
        Err(e) => return Err(DeviceError::new_err(e.to_string())),
    };
    list.into_iter()
        .map(|d| {
            let dict = PyDict::new(py);
            dict.set_item("index", d.index)?;
            dict.set_item("name", d.name)?;
            dict.set_item("driver", d.driver)?;
            dict.set_item("device_type", d.device_type)?;
            dict.set_item("api_version", d.api_version)?;
            dict.set_item("ray_tracing", d.ray_tracing)?;
            dict.set_item("memory_bytes", d.memory_bytes)?;
            dict.set_item("float64", d.float64)?;
            let kernels = Kernel::ALL.iter().filter(|k| d.ray_tracing || !k.needs_ray_tracing());
            dict.set_item("backends", kernels.map(|k| k.name()).collect::<Vec<_>>())?;
            Ok(dict)
        })
        .collect()
}
