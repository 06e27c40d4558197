//! GPU memory and submission, the parts the device object (`device.rs`) is made of: named,
//! counted buffers (one allocation each), one-shot command submission, and uploads/downloads
//! through one bounded staging buffer.

use crate::context::Context;
use crate::error::{VkError, VkResult};
use crate::external::{SemaphoreKind, SharedSemaphore};
use ash::vk;
use std::os::fd::{IntoRawFd, OwnedFd};
use std::sync::{Arc, Mutex};

/// What an allocation is for; decides which report total it counts in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemKind {
    /// Mesh data on the GPU: vertices, tets, a field.
    Mesh,
    /// The kernel's search structure: BVH nodes, acceleration structures, primitive tables.
    Structure,
    /// Only alive while building (AS build scratch, build inputs, uncompacted structures).
    Scratch,
    /// The staging buffer for uploads and downloads.
    Staging,
    /// Per-batch query points and results.
    Query,
}

/// One live allocation.
#[derive(Clone, Debug)]
pub struct MemItem {
    pub name: String,
    pub kind: MemKind,
    pub bytes: u64,
}

/// Counts live allocations and the peak of their sum.
#[derive(Debug, Default)]
pub(crate) struct Tracker {
    live: Vec<(u64, MemItem)>,
    next_id: u64,
    current: u64,
    peak: u64,
}

impl Tracker {
    fn add(&mut self, item: MemItem) -> u64 {
        self.next_id += 1;
        self.current += item.bytes;
        self.peak = self.peak.max(self.current);
        self.live.push((self.next_id, item));
        self.next_id
    }

    fn remove(&mut self, id: u64) {
        if let Some(i) = self.live.iter().position(|(k, _)| *k == id) {
            self.current -= self.live.swap_remove(i).1.bytes;
        }
    }

    pub fn peak(&self) -> u64 {
        self.peak
    }

    /// Live allocations, in allocation order.
    pub fn items(&self) -> Vec<MemItem> {
        let mut v = self.live.clone();
        v.sort_by_key(|(k, _)| *k);
        v.into_iter().map(|(_, m)| m).collect()
    }
}

pub(crate) type SharedTracker = Arc<Mutex<Tracker>>;

/// Where a buffer lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Location {
    Device,
    /// Host-visible and coherent (staging), preferably cached for fast reads.
    Host,
}

/// What a buffer is: its size and usage, where it lives, and the report total it counts in.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BufferDesc {
    pub size: u64,
    pub usage: vk::BufferUsageFlags,
    pub kind: MemKind,
    pub location: Location,
}

impl BufferDesc {
    /// A device-local buffer.
    pub fn device(kind: MemKind, size: u64, usage: vk::BufferUsageFlags) -> BufferDesc {
        BufferDesc { size, usage, kind, location: Location::Device }
    }

    /// A device-local storage buffer that transfers fill and read (query points, results).
    pub fn io(kind: MemKind, size: u64) -> BufferDesc {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        Self::device(kind, size, usage)
    }
}

#[cfg_attr(not(feature = "cuda"), allow(dead_code))] // shared by cuda_interop.rs
/// Whether a buffer's memory is shared with another API (CUDA) through an opaque fd; shared
/// memory is a dedicated allocation, as CUDA's import of it asks.
pub(crate) enum Sharing {
    None,
    /// Exportable: [`Buffer::export_fd`] gives fds of it.
    Export,
    /// (Made by the tests: CUDA imports Vulkan's memory, never the reverse.)
    #[cfg_attr(not(test), allow(dead_code))]
    /// The memory behind an exported fd, for a buffer of the same description (same size and
    /// usage): Vulkan owns the fd once the import succeeds.
    Import(OwnedFd),
}

/// A buffer with its own memory allocation. Dropping it frees both and updates the tracker.
pub(crate) struct Buffer {
    ctx: Arc<Context>,
    tracker: SharedTracker,
    id: u64,
    pub buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    pub size: u64,
    /// Bytes of the allocation (at least `size`): what an importer of its fd must name.
    #[cfg_attr(not(feature = "cuda"), allow(dead_code))]
    pub alloc_size: u64,
    /// Device address when created with SHADER_DEVICE_ADDRESS usage, else 0.
    pub address: u64,
    mapped: *mut u8,
}

// SAFETY: the mapped pointer is only used through &mut self; Vulkan handles are plain ids.
unsafe impl Send for Buffer {}

