//! Backend selection: `cpu` here; the Vulkan kernels plug in through the same
//! `BatchLocator` trait.

use anyhow::{bail, Result};
use std::sync::Arc;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};

pub const CPU: &str = "cpu";

/// Every backend name the CLI accepts (besides `auto`).
pub fn names() -> Vec<&'static str> {
    vec![CPU]
}

/// Options that matter to some backends.
#[derive(Clone, Debug, Default)]
pub struct BackendOptions {
    pub device: Option<usize>,
}

/// Backends that can run on this machine, in the order `auto` prefers them.
pub fn available(_opts: &BackendOptions) -> Vec<&'static str> {
    vec![CPU]
}

/// Builds the named backend over `mesh`. `auto` picks the first available one.
pub fn make(name: &str, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<Box<dyn BatchLocator>> {
    let name = if name == "auto" { available(opts)[0] } else { name };
    match name {
        CPU => Ok(Box::new(CpuLocator::new(mesh.clone()))),
        other => bail!("unknown backend '{other}' (known: {}, auto)", names().join(", ")),
    }
}
