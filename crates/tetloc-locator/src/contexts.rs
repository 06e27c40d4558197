//! The process' Vulkan contexts: one per device index, opened on first use and shared by
//! every locator on that device. Validation is on when `TETLOC_VK_VALIDATION` is set.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
use tetloc_vulkan::{Context, ContextOptions, VkError};

/// Why there is no context: no Vulkan at all (loader, driver or device missing), or a failure.
#[derive(Clone, Debug)]
pub struct NoContext {
    pub no_vulkan: bool,
    pub msg: String,
}

type Contexts = Mutex<HashMap<Option<usize>, Result<Arc<Context>, NoContext>>>;

fn contexts() -> &'static Contexts {
    static CONTEXTS: OnceLock<Contexts> = OnceLock::new();
    CONTEXTS.get_or_init(Default::default)
}

/// The process' context on `device` (the best device when `None`), opened once; a failure is
/// remembered too.
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
pub fn is_no_vulkan(e: &VkError) -> bool {
    matches!(
        e,
        VkError::NoLoader(_)
            | VkError::NoDevice
            | VkError::Vk { what: "vkCreateInstance", result: ash::vk::Result::ERROR_INCOMPATIBLE_DRIVER }
    )
}

/// Validation-layer errors reported so far on every open context (tests check for 0).
pub fn validation_errors() -> usize {
    let map = contexts().lock().unwrap_or_else(|p| p.into_inner());
    map.values().filter_map(|c| c.as_ref().ok()).map(|c| c.validation_errors()).sum()
}
