//! The zero-copy path between CUDA and Vulkan (issue 33; feature `cuda`): a soft-bvh locator
//! whose query points and answers live in Vulkan memory that CUDA imports, so that CUDA
//! tensors are located with no host copy.
//!
//! - Memory: two exportable Vulkan buffers (points, answers; `external.rs`), each a dedicated
//!   allocation exported as an opaque fd and imported by `cuImportExternalMemory` +
//!   `cuExternalMemoryGetMappedBuffer`. The kernel reads the points and writes the answers
//!   in place (ids, or ids with the nodes and weights of OUT_WEIGHTS that `tetloc.torch`
//!   interpolates with): its own pipelines bind the shared buffers (as `stream.rs` does).
//! - Order: one shared timeline semaphore (binary ones where timelines cannot be shared).
//!   On the caller's stream: copy the points in (`cuMemcpyDtoDAsync`), signal; the Vulkan
//!   submission waits for that and signals the next value; the stream waits for it and copies
//!   the ids out. No device-wide synchronize: the host waits only for its own submission.
//! - Reuse: buffers, imports and pipelines are kept between calls and grown when a batch is
//!   larger; an event recorded after each call's last copy makes the next call (on any
//!   stream) wait before it overwrites what the last one still reads.
//! - The CUDA driver is loaded at run time (cudarc's dynamic loading): without it every entry
//!   point answers [`CudaError::NoDriver`]. CUDA and Vulkan must be the same GPU (device
//!   UUIDs), else [`CudaError::DifferentGpu`].
//!
//! Meshes of linear tets stored in f32 in the identity working frame, f32 points: others
//! are refused with [`CudaError::Unsupported`] (the host path serves them, its answers
//! certified on the file's data).

use crate::context::{Context, ContextOptions};
use crate::error::VkError;
use crate::external::{semaphore_kind, SemaphoreKind, SharedSemaphore};
use crate::interface::*;
use crate::locator::{LocatorOptions, VulkanLocator};
use crate::memory::{Buffer, BufferDesc, MemKind, Sharing};
use crate::pipeline::{Binding, Descriptors, Pipeline, Spec};
use crate::Kernel;
use ash::vk;
use cudarc::driver::sys as cu;
use std::os::fd::{AsRawFd, IntoRawFd, OwnedFd};
use std::sync::{Arc, OnceLock};
use tetloc_core::Mesh;

/// A CUDA handle descriptor with its `type_` set and every other field zero. `type_` is a
/// Rust enum with no zero value, so the struct cannot be `mem::zeroed()` (a non-unwinding
/// panic, seen on the H100): zeroed memory with the enum written in place, then read.
macro_rules! with_type {
    ($desc:ty, $type_:expr) => {{
        let type_ = $type_;
        let mut d = std::mem::MaybeUninit::<$desc>::zeroed();
        // SAFETY: the other fields (integers, a union of an fd and pointers, reserved words)
        // are valid as zeros, and `type_` is written with a valid value before `assume_init`.
        unsafe {
            std::ptr::addr_of_mut!((*d.as_mut_ptr()).type_).write(type_);
            d.assume_init()
        }
    }};
}

