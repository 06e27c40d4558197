//! The CLI's options of the front door ([`tetloc_locator`]): which backends there are, what
//! `auto` means and how locators are stacked are decided there, for every front end.

use anyhow::Result;
use std::sync::Arc;
use tetloc_core::Mesh;
use tetloc_locator::{Backend, Locator, LocatorBuilder};
use tetloc_vulkan::{BuildOn, LocatorOptions, RtOptions};

/// Every backend name the CLI accepts (besides `auto`, and `all` for bench).
pub fn names() -> Vec<&'static str> {
    tetloc_locator::names()
}

/// Options that matter to some backends.
#[derive(Clone, Debug)]
pub struct BackendOptions {
    pub device: Option<usize>,
    /// rt kernels: primitives per bottom-level structure (`None`: one structure).
    pub split: Option<usize>,
    pub compact: bool,
    /// GPU kernels: sort each batch along the Morton curve before locating it.
    pub order_queries: bool,
    /// soft-bvh layout (tetloc_vulkan::PRESETS).
    pub preset: String,
    /// soft-bvh: build its structure on the GPU or on the CPU.
    pub build: BuildOn,
    /// Do not say which backend `auto` chose.
    pub quiet: bool,
}

impl Default for BackendOptions {
    fn default() -> Self {
        let d = LocatorOptions::default();
        BackendOptions {
            device: None,
            split: d.rt.split,
            compact: d.rt.compact,
            order_queries: d.order_queries,
            preset: "fast".into(),
            build: d.soft_bvh.build,
            quiet: false,
        }
    }
}

impl BackendOptions {
    fn locator_options(&self) -> LocatorOptions {
        // The CLI offers only the known names (clap checks them).
        let mut o = LocatorOptions::preset(&self.preset).unwrap_or_default();
        o.rt = RtOptions { split: self.split, compact: self.compact };
        o.soft_bvh.build = self.build;
        o.order_queries = self.order_queries;
        o
    }

    /// The builder of backend `name` over `mesh` with these options, and the backend it
    /// builds: `auto` is decided now (and said on stderr unless quiet), before any spinner.
    pub fn builder(&self, mesh: &Arc<Mesh>, name: &str) -> Result<(Backend, LocatorBuilder<'static>)> {
        let b = Locator::builder(mesh.clone())
            .backend(name.parse()?)
            .device(self.device)
            .vulkan_options(self.locator_options())
            .quiet(self.quiet);
        let (backend, _) = b.resolve()?;
        Ok((backend, b.backend(backend)))
    }
}

/// Backends that can run here: the Vulkan kernels this device supports, then `cpu`.
pub fn available(opts: &BackendOptions) -> Vec<&'static str> {
    tetloc_locator::available(opts.device).into_iter().map(Backend::name).collect()
}
