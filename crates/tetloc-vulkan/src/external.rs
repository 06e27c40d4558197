//! Memory and semaphores shared with another API on the same GPU (CUDA: `cuda_interop.rs`)
//! through opaque file descriptors (`VK_KHR_external_memory_fd`,
//! `VK_KHR_external_semaphore_fd`). The context enables the two extensions only where the
//! device has them; without them every call here is a clear "not supported on this device"
//! error. Buffers are exported or imported by `memory::Buffer::shared`; semaphores are here.

use crate::context::{Context, ExternalFd};
use crate::error::{VkError, VkResult};
use ash::vk;
use std::os::fd::{AsRawFd, FromRawFd, IntoRawFd, OwnedFd};
use std::sync::Arc;

/// The error of a device without what sharing needs (`what`).
fn unsupported(ctx: &Context, what: &str) -> VkError {
    VkError::Unsupported {
        device: ctx.device_name(),
        reason: format!("sharing memory with CUDA is not supported on this device: {what}"),
    }
}

/// The fd extensions' tables, or the error of a device with neither.
fn fd_tables(ctx: &Context) -> VkResult<&ExternalFd> {
    ctx.external
        .as_ref()
        .ok_or_else(|| unsupported(ctx, "it lacks VK_KHR_external_memory_fd and VK_KHR_external_semaphore_fd"))
}

/// `VK_KHR_external_memory_fd`'s functions, or the error of a device without it.
pub(crate) fn memory_fd(ctx: &Context) -> VkResult<&ash::khr::external_memory_fd::Device> {
    fd_tables(ctx)?.memory.as_ref().ok_or_else(|| unsupported(ctx, "it lacks VK_KHR_external_memory_fd"))
}

/// `VK_KHR_external_semaphore_fd`'s functions, or the error of a device without it.
fn semaphore_fd(ctx: &Context) -> VkResult<&ash::khr::external_semaphore_fd::Device> {
    fd_tables(ctx)?.semaphore.as_ref().ok_or_else(|| unsupported(ctx, "it lacks VK_KHR_external_semaphore_fd"))
}

/// Checks that buffers of `usage` can be exported and imported as opaque fds.
pub(crate) fn check_memory(ctx: &Context, usage: vk::BufferUsageFlags) -> VkResult<()> {
    memory_fd(ctx)?;
    let ext = fd_tables(ctx)?;
    let info = vk::PhysicalDeviceExternalBufferInfo::default()
        .usage(usage)
        .handle_type(vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD);
    let mut props = vk::ExternalBufferProperties::default();
    // SAFETY: a capability query on the context's physical device (Vulkan 1.1 core).
    unsafe { ctx.instance.get_physical_device_external_buffer_properties(ext.physical, &info, &mut props) };
    let f = props.external_memory_properties.external_memory_features;
    let both = vk::ExternalMemoryFeatureFlags::EXPORTABLE | vk::ExternalMemoryFeatureFlags::IMPORTABLE;
    if !f.contains(both) {
        return Err(unsupported(
            ctx,
            &format!("buffers of usage {usage:?} cannot be exported and imported as opaque fds"),
        ));
    }
    Ok(())
}

/// How Vulkan and CUDA order their work: one timeline semaphore (values counting up; Vulkan
/// waits for CUDA's value and signals the next), or, where timelines cannot be shared, binary
/// semaphores (one each way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SemaphoreKind {
    Timeline,
    Binary,
}

/// Whether a semaphore of `kind` can be exported and imported as an opaque fd.
fn semaphore_shareable(ctx: &Context, ext: &ExternalFd, kind: SemaphoreKind) -> bool {
    if kind == SemaphoreKind::Timeline && !ext.timeline {
        return false;
    }
    let mut ty = vk::SemaphoreTypeCreateInfo::default().semaphore_type(match kind {
        SemaphoreKind::Timeline => vk::SemaphoreType::TIMELINE,
        SemaphoreKind::Binary => vk::SemaphoreType::BINARY,
    });
    let info = vk::PhysicalDeviceExternalSemaphoreInfo::default()
        .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD)
        .push_next(&mut ty);
    let mut props = vk::ExternalSemaphoreProperties::default();
    // SAFETY: a capability query on the context's physical device (Vulkan 1.1 core, the
    // chained type struct 1.2 core).
    unsafe { ctx.instance.get_physical_device_external_semaphore_properties(ext.physical, &info, &mut props) };
    let both = vk::ExternalSemaphoreFeatureFlags::EXPORTABLE | vk::ExternalSemaphoreFeatureFlags::IMPORTABLE;
    props.external_semaphore_features.contains(both)
}