/// Everything that can go wrong on the zero-copy path.
#[derive(Debug, thiserror::Error)]
pub enum CudaError {
    #[error("CUDA driver not found (libcuda.so.1 could not be loaded): the zero-copy path needs the NVIDIA driver; CPU tensors and the host path work without it")]
    NoDriver,
    #[error("{what} failed: CUDA error {code} ({name})")]
    Call { what: &'static str, code: u32, name: String },
    #[error("CUDA device {cuda} (UUID {cuda_uuid}) is not the Vulkan device {vulkan}: memory is shared only within one GPU; pick the Vulkan device of that GPU, or use the host path")]
    DifferentGpu { cuda: i32, cuda_uuid: String, vulkan: String },
    #[error("{0}")]
    Unsupported(String),
    #[error(transparent)]
    Vulkan(#[from] VkError),
}

impl From<CudaError> for tetloc_core::Error {
    fn from(e: CudaError) -> Self {
        tetloc_core::Error::Backend { backend: "cuda-vulkan".into(), source: Box::new(e) }
    }
}

pub type CudaResult<T> = Result<T, CudaError>;

/// The error of a failed call.
fn check(what: &'static str, r: cu::CUresult) -> CudaResult<()> {
    if r == cu::CUresult::CUDA_SUCCESS {
        return Ok(());
    }
    let mut text: *const std::ffi::c_char = std::ptr::null();
    // SAFETY: the driver is loaded (we only call after `load`); it writes a static string.
    let name = unsafe {
        match cu::cuGetErrorName(r, &mut text) {
            cu::CUresult::CUDA_SUCCESS if !text.is_null() => {
                std::ffi::CStr::from_ptr(text).to_string_lossy().into_owned()
            }
            _ => format!("{r:?}"),
        }
    };
    Err(CudaError::Call { what, code: r as u32, name })
}

/// Loads the driver and initialises it, once a process.
fn load() -> CudaResult<()> {
    static LOADED: OnceLock<Result<(), String>> = OnceLock::new();
    let r = LOADED.get_or_init(|| {
        // SAFETY: only tries to dlopen libcuda (cudarc would panic on a missing library later;
        // this check comes first).
        if !unsafe { cu::is_culib_present() } {
            return Err(String::new());
        }
        // SAFETY: cuInit has no preconditions.
        check("cuInit", unsafe { cu::cuInit(0) }).map_err(|e| e.to_string())
    });
    match r {
        Ok(()) => Ok(()),
        Err(e) if e.is_empty() => Err(CudaError::NoDriver),
        Err(e) => Err(CudaError::Unsupported(e.clone())),
    }
}

/// Whether the CUDA driver can be loaded here.
pub fn driver_available() -> bool {
    load().is_ok()
}

fn uuid_text(u: &[u8; 16]) -> String {
    u.iter().map(|b| format!("{b:02x}")).collect()
}

/// The UUID of CUDA device `ordinal` (what Vulkan's deviceUUID is on the same GPU).
pub fn cuda_uuid(ordinal: i32) -> CudaResult<[u8; 16]> {
    load()?;
    let mut dev: cu::CUdevice = 0;
    // SAFETY: the driver is initialised; out-pointers are live locals.
    unsafe { check("cuDeviceGet", cu::cuDeviceGet(&mut dev, ordinal))? };
    // SAFETY: as above; a CUuuid is 16 plain bytes.
    let mut uuid: cu::CUuuid = unsafe { std::mem::zeroed() };
    // SAFETY: as above.
    unsafe { check("cuDeviceGetUuid", cu::cuDeviceGetUuid_v2(&mut uuid, dev))? };
    Ok(uuid.bytes.map(|b| b as u8))
}

/// The primary context of a CUDA device (the one PyTorch uses), retained while alive.
struct Primary {
    dev: cu::CUdevice,
    ctx: cu::CUcontext,
}

impl Primary {
    fn retain(ordinal: i32) -> CudaResult<Primary> {
        let mut dev: cu::CUdevice = 0;
        let mut ctx: cu::CUcontext = std::ptr::null_mut();
        // SAFETY: the driver is initialised; out-pointers are live locals.
        unsafe {
            check("cuDeviceGet", cu::cuDeviceGet(&mut dev, ordinal))?;
            check("cuDevicePrimaryCtxRetain", cu::cuDevicePrimaryCtxRetain(&mut ctx, dev))?;
        }
        Ok(Primary { dev, ctx })
    }

    /// Makes the context current on this thread until the guard drops.
    fn bind(&self) -> CudaResult<Bound> {
        // SAFETY: a retained, live context.
        unsafe { check("cuCtxPushCurrent", cu::cuCtxPushCurrent_v2(self.ctx))? };
        Ok(Bound)
    }
}

impl Drop for Primary {
    fn drop(&mut self) {
        // SAFETY: retained in `retain`; released once.
        unsafe { cu::cuDevicePrimaryCtxRelease_v2(self.dev) };
    }
}

/// A context pushed by [`Primary::bind`], popped on drop.
struct Bound;

impl Drop for Bound {
    fn drop(&mut self) {
        let mut old: cu::CUcontext = std::ptr::null_mut();
        // SAFETY: pops the context this guard pushed.
        unsafe { cu::cuCtxPopCurrent_v2(&mut old) };
    }
}

/// A Vulkan buffer's memory imported into CUDA: `ptr` is its CUDA device address. Dropped
/// only with the context bound and after CUDA's last use of it (`CudaLocator::ensure_io`),
/// before the Vulkan buffer.
struct Import {
    ptr: cu::CUdeviceptr,
    ext: cu::CUexternalMemory,
}

impl Import {
    fn new(vk: &Buffer) -> CudaResult<Import> {
        let fd: OwnedFd = vk.export_fd()?;
        let mut desc = with_type!(
            cu::CUDA_EXTERNAL_MEMORY_HANDLE_DESC,
            cu::CUexternalMemoryHandleType::CU_EXTERNAL_MEMORY_HANDLE_TYPE_OPAQUE_FD
        );
        desc.handle.fd = fd.as_raw_fd();
        desc.size = vk.alloc_size;
        desc.flags = cu::CUDA_EXTERNAL_MEMORY_DEDICATED; // Vulkan allocated it dedicated
        let mut ext: cu::CUexternalMemory = std::ptr::null_mut();
        // SAFETY: a valid descriptor of a live exported allocation; the caller bound the context.
        unsafe { check("cuImportExternalMemory", cu::cuImportExternalMemory(&mut ext, &desc))? };
        let _ = fd.into_raw_fd(); // imported: the fd is CUDA's now
                                  // SAFETY: as above: all zeros is valid.
        let mut buf: cu::CUDA_EXTERNAL_MEMORY_BUFFER_DESC = unsafe { std::mem::zeroed() };
        buf.size = vk.size;
        let mut ptr: cu::CUdeviceptr = 0;
        // SAFETY: the range lies within the imported allocation.
        let mapped = unsafe {
            check("cuExternalMemoryGetMappedBuffer", cu::cuExternalMemoryGetMappedBuffer(&mut ptr, ext, &buf))
        };
        if let Err(e) = mapped {
            // SAFETY: imported above, not mapped.
            unsafe { cu::cuDestroyExternalMemory(ext) };
            return Err(e);
        }
        Ok(Import { ptr, ext })
    }
}

impl Drop for Import {
    fn drop(&mut self) {
        // SAFETY: the mapping and import made in `new`, no longer used (see the type's doc).
        unsafe {
            cu::cuMemFree_v2(self.ptr);
            cu::cuDestroyExternalMemory(self.ext);
        }
    }
}

/// A Vulkan semaphore that CUDA imported.
struct SharedSem {
    cu: cu::CUexternalSemaphore,
    vk: SharedSemaphore,
}

impl SharedSem {
    fn new(ctx: &Arc<Context>, kind: SemaphoreKind) -> CudaResult<SharedSem> {
        let vk = SharedSemaphore::new(ctx, kind)?;
        let fd = vk.export_fd()?;
        let mut desc = with_type!(
            cu::CUDA_EXTERNAL_SEMAPHORE_HANDLE_DESC,
            match kind {
                SemaphoreKind::Timeline => {
                    cu::CUexternalSemaphoreHandleType::CU_EXTERNAL_SEMAPHORE_HANDLE_TYPE_TIMELINE_SEMAPHORE_FD
                }
                SemaphoreKind::Binary => cu::CUexternalSemaphoreHandleType::CU_EXTERNAL_SEMAPHORE_HANDLE_TYPE_OPAQUE_FD,
            }
        );
        desc.handle.fd = fd.as_raw_fd();
        let mut sem: cu::CUexternalSemaphore = std::ptr::null_mut();
        // SAFETY: a valid descriptor of a live exported semaphore; the caller bound the context.
        unsafe { check("cuImportExternalSemaphore", cu::cuImportExternalSemaphore(&mut sem, &desc))? };
        let _ = fd.into_raw_fd(); // imported: the fd is CUDA's now
        Ok(SharedSem { cu: sem, vk })
    }

    /// Signals `value` (timeline) on `stream`.
    fn signal(&self, value: u64, stream: cu::CUstream) -> CudaResult<()> {
        // SAFETY: all zeros is valid; the value is the timeline's (ignored for binary).
        let mut p: cu::CUDA_EXTERNAL_SEMAPHORE_SIGNAL_PARAMS = unsafe { std::mem::zeroed() };
        p.params.fence.value = value;
        // SAFETY: a live imported semaphore, the caller's stream, the context bound.
        unsafe {
            check("cuSignalExternalSemaphoresAsync", cu::cuSignalExternalSemaphoresAsync(&self.cu, &p, 1, stream))
        }
    }

    /// Makes `stream` wait for `value` (timeline).
    fn wait(&self, value: u64, stream: cu::CUstream) -> CudaResult<()> {
        // SAFETY: as in `signal`.
        let mut p: cu::CUDA_EXTERNAL_SEMAPHORE_WAIT_PARAMS = unsafe { std::mem::zeroed() };
        p.params.fence.value = value;
        // SAFETY: as in `signal`.
        unsafe { check("cuWaitExternalSemaphoresAsync", cu::cuWaitExternalSemaphoresAsync(&self.cu, &p, 1, stream)) }
    }
}

impl Drop for SharedSem {
    fn drop(&mut self) {
        // SAFETY: imported in `new`; no pending stream work uses it (`CudaLocator::drop`).
        unsafe { cu::cuDestroyExternalSemaphore(self.cu) };
    }
}

/// How the two APIs hand over: a timeline (values counting up), or a binary pair.
enum Handover {
    Timeline { sem: SharedSem, value: u64 },
    Binary { to_vulkan: SharedSem, to_cuda: SharedSem },
}

/// CUDA's imports of an [`Io`]'s buffers.
struct Imports {
    points: Import,
    out: Import,
}

/// What a call writes a point: its id, or its id with its nodes and weights (OUT_WEIGHTS).
/// Ordered by what the output buffer must hold.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Answer {
    Ids,
    Weights,
}

impl Answer {
    /// 32-bit words a point takes in the output buffer.
    fn words(self) -> usize {
        match self {
            Answer::Ids => 1,
            Answer::Weights => WEIGHTS_WORDS as usize,
        }
    }
}

/// A kernel's pipeline over the shared buffers, with its exact second pass when deferring.
struct Launch {
    pipeline: Pipeline,
    exact: Option<Pipeline>,
}

/// The shared buffers of batches of up to `capacity` points and the pipelines that read and
/// write them in place.
struct Io {
    // Field order is drop order: the pipelines and descriptors before the buffers.
    ids: Launch,
    /// With `answer` Weights only (its buffer holds the nodes and weights).
    weights: Option<Launch>,
    desc: Descriptors,
    deferred: Option<Buffer>,
    points: Buffer,
    /// The ids, then (Weights) the nodes and the weights: `answer.words()` words a point.
    out: Buffer,
    answer: Answer,
    capacity: usize,
}

impl Io {
    /// Buffers for `capacity` points and `answer`s (exportable when `sharing`) and the
    /// pipelines of `loc`'s kernel bound to them.
    fn new(loc: &mut VulkanLocator, capacity: usize, answer: Answer, sharing: bool) -> CudaResult<Io> {
        let dev = loc.device();
        let mut shared = |bytes: u64, name: &str| {
            let desc = BufferDesc::io(MemKind::Query, bytes);
            match sharing {
                true => dev.create_shared_buffer(desc, name, Sharing::Export),
                false => dev.create_buffer(desc, name, None),
            }
        };
        let points = shared(12 * capacity as u64, "cuda points")?;
        let out = shared(4 * (answer.words() * capacity) as u64, "cuda answers")?;
        let weights_spec = (answer == Answer::Weights).then(|| loc.resources_for(OUT_WEIGHTS, false).spec);
        let res = loc.resources_for(OUT_IDS, false);
        let (dev, plan) = (res.dev, res.plan);
        if plan.locate.ray_tracing() {
            return Err(CudaError::Unsupported("the zero-copy path runs the soft-bvh compute kernel".into()));
        }
        let deferred = match plan.exact_pass {
            Some(_) => {
                let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::INDIRECT_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_DST;
                let desc = BufferDesc::device(MemKind::Query, 16 + 4 * capacity as u64, usage);
                Some(dev.create_buffer(desc, "cuda deferred samples", None)?)
            }
            None => None,
        };
        let unbound = dev.unbound();
        let mut bindings = res.bindings;
        bindings.extend([
            Binding::buffer(B_QUERIES, &points),
            Binding::buffer(B_OUT, &out),
            Binding::buffer(B_DEFER, deferred.as_ref().unwrap_or(unbound)),
            Binding::buffer(B_ORDER_POINTS, unbound),
            Binding::buffer(B_ORDER_PERM, unbound),
            Binding::buffer(B_GRID_AXES, unbound),
        ]);
        let ctx = dev.ctx().clone();
        let desc = Descriptors::new(&ctx, &bindings, plan.locate.stages())?;
        let mut launch = |spec: Spec| -> CudaResult<Launch> {
            let spec = spec.set(sc::SAMPLE_MODE, SAMPLE_HOST as u32).set(sc::RECORD_POINTS, 0).set(sc::ORDERED, 0);
            let pipeline = plan.locate.pipeline(dev, desc.layout, res.f64, &spec.clone().concat(&plan.locate_spec))?;
            let exact = match &plan.exact_pass {
                Some(e) => Some(plan.locate.pipeline(dev, desc.layout, res.f64, &spec.concat(e))?),
                None => None,
            };
            Ok(Launch { pipeline, exact })
        };
        let ids = launch(res.spec)?;
        let weights = weights_spec.map(&mut launch).transpose()?;
        Ok(Io { ids, weights, desc, deferred, points, out, answer, capacity })
    }

