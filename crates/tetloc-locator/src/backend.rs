//! Backend names: `cpu`, the Vulkan kernels, and `auto`.

use crate::{contexts, Error};
use std::str::FromStr;
use tetloc_vulkan::{DeviceInfo, Kernel};

pub const CPU: &str = "cpu";
pub const AUTO: &str = "auto";

/// What a front end asks for: `auto` (decided by [`crate::auto`]), the CPU, or a Vulkan kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Backend {
    #[default]
    Auto,
    Cpu,
    Kernel(Kernel),
}

impl Backend {
    /// The name on the command line and in Python (`auto`, `cpu`, `soft-bvh`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Backend::Auto => AUTO,
            Backend::Cpu => CPU,
            Backend::Kernel(k) => k.name(),
        }
    }
}

tetloc_core::display_name!(Backend);

impl FromStr for Backend {
    type Err = Error;
    fn from_str(name: &str) -> Result<Backend, Error> {
        match name {
            AUTO => Ok(Backend::Auto),
            CPU => Ok(Backend::Cpu),
            _ => Kernel::ALL
                .into_iter()
                .find(|k| k.name() == name)
                .map(Backend::Kernel)
                .ok_or_else(|| Error::UnknownBackend { name: name.to_string(), known: names().join(", ") }),
        }
    }
}

/// Every backend name besides `auto`: `cpu`, then the Vulkan kernels.
pub fn names() -> Vec<&'static str> {
    std::iter::once(CPU).chain(Kernel::ALL.iter().map(|k| k.name())).collect()
}

/// The Vulkan kernels a device runs (the rt kernels need ray-tracing pipelines).
pub fn kernels_on(device: &DeviceInfo) -> Vec<Kernel> {
    Kernel::ALL.into_iter().filter(|k| device.ray_tracing || !k.needs_ray_tracing()).collect()
}

/// The backends that can run here on `device`: the Vulkan kernels it supports, then `cpu`.
pub fn available(device: Option<usize>) -> Vec<Backend> {
    let mut out = Vec::new();
    if let Ok(ctx) = contexts::context(device) {
        out.extend(kernels_on(ctx.info()).into_iter().map(Backend::Kernel));
    }
    out.push(Backend::Cpu);
    out
}