/// The semaphores this device shares: timeline where it can, else binary, else the error.
pub fn semaphore_kind(ctx: &Context) -> VkResult<SemaphoreKind> {
    semaphore_fd(ctx)?;
    let ext = fd_tables(ctx)?;
    [SemaphoreKind::Timeline, SemaphoreKind::Binary]
        .into_iter()
        .find(|&k| semaphore_shareable(ctx, ext, k))
        .ok_or_else(|| unsupported(ctx, "its semaphores cannot be exported as opaque fds"))
}

/// A semaphore whose payload is shared through opaque fds.
pub(crate) struct SharedSemaphore {
    ctx: Arc<Context>,
    pub sem: vk::Semaphore,
    pub kind: SemaphoreKind,
}

impl SharedSemaphore {
    fn create(ctx: &Arc<Context>, kind: SemaphoreKind, import: Option<OwnedFd>) -> VkResult<SharedSemaphore> {
        let fns = semaphore_fd(ctx)?;
        let ext = fd_tables(ctx)?;
        if !semaphore_shareable(ctx, ext, kind) {
            return Err(unsupported(ctx, &format!("{kind:?} semaphores cannot be exported as opaque fds")));
        }
        let handle = vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD;
        let mut ty = vk::SemaphoreTypeCreateInfo::default().semaphore_type(match kind {
            SemaphoreKind::Timeline => vk::SemaphoreType::TIMELINE,
            SemaphoreKind::Binary => vk::SemaphoreType::BINARY,
        });
        let mut export = vk::ExportSemaphoreCreateInfo::default().handle_types(handle);
        let mut info = vk::SemaphoreCreateInfo::default().push_next(&mut ty);
        if import.is_none() {
            info = info.push_next(&mut export);
        }
        // SAFETY: a valid create info; the semaphore is destroyed on the error path and in Drop.
        let sem = unsafe { ctx.device.create_semaphore(&info, None) }.map_err(VkError::vk("vkCreateSemaphore"))?;
        let s = SharedSemaphore { ctx: ctx.clone(), sem, kind };
        if let Some(fd) = import {
            let info = vk::ImportSemaphoreFdInfoKHR::default().semaphore(sem).handle_type(handle).fd(fd.as_raw_fd());
            // SAFETY: a live semaphore of the same type as the exported one; on success the
            // fd belongs to Vulkan, so we let go of it.
            unsafe { fns.import_semaphore_fd(&info) }.map_err(VkError::vk("vkImportSemaphoreFdKHR"))?;
            let _ = fd.into_raw_fd();
        }
        Ok(s)
    }

    /// An exportable semaphore of `kind` (a timeline starts at 0).
    pub fn new(ctx: &Arc<Context>, kind: SemaphoreKind) -> VkResult<SharedSemaphore> {
        Self::create(ctx, kind, None)
    }

    /// A semaphore sharing the payload behind `fd` (exported from a semaphore of `kind`).
    #[cfg(test)]
    pub fn import(ctx: &Arc<Context>, kind: SemaphoreKind, fd: OwnedFd) -> VkResult<SharedSemaphore> {
        Self::create(ctx, kind, Some(fd))
    }