    /// Runs the kernel over the first `n` points of the buffer into the output buffer (as
    /// `answer` asks; this Io must hold it), in one submission that waits for `wait` and
    /// signals `signal`.
    fn run(
        &self,
        loc: &mut VulkanLocator,
        n: usize,
        answer: Answer,
        wait: Option<(&SharedSemaphore, u64)>,
        signal: Option<(&SharedSemaphore, u64)>,
    ) -> CudaResult<()> {
        let launch = match answer {
            Answer::Ids => &self.ids,
            Answer::Weights => self.weights.as_ref().expect("an Io made for weights"),
        };
        let mut params = loc.resources_for(OUT_IDS, false).params;
        params.counts[0] = n as u32;
        let workgroup = LocatorOptions::default().soft_bvh.workgroup_size;
        let exact = launch.exact.as_ref().zip(self.deferred.as_ref());
        loc.device()
            .run_synced(wait, signal, |r| record_launch(r, &self.desc, &launch.pipeline, exact, &params, workgroup))?;
        Ok(())
    }
}

/// Where [`CudaLocator::weights`] writes: CUDA addresses of n ids (i32), and of 4 n nodes
/// (i32) and 4 n weights (f32).
#[derive(Clone, Copy, Debug)]
pub struct WeightsOut {
    pub ids: u64,
    pub nodes: u64,
    pub weights: u64,
}

/// See the module's documentation.
pub struct CudaLocator {
    // Field order is drop order: CUDA's imports before the Vulkan objects, the context last.
    imports: Option<Imports>,
    io: Option<Io>,
    /// Always `Some` but in `drop`, which destroys it with the context bound.
    handover: Option<Handover>,
    /// Recorded on the last call's stream after its last copy (null before the first call).
    last: cu::CUevent,
    loc: VulkanLocator,
    cuda_device: i32,
    primary: Primary,
}

// SAFETY: the CUDA handles are plain ids used with the context pushed on the calling thread;
// the locator is used through &mut self only.
unsafe impl Send for CudaLocator {}

impl CudaLocator {
    /// A soft-bvh locator of `mesh` on the Vulkan device of CUDA device `cuda_device` (found
    /// by UUID, or `vulkan_device` when given, which must be that GPU).
    pub fn new(mesh: Arc<Mesh>, cuda_device: i32, vulkan_device: Option<usize>, validation: bool) -> CudaResult<Self> {
        load()?;
        let uuid = cuda_uuid(cuda_device)?;
        // The kernel's answers are final only where it decides on the file's data: a mesh
        // stored in f64 or shifted needs the host's certification (`VulkanLocator::query`).
        if mesh.cells.is_some() || mesh.tet_nodes.is_some() || mesh.wants_f64_points() {
            return Err(CudaError::Unsupported(
                "the zero-copy path takes meshes of linear tets stored in f32 in their own frame; this mesh goes through the host, which checks the answers on the file's data"
                    .into(),
            ));
        }
        let devices = crate::context::devices()?;
        let index = match vulkan_device {
            Some(i) => i,
            None => {
                devices.iter().find(|d| d.uuid == uuid).map(|d| d.index).ok_or_else(|| CudaError::DifferentGpu {
                    cuda: cuda_device,
                    cuda_uuid: uuid_text(&uuid),
                    vulkan: "(none of this machine's Vulkan devices has that UUID)".into(),
                })?
            }
        };
        let ctx =
            Context::with_options(ContextOptions { device_index: Some(index), validation, ..Default::default() })?;
        check_same_gpu(cuda_device, &uuid, &ctx)?;
        let primary = Primary::retain(cuda_device)?;
        let _bound = primary.bind()?;
        let kind = semaphore_kind(&ctx)?;
        let handover = match kind {
            SemaphoreKind::Timeline => Handover::Timeline { sem: SharedSem::new(&ctx, kind)?, value: 0 },
            SemaphoreKind::Binary => {
                Handover::Binary { to_vulkan: SharedSem::new(&ctx, kind)?, to_cuda: SharedSem::new(&ctx, kind)? }
            }
        };
        let mut last: cu::CUevent = std::ptr::null_mut();
        // SAFETY: the context is bound; the flag makes an event without timing.
        unsafe {
            let flags = cu::CUevent_flags::CU_EVENT_DISABLE_TIMING as u32;
            check("cuEventCreate", cu::cuEventCreate(&mut last, flags))?;
        }
        let loc = VulkanLocator::new(ctx, mesh, Kernel::SoftBvh, LocatorOptions::default())?;
        Ok(CudaLocator { imports: None, io: None, handover: Some(handover), last, loc, cuda_device, primary })
    }

