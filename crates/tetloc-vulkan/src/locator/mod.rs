//! `VulkanLocator`: a mesh on the GPU, one kernel's search structure, and the batch API.

use crate::context::Context;
use crate::error::{VkError, VkResult};
use crate::gpu_types::*;
use crate::memory::{
    self, full_barrier, Buffer, Chunked, Commands, Location, MemItem, MemKind, SharedTracker, Staging, Tracker,
};
use crate::pipeline::{self, Descriptors, Pipeline, RtShaders, Spec};
use crate::rt::{self, AsReport, Geometry, RtStructure};
use crate::shaders;
use crate::soft_bvh;
use ash::vk;
use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tetloc_core::bvh::{BuildPreset, Bvh};
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::{FieldLocation, Mesh};
use tetloc_core::BatchLocator;

/// The four point-location kernels of the paper.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// BVH traversal and point-in-tet in a compute shader (the paper's cuda-bvh).
    SoftBvh,
    /// Ray-tracing BVH over one box per tet, point-in-tet in an intersection shader.
    RtBvh,
    /// Four inward-facing triangles per tet, closest hit with back faces culled.
    RtRepFaces,
    /// Each unique face once with its two tets, closest hit picks the side.
    RtSharedFaces,
}

impl Kernel {
    pub const ALL: [Kernel; 4] = [Kernel::SoftBvh, Kernel::RtBvh, Kernel::RtRepFaces, Kernel::RtSharedFaces];

    pub fn name(self) -> &'static str {
        match self {
            Kernel::SoftBvh => "soft-bvh",
            Kernel::RtBvh => "rt-bvh",
            Kernel::RtRepFaces => "rt-rep-faces",
            Kernel::RtSharedFaces => "rt-shared-faces",
        }
    }

    /// True for the kernels that need ray-tracing pipelines.
    pub fn needs_ray_tracing(self) -> bool {
        self != Kernel::SoftBvh
    }
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Kernel {
    type Err = String;
    fn from_str(s: &str) -> Result<Kernel, String> {
        Kernel::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("unknown kernel '{s}' (known: {})", Kernel::ALL.map(|k| k.name()).join(", ")))
    }
}

/// Options of a [`VulkanLocator`].
#[derive(Clone, Debug)]
pub struct LocatorOptions {
    /// rt kernels: at most this many primitives (boxes or triangles) per bottom-level
    /// acceleration structure, all under one top-level one; `None`: one structure.
    pub split: Option<usize>,
    /// rt kernels: compact each bottom-level structure after its build.
    pub compact: bool,
    /// Points per kernel launch; larger batches run in chunks (bounds the query buffers).
    pub chunk_points: usize,
    /// soft-bvh: tets per BVH leaf: 1 (the paper's layout; the reference holds the tet id) or
    /// 4 (up to four, fewer nodes, an index list). 1 measured faster on the H100 (NOTES.md).
    pub leaf_size: usize,
    /// Use the exact f64 fallback of the point-in-tet test when the device has shaderFloat64;
    /// `false` forces the pure-f32 test.
    pub float64: bool,
    /// soft-bvh: invocations per workgroup.
    pub workgroup_size: u32,
    /// soft-bvh: start each traversal below the root, at the node an entry grid names for the
    /// point's cell (about `GRID_TETS_PER_CELL` tets per cell, 4 B per cell). Unmeasured on
    /// GPUs so far: off by default (NOTES.md).
    pub grid_start: bool,
    /// soft-bvh: walk through face neighbours from a start tet the entry grid names for the
    /// point's cell (the tet holding the cell's centre), traversal from the cell's node as the
    /// exact fallback; +4 B per cell and the neighbours (16 B per tet). Implies the grid. The
    /// default: on the H100 5.1x (uniform) and 2.0x (random) faster than traversal (NOTES.md).
    pub walk_start: bool,
    /// soft-bvh entry grid resolution: about this many tets per cell.
    pub grid_tets_per_cell: usize,
    /// soft-bvh: decide the point-in-tet test in f32 first and enter the full test (with its
    /// f64 fallback) only when f32 cannot; same answers, no f64 state on the hot path.
    pub f32_first: bool,
    /// soft-bvh: decide every test in f32 and defer the samples f32 cannot decide to a second,
    /// exact dispatch (indirect, over a list the first pass appends to); same answers, and the
    /// first pass holds no f64 code. Not yet measured on a GPU: off by default (NOTES.md).
    pub defer_exact: bool,
    /// Size of the staging buffer that all uploads and downloads go through.
    pub staging_bytes: u64,
    /// Split mesh and soft-bvh arrays into several buffers above this size (default: the
    /// device's limits, 4 GiB on the H100). Tests set it tiny to exercise the splitting.
    pub max_buffer_bytes: Option<u64>,
}

