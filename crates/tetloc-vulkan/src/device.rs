//! The device object, in the manner of kajiya's `Device::create_buffer(desc, name, data)`:
//! one value owns what every GPU operation of a locator needs — the context, the allocation
//! tracker behind the memory report, the staging buffer and the command pool — and offers
//! named buffers with their data, arrays split over several buffers, writes, downloads and
//! recorded submissions (with barriers, see [`Recording`]). Callers pass this one object.

use crate::context::Context;
use crate::error::{VkError, VkResult};
use crate::interface::MAX_CHUNKS;
use crate::memory::{Buffer, BufferDesc, Commands, MemItem, MemKind, SemOp, SharedTracker, Sharing, Staging, Tracker};
use ash::vk;
use std::sync::{Arc, Mutex};

pub(crate) use crate::memory::Recording;

/// See the module's documentation.
pub(crate) struct Device {
    // Field order is drop order: the command pool and buffers before the context they hold.
    cmds: Commands,
    staging: Staging,
    unbound: Buffer,
    tracker: SharedTracker,
    /// Split arrays above this size (device limits, or a test's smaller one).
    max_buffer: u64,
    /// The largest buffer the device allows a shader to bind (no test hook).
    device_max_buffer: u64,
    ctx: Arc<Context>,
}

/// An array in one device buffer, or split over several of `per_chunk` elements each when it
/// is larger than one buffer may be (shaders/common/mesh.glsl reads both).
pub(crate) struct Split {
    pub parts: Vec<Buffer>,
    /// Elements per buffer; 0 when there is one buffer.
    pub per_chunk: u32,
}

impl Split {
    /// An array in one buffer.
    pub fn whole(buf: Buffer) -> Split {
        Split { parts: vec![buf], per_chunk: 0 }
    }
}

impl Drop for Device {
    /// The pipelines this locator (or marcher, or tracer) compiled are kept for the next
    /// process (the process' contexts live as long as it does, so their own drop is too late).
    fn drop(&mut self) {
        self.ctx.save_pipeline_cache();
    }
}

impl Device {
    /// A device object on `ctx` with a staging buffer of `staging_bytes`; arrays larger than
    /// one buffer may be (or than `max_buffer_bytes`, a test hook) are split.
    pub fn new(ctx: &Arc<Context>, staging_bytes: u64, max_buffer_bytes: Option<u64>) -> VkResult<Device> {
        let tracker: SharedTracker = Arc::new(Mutex::new(Tracker::default()));
        let cmds = Commands::new(ctx)?;
        let staging = Staging::new(ctx, &tracker, staging_bytes)?;
        let desc = BufferDesc::device(MemKind::Query, 16, vk::BufferUsageFlags::STORAGE_BUFFER);
        let unbound = Buffer::new(ctx, &tracker, desc, "unbound")?;
        let l = &ctx.limits;
        let alloc = if l.max_allocation > 0 { l.max_allocation } else { u64::MAX };
        let device_max_buffer = alloc.min(l.max_storage_buffer_range);
        let max_buffer = (device_max_buffer.min(max_buffer_bytes.unwrap_or(u64::MAX)) & !63).max(64);
        Ok(Device { cmds, staging, unbound, tracker, max_buffer, device_max_buffer, ctx: ctx.clone() })
    }

    pub fn ctx(&self) -> &Arc<Context> {
        &self.ctx
    }

    /// Arrays larger than this many bytes are split.
    pub fn max_buffer(&self) -> u64 {
        self.max_buffer
    }

    /// The largest buffer a shader may bind on this device (arrays that are never split
    /// must fit it).
    pub fn device_max_buffer(&self) -> u64 {
        self.device_max_buffer
    }

    /// A small buffer for bindings that a pipeline declares but does not use.
    pub fn unbound(&self) -> &Buffer {
        &self.unbound
    }

    /// A buffer named `name` (the memory report's name), filled with `data` when given.
    pub fn create_buffer(
        &mut self,
        desc: BufferDesc,
        name: impl Into<String>,
        data: Option<&[u8]>,
    ) -> VkResult<Buffer> {
        let mut desc = desc;
        if data.is_some() {
            desc.usage |= vk::BufferUsageFlags::TRANSFER_DST;
        }
        let buf = Buffer::new(&self.ctx, &self.tracker, desc, name)?;
        if let Some(data) = data {
            self.staging.upload(&mut self.cmds, &buf, 0, data)?;
        }
        Ok(buf)
    }

    #[cfg_attr(not(feature = "cuda"), allow(dead_code))]
    /// A buffer named `name` whose memory is shared with another API (CUDA) as `sharing` says
    /// (`external.rs`); an error on a device without the fd extensions.
    pub fn create_shared_buffer(
        &mut self,
        desc: BufferDesc,
        name: impl Into<String>,
        sharing: Sharing,
    ) -> VkResult<Buffer> {
        Buffer::shared(&self.ctx, &self.tracker, desc, name, sharing)
    }

    #[cfg_attr(not(feature = "cuda"), allow(dead_code))]
    /// [`Device::run`] that first waits for `wait` and then signals `signal` (a semaphore and
    /// a timeline value) on the device.
    pub fn run_synced<R>(&mut self, wait: SemOp, signal: SemOp, record: impl FnOnce(&Recording) -> R) -> VkResult<R> {
        self.cmds.run_synced(wait, signal, record)
    }