    /// The Vulkan locator (its context, memory report).
    pub fn vulkan(&self) -> &VulkanLocator {
        &self.loc
    }

    /// The CUDA device this locator serves.
    pub fn cuda_device(&self) -> i32 {
        self.cuda_device
    }

    /// How the two APIs hand over work ("timeline" or "binary").
    pub fn semaphores(&self) -> &'static str {
        match self.handover {
            Some(Handover::Binary { .. }) => "binary",
            _ => "timeline",
        }
    }

    /// Points a batch may hold before the shared buffers grow.
    pub fn capacity(&self) -> usize {
        self.io.as_ref().map_or(0, |io| io.capacity)
    }

    /// Locates `n` f32 points (x, y, z interleaved) at CUDA address `points` into `n` i32 ids
    /// (-1 outside) at CUDA address `ids`, in order on CUDA stream `stream` (0: the legacy
    /// default stream). Returns once the kernel has run; the ids' copy is queued on `stream`.
    ///
    /// # Safety
    /// `points` and `ids` must be device memory of the CUDA device this locator serves, of
    /// `12 n` and `4 n` bytes, alive until the stream has passed this call's work; `stream` a
    /// live stream of that device (or 0).
    pub unsafe fn locate(&mut self, points: u64, n: usize, ids: u64, stream: u64) -> CudaResult<()> {
        // SAFETY: the caller's promises, as this function's.
        unsafe { self.run(points, n, Answer::Ids, &[(ids, 0, 4)], stream) }
    }