impl Buffer {
    pub fn new(
        ctx: &Arc<Context>,
        tracker: &SharedTracker,
        desc: BufferDesc,
        name: impl Into<String>,
    ) -> VkResult<Buffer> {
        Self::shared(ctx, tracker, desc, name, Sharing::None)
    }

    /// [`Buffer::new`] whose memory is exported or imported as `sharing` says. Sharing needs
    /// the device's fd extensions (`Context::external`): without them, a clear error.
    pub fn shared(
        ctx: &Arc<Context>,
        tracker: &SharedTracker,
        desc: BufferDesc,
        name: impl Into<String>,
        sharing: Sharing,
    ) -> VkResult<Buffer> {
        let BufferDesc { size, usage, kind, location } = desc;
        let name = name.into();
        let size = size.max(16);
        if ctx.limits.max_allocation > 0 && size > ctx.limits.max_allocation {
            return Err(VkError::TooLarge {
                name,
                bytes: size,
                limit: ctx.limits.max_allocation,
                what: "maxMemoryAllocationSize",
            });
        }
        let dev = &ctx.device;
        let with_address = usage.contains(vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS);
        let shared = !matches!(sharing, Sharing::None);
        if shared {
            crate::external::check_memory(ctx, usage)?;
        }
        let handle = vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD;
        // SAFETY: valid create infos; every handle is destroyed on the error paths and in Drop.
        unsafe {
            let mut external = vk::ExternalMemoryBufferCreateInfo::default().handle_types(handle);
            let mut info = vk::BufferCreateInfo::default().size(size).usage(usage);
            if shared {
                info = info.push_next(&mut external);
            }
            let buffer = dev.create_buffer(&info, None).map_err(VkError::vk("vkCreateBuffer"))?;
            let req = dev.get_buffer_memory_requirements(buffer);
            let (want, prefer) = match location {
                Location::Device => (vk::MemoryPropertyFlags::DEVICE_LOCAL, vk::MemoryPropertyFlags::empty()),
                Location::Host => (
                    vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT,
                    vk::MemoryPropertyFlags::HOST_CACHED,
                ),
            };
            let type_index = match ctx.memory_type(req.memory_type_bits, want, prefer) {
                Ok(t) => t,
                Err(e) => {
                    dev.destroy_buffer(buffer, None);
                    return Err(e);
                }
            };
            let mut flags = vk::MemoryAllocateFlagsInfo::default().flags(vk::MemoryAllocateFlags::DEVICE_ADDRESS);
            let mut alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(type_index);
            if with_address {
                alloc = alloc.push_next(&mut flags);
            }
            let mut dedicated = vk::MemoryDedicatedAllocateInfo::default().buffer(buffer);
            let mut export = vk::ExportMemoryAllocateInfo::default().handle_types(handle);
            let fd = match &sharing {
                Sharing::Import(fd) => std::os::fd::AsRawFd::as_raw_fd(fd),
                _ => -1,
            };
            let mut import = vk::ImportMemoryFdInfoKHR::default().handle_type(handle).fd(fd);
            match sharing {
                Sharing::None => {}
                Sharing::Export => alloc = alloc.push_next(&mut dedicated).push_next(&mut export),
                Sharing::Import(_) => alloc = alloc.push_next(&mut dedicated).push_next(&mut import),
            }
            let memory = match dev.allocate_memory(&alloc, None) {
                Ok(m) => m,
                Err(result) => {
                    dev.destroy_buffer(buffer, None);
                    return Err(VkError::Vk { what: "vkAllocateMemory", result });
                }
            };
            if let Sharing::Import(fd) = sharing {
                // The import succeeded: the fd is Vulkan's now (closed with the memory).
                let _ = fd.into_raw_fd();
            }
            let bound = dev.bind_buffer_memory(buffer, memory, 0).map_err(VkError::vk("vkBindBufferMemory"));
            let mapped = match (bound, location) {
                (Err(e), _) => Err(e),
                (Ok(()), Location::Host) => dev
                    .map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                    .map(|p| p as *mut u8)
                    .map_err(VkError::vk("vkMapMemory")),
                (Ok(()), Location::Device) => Ok(std::ptr::null_mut()),
            };
            let mapped = match mapped {
                Ok(p) => p,
                Err(e) => {
                    dev.destroy_buffer(buffer, None);
                    dev.free_memory(memory, None);
                    return Err(e);
                }
            };
            let address = if with_address {
                dev.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(buffer))
            } else {
                0
            };
            let id = tracker.lock().unwrap().add(MemItem { name, kind, bytes: req.size });
            let alloc_size = req.size;
            Ok(Buffer {
                ctx: ctx.clone(),
                tracker: tracker.clone(),
                id,
                buffer,
                memory,
                size,
                alloc_size,
                address,
                mapped,
            })
        }
    }

    /// The mapped bytes of a host buffer.
    pub fn mapped(&mut self) -> &mut [u8] {
        assert!(!self.mapped.is_null(), "not a host-visible buffer");
        // SAFETY: the whole allocation (>= size) is mapped for the buffer's lifetime.
        unsafe { std::slice::from_raw_parts_mut(self.mapped, self.size as usize) }
    }

    #[cfg_attr(not(feature = "cuda"), allow(dead_code))]
    /// A new opaque fd of this buffer's memory (made with [`Sharing::Export`]); the caller owns it.
    pub fn export_fd(&self) -> VkResult<OwnedFd> {
        let fns = crate::external::memory_fd(&self.ctx)?;
        let info = vk::MemoryGetFdInfoKHR::default()
            .memory(self.memory)
            .handle_type(vk::ExternalMemoryHandleTypeFlags::OPAQUE_FD);
        // SAFETY: live memory allocated exportable as an opaque fd (else the call fails).
        let fd = unsafe { fns.get_memory_fd(&info) }.map_err(VkError::vk("vkGetMemoryFdKHR"))?;
        // SAFETY: vkGetMemoryFdKHR returns a new fd that the caller owns.
        Ok(unsafe { <OwnedFd as std::os::fd::FromRawFd>::from_raw_fd(fd) })
    }

    pub fn info(&self) -> vk::DescriptorBufferInfo {
        vk::DescriptorBufferInfo { buffer: self.buffer, offset: 0, range: vk::WHOLE_SIZE }
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: all work using the buffer has completed: every submission is waited for.
        unsafe {
            self.ctx.device.destroy_buffer(self.buffer, None);
            self.ctx.device.free_memory(self.memory, None);
        }
        self.tracker.lock().unwrap().remove(self.id);
    }
}