impl Default for LocatorOptions {
    fn default() -> Self {
        LocatorOptions {
            split: Some(1 << 20),
            compact: true,
            chunk_points: 1 << 22,
            leaf_size: 1,
            float64: true,
            workgroup_size: 128,
            grid_start: false,
            walk_start: true,
            grid_tets_per_cell: GRID_TETS_PER_CELL,
            f32_first: false,
            defer_exact: false,
            staging_bytes: memory::STAGING_BYTES,
            max_buffer_bytes: None,
        }
    }
}

/// GPU memory of one locator, like the paper's Table 2.
#[derive(Clone, Debug)]
pub struct MemoryReport {
    /// Resident after the build: mesh and search structure (not staging or query buffers).
    pub final_bytes: u64,
    /// Most memory alive at once during the build, build scratch and staging included.
    pub peak_bytes: u64,
    /// Every allocation alive after the build.
    pub items: Vec<MemItem>,
    /// Acceleration-structure sizes (rt kernels).
    pub accel: Option<AsReport>,
}

/// Where the points of a launch come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleMode {
    /// Points uploaded from the host.
    Host,
    /// The centre of every tet, generated in the kernel (paper: "uniform").
    Uniform,
    /// A random point in a random tet, generated in the kernel (paper: "random").
    Random,
    /// Uniform in the mesh's bounding box, generated in the kernel.
    BBox,
}

impl SampleMode {
    pub const ALL: [SampleMode; 4] = [SampleMode::Uniform, SampleMode::Random, SampleMode::BBox, SampleMode::Host];

    pub fn name(self) -> &'static str {
        match self {
            SampleMode::Host => "host",
            SampleMode::Uniform => "uniform",
            SampleMode::Random => "random",
            SampleMode::BBox => "bbox",
        }
    }

    pub(crate) fn code(self) -> i32 {
        match self {
            SampleMode::Host => SAMPLE_HOST,
            SampleMode::Uniform => SAMPLE_UNIFORM,
            SampleMode::Random => SAMPLE_RANDOM,
            SampleMode::BBox => SAMPLE_BBOX,
        }
    }
}

impl FromStr for SampleMode {
    type Err = String;
    fn from_str(s: &str) -> Result<SampleMode, String> {
        SampleMode::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            format!("unknown sample mode '{s}' (known: {})", SampleMode::ALL.map(|m| m.name()).join(", "))
        })
    }
}

/// One compiled variant of a kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Variant {
    pub sample: i32,
    pub output: i32,
    pub record: bool,
}

/// The search structure; its buffers are only held (bound in the descriptor set).
#[allow(clippy::large_enum_variant)]
enum Structure {
    Soft {
        _buffers: Vec<Buffer>,
        stack: u32,
        direct: bool,
        grid: bool,
        walk: bool,
        nodes_chunk: u32,
        neighbors_chunk: u32,
    },
    Rt(RtStructure),
}

/// A locator's GPU resources as another pipeline binds them (see `VulkanLocator::resources`).
pub(crate) struct Resources {
    /// (binding, the buffers of its array elements), every storage-buffer binding.
    pub buffers: Vec<(u32, Vec<vk::DescriptorBufferInfo>)>,
    /// soft-bvh: the neighbour table is among `buffers` (the walk start uses it).
    pub soft_neighbors: bool,
    /// The top-level acceleration structure (rt kernels), bound at `B_ACCEL`.
    pub accel: Option<vk::AccelerationStructureKHR>,
    /// A small buffer for bindings a pipeline declares but does not use.
    pub dummy: vk::DescriptorBufferInfo,
}

/// soft-bvh entry grid resolution: about this many tets per cell (a 1M-tet jets mesh then
/// starts traversal at level 6-7 of 13 on median; walks from a cell's start take 1.7 tests
/// a sample on jets 12M, 2.1 at 2 tets a cell).
pub const GRID_TETS_PER_CELL: usize = 1;

/// Most tets the face kernels visit when the closest hit's tet is off by rounding.
const WALK_MAX: i32 = 16;
/// Most tets a soft-bvh walk start visits before traversal takes over (jets: 1.7-2.6 on
/// average from a cell-centre start, NOTES.md).
const SOFT_WALK_MAX: i32 = 32;