    /// Locates as [`locate`](Self::locate) into `out.ids` and also writes how each point's
    /// values are interpolated in its tet: the tet's four vertex ids (`out.nodes`, 0 outside)
    /// and their weights (`out.weights`, f32 barycentrics, the kernel's value path's; 0
    /// outside), four a point. A value is Σ weights[4i + j] · field[nodes[4i + j]].
    ///
    /// # Safety
    /// As [`locate`](Self::locate), and `out.nodes` and `out.weights` device memory of `16 n`
    /// bytes each.
    pub unsafe fn weights(&mut self, points: u64, n: usize, out: WeightsOut, stream: u64) -> CudaResult<()> {
        let word = |at: u32| 4 * at as usize * n;
        let copies = [(out.ids, 0, 4), (out.nodes, word(WEIGHTS_NODES_AT), 16), (out.weights, word(WEIGHTS_AT), 16)];
        // SAFETY: the caller's promises, as this function's.
        unsafe { self.run(points, n, Answer::Weights, &copies, stream) }
    }

    /// One call: the points in, the kernel writing `answer`, and each `(to, at, bytes)` of
    /// `copies` out: `bytes · n` bytes from byte `at` of the output buffer to CUDA address `to`.
    ///
    /// # Safety
    /// As [`locate`](Self::locate), for every address of `copies`.
    unsafe fn run(
        &mut self,
        points: u64,
        n: usize,
        answer: Answer,
        copies: &[(u64, usize, usize)],
        stream: u64,
    ) -> CudaResult<()> {
        if n == 0 {
            return Ok(());
        }
        let _bound = self.primary.bind()?;
        let stream = stream as cu::CUstream;
        self.ensure_io(n, answer)?;
        let (Some(io), Some(imports)) = (self.io.as_ref(), self.imports.as_ref()) else {
            unreachable!("ensure_io made them")
        };
        // SAFETY: the context is bound; the caller vouches for the pointers and the stream; the
        // shared buffers hold `capacity >= n` points. The previous call's copy out (maybe on
        // another stream) finishes before this call's work on `stream` begins.
        unsafe {
            if !self.last.is_null() {
                check("cuStreamWaitEvent", cu::cuStreamWaitEvent(stream, self.last, 0))?;
            }
            check("cuMemcpyDtoDAsync", cu::cuMemcpyDtoDAsync_v2(imports.points.ptr, points, 12 * n, stream))?;
        }
        let (go, done) = match self.handover.as_mut().expect("alive until drop") {
            Handover::Timeline { sem, value } => {
                *value += 2;
                sem.signal(*value - 1, stream)?;
                ((&sem.vk, *value - 1), (&*sem, *value))
            }
            Handover::Binary { to_vulkan, to_cuda } => {
                to_vulkan.signal(0, stream)?;
                ((&to_vulkan.vk, 0), (&*to_cuda, 0))
            }
        };
        io.run(&mut self.loc, n, answer, Some(go), Some((&done.0.vk, done.1)))?;
        done.0.wait(done.1, stream)?;
        // SAFETY: as above: the output buffer holds n answers once the stream has waited, in
        // the layout of OUT_IDS / OUT_WEIGHTS that `copies` follows.
        unsafe {
            for &(to, at, bytes) in copies {
                let from = imports.out.ptr + at as u64;
                check("cuMemcpyDtoDAsync", cu::cuMemcpyDtoDAsync_v2(to, from, bytes * n, stream))?;
            }
            check("cuEventRecord", cu::cuEventRecord(self.last, stream))?;
        }
        Ok(())
    }