    /// A timeline semaphore that is not exported (for tests of the submissions on devices
    /// without `VK_KHR_external_semaphore_fd`).
    #[cfg(test)]
    pub fn local_timeline(ctx: &Arc<Context>) -> VkResult<SharedSemaphore> {
        let mut ty = vk::SemaphoreTypeCreateInfo::default().semaphore_type(vk::SemaphoreType::TIMELINE);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut ty);
        // SAFETY: a valid create info (timeline semaphores are enabled where supported).
        let sem = unsafe { ctx.device.create_semaphore(&info, None) }.map_err(VkError::vk("vkCreateSemaphore"))?;
        Ok(SharedSemaphore { ctx: ctx.clone(), sem, kind: SemaphoreKind::Timeline })
    }

    /// A new opaque fd of this semaphore; the caller owns it.
    pub fn export_fd(&self) -> VkResult<OwnedFd> {
        let fns = semaphore_fd(&self.ctx)?;
        let info = vk::SemaphoreGetFdInfoKHR::default()
            .semaphore(self.sem)
            .handle_type(vk::ExternalSemaphoreHandleTypeFlags::OPAQUE_FD);
        // SAFETY: a live semaphore created exportable as an opaque fd.
        let fd = unsafe { fns.get_semaphore_fd(&info) }.map_err(VkError::vk("vkGetSemaphoreFdKHR"))?;
        // SAFETY: vkGetSemaphoreFdKHR returns a new fd that the caller owns.
        Ok(unsafe { OwnedFd::from_raw_fd(fd) })
    }

    /// A timeline's current value.
    #[cfg(test)]
    pub fn value(&self) -> VkResult<u64> {
        // SAFETY: a live timeline semaphore.
        unsafe { self.ctx.device.get_semaphore_counter_value(self.sem) }
            .map_err(VkError::vk("vkGetSemaphoreCounterValue"))
    }

    /// Sets a timeline to `value` from the host.
    #[cfg(test)]
    pub fn signal(&self, value: u64) -> VkResult<()> {
        let info = vk::SemaphoreSignalInfo::default().semaphore(self.sem).value(value);
        // SAFETY: a live timeline semaphore; `value` is larger than its current value.
        unsafe { self.ctx.device.signal_semaphore(&info) }.map_err(VkError::vk("vkSignalSemaphore"))
    }
}

