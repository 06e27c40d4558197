//! The backend's typed errors. They convert into `tetloc_core::Error::Backend`.

use ash::vk;

/// Everything that can go wrong in the Vulkan backend.
#[derive(Debug, thiserror::Error)]
pub enum VkError {
    /// `libvulkan.so.1` (or the platform's loader) could not be opened.
    #[error("the Vulkan loader could not be loaded ({0}); install the Vulkan loader (e.g. libvulkan1) and a driver")]
    NoLoader(String),

    #[error("no Vulkan device found (the loader found no driver that exposes a device)")]
    NoDevice,

    #[error("Vulkan device index {index} out of range: there are {count} devices (see `tetloc devices`)")]
    BadDeviceIndex { index: usize, count: usize },

    /// The device cannot run tetloc at all (too old an API version, no compute queue, ...).
    #[error("{device}: {reason}")]
    Unsupported { device: String, reason: String },

    /// A ray-tracing kernel on a device without ray-tracing pipelines.
    #[error("{device}: kernel '{kernel}' needs ray-tracing pipelines (VK_KHR_ray_tracing_pipeline and VK_KHR_acceleration_structure), which this device lacks; use soft-bvh")]
    NoRayTracing { device: String, kernel: String },

    /// The GPU has no usable timestamps on the queue tetloc uses (benchmarks need them).
    #[error("{device}: the compute queue has no timestamp support, so kernels cannot be timed")]
    NoTimestamps { device: String },

    /// A Vulkan call failed.
    #[error("{what} failed: {result}")]
    Vk { what: &'static str, result: vk::Result },

    /// A buffer would exceed what the device can bind or allocate.
    #[error("{name}: {bytes} bytes exceed the device's limit of {limit} bytes ({what})")]
    TooLarge { name: String, bytes: u64, limit: u64, what: &'static str },

    #[error("no memory type with {0:?} for this buffer")]
    NoMemoryType(vk::MemoryPropertyFlags),

    /// The mesh does not fit one of the backend's encodings (index widths, ...).
    #[error("{0}")]
    Mesh(String),
}

impl VkError {
    /// Maps `vk::Result` errors of the named call.
    pub(crate) fn vk(what: &'static str) -> impl Fn(vk::Result) -> VkError {
        move |result| VkError::Vk { what, result }
    }
}

impl From<VkError> for tetloc_core::Error {
    fn from(e: VkError) -> Self {
        tetloc_core::Error::Backend { backend: "vulkan".into(), source: Box::new(e) }
    }
}

pub type VkResult<T> = std::result::Result<T, VkError>;