/// A semaphore operation of a submission: the semaphore and the timeline value to wait for
/// or signal (ignored for binary semaphores), or none.
pub(crate) type SemOp<'a> = Option<(&'a SharedSemaphore, u64)>;

/// A command pool with one command buffer and a fence: record, submit, wait.
pub(crate) struct Commands {
    ctx: Arc<Context>,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

/// Longest we wait for one submission before reporting the GPU as hung.
const SUBMIT_TIMEOUT_NS: u64 = 600_000_000_000;

impl Commands {
    pub fn new(ctx: &Arc<Context>) -> VkResult<Commands> {
        let dev = &ctx.device;
        // SAFETY: plain object creation; partial results are destroyed on error.
        unsafe {
            let pool = dev
                .create_command_pool(&vk::CommandPoolCreateInfo::default().queue_family_index(ctx.queue_family), None)
                .map_err(VkError::vk("vkCreateCommandPool"))?;
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(pool).command_buffer_count(1);
            let cmd = match dev.allocate_command_buffers(&alloc) {
                Ok(c) => c[0],
                Err(result) => {
                    dev.destroy_command_pool(pool, None);
                    return Err(VkError::Vk { what: "vkAllocateCommandBuffers", result });
                }
            };
            let fence = match dev.create_fence(&vk::FenceCreateInfo::default(), None) {
                Ok(f) => f,
                Err(result) => {
                    dev.destroy_command_pool(pool, None);
                    return Err(VkError::Vk { what: "vkCreateFence", result });
                }
            };
            Ok(Commands { ctx: ctx.clone(), pool, cmd, fence })
        }
    }

    /// Records commands with `record`, submits them and waits for completion. Every
    /// submission starts with a full memory barrier, so it sees all earlier submissions' writes.
    pub fn run<R>(&mut self, record: impl FnOnce(&Recording) -> R) -> VkResult<R> {
        self.run_synced(None, None, record)
    }