/// A mesh on one Vulkan device with one kernel's search structure.
pub struct VulkanLocator {
    pub(crate) ctx: Arc<Context>,
    pub(crate) mesh: Arc<Mesh>,
    pub(crate) kernel: Kernel,
    pub(crate) opts: LocatorOptions,
    pub(crate) f64: bool,
    pub(crate) tracker: SharedTracker,
    pub(crate) cmds: Commands,
    pub(crate) staging: Staging,
    pub(crate) desc: Descriptors,
    _points: Chunked,
    _tets: Chunked,
    dummy: Buffer,
    field: Option<(String, FieldLocation, Buffer)>,
    /// Query points and results, `io_capacity` points each.
    pub(crate) io: Option<(Buffer, Buffer)>,
    io_capacity: usize,
    structure: Structure,
    pub(crate) pipelines: HashMap<Variant, Pipeline>,
    /// soft-bvh with `defer_exact`: the exact second pass of each variant, and the list of
    /// deferred samples (header: indirect dispatch size, count; then sample indices).
    pub(crate) exact_pipelines: HashMap<Variant, Pipeline>,
    pub(crate) defer: Option<Buffer>,
    build_seconds: f64,
    memory: MemoryReport,
}

impl VulkanLocator {
    /// Uploads the mesh and builds `kernel`'s search structure on `ctx`'s device.
    pub fn new(ctx: Arc<Context>, mesh: Arc<Mesh>, kernel: Kernel, opts: LocatorOptions) -> VkResult<VulkanLocator> {
        let t0 = Instant::now();
        if kernel.needs_ray_tracing() && ctx.rt.is_none() {
            return Err(VkError::NoRayTracing { device: ctx.device_name(), kernel: kernel.name().into() });
        }
        if opts.chunk_points == 0
            || ![1, 4].contains(&opts.leaf_size)
            || opts.workgroup_size == 0
            || opts.grid_tets_per_cell == 0
        {
            return Err(VkError::Mesh(format!(
                "invalid options: chunk_points {} (> 0), leaf_size {} (1 or 4), workgroup_size {} (> 0), grid_tets_per_cell {} (> 0)",
                opts.chunk_points, opts.leaf_size, opts.workgroup_size, opts.grid_tets_per_cell
            )));
        }
        if !ctx.info().nonuniform_buffers {
            return Err(VkError::Mesh(format!(
                "{} lacks shaderStorageBufferArrayNonUniformIndexing, which the kernels use to read arrays split over buffers",
                ctx.device_name()
            )));
        }
        if mesh.n_tets() >= i32::MAX as usize {
            return Err(VkError::Mesh(format!("{} tets: more than 32-bit signed ids can name", mesh.n_tets())));
        }
        let tracker: SharedTracker = Arc::new(Mutex::new(Tracker::default()));
        let mut cmds = Commands::new(&ctx)?;
        let mesh_bytes = (mesh.points.len() * 12).max(mesh.tets.len() * 16) as u64;
        let mut staging = Staging::new(&ctx, &tracker, opts.staging_bytes.min(mesh_bytes.max(1 << 16)))?;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut point_usage = storage;
        if kernel.needs_ray_tracing() {
            point_usage |= vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        }
        let max_bytes = memory::max_buffer_bytes(&ctx, opts.max_buffer_bytes);
        let points = memory::chunked_buffer(
            &ctx,
            &tracker,
            &mut staging,
            &mut cmds,
            "mesh points",
            MemKind::Mesh,
            point_usage,
            bytemuck::cast_slice(&mesh.points),
            12,
            max_bytes,
        )?;
        let tets = memory::chunked_buffer(
            &ctx,
            &tracker,
            &mut staging,
            &mut cmds,
            "mesh tets",
            MemKind::Mesh,
            storage,
            bytemuck::cast_slice(&mesh.tets),
            16,
            max_bytes,
        )?;
        let dummy = Buffer::new(&ctx, &tracker, "unbound", MemKind::Query, 16, storage, Location::Device)?;

        let f64 = opts.float64 && ctx.info().float64;
        const SB: vk::DescriptorType = vk::DescriptorType::STORAGE_BUFFER;
        let hi = MAX_CHUNKS as u32 - 1;
        let mut bindings = vec![
            (B_POINTS, SB, 1),
            (B_TETS, SB, 1),
            (B_FIELD, SB, 1),
            (B_QUERIES, SB, 1),
            (B_OUT, SB, 1),
            (B_PRIMS, SB, 1),
            (B_POINTS_HI, SB, hi),
            (B_TETS_HI, SB, hi),
            (B_NEIGHBORS_HI, SB, hi),
        ];
        let (structure, desc) = match kernel {
            Kernel::SoftBvh => {
                let preset = if opts.leaf_size == 1 { BuildPreset::SingleTetLeaves } else { BuildPreset::Fast };
                let bvh = Bvh::build(&mesh.points, &mesh.tets, preset);
                let q = soft_bvh::collapse(&bvh)?;
                drop(bvh);
                let nodes = memory::chunked_buffer(
                    &ctx,
                    &tracker,
                    &mut staging,
                    &mut cmds,
                    "bvh nodes",
                    MemKind::Structure,
                    storage,
                    bytemuck::cast_slice(&q.nodes),
                    64,
                    max_bytes,
                )?;
                let prims = if q.direct {
                    None
                } else {
                    Some(memory::device_buffer_with(
                        &ctx,
                        &tracker,
                        &mut staging,
                        &mut cmds,
                        "bvh prims",
                        MemKind::Structure,
                        storage,
                        bytemuck::cast_slice(&q.prims),
                    )?)
                };
                let grid = if opts.grid_start || opts.walk_start {
                    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
                    let g = q.entry_grid(&mesh.points, &mesh.tets, lo, hi, opts.grid_tets_per_cell, opts.walk_start);
                    Some(memory::device_buffer_with(
                        &ctx,
                        &tracker,
                        &mut staging,
                        &mut cmds,
                        "entry grid",
                        MemKind::Structure,
                        storage,
                        bytemuck::cast_slice(&g.words()),
                    )?)
                } else {
                    None
                };
                let neighbors = if opts.walk_start {
                    let nb = bytemuck::cast_slice(mesh.neighbors());
                    Some(memory::chunked_buffer(
                        &ctx,
                        &tracker,
                        &mut staging,
                        &mut cmds,
                        "tet neighbours",
                        MemKind::Structure,
                        storage,
                        nb,
                        16,
                        max_bytes,
                    )?)
                } else {
                    None
                };
                bindings.extend([
                    (B_ACCEL, SB, 1),
                    (B_GRID, SB, 1),
                    (B_NEIGHBORS, SB, 1),
                    (B_ACCEL_HI, SB, hi),
                    (B_DEFER, SB, 1),
                ]);
                let desc = Descriptors::new(&ctx, &bindings, vk::ShaderStageFlags::COMPUTE)?;
                desc.write_buffers(&[
                    (B_PRIMS, prims.as_ref().unwrap_or(&dummy)),
                    (B_GRID, grid.as_ref().unwrap_or(&dummy)),
                    (B_DEFER, &dummy),
                ])?;
                bind_chunked(&desc, B_ACCEL, B_ACCEL_HI, Some(&nodes), &dummy)?;
                bind_chunked(&desc, B_NEIGHBORS, B_NEIGHBORS_HI, neighbors.as_ref(), &dummy)?;
                let (stack, direct, has_grid) = (q.stack_size(), q.direct, grid.is_some());
                let (nodes_chunk, neighbors_chunk) = (nodes.per_chunk, neighbors.as_ref().map_or(0, |n| n.per_chunk));
                let mut buffers: Vec<Buffer> = [prims, grid].into_iter().flatten().collect();
                buffers.extend(nodes.parts);
                buffers.extend(neighbors.into_iter().flat_map(|n| n.parts));
                let walk = opts.walk_start;
                (
                    Structure::Soft {
                        _buffers: buffers,
                        stack,
                        direct,
                        grid: has_grid,
                        walk,
                        nodes_chunk,
                        neighbors_chunk,
                    },
                    desc,
                )
            }
            _ => {
                let geometry = match kernel {
                    Kernel::RtBvh => Geometry::Boxes,
                    Kernel::RtRepFaces => Geometry::RepFaces,
                    _ => Geometry::SharedFaces,
                };
                if points.parts.len() > 1 {
                    return Err(VkError::TooLarge {
                        name: "mesh points".into(),
                        bytes: mesh.points.len() as u64 * 12,
                        limit: max_bytes,
                        what: "one buffer: the ray-tracing kernels build from a single vertex buffer",
                    });
                }
                let s = rt::build(
                    &ctx,
                    &tracker,
                    &mut staging,
                    &mut cmds,
                    &mesh,
                    &points.parts[0],
                    geometry,
                    opts.split,
                    opts.compact,
                )?;
                bindings.extend([
                    (B_ACCEL, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR, 1),
                    (B_INSTANCES, SB, 1),
                    (B_NEIGHBORS, SB, 1),
                ]);
                let stages = vk::ShaderStageFlags::RAYGEN_KHR
                    | vk::ShaderStageFlags::MISS_KHR
                    | vk::ShaderStageFlags::CLOSEST_HIT_KHR
                    | vk::ShaderStageFlags::INTERSECTION_KHR;
                let desc = Descriptors::new(&ctx, &bindings, stages)?;
                desc.write_accel(B_ACCEL, s.tlas.handle);
                desc.write_buffers(&[
                    (B_PRIMS, &s.prims),
                    (B_INSTANCES, &s.instance_base),
                    (B_NEIGHBORS, s.neighbors.as_ref().unwrap_or(&dummy)),
                ])?;
                desc.write_buffer_array(B_NEIGHBORS_HI, &[&dummy; MAX_CHUNKS - 1])?;
                (Structure::Rt(s), desc)
            }
        };
        desc.write_buffers(&[(B_FIELD, &dummy), (B_QUERIES, &dummy), (B_OUT, &dummy)])?;
        bind_chunked(&desc, B_POINTS, B_POINTS_HI, Some(&points), &dummy)?;
        bind_chunked(&desc, B_TETS, B_TETS_HI, Some(&tets), &dummy)?;

        let (items, peak) = {
            let t = tracker.lock().unwrap();
            (t.items(), t.peak())
        };
        let final_bytes =
            items.iter().filter(|m| matches!(m.kind, MemKind::Mesh | MemKind::Structure)).map(|m| m.bytes).sum();
        let accel = match &structure {
            Structure::Rt(s) => Some(s.report),
            Structure::Soft { .. } => None,
        };
        let memory = MemoryReport { final_bytes, peak_bytes: peak, items, accel };
        let mut loc = VulkanLocator {
            ctx,
            mesh,
            kernel,
            opts,
            f64,
            tracker,
            cmds,
            staging,
            desc,
            _points: points,
            _tets: tets,
            dummy,
            field: None,
            io: None,
            io_capacity: 0,
            structure,
            pipelines: HashMap::new(),
            exact_pipelines: HashMap::new(),
            defer: None,
            build_seconds: 0.0,
            memory,
        };
        // Compile the id variant now, so that building includes pipeline creation.
        loc.pipeline(Variant { sample: SAMPLE_HOST, output: OUT_IDS, record: false })?;
        loc.build_seconds = t0.elapsed().as_secs_f64();
        Ok(loc)
    }

    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
    }

    /// Seconds spent in `new`: uploads, structure build (and compaction), first pipeline.
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// GPU memory after the build (final) and during it (peak), with every allocation named.
    pub fn memory_report(&self) -> &MemoryReport {
        &self.memory
    }

    /// True when the point-in-tet test runs with the exact f64 fallback (else pure f32).
    pub fn uses_float64(&self) -> bool {
        self.f64
    }

    /// soft-bvh with `defer_exact` on a device with the f64 test.
    fn defers(&self) -> bool {
        self.opts.defer_exact && self.f64 && matches!(self.structure, Structure::Soft { .. })
    }

    /// The pipeline for `v`, created on first use (with its exact second pass when deferring).
    pub(crate) fn pipeline(&mut self, v: Variant) -> VkResult<&Pipeline> {
        if self.defers() && !self.exact_pipelines.contains_key(&v) {
            let p = self.make_pipeline(v, true)?;
            self.exact_pipelines.insert(v, p);
        }
        if !self.pipelines.contains_key(&v) {
            let p = self.make_pipeline(v, false)?;
            self.pipelines.insert(v, p);
        }
        Ok(&self.pipelines[&v])
    }

    /// The pipeline of variant `v`, or its exact second pass (`defer_exact`).
    fn make_pipeline(&mut self, v: Variant, exact_pass: bool) -> VkResult<Pipeline> {
        let defer = self.defers() && !exact_pass;
        let spec = self.spec(v.output).set(SC_SAMPLE_MODE, v.sample as u32).set(SC_RECORD_POINTS, v.record as u32);
        match &self.structure {
            Structure::Soft { .. } => {
                let spec = spec
                    .set(SC_F32_FIRST, (self.opts.f32_first || defer) as u32)
                    .set(SC_DEFER_EXACT, defer as u32)
                    .set(SC_EXACT_PASS, exact_pass as u32)
                    .set(SC_WORKGROUP, self.opts.workgroup_size);
                pipeline::compute_pipeline(&self.ctx, self.desc.layout, shaders::SOFT_BVH.pick(self.f64), &spec)
            }
            Structure::Rt(_) => {
                let sh = self.rt_shaders(shaders::RT_RGEN);
                pipeline::rt_pipeline(
                    &self.ctx,
                    &self.tracker,
                    &mut self.staging,
                    &mut self.cmds,
                    self.desc.layout,
                    &sh,
                    &spec,
                )
            }
        }
    }

    /// The specialization constants of this kernel's shaders for `output` (the volume
    /// marcher's pipelines start from these too): the test's constants, how the arrays are
    /// split over buffers, and the kernel's own.
    pub(crate) fn spec(&self, output: i32) -> Spec {
        let spec = Spec::default()
            .set(SC_OUTPUT_MODE, output as u32)
            .set(SC_ORIENT_ERR_BOUND, tetloc_core::geom::ORIENT_ERR_BOUND_F32.to_bits())
            .set(SC_BARY_F32_TRUST, tetloc_core::geom::BARY_F32_TRUST.to_bits())
            .set(SC_POINTS_CHUNK, self._points.per_chunk)
            .set(SC_TETS_CHUNK, self._tets.per_chunk);
        match &self.structure {
            Structure::Soft { stack, direct, grid, walk, nodes_chunk, neighbors_chunk, .. } => spec
                .set(SC_NODES_CHUNK, *nodes_chunk)
                .set(SC_NEIGHBORS_CHUNK, *neighbors_chunk)
                .set(SC_WALK_MAX, SOFT_WALK_MAX as u32)
                .set(SC_WALK_START, *walk as u32)
                .set(SC_STACK_SIZE, *stack)
                .set(SC_DIRECT_LEAVES, *direct as u32)
                .set(SC_GRID_START, *grid as u32),
            Structure::Rt(_) => {
                const OPAQUE: u32 = 0x1;
                const TERMINATE_ON_FIRST_HIT: u32 = 0x4;
                const CULL_BACK_FACING: u32 = 0x10;
                let (flags, retry) = match self.kernel {
                    Kernel::RtBvh => (OPAQUE | TERMINATE_ON_FIRST_HIT, false),
                    Kernel::RtRepFaces => (OPAQUE | CULL_BACK_FACING, true),
                    _ => (OPAQUE, true),
                };
                spec.set(SC_WALK_MAX, WALK_MAX as u32).set(SC_RAY_FLAGS, flags).set(SC_RETRY_ON_MISS, retry as u32)
            }
        }
    }

    /// This rt kernel's miss and hit shaders behind the ray generation shader `raygen`.
    pub(crate) fn rt_shaders(&self, raygen: &'static [u8]) -> RtShaders<'static> {
        let (chit, rint) = match self.kernel {
            Kernel::RtBvh => (shaders::RT_BVH_RCHIT, Some(shaders::RT_BVH_RINT.pick(self.f64))),
            Kernel::RtRepFaces => (shaders::RT_REP_RCHIT.pick(self.f64), None),
            _ => (shaders::RT_SHARED_RCHIT.pick(self.f64), None),
        };
        RtShaders { raygen, miss: shaders::RT_RMISS, closest_hit: chit, intersection: rint }
    }

    /// What the volume marcher binds of this locator (no second upload): every buffer
    /// binding of the kernel but the query, output and deferral buffers, with the field
    /// `ensure_field` uploaded last.
    pub(crate) fn resources(&self) -> Resources {
        let buffers =
            self.desc.buffer_bindings().into_iter().filter(|(b, _)| ![B_QUERIES, B_OUT, B_DEFER].contains(b)).collect();
        let accel = match &self.structure {
            Structure::Soft { .. } => None,
            Structure::Rt(s) => Some(s.tlas.handle),
        };
        let soft_neighbors = matches!(self.structure, Structure::Soft { walk: true, .. });
        Resources { buffers, accel, soft_neighbors, dummy: self.dummy.info() }
    }

    /// Push constants for a launch of `n` points starting at global sample index `base`.
    pub(crate) fn params(&self, n: usize, base: usize, seed: u32) -> Params {
        let (lo, hi) = (self.mesh.info.bounds_min, self.mesh.info.bounds_max);
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max).max(f32::MIN_POSITIVE);
        let (tmax, dir) = match self.kernel {
            // An infinitesimal ray: it only finds the boxes that contain its origin.
            Kernel::RtBvh => (extent * 1e-10, [1.0f32, 1.0, 1.0]),
            // Long enough to cross any tet: a chord is at most its longest edge. The
            // direction avoids the axis and diagonal planes of structured meshes.
            _ => (self.mesh.info.max_edge_length * 1.01 + extent * 1e-6, [1.0, 0.754_877_7, 0.569_840_3]),
        };
        let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        Params {
            counts: [n as u32, base as u32, self.mesh.n_tets() as u32, seed],
            lo_tmin: [lo[0], lo[1], lo[2], 0.0],
            hi_tmax: [hi[0], hi[1], hi[2], tmax],
            dir: [dir[0] / norm, dir[1] / norm, dir[2] / norm, 0.0],
        }
    }

    /// Most points one launch may take: the chunk size, capped by the device's dispatch limits.
    pub(crate) fn launch_limit(&self) -> usize {
        let l = &self.ctx.limits;
        let mut lim = self.opts.chunk_points.min(u32::MAX as usize);
        if let Some(rt) = &self.ctx.rt {
            if self.kernel.needs_ray_tracing() {
                lim = lim.min(rt.max_dispatch as usize);
            }
        }
        let groups = l.max_workgroup_count[0] as usize * l.max_workgroup_count[1] as usize;
        lim.min(groups.saturating_mul(self.opts.workgroup_size as usize))
    }

    /// Makes sure the query and result buffers hold `n` points and are bound.
    pub(crate) fn ensure_io(&mut self, n: usize) -> VkResult<()> {
        if self.io.is_some() && self.io_capacity >= n {
            return Ok(());
        }
        self.io = None;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let q = Buffer::new(
            &self.ctx,
            &self.tracker,
            "query points",
            MemKind::Query,
            (n * 12) as u64,
            usage,
            Location::Device,
        )?;
        let o = Buffer::new(
            &self.ctx,
            &self.tracker,
            "query results",
            MemKind::Query,
            (n * 4) as u64,
            usage,
            Location::Device,
        )?;
        self.desc.write_buffers(&[(B_QUERIES, &q), (B_OUT, &o)])?;
        if self.defers() {
            self.defer = None;
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST;
            let d = Buffer::new(
                &self.ctx,
                &self.tracker,
                "deferred samples",
                MemKind::Query,
                16 + (n * 4) as u64,
                usage,
                Location::Device,
            )?;
            self.desc.write_buffers(&[(B_DEFER, &d)])?;
            self.defer = Some(d);
        }
        self.io = Some((q, o));
        self.io_capacity = n;
        Ok(())
    }

    /// Uploads `name` (if not already on the GPU) and returns its output mode.
    pub(crate) fn ensure_field(&mut self, name: &str) -> tetloc_core::Result<i32> {
        let mesh = self.mesh.clone();
        let f = mesh.field(name)?;
        let mode = match f.location {
            FieldLocation::Vertex => OUT_VERTEX,
            FieldLocation::Cell => OUT_CELL,
        };
        if self.field.as_ref().map(|(n, _, _)| n.as_str()) != Some(name) {
            // Free the old field first so that only one is resident.
            self.field = None;
            self.desc.write_buffers(&[(B_FIELD, &self.dummy)])?;
            let buf = memory::device_buffer_with(
                &self.ctx,
                &self.tracker,
                &mut self.staging,
                &mut self.cmds,
                &format!("field {name}"),
                MemKind::Mesh,
                vk::BufferUsageFlags::STORAGE_BUFFER,
                bytemuck::cast_slice(&f.values),
            )?;
            self.desc.write_buffers(&[(B_FIELD, &buf)])?;
            self.field = Some((name.to_string(), f.location, buf));
        }
        Ok(mode)
    }

    /// Runs host points through variant `output`, writing 4 bytes per point into `out`.
    fn run_host(&mut self, points: &[Vec3], output: i32, out: &mut [u8]) -> VkResult<()> {
        let v = Variant { sample: SAMPLE_HOST, output, record: false };
        self.pipeline(v)?;
        let chunk = self.launch_limit().min(points.len().max(1));
        self.ensure_io(chunk)?;
        for (pts, res) in points.chunks(chunk).zip(out.chunks_mut(chunk * 4)) {
            let (q, o) = self.io.as_ref().unwrap();
            self.staging.upload(&mut self.cmds, q, 0, bytemuck::cast_slice(pts))?;
            let params = self.params(pts.len(), 0, 0);
            let launch = launch!(self, v);
            self.cmds.run(|dev, cmd| launch.record(dev, cmd, &params))?;
            self.staging.download(&mut self.cmds, o, 0, res)?;
        }
        Ok(())
    }

    /// Runs `n` in-kernel samples of `mode` (not `Host`) with seed `seed`, and returns the
    /// generated points with their tet ids (-1 outside). For checks: benchmarks time the
    /// same kernels without recording points.
    pub fn locate_generated(&mut self, mode: SampleMode, n: usize, seed: u32) -> VkResult<(Vec<Vec3>, Vec<i32>)> {
        if mode == SampleMode::Host {
            return Err(VkError::Mesh("locate_generated needs a generated sample mode, not host".into()));
        }
        let v = Variant { sample: mode.code(), output: OUT_IDS, record: true };
        self.pipeline(v)?;
        let chunk = self.launch_limit().min(n.max(1));
        self.ensure_io(chunk)?;
        let mut points = vec![[0f32; 3]; n];
        let mut ids = vec![0i32; n];
        for base in (0..n).step_by(chunk) {
            let len = chunk.min(n - base);
            let params = self.params(len, base, seed);
            self.run_launch(v, &params)?;
            let (q, o) = self.io.as_ref().unwrap();
            self.staging.download(&mut self.cmds, q, 0, bytemuck::cast_slice_mut(&mut points[base..base + len]))?;
            self.staging.download(&mut self.cmds, o, 0, bytemuck::cast_slice_mut(&mut ids[base..base + len]))?;
        }
        Ok((points, ids))
    }

    /// Submits one launch and waits for it.
    pub(crate) fn run_launch(&mut self, v: Variant, params: &Params) -> VkResult<()> {
        self.pipeline(v)?;
        let launch = launch!(self, v);
        self.cmds.run(|dev, cmd| launch.record(dev, cmd, params))
    }
}