    /// Makes the shared buffers hold `n` points and `answer`s (growing them, after the last
    /// call's stream work is done with the old ones) and the pipelines that read them. Once a
    /// call asks for weights, the buffers keep room for them.
    fn ensure_io(&mut self, n: usize, answer: Answer) -> CudaResult<()> {
        let have = self.io.as_ref().map(|io| (io.capacity, io.answer));
        if have.is_some_and(|(c, a)| c >= n && a >= answer) {
            return Ok(());
        }
        let (n, answer) = have.map_or((n, answer), |(c, a)| (n.max(c), answer.max(a)));
        // SAFETY: the context is bound (by the caller); waits for the last call's copies only.
        unsafe { check("cuEventSynchronize", cu::cuEventSynchronize(self.last))? };
        self.imports = None;
        self.io = None;
        let io = Io::new(&mut self.loc, n.max(1 << 16), answer, true)?;
        self.imports = Some(Imports { points: Import::new(&io.points)?, out: Import::new(&io.out)? });
        self.io = Some(io);
        Ok(())
    }
}

/// Records one launch over the shared points: the kernel, and with deferred exact tests the
/// exact second pass over the samples the first deferred (as `locator/launch.rs` does).
fn record_launch(
    r: &crate::device::Recording,
    desc: &Descriptors,
    pipeline: &Pipeline,
    exact: Option<(&Pipeline, &Buffer)>,
    params: &Params,
    workgroup: u32,
) {
    let bind = |p: &Pipeline| {
        // SAFETY: recording into a command buffer in the recording state, with live objects;
        // the push constants are the layout's range.
        unsafe {
            r.dev.cmd_bind_pipeline(r.cmd, p.bind_point, p.pipeline);
            r.dev.cmd_bind_descriptor_sets(r.cmd, p.bind_point, desc.layout, 0, &[desc.set], &[]);
            r.dev.cmd_push_constants(r.cmd, desc.layout, desc.stages, 0, bytemuck::bytes_of(params));
        }
    };
    if let Some((_, list)) = exact {
        // Empty the deferred-sample list: dispatch size (0, 1, 1), count 0.
        // SAFETY: as above; 16 bytes, far below vkCmdUpdateBuffer's limit.
        unsafe { r.dev.cmd_update_buffer(r.cmd, list.buffer, 0, bytemuck::cast_slice(&[0u32, 1, 1, 0])) };
        r.barrier();
    }
    bind(pipeline);
    let groups = (params.counts[0] as u64).div_ceil(workgroup as u64);
    let x = groups.min(r.ctx.limits.max_workgroup_count[0] as u64).max(1);
    // SAFETY: a compute pipeline is bound; the shader linearises the 2D grid of workgroups.
    unsafe { r.dev.cmd_dispatch(r.cmd, x as u32, groups.div_ceil(x) as u32, 1) };
    if let Some((p, list)) = exact {
        r.barrier();
        bind(p);
        // SAFETY: as above; the list starts with the dispatch size the first pass counted.
        unsafe { r.dev.cmd_dispatch_indirect(r.cmd, list.buffer, 0) };
    }
    r.barrier();
}