    /// [`Commands::run`] that first waits for `wait` and then signals `signal` (semaphore and
    /// timeline value; the value is ignored for binary semaphores): how work is ordered with
    /// another API's (`cuda_interop.rs`).
    pub fn run_synced<R>(&mut self, wait: SemOp, signal: SemOp, record: impl FnOnce(&Recording) -> R) -> VkResult<R> {
        let dev = &self.ctx.device;
        let rec = Recording { ctx: &self.ctx, dev, cmd: self.cmd };
        // SAFETY: the previous submission has completed (we always wait), so the pool can be
        // reset; the queue is externally synchronised by the context's mutex.
        unsafe {
            dev.reset_command_pool(self.pool, vk::CommandPoolResetFlags::empty())
                .map_err(VkError::vk("vkResetCommandPool"))?;
            dev.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .map_err(VkError::vk("vkBeginCommandBuffer"))?;
            rec.barrier();
            let r = record(&rec);
            dev.end_command_buffer(self.cmd).map_err(VkError::vk("vkEndCommandBuffer"))?;
            let cmds = [self.cmd];
            let (wait_sems, wait_values): (Vec<_>, Vec<_>) = wait.iter().map(|(s, v)| (s.sem, *v)).unzip();
            let (signal_sems, signal_values): (Vec<_>, Vec<_>) = signal.iter().map(|(s, v)| (s.sem, *v)).unzip();
            let stages = vec![vk::PipelineStageFlags::ALL_COMMANDS; wait_sems.len()];
            let timeline = wait.iter().chain(&signal).any(|(s, _)| s.kind == SemaphoreKind::Timeline);
            let mut values = vk::TimelineSemaphoreSubmitInfo::default()
                .wait_semaphore_values(&wait_values)
                .signal_semaphore_values(&signal_values);
            let mut submit = vk::SubmitInfo::default()
                .command_buffers(&cmds)
                .wait_semaphores(&wait_sems)
                .wait_dst_stage_mask(&stages)
                .signal_semaphores(&signal_sems);
            if timeline {
                submit = submit.push_next(&mut values);
            }
            {
                let queue = self.ctx.queue.lock().unwrap();
                dev.queue_submit(*queue, &[submit], self.fence).map_err(VkError::vk("vkQueueSubmit"))?;
            }
            let waited = dev.wait_for_fences(&[self.fence], true, SUBMIT_TIMEOUT_NS);
            dev.reset_fences(&[self.fence]).map_err(VkError::vk("vkResetFences"))?;
            waited.map_err(VkError::vk("vkWaitForFences"))?;
            Ok(r)
        }
    }
}

/// A command buffer being recorded, with the context it belongs to.
pub(crate) struct Recording<'a> {
    pub ctx: &'a Context,
    pub dev: &'a ash::Device,
    pub cmd: vk::CommandBuffer,
}

impl Recording<'_> {
    /// Makes all earlier writes (transfers, builds, shaders) visible to all later commands.
    pub fn barrier(&self) {
        let all = vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE;
        self.memory_barrier(vk::PipelineStageFlags::ALL_COMMANDS, vk::AccessFlags::MEMORY_WRITE, all);
    }

    /// Makes the `src` writes of earlier commands at `stage` visible to the `dst` accesses of
    /// later ones at `stage`.
    pub fn memory_barrier(&self, stage: vk::PipelineStageFlags, src: vk::AccessFlags, dst: vk::AccessFlags) {
        let barrier = vk::MemoryBarrier::default().src_access_mask(src).dst_access_mask(dst);
        let no_deps = vk::DependencyFlags::empty();
        // SAFETY: recording into a command buffer in the recording state.
        unsafe { self.dev.cmd_pipeline_barrier(self.cmd, stage, stage, no_deps, &[barrier], &[], &[]) };
    }
}

impl Drop for Commands {
    fn drop(&mut self) {
        // SAFETY: no submission is pending (run() always waits).
        unsafe {
            self.ctx.device.destroy_fence(self.fence, None);
            self.ctx.device.destroy_command_pool(self.pool, None);
        }
    }
}

/// Default size of the staging buffer: uploads and downloads move through it in pieces.
pub const STAGING_BYTES: u64 = 64 << 20;

/// The one bounded staging buffer of a device object.
pub(crate) struct Staging {
    buf: Buffer,
}

impl Staging {
    pub fn new(ctx: &Arc<Context>, tracker: &SharedTracker, bytes: u64) -> VkResult<Staging> {
        let usage = vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
        let desc = BufferDesc { size: bytes, usage, kind: MemKind::Staging, location: Location::Host };
        Ok(Staging { buf: Buffer::new(ctx, tracker, desc, "staging")? })
    }

