//! tetloc's Vulkan backend.
