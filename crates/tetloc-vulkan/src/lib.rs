//! tetloc's Vulkan backend: which tet contains each point, and the field value there, on any
//! Vulkan device. Four kernels after Wald et al., "RTX Beyond Ray Tracing" (HPG 2019):
//! `soft-bvh` (a compute shader traversing a quantized 4-wide BVH) and three ray-tracing
//! pipeline kernels (`rt-bvh`, `rt-rep-faces`, `rt-shared-faces`). Every kernel uses the one
//! watertight point-in-tet test of `tetloc_core::geom`, mirrored in `shaders/common/tet.glsl`.
//!
//! Layout: `kernels/` (one module per kernel, each building a `Plan`), `locator/` (the batch
//! API over any plan, and the benchmarks), `march.rs` (the volume marcher over any plan), `stream.rs` (particle tracing on soft-bvh),
//! `device.rs` (the device object: buffers, uploads, submissions), `interface.rs` (the one
//! definition of the Rust/GLSL interface; build.rs writes its GLSL side).
//!
//! ```no_run
//! use std::sync::Arc;
//! use tetloc_core::BatchLocator;
//! use tetloc_vulkan::{Context, Kernel, LocatorOptions, VulkanLocator};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! # let mesh: Arc<tetloc_core::Mesh> = unimplemented!();
//! let ctx = Context::new(None)?;
//! let mut loc = VulkanLocator::new(ctx, mesh, Kernel::SoftBvh, LocatorOptions::default())?;
//! let mut ids = vec![0; 1];
//! loc.locate(&[[0.1, 0.2, 0.3]], &mut ids)?;
//! # Ok(()) }
//! ```

mod context;
#[cfg(feature = "cuda")]
pub mod cuda_interop;
mod device;
mod error;
#[cfg_attr(not(feature = "cuda"), allow(dead_code))] // used by cuda_interop.rs and tests
mod external;
mod hinted;
mod interface;
mod kernels;
mod locator;
mod march;
mod memory;
pub mod memprobe;
mod nvml;
mod packed;
mod pipeline;
mod shaders;
mod stream;
mod weights;

pub use context::{devices, Context, ContextOptions, DeviceInfo};
pub use error::VkError;
pub use external::{semaphore_kind, SemaphoreKind};
/// Most fields one launch samples; a query of more takes a pass each this many.
pub use interface::MAX_FIELDS;
pub use kernels::rt::AsReport;
pub use kernels::BuildOn;
pub use kernels::{Kernel, RtOptions, SoftBvhOptions, GRID_TETS_PER_CELL, PRESETS};
#[cfg(any(test, feature = "test-hooks"))]
pub use locator::TestHooks;
pub use locator::{si, BenchOptions, BenchResult, LocatorOptions, MemoryReport, VulkanLocator};
pub use march::{MarchGrid, MarchScene, MarchStats, MarchView, VolumeMarcher};
pub use memory::{MemItem, MemKind, STAGING_BYTES};
pub use stream::StreamStats;
/// The query sets (`centers`, `random`, `bbox` generated in the kernels; `host` uploaded).
pub use tetloc_core::queries::QueryKind;
pub use weights::GpuWeights;

#[cfg(test)]
mod tests {
    /// Locators move between threads (one per thread); contexts are shared.
    #[test]
    fn thread_safety() {
        fn send<T: Send>() {}
        fn send_sync<T: Send + Sync>() {}
        send::<crate::VulkanLocator>();
        send_sync::<crate::Context>();
    }
}