/// Checks that CUDA device `cuda` (UUID `uuid`) is the GPU of the Vulkan context.
fn check_same_gpu(cuda: i32, uuid: &[u8; 16], ctx: &Context) -> CudaResult<()> {
    if &ctx.uuid == uuid {
        return Ok(());
    }
    Err(CudaError::DifferentGpu {
        cuda,
        cuda_uuid: uuid_text(uuid),
        vulkan: format!("{} '{}' (UUID {})", ctx.info().index, ctx.info().name, uuid_text(&ctx.uuid)),
    })
}

impl Drop for CudaLocator {
    fn drop(&mut self) {
        if let Ok(_bound) = self.primary.bind() {
            // SAFETY: waits for the last call's stream work (not the device), then frees the
            // imports (context bound) before the Vulkan objects go.
            unsafe {
                if !self.last.is_null() {
                    cu::cuEventSynchronize(self.last);
                    cu::cuEventDestroy_v2(self.last);
                }
            }
            self.imports = None;
            self.io = None;
            self.handover = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// This machine has no NVIDIA driver in CI: the path says so clearly, never panics.
    #[test]
    fn without_the_driver_the_error_is_clear() {
        // SAFETY: only tries to dlopen libcuda.
        if unsafe { cu::is_culib_present() } {
            tetloc_testdata::skip("without_the_driver_the_error_is_clear", "a CUDA driver is installed here");
            return;
        }
        assert!(!driver_available());
        let e = cuda_uuid(0).unwrap_err();
        assert!(matches!(e, CudaError::NoDriver));
        assert!(e.to_string().starts_with("CUDA driver not found"), "{e}");
        let mesh =
            Arc::new(Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, 1000, 1), "jets").unwrap());
        let e = CudaLocator::new(mesh, 0, None, true).err().expect("refused");
        assert!(e.to_string().starts_with("CUDA driver not found"), "{e}");
    }