/// Binds a split array: its first buffer at `lo`, the others (or `dummy`) at the array `hi`.
/// `None`: the array is not used; everything gets `dummy`.
fn bind_chunked(desc: &Descriptors, lo: u32, hi: u32, array: Option<&Chunked>, dummy: &Buffer) -> VkResult<()> {
    let part = |k: usize| array.and_then(|a| a.parts.get(k)).unwrap_or(dummy);
    desc.write_buffers(&[(lo, part(0))])?;
    desc.write_buffer_array(hi, &(1..MAX_CHUNKS).map(part).collect::<Vec<_>>())
}

/// The [`Launch`] of variant `v` (whose pipeline must exist), borrowing only the fields it
/// reads so that `cmds` and `staging` stay usable beside it.
macro_rules! launch {
    ($loc:expr, $v:expr) => {
        crate::locator::Launch {
            ctx: &$loc.ctx,
            desc: &$loc.desc,
            pipeline: &$loc.pipelines[&$v],
            exact: $loc.exact_pipelines.get(&$v).zip($loc.defer.as_ref().map(|b| b.buffer)),
            workgroup: $loc.opts.workgroup_size,
        }
    };
}
pub(crate) use launch;

/// Everything needed to record one kernel launch.
pub(crate) struct Launch<'a> {
    pub ctx: &'a Context,
    pub desc: &'a Descriptors,
    pub pipeline: &'a Pipeline,
    /// soft-bvh with `defer_exact`: the exact second pass and the deferred-sample list.
    pub exact: Option<(&'a Pipeline, vk::Buffer)>,
    pub workgroup: u32,
}