    /// Copies `data` into `dst` at `offset`, one staging-buffer-full at a time.
    pub fn upload(&mut self, cmds: &mut Commands, dst: &Buffer, offset: u64, data: &[u8]) -> VkResult<()> {
        let step = self.buf.size as usize;
        for (k, piece) in data.chunks(step).enumerate() {
            // On every core: one core copies ~10 GB/s, the mesh of 62M tets is 1.1 GB.
            par_copy(&mut self.buf.mapped()[..piece.len()], piece);
            let region =
                vk::BufferCopy { src_offset: 0, dst_offset: offset + (k * step) as u64, size: piece.len() as u64 };
            let src = self.buf.buffer;
            // SAFETY: both buffers are alive and large enough; the copy completes before return.
            cmds.run(|r| unsafe { r.dev.cmd_copy_buffer(r.cmd, src, dst.buffer, &[region]) })?;
        }
        Ok(())
    }

    /// One launch's round trip in one submission: `input` into `dst` from byte 0, the
    /// commands `record` records, then the first bytes of `src` into `outs`, one after the
    /// other (ids, then values). The host copies use every core (the staging buffer is host
    /// memory the device copies from and to directly); all must fit in the staging buffer
    /// together.
    pub fn round_trip(
        &mut self,
        cmds: &mut Commands,
        (input, dst): (&[u8], &Buffer),
        (src, outs): (&Buffer, &mut [&mut [u8]]),
        record: impl FnOnce(&Recording),
    ) -> VkResult<()> {
        let n_in = input.len();
        let n_out: usize = outs.iter().map(|o| o.len()).sum();
        assert!(n_in + n_out <= self.buf.size as usize, "a round trip larger than the staging buffer");
        par_copy(&mut self.buf.mapped()[..n_in], input);
        let stage = self.buf.buffer;
        let up = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: n_in as u64 };
        let down = vk::BufferCopy { src_offset: 0, dst_offset: n_in as u64, size: n_out as u64 };
        cmds.run(|r| {
            // SAFETY: live buffers, large enough (asserted above); the work completes before return.
            unsafe { r.dev.cmd_copy_buffer(r.cmd, stage, dst.buffer, &[up]) };
            r.barrier();
            record(r);
            r.barrier();
            // SAFETY: as above.
            unsafe { r.dev.cmd_copy_buffer(r.cmd, src.buffer, stage, &[down]) };
        })?;
        let mut at = n_in;
        for out in outs.iter_mut() {
            par_copy(out, &self.buf.mapped()[at..at + out.len()]);
            at += out.len();
        }
        Ok(())
    }

    pub fn bytes(&self) -> usize {
        self.buf.size as usize
    }

    /// Copies `out.len()` bytes of `src` from `offset` into `out`.
    pub fn download(&mut self, cmds: &mut Commands, src: &Buffer, offset: u64, out: &mut [u8]) -> VkResult<()> {
        let step = self.buf.size as usize;
        for (k, piece) in out.chunks_mut(step).enumerate() {
            let region =
                vk::BufferCopy { src_offset: offset + (k * step) as u64, dst_offset: 0, size: piece.len() as u64 };
            let dst = self.buf.buffer;
            // SAFETY: as in upload; the fence wait in run() makes the host see the copy.
            cmds.run(|r| unsafe { r.dev.cmd_copy_buffer(r.cmd, src.buffer, dst, &[region]) })?;
            // On every core, as uploads: a fresh `out` also faults its pages in on every core
            // (the step weights download 64 MB a step at 16M points).
            par_copy(piece, &self.buf.mapped()[..piece.len()]);
        }
        Ok(())
    }
}

/// `dst.copy_from_slice(src)` on every core, in 1 MiB pieces.
fn par_copy(dst: &mut [u8], src: &[u8]) {
    use rayon::prelude::*;
    dst.par_chunks_mut(1 << 20).zip(src.par_chunks(1 << 20)).for_each(|(d, s)| d.copy_from_slice(s));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracker_counts_live_and_peak() {
        let mut t = Tracker::default();
        let a = t.add(MemItem { name: "a".into(), kind: MemKind::Mesh, bytes: 100 });
        let b = t.add(MemItem { name: "b".into(), kind: MemKind::Scratch, bytes: 50 });
        t.remove(b);
        let _c = t.add(MemItem { name: "c".into(), kind: MemKind::Structure, bytes: 20 });
        assert_eq!(t.current, 120);
        assert_eq!(t.peak(), 150);
        t.remove(a);
        assert_eq!(t.items().iter().map(|m| m.name.as_str()).collect::<Vec<_>>(), ["c"]);
    }
}
