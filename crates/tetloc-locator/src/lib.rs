//! tetloc's front door: the one place where a front end (the CLI and its MPI ranks, render,
//! Python, and whatever comes next) turns "this mesh, this backend, these options" into a
//! locator. It owns
//!
//! - the backend names ([`Backend`]: parsed and listed here, with one error message),
//! - the process' Vulkan contexts, one per device index ([`context`]),
//! - `auto`, with one meaning everywhere ([`auto`]): `cpu` without Vulkan or on a Vulkan
//!   device that runs on the CPU (lavapipe), else the fastest backend in a measurement of at
//!   most two seconds, cached per device and driver,
//! - the wrapper stack ([`Layer`]): `FiniteOnly → CellLocator → F64Values → WithTolerance`.
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let mesh: std::sync::Arc<tetloc_core::Mesh> = unimplemented!();
//! use tetloc_locator::{Backend, Locator};
//! let built = Locator::builder(mesh).backend("auto".parse::<Backend>()?).tolerance("1%".parse()?).build()?;
//! println!("{} ({})", built.describe(), built.build_seconds);
//! let mut loc = built.locator;
//! # Ok(()) }
//! ```

mod backend;
mod builder;
mod contexts;
#[cfg(test)]
mod tests;

pub use backend::{available, kernels_on, names, Backend, AUTO, CPU};
pub use builder::auto::{self, AutoChoice, AutoReason};
pub use builder::{Bare, BareLocator, Built, Layer, Locator, LocatorBuilder, Memory};
pub use contexts::{context, is_no_vulkan, validation_errors, NoContext};
pub use tetloc_vulkan::{Kernel, LocatorOptions};

/// Why no locator was built.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A backend name that is none of [`names`] nor `auto`.
    #[error("unknown backend '{name}' (known: {known}, auto)")]
    UnknownBackend { name: String, known: String },
    /// A GPU backend without a Vulkan device to run on.
    #[error("{backend}: no Vulkan device: {reason}")]
    NoDevice { backend: &'static str, reason: String },
    /// A ray-tracing kernel on a device without ray-tracing pipelines.
    #[error("{backend}: the device '{device}' has no ray-tracing pipelines; use soft-bvh or cpu")]
    NoRayTracing { backend: &'static str, device: String },
    /// The Vulkan backend failed to build.
    #[error("{backend}: {source}")]
    Vulkan {
        backend: &'static str,
        #[source]
        source: tetloc_vulkan::VkError,
    },
    /// The core refused (a bad mesh, a failed measurement, a cache that cannot be read).
    #[error(transparent)]
    Core(#[from] tetloc_core::Error),
}

impl Error {
    /// Whether the error is about the GPU (front ends raise their device error for it).
    pub fn is_device(&self) -> bool {
        matches!(self, Error::NoDevice { .. } | Error::NoRayTracing { .. } | Error::Vulkan { .. })
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Samples per second as text: `1.23 G/s`, `45.6 M/s`, `789 k/s`.
pub fn fmt_rate(r: f64) -> String {
    if r >= 1e9 {
        format!("{:.2} G/s", r / 1e9)
    } else if r >= 1e6 {
        format!("{:.1} M/s", r / 1e6)
    } else {
        format!("{:.0} k/s", r / 1e3)
    }
}