impl Launch<'_> {
    /// Records one launch over `params.counts[0]` points.
    pub fn record(&self, dev: &ash::Device, cmd: vk::CommandBuffer, params: &Params) {
        let p = self.pipeline;
        let n = params.counts[0] as u64;
        // SAFETY: recording into a command buffer in the recording state, with live objects.
        unsafe {
            if let Some((_, list)) = self.exact {
                // Empty the deferred-sample list: dispatch size (0, 1, 1), count 0.
                full_barrier(dev, cmd);
                dev.cmd_update_buffer(cmd, list, 0, bytemuck::cast_slice(&[0u32, 1, 1, 0]));
                full_barrier(dev, cmd);
            }
            dev.cmd_bind_pipeline(cmd, p.bind_point, p.pipeline);
            dev.cmd_bind_descriptor_sets(cmd, p.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
            dev.cmd_push_constants(cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(params));
            match &p.sbt {
                None => {
                    // 2D grid of workgroups when one row is not enough; the shader linearises it.
                    let groups = n.div_ceil(self.workgroup as u64);
                    let x = groups.min(self.ctx.limits.max_workgroup_count[0] as u64).max(1);
                    dev.cmd_dispatch(cmd, x as u32, groups.div_ceil(x) as u32, 1);
                }
                Some(sbt) => {
                    let l = &self.ctx.limits;
                    let max_width = l.max_workgroup_count[0] as u64 * l.max_workgroup_size[0] as u64;
                    let width = n.min(max_width).max(1);
                    let empty = vk::StridedDeviceAddressRegionKHR::default();
                    let rt = self.ctx.rt.as_ref().unwrap();
                    rt.pipeline.cmd_trace_rays(
                        cmd,
                        &sbt.raygen,
                        &sbt.miss,
                        &sbt.hit,
                        &empty,
                        width as u32,
                        n.div_ceil(width) as u32,
                        1,
                    );
                }
            }
            if let Some((exact, list)) = self.exact {
                // The samples the f32 pass deferred, exactly: as many workgroups as it counted.
                full_barrier(dev, cmd);
                dev.cmd_bind_pipeline(cmd, exact.bind_point, exact.pipeline);
                dev.cmd_bind_descriptor_sets(cmd, exact.bind_point, self.desc.layout, 0, &[self.desc.set], &[]);
                dev.cmd_push_constants(cmd, self.desc.layout, self.desc.stages, 0, bytemuck::bytes_of(params));
                dev.cmd_dispatch_indirect(cmd, list, 0);
            }
        }
    }
}

impl BatchLocator for VulkanLocator {
    fn name(&self) -> &str {
        self.kernel.name()
    }

    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> tetloc_core::Result<()> {
        if points.len() != ids.len() {
            return Err(tetloc_core::Error::Invalid(format!(
                "{} points but an output buffer for {}",
                points.len(),
                ids.len()
            )));
        }
        if points.is_empty() {
            return Ok(());
        }
        self.run_host(points, OUT_IDS, bytemuck::cast_slice_mut(ids))?;
        Ok(())
    }

    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> tetloc_core::Result<()> {
        if points.len() != values.len() {
            return Err(tetloc_core::Error::Invalid(format!(
                "{} points but an output buffer for {}",
                points.len(),
                values.len()
            )));
        }
        let mode = self.ensure_field(field)?;
        if points.is_empty() {
            return Ok(());
        }
        self.run_host(points, mode, bytemuck::cast_slice_mut(values))?;
        Ok(())
    }
}