impl Drop for SharedSemaphore {
    fn drop(&mut self) {
        // SAFETY: no pending submission uses it (every submission is waited for).
        unsafe { self.ctx.device.destroy_semaphore(self.sem, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::Device;
    use crate::memory::{BufferDesc, MemKind, Sharing};

    /// Whether this device has the extension `name` (`present`); prints which way the test
    /// goes (lavapipe's answer depends on the Mesa version), so that a refusal is never a
    /// silent skip.
    fn shares(ctx: &Context, test: &str, name: &str, present: bool) -> bool {
        let how = if present { "present: checking the round trip" } else { "absent: checking the refusal" };
        eprintln!("{test}: {}: {name} {how}", ctx.info().name);
        present
    }

    #[test]
    fn exported_buffer_imports_with_same_bytes() {
        let Some(ctx) = crate::context::test_context("exported_buffer_imports_with_same_bytes") else { return };
        let mut dev = Device::new(&ctx, 1 << 20, None).unwrap();
        let desc = BufferDesc::io(MemKind::Query, 4096);
        let present = memory_fd(&ctx).is_ok();
        if !shares(&ctx, "exported_buffer_imports_with_same_bytes", "VK_KHR_external_memory_fd", present) {
            let err = dev.create_shared_buffer(desc, "exported", Sharing::Export).err().expect("refused");
            assert!(err.to_string().contains("not supported on this device"), "{err}");
            return;
        }
        let data: Vec<u8> = (0..4096u32).map(|i| (i * 7 % 251) as u8).collect();
        let a = dev.create_shared_buffer(desc, "exported", Sharing::Export).unwrap();
        dev.write(&a, 0, &data).unwrap();
        let fd = a.export_fd().unwrap();
        let b = dev.create_shared_buffer(desc, "imported", Sharing::Import(fd)).unwrap();
        assert_eq!(b.alloc_size, a.alloc_size);
        let mut back = vec![0u8; 4096];
        dev.download(&b, 0, &mut back).unwrap();
        assert_eq!(back, data, "the imported allocation holds the exported bytes");
        // And writes through the import are seen by the exporter: one memory.
        dev.write(&b, 100, &[9, 8, 7]).unwrap();
        dev.download(&a, 100, &mut back[..3]).unwrap();
        assert_eq!(&back[..3], &[9, 8, 7]);
        drop((a, b));
        assert_eq!(ctx.validation_errors(), 0);
    }

    /// The submission a CUDA handover makes: wait for a timeline value, run, signal the next
    /// (on a semaphore that is not exported, so that every device runs it; validated).
    #[test]
    fn submission_waits_for_and_signals_a_timeline() {
        let Some(ctx) = crate::context::test_context("submission_waits_for_and_signals_a_timeline") else { return };
        let sem = SharedSemaphore::local_timeline(&ctx).unwrap();
        let mut dev = Device::new(&ctx, 1 << 20, None).unwrap();
        let buf = dev.create_buffer(BufferDesc::io(MemKind::Query, 64), "b", None).unwrap();
        sem.signal(1).unwrap();
        dev.run_synced(Some((&sem, 1)), Some((&sem, 2)), |r| {
            // SAFETY: a live buffer, filled within its 64 bytes.
            unsafe { r.dev.cmd_fill_buffer(r.cmd, buf.buffer, 0, 64, 7) }
        })
        .unwrap();
        // The fence's wait orders the signal before it, but lavapipe has been seen (once, under
        // load) to report the counter a moment after the fence: allow it a second.
        let t = std::time::Instant::now();
        while sem.value().unwrap() < 2 && t.elapsed().as_secs_f64() < 1.0 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert_eq!(sem.value().unwrap(), 2, "the submission signalled the next value");
        let mut back = [0u8; 4];
        dev.download(&buf, 0, &mut back).unwrap();
        assert_eq!(u32::from_ne_bytes(back), 7);
        assert_eq!(ctx.validation_errors(), 0);
    }

    #[test]
    fn exported_semaphore_shares_its_payload() {
        let Some(ctx) = crate::context::test_context("exported_semaphore_shares_its_payload") else { return };
        let present = semaphore_fd(&ctx).is_ok();
        if !shares(&ctx, "exported_semaphore_shares_its_payload", "VK_KHR_external_semaphore_fd", present) {
            let err = semaphore_kind(&ctx).expect_err("refused");
            assert!(err.to_string().contains("not supported on this device"), "{err}");
            return;
        }
        let kind = match semaphore_kind(&ctx) {
            Ok(k) => k,
            Err(e) => {
                // The extension is there, but no semaphore type is exportable: refused clearly.
                eprintln!("exported_semaphore_shares_its_payload: refused: {e}");
                assert!(e.to_string().contains("not supported on this device"), "{e}");
                return;
            }
        };
        eprintln!("exported_semaphore_shares_its_payload: sharing {kind:?} semaphores");
        let a = SharedSemaphore::new(&ctx, kind).unwrap();
        let b = SharedSemaphore::import(&ctx, kind, a.export_fd().unwrap()).unwrap();
        if kind == SemaphoreKind::Timeline {
            a.signal(5).unwrap();
            assert_eq!(b.value().unwrap(), 5, "the import sees the exporter's value");
            b.signal(9).unwrap();
            assert_eq!(a.value().unwrap(), 9);
        }
        // A submission that waits on one and signals the other runs (and is validated).
        let mut dev = Device::new(&ctx, 1 << 20, None).unwrap();
        let (wait, signal) = match kind {
            SemaphoreKind::Timeline => ((&b, 9), (&a, 10)),
            SemaphoreKind::Binary => {
                dev.run_synced(None, Some((&a, 0)), |_| ()).unwrap();
                ((&b, 0), (&a, 0))
            }
        };
        dev.run_synced(Some(wait), Some(signal), |r| r.barrier()).unwrap();
        if kind == SemaphoreKind::Timeline {
            assert_eq!(b.value().unwrap(), 10);
        }
        assert_eq!(ctx.validation_errors(), 0);
    }
}