    /// A device-local buffer holding `data`. Storage buffers are checked against the range a
    /// shader may bind.
    pub fn upload(&mut self, name: &str, kind: MemKind, usage: vk::BufferUsageFlags, data: &[u8]) -> VkResult<Buffer> {
        let limit = self.ctx.limits.max_storage_buffer_range;
        if usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER) && data.len() as u64 > limit {
            let bytes = data.len() as u64;
            return Err(VkError::TooLarge { name: name.into(), bytes, limit, what: "maxStorageBufferRange" });
        }
        self.create_buffer(BufferDesc::device(kind, data.len() as u64, usage), name, Some(data))
    }

    /// `data` (elements of `elem_bytes`) in one device buffer named `name`, or, when it is
    /// larger than one buffer may be, in up to `MAX_CHUNKS` buffers of whole elements.
    pub fn upload_split(
        &mut self,
        name: &str,
        kind: MemKind,
        usage: vk::BufferUsageFlags,
        data: &[u8],
        elem_bytes: usize,
    ) -> VkResult<Split> {
        let max_bytes = self.max_buffer;
        if data.len() as u64 <= max_bytes {
            return Ok(Split::whole(self.upload(name, kind, usage, data)?));
        }
        let per = (max_bytes / elem_bytes as u64).min(u32::MAX as u64) as usize;
        let n_parts = (data.len() / elem_bytes).div_ceil(per.max(1));
        if per == 0 || n_parts > MAX_CHUNKS as usize {
            return Err(VkError::TooLarge {
                name: name.into(),
                bytes: data.len() as u64,
                limit: MAX_CHUNKS as u64 * max_bytes,
                what: "16 buffers of the device's largest buffer (maxMemoryAllocationSize, maxStorageBufferRange)",
            });
        }
        let parts = data
            .chunks(per * elem_bytes)
            .enumerate()
            .map(|(k, piece)| self.upload(&format!("{name} {}/{n_parts}", k + 1), kind, usage, piece))
            .collect::<VkResult<Vec<_>>>()?;
        Ok(Split { parts, per_chunk: per as u32 })
    }

    /// Copies `data` into `dst` from byte `offset`.
    pub fn write(&mut self, dst: &Buffer, offset: u64, data: &[u8]) -> VkResult<()> {
        self.staging.upload(&mut self.cmds, dst, offset, data)
    }

    /// A launch's round trip in one submission: `input` into `dst`, the commands `record`
    /// records, the first bytes of `src` back into the outputs, one after the other (together
    /// at most [`Device::round_trip_bytes`]).
    pub fn round_trip(
        &mut self,
        input: (&[u8], &Buffer),
        output: (&Buffer, &mut [&mut [u8]]),
        record: impl FnOnce(&Recording),
    ) -> VkResult<()> {
        self.staging.round_trip(&mut self.cmds, input, output, record)
    }

    /// The most bytes one round trip moves (in and out together).
    pub fn round_trip_bytes(&self) -> usize {
        self.staging.bytes()
    }

    /// Copies `out.len()` bytes of `src` from byte `offset` into `out`.
    pub fn download(&mut self, src: &Buffer, offset: u64, out: &mut [u8]) -> VkResult<()> {
        self.staging.download(&mut self.cmds, src, offset, out)
    }

    /// Records commands with `record`, submits them and waits for completion. Every
    /// submission starts with a full barrier, so it sees all earlier submissions' writes.
    pub fn run<R>(&mut self, record: impl FnOnce(&Recording) -> R) -> VkResult<R> {
        self.cmds.run(record)
    }

    /// Every live allocation (in allocation order) and the peak of their sum so far.
    pub fn memory(&self) -> (Vec<MemItem>, u64) {
        let t = self.tracker.lock().unwrap_or_else(|e| e.into_inner());
        (t.items(), t.peak())
    }

    /// GPU seconds of each of `runs` runs of `record`, from timestamps around each run (with
    /// barriers), all in one submission. Every query is reset and then written before any is
    /// read, after the fence: waiting on an unwritten query hangs some drivers.
    pub fn time_runs(&mut self, runs: usize, record: impl Fn(&Recording)) -> VkResult<Vec<f64>> {
        let ctx = self.ctx.clone();
        let bits = ctx.limits.timestamp_valid_bits;
        if bits == 0 {
            return Err(VkError::NoTimestamps { device: ctx.info().name.clone() });
        }
        let queries = 2 * runs as u32;
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(queries);
        // SAFETY: plain query-pool creation; destroyed below on every path.
        let pool = unsafe { ctx.device.create_query_pool(&info, None) }.map_err(VkError::vk("vkCreateQueryPool"))?;
        // SAFETY: recording with live objects; the pool outlives the submission (run waits).
        let recorded = self.run(|r| unsafe {
            r.dev.cmd_reset_query_pool(r.cmd, pool, 0, queries);
            for k in 0..runs as u32 {
                r.barrier();
                r.dev.cmd_write_timestamp(r.cmd, vk::PipelineStageFlags::TOP_OF_PIPE, pool, 2 * k);
                record(r);
                r.barrier();
                r.dev.cmd_write_timestamp(r.cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, pool, 2 * k + 1);
            }
        });
        let mut ticks = vec![0u64; 2 * runs];
        let read = recorded.and_then(|()| {
            // SAFETY: all queries were written by the completed submission.
            unsafe { ctx.device.get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64) }
                .map_err(VkError::vk("vkGetQueryPoolResults"))
        });
        // SAFETY: the submission using the pool has completed.
        unsafe { ctx.device.destroy_query_pool(pool, None) };
        read?;
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        let period = ctx.limits.timestamp_period_ns * 1e-9;
        Ok((0..runs).map(|r| ((ticks[2 * r + 1].wrapping_sub(ticks[2 * r])) & mask) as f64 * period).collect())
    }
}