    /// The kernel reading and writing the shared buffers in place answers what the locator's
    /// own path answers (exportable buffers where lavapipe has them, plain ones otherwise).
    #[test]
    fn in_place_launch_matches_the_locator() {
        let test = "in_place_launch_matches_the_locator";
        let Some(ctx) = crate::context::test_context(test) else { return };
        let sharing = crate::external::memory_fd(&ctx).is_ok();
        eprintln!("{test}: exportable buffers: {sharing}");
        let raw = tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, 5000, 2);
        let mesh = Arc::new(Mesh::new(raw, "jets").unwrap());
        let mut loc =
            VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, LocatorOptions::default()).unwrap();
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let n = 3000;
        let pts: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                // 10% beyond the box on each side: points inside and outside.
                let t = |k: usize, a: f32, b: f32| {
                    a + (b - a) * (1.2 * ((i * (7 + 6 * k) + 3 * k) % 101) as f32 / 100.0 - 0.1)
                };
                [t(0, lo[0], hi[0]), t(1, lo[1], hi[1]), t(2, lo[2], hi[2])]
            })
            .collect();
        let mut want = vec![0; n];
        let mut values = vec![0f32; n];
        tetloc_core::BatchLocator::locate_and_sample(&mut loc, &pts, "f", &mut want, &mut values).unwrap();
        let io = Io::new(&mut loc, 4096, Answer::Weights, sharing).unwrap();
        loc.device().write(&io.points, 0, bytemuck::cast_slice(&pts)).unwrap();
        io.run(&mut loc, n, Answer::Ids, None, None).unwrap();
        let mut got = vec![0u32; WEIGHTS_WORDS as usize * n];
        loc.device().download(&io.out, 0, bytemuck::cast_slice_mut(&mut got[..n])).unwrap();
        assert_eq!(bytemuck::cast_slice::<u32, i32>(&got[..n]), want);
        assert!(want.iter().any(|&i| i >= 0) && want.iter().any(|&i| i < 0), "inside and outside both tested");

        // Weights: the same ids; a point's nodes are its tet's vertices, its weights the
        // barycentrics that give back the point and the locator's own value.
        got.fill(u32::MAX);
        io.run(&mut loc, n, Answer::Weights, None, None).unwrap();
        loc.device().download(&io.out, 0, bytemuck::cast_slice_mut(&mut got)).unwrap();
        assert_eq!(bytemuck::cast_slice::<u32, i32>(&got[..n]), want);
        let f = &mesh.field("f").unwrap().values;
        for (i, p) in pts.iter().enumerate() {
            let (nodes_at, weights_at) = (WEIGHTS_NODES_AT as usize * n + 4 * i, WEIGHTS_AT as usize * n + 4 * i);
            let nodes = &got[nodes_at..nodes_at + 4];
            let w: Vec<f32> = got[weights_at..weights_at + 4].iter().map(|&b| f32::from_bits(b)).collect();
            if want[i] < 0 {
                assert!(nodes.iter().all(|&v| v == 0) && w.iter().all(|&v| v == 0.0), "outside: zeros");
                continue;
            }
            assert_eq!(nodes, mesh.tets[want[i] as usize], "point {i}: the nodes are its tet's vertices");
            assert!(w.iter().all(|&v| v >= -1e-6) && (w.iter().sum::<f32>() - 1.0).abs() < 1e-5, "{w:?}");
            let x: Vec<f64> =
                (0..3).map(|k| (0..4).map(|j| w[j] as f64 * mesh.points[nodes[j] as usize][k] as f64).sum()).collect();
            let size = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max) as f64;
            assert!((0..3).all(|k| (x[k] - p[k] as f64).abs() < 1e-5 * size), "point {i}: {x:?} vs {p:?}");
            let v: f32 = (0..4).map(|j| w[j] * f[nodes[j] as usize]).sum();
            assert!((v - values[i]).abs() <= 1e-5 * values[i].abs().max(1.0), "point {i}: {v} vs {}", values[i]);
        }
        drop(io);
        assert_eq!(ctx.validation_errors(), 0);
    }

    #[test]
    fn a_different_gpu_is_refused_by_uuid() {
        let Some(ctx) = crate::context::test_context("a_different_gpu_is_refused_by_uuid") else { return };
        let mut other = ctx.uuid;
        other[0] ^= 0xff;
        let e = check_same_gpu(1, &other, &ctx).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("is not the Vulkan device") && text.contains(&uuid_text(&ctx.uuid)), "{text}");
        check_same_gpu(0, &ctx.uuid.clone(), &ctx).unwrap();
    }
}
