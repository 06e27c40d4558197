//! `VulkanLocator`: a mesh on the GPU, one kernel's search structure (its [`Plan`]), and the
//! batch API. The locator knows no kernel by name: it uploads the mesh, lets the kernel build
//! its plan, and runs the plan's pipelines.

mod bench;
mod launch;
mod order;

pub use bench::{si, BenchOptions, BenchResult};
use launch::{Launcher, Output, Variant};
use order::{Ordering, ORDER_MIN_POINTS};

use crate::context::Context;
use crate::device::{Device, Split};
use crate::error::{VkError, VkResult};
use crate::interface::*;
use crate::kernels::{Inputs, Kernel, Plan, RtOptions, SoftBvhOptions};
use crate::memory::{Buffer, BufferDesc, MemItem, MemKind, STAGING_BYTES};
use crate::packed;
use crate::pipeline::{Binding, Descriptors, Pipeline, Spec};
use crate::AsReport;
use ash::vk;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::geom::ImageGrid;
use tetloc_core::geom::Vec3;
use tetloc_core::locate::{certify, check_sample_lengths, query_grid_points, GridSampler, LineTracer, Points, Values};
use tetloc_core::mesh::{FieldLocation, Mesh};
use tetloc_core::queries::QueryKind;
use tetloc_core::BatchLocator;

/// Options of a [`VulkanLocator`]: what every kernel shares, and each kernel family's own
/// ([`SoftBvhOptions`], [`RtOptions`]; a kernel reads only its family's).
#[derive(Clone, Debug)]
pub struct LocatorOptions {
    /// Points per kernel launch; larger batches run in chunks (bounds the query buffers). On
    /// meshes of 32M tets or more, ordered launches of generated points take at least a point
    /// per 8 tets (up to 128M points and 1/32 of the device's memory; see `launch_points`).
    pub chunk_points: usize,
    /// Use the exact f64 fallback of the point-in-tet test when the device has shaderFloat64;
    /// `false` forces the pure-f32 test.
    pub float64: bool,
    /// Sort each launch's points along the Morton curve on the GPU before locating them
    /// (batches of random or host points of at least `ORDER_MIN_POINTS`; answers keep the
    /// given order): keeps random queries on few pages of a large mesh (NOTES.md).
    pub order_queries: bool,
    /// With query ordering: make the paper's random points in the order of their tets (a
    /// counting sort of the sample indices by tet first), so that making them reads the mesh
    /// nearly in order. `None`: on meshes whose tets and vertices pass 8 GiB (~450M tets),
    /// where random reads of them approach the address-translation knee; the same points and
    /// answers either way.
    pub random_in_tet_order: Option<bool>,
    /// Size of the staging buffer that all uploads and downloads go through.
    pub staging_bytes: u64,
    /// Store the tets' vertex ids (every kernel), soft-bvh's neighbours and leaf prims in as
    /// many bits as the mesh needs (`crate::packed`: 24 and 26 bits at jets 62M, 7.75 B a tet
    /// less), each array where it fits one buffer; the same answers. On in `compact` and
    /// `small`.
    pub pack_ids: bool,
    pub soft_bvh: SoftBvhOptions,
    pub rt: RtOptions,
    /// Hooks that force rare paths in tests (feature `test-hooks`).
    #[cfg(any(test, feature = "test-hooks"))]
    pub test_hooks: TestHooks,
}

/// What tests set to reach paths that real meshes reach only at sizes a test cannot afford.
#[cfg(any(test, feature = "test-hooks"))]
#[derive(Clone, Debug, Default)]
pub struct TestHooks {
    /// Split mesh and soft-bvh arrays into several buffers above this size (default: the
    /// device's limits, 4 GiB on the H100).
    pub max_buffer_bytes: Option<u64>,
    /// With `pack_ids`: at least this many bits a field (25 to 31 bits take the readers'
    /// five-word path; wider fields hold the same values). 0: as few as the mesh needs.
    pub pack_min_bits: u32,
}

impl Default for LocatorOptions {
    fn default() -> Self {
        LocatorOptions {
            chunk_points: 1 << 22,
            float64: true,
            order_queries: true,
            random_in_tet_order: None,
            staging_bytes: STAGING_BYTES,
            pack_ids: false,
            soft_bvh: SoftBvhOptions::fast(),
            rt: RtOptions::default(),
            #[cfg(any(test, feature = "test-hooks"))]
            test_hooks: TestHooks::default(),
        }
    }
}

impl LocatorOptions {
    /// The options of preset `name` ([`PRESETS`](crate::PRESETS)): soft-bvh's layout of that name
    /// ([`SoftBvhOptions::preset`]), with packed ids in `compact` and `small` (the rt kernels
    /// take only their packed tets); `None` for an unknown name.
    pub fn preset(name: &str) -> Option<LocatorOptions> {
        let soft_bvh = SoftBvhOptions::preset(name)?;
        Some(LocatorOptions { soft_bvh, pack_ids: name != "fast", ..Default::default() })
    }

    /// What is wrong with these options, if anything.
    pub fn validate(&self) -> Result<(), String> {
        if self.chunk_points == 0 || self.staging_bytes < 1 << 10 {
            return Err(format!(
                "chunk_points {} (> 0), staging_bytes {} (>= 1 KiB)",
                self.chunk_points, self.staging_bytes
            ));
        }
        self.soft_bvh.validate()?;
        self.rt.validate()
    }

    /// The largest buffer to allocate, when a test says.
    fn max_buffer_bytes(&self) -> Option<u64> {
        #[cfg(any(test, feature = "test-hooks"))]
        return self.test_hooks.max_buffer_bytes;
        #[cfg(not(any(test, feature = "test-hooks")))]
        None
    }

    /// With `pack_ids`: the fewest bits a packed field takes.
    fn pack(&self) -> Option<u32> {
        #[cfg(any(test, feature = "test-hooks"))]
        let min_bits = self.test_hooks.pack_min_bits;
        #[cfg(not(any(test, feature = "test-hooks")))]
        let min_bits = 0;
        self.pack_ids.then_some(min_bits)
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

/// A mesh on one Vulkan device with one kernel's search structure.
pub struct VulkanLocator {
    // Field order is drop order: pipelines and buffers before the device object.
    launcher: Launcher,
    io: Option<Io>,
    /// The hinted locate's pipeline and buffers, once used (`crate::hinted`).
    pub(crate) hinted: Option<crate::hinted::Hinted>,
    /// The fields on the GPU, in the order B_FIELD binds them: those of the last launch
    /// that sampled fields (only they are resident).
    fields: Vec<(String, Buffer)>,
    /// The `grid` sample set's axes on the GPU, for this grid (in the file's coordinates or
    /// the working frame).
    grid_axes: Option<(ImageGrid, bool, Buffer)>,
    plan: Plan,
    mesh_on_device: MeshOnDevice,
    mesh: Arc<Mesh>,
    kernel: Kernel,
    opts: LocatorOptions,
    f64: bool,
    build_seconds: f64,
    /// Wall seconds of each stage of `new`: the mesh upload, the kernel's structure, the
    /// first pipeline.
    build_stages: Vec<(String, f64)>,
    memory: MemoryReport,
    /// Makes f64 answers exact on the file's data (kept: its boundary boxes, once built).
    certifier: certify::Certifier,
    dev: Device,
}

/// The mesh's vertices and tets on the device (split over buffers when large), for
/// higher-order tets their other nodes and the shape functions' lattice (high_order.glsl), and
/// for a kernel that takes one box a cell of a mixed mesh the cells' first tets.
pub(crate) struct MeshOnDevice {
    points: Split,
    /// A mesh stored in f64: each vertex's residual (`Mesh::working_residuals`), split like
    /// the vertices; sets `REFINE_BARY`.
    residuals: Option<Split>,
    tets: Split,
    /// Bits a field of the packed tets (`crate::packed`; 0: u32x4 tets).
    tet_bits: u32,
    high_order: Option<HighOrder>,
    /// `Cells::first_tets` (mesh.glsl `tl_prim_tets`): present when the kernel takes one box
    /// a cell (`KernelDef::cell_boxes`) and the mesh has cells; sets `CELL_BOXES`.
    cell_tets: Option<Buffer>,
}

struct HighOrder {
    nodes: Buffer,
    lattice: Buffer,
    /// Nodes per tet after the corners, order, Bezier.
    spec: (u32, u32, bool),
}

/// The query points and results of launches of up to `capacity` points, and with deferred
/// exact tests the list of deferred samples (header: indirect dispatch size, count; then
/// sample indices).
struct Io {
    queries: Buffer,
    results: Buffer,
    deferred: Option<Buffer>,
    /// Query ordering's passes and buffers, when the options ask for it.
    order: Option<Ordering>,
    capacity: usize,
}

/// What the volume marcher uses of a locator (see [`VulkanLocator::resources`]).
pub(crate) struct Resources<'a> {
    pub dev: &'a mut Device,
    pub plan: &'a Plan,
    pub mesh: &'a Arc<Mesh>,
    /// The mesh's, the field's and the structure's bindings (not the queries').
    pub bindings: Vec<Binding>,
    /// The specialization constants for the field's output mode: the test's, the split
    /// arrays', the kernel's.
    pub spec: Spec,
    /// The push constants of a launch (bounds, ray).
    pub params: Params,
    pub f64: bool,
}

impl Resources<'_> {
    /// Shaders that walk from tet to tet (the marcher, the tracer) on a plan whose bindings
    /// lack the neighbour table (soft-bvh without its walk start) bind one of their own (one
    /// buffer, named `name`); the buffer must live as long as the bindings are used.
    pub fn bind_own_neighbors(&mut self, name: &str) -> VkResult<Option<Buffer>> {
        if !self.plan.march_needs_neighbors {
            return Ok(None);
        }
        let nb = bytemuck::cast_slice(self.mesh.neighbors());
        let buf = self.dev.upload(name, MemKind::Structure, vk::BufferUsageFlags::STORAGE_BUFFER, nb)?;
        self.bindings.retain(|b| b.slot != B_NEIGHBORS);
        self.bindings.push(Binding::buffer(B_NEIGHBORS, &buf));
        Ok(Some(buf))
    }
}

impl VulkanLocator {
    /// Uploads the mesh and builds `kernel`'s search structure on `ctx`'s device.
    pub fn new(ctx: Arc<Context>, mesh: Arc<Mesh>, kernel: Kernel, opts: LocatorOptions) -> VkResult<VulkanLocator> {
        let t0 = Instant::now();
        check(&ctx, &mesh, kernel, &opts)?;
        let mesh_bytes = (mesh.points.len() * 12).max(mesh.tets.len() * 16) as u64;
        // Small meshes get a smaller staging buffer, but one that still moves large batches
        // of points in few round trips.
        let staging = opts.staging_bytes.min(mesh_bytes.max(16 << 20));
        let mut dev = Device::new(&ctx, staging, opts.max_buffer_bytes())?;
        let t_upload = Instant::now();
        let pack = opts.pack();
        let def = kernel.def();
        let mesh_on_device = MeshOnDevice::upload(&mut dev, &mesh, def.ray_tracing, pack, def.cell_boxes)?;
        let mut stages = vec![("mesh upload".to_string(), t_upload.elapsed().as_secs_f64())];
        let f64 = opts.float64 && ctx.info().float64;
        let mesh_bindings = mesh_on_device.bindings(dev.unbound());
        let inputs = mesh_on_device.inputs(&mesh, &mesh_bindings, &opts, f64);
        let mut plan = (def.plan)(&mut dev, &inputs)?;
        stages.append(&mut plan.build_stages);
        let desc = Descriptors::new(&ctx, &Self::locate_bindings(&dev, &mesh_on_device, &plan), plan.locate.stages())?;
        let (items, peak_bytes) = dev.memory();
        let final_bytes =
            items.iter().filter(|m| matches!(m.kind, MemKind::Mesh | MemKind::Structure)).map(|m| m.bytes).sum();
        let memory = MemoryReport { final_bytes, peak_bytes, items, accel: plan.accel };
        let launcher = Launcher {
            pipelines: HashMap::new(),
            exact_pipelines: HashMap::new(),
            desc,
            workgroup: opts.soft_bvh.workgroup_size,
        };
        let mut loc = VulkanLocator {
            launcher,
            io: None,
            hinted: None,
            fields: vec![],
            grid_axes: None,
            plan,
            mesh_on_device,
            mesh,
            kernel,
            opts,
            f64,
            build_seconds: 0.0,
            build_stages: vec![],
            memory,
            // The kernels that search every tet miss no point of the copy; the face kernels
            // can stop at a face with no tet behind it.
            certifier: certify::Certifier::new(matches!(kernel, Kernel::SoftBvh | Kernel::RtBvh)),
            dev,
        };
        // Compile the id variant now, so that building includes pipeline creation.
        let t_pipeline = Instant::now();
        loc.pipeline(Variant { sample: SAMPLE_HOST, output: Output::IDS, record: false, ordered: false })?;
        stages.push(("locate pipeline".to_string(), t_pipeline.elapsed().as_secs_f64()));
        loc.build_stages = stages;
        loc.build_seconds = t0.elapsed().as_secs_f64();
        Ok(loc)
    }

    /// The locate pipelines' bindings: the mesh's, the field's and the queries' (all
    /// `unbound` until used), and the kernel's.
    fn locate_bindings(dev: &Device, mesh: &MeshOnDevice, plan: &Plan) -> Vec<Binding> {
        let unbound = dev.unbound();
        let mut b = mesh.bindings(unbound);
        b.extend(
            [B_QUERIES, B_OUT, B_DEFER, B_ORDER_POINTS, B_ORDER_PERM, B_GRID_AXES]
                .map(|slot| Binding::buffer(slot, unbound)),
        );
        b.push(Binding::array(B_FIELD, &[], MAX_FIELDS, unbound));
        b.extend(plan.bindings.iter().cloned());
        b
    }

    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    pub fn context(&self) -> &Arc<Context> {
        self.dev.ctx()
    }

    /// Seconds spent in `new`: uploads, structure build (and compaction), first pipeline.
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Wall seconds of each stage of `new`: the mesh upload, the kernel's structure (soft-bvh
    /// names its build's stages, `gpu: ...` or `cpu: ...`), the first locate pipeline.
    pub fn build_stages(&self) -> &[(String, f64)] {
        &self.build_stages
    }

    /// GPU memory after the build (final) and during it (peak), with every allocation named.
    pub fn memory_report(&self) -> &MemoryReport {
        &self.memory
    }

    /// True when the point-in-tet test runs with the exact f64 fallback (else pure f32).
    pub fn uses_float64(&self) -> bool {
        self.f64
    }

    /// The device object (the volume marcher submits its frames through it).
    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// The kernel's programs and structure.
    pub(crate) fn plan(&self) -> &Plan {
        &self.plan
    }

    pub(crate) fn device(&mut self) -> &mut Device {
        &mut self.dev
    }

    /// What the volume marcher binds and specializes (no second upload): the mesh, the field
    /// `field` (uploaded now if it is not on the GPU), the kernel's structure and plan.
    pub(crate) fn resources(&mut self, field: &str) -> tetloc_core::Result<Resources<'_>> {
        let output = self.ensure_field(field)?;
        Ok(self.resources_for(output, true))
    }

    /// [`Self::resources`] for a shader specialised to `output` that reads the uploaded field
    /// (`with_field`) or brings its own data (the field binding then names no field).
    pub(crate) fn resources_for(&mut self, output: i32, with_field: bool) -> Resources<'_> {
        let mut bindings = self.mesh_on_device.bindings(self.dev.unbound());
        let fields: Vec<&Buffer> = self.fields.iter().filter(|_| with_field).map(|(_, b)| b).collect();
        bindings.push(Binding::array(B_FIELD, &fields, MAX_FIELDS, self.dev.unbound()));
        bindings.extend(self.plan.bindings.iter().cloned());
        Resources {
            spec: self.spec(output),
            params: self.params(0, 0, 0),
            bindings,
            plan: &self.plan,
            mesh: &self.mesh,
            f64: self.f64,
            dev: &mut self.dev,
        }
    }

    /// The pipeline for `v`, created on first use (with its exact second pass when deferring).
    fn pipeline(&mut self, v: Variant) -> VkResult<&Pipeline> {
        let spec = self
            .spec(v.output.mode)
            .set(sc::FIELD_COUNT, v.output.fields)
            .set(sc::FIELD_CELLS, v.output.cells)
            .set(sc::SAMPLE_MODE, v.sample as u32)
            .set(sc::RECORD_POINTS, v.record as u32)
            .set(sc::ORDERED, v.ordered as u32);
        if v.ordered {
            let order_spec = self.spec(OUT_IDS);
            let io = self.io.as_mut().expect("ensure_io runs before ordered pipelines are made");
            io.order.as_mut().expect("ordering is on").prepare(&mut self.dev, v.sample, &order_spec)?;
        }
        let layout = self.launcher.desc.layout;
        if let Some(exact) = &self.plan.exact_pass {
            if !self.launcher.exact_pipelines.contains_key(&v) {
                let p = self.plan.locate.pipeline(&mut self.dev, layout, self.f64, &spec.clone().concat(exact))?;
                self.launcher.exact_pipelines.insert(v, p);
            }
        }
        if !self.launcher.pipelines.contains_key(&v) {
            let p = self.plan.locate.pipeline(&mut self.dev, layout, self.f64, &spec.concat(&self.plan.locate_spec))?;
            self.launcher.pipelines.insert(v, p);
        }
        Ok(&self.launcher.pipelines[&v])
    }

    /// The specialization constants of this locator's pipelines for `output` (the volume
    /// marcher's too): the test's constants, how the arrays are split over buffers, and the
    /// kernel's own.
    fn spec(&self, output: i32) -> Spec {
        let spec = Spec::default()
            .set(sc::OUTPUT_MODE, output as u32)
            .set(sc::ORIENT_ERR_BOUND_F32, tetloc_core::geom::ORIENT_ERR_BOUND_F32.to_bits())
            .set(sc::BARY_F32_TRUST, tetloc_core::geom::BARY_F32_TRUST.to_bits())
            .set(sc::LOCAL_ORIENT_BOUND, tetloc_core::geom::predicates::local::LOCAL_ORIENT_BOUND.to_bits())
            .set(
                sc::CERTIFY_DELTA,
                if self.mesh.wants_f64_points() { self.mesh.info.frame.delta } else { -1.0 }.to_bits(),
            )
            .set(sc::POINTS_CHUNK, self.mesh_on_device.points.per_chunk)
            .set(sc::TETS_CHUNK, self.mesh_on_device.tets.per_chunk)
            .set(sc::TET_BITS, self.mesh_on_device.tet_bits);
        self.mesh_on_device.spec(spec).concat(&self.plan.spec)
    }

    /// Push constants for a launch of `n` points starting at global sample index `base`.
    fn params(&self, n: usize, base: usize, seed: u32) -> Params {
        let (lo, hi) = (self.mesh.info.bounds_min, self.mesh.info.bounds_max);
        let ray = self.plan.ray;
        Params {
            counts: [n as u32, base as u32, self.mesh.n_tets() as u32, seed],
            lo_tmin: [lo[0], lo[1], lo[2], 0.0],
            hi_tmax: [hi[0], hi[1], hi[2], ray.tmax],
            dir: [ray.dir[0], ray.dir[1], ray.dir[2], 0.0],
            ..Default::default()
        }
    }

    /// Push constants for a launch of `len` generated points of `kind` from global index
    /// `base`, of `n` in all (the `grid` set's grid depends on `n`).
    fn generated_params(&self, kind: QueryKind, len: usize, base: usize, n: usize, seed: u32) -> Params {
        let mut p = self.params(len, base, seed);
        if kind == QueryKind::Grid {
            let g = tetloc_core::queries::grid(&self.mesh, n);
            p.grid = [g.dims[0] as u32, g.dims[1] as u32, 0, 0];
        }
        p
    }

    /// Makes the kernels' `grid` sample set the points of `grid` (given in the file's
    /// coordinates when `file_coords`, else in the working frame): each axis's coordinates as
    /// the grid gives them (`ImageGrid::point64`: its f64 points, or their f32 rounding),
    /// taken to the working frame as a query's points are, so that the kernel locates exactly
    /// the points a query of the grid's points would have sent.
    fn ensure_grid_axes(&mut self, grid: &ImageGrid, file_coords: bool) -> VkResult<()> {
        if self.grid_axes.as_ref().is_some_and(|(g, f, _)| g == grid && *f == file_coords) {
            return Ok(());
        }
        self.grid_axes = None;
        self.launcher.desc.write(&[Binding::buffer(B_GRID_AXES, self.dev.unbound())]);
        let [nx, ny, _] = grid.dims;
        let frame = self.mesh.info.frame;
        let exact =
            |i: usize| if file_coords { frame.to_working64(grid.point64(i)) } else { grid.point(i).map(f64::from) };
        let along = |k: usize| -> Vec<f64> {
            let step = [1, nx, nx * ny][k];
            (0..grid.dims[k]).map(|i| exact(i * step)[k]).collect()
        };
        let exact_axes: Vec<f64> = (0..3).flat_map(along).collect();
        let mut axes: Vec<f32> = exact_axes.iter().map(|&x| x as f32).collect();
        // A grid of f64 points: each coordinate's residual after the axes, which the kernels'
        // values on a mesh stored in f64 take (tl_sample_residual); params.grid[3] says where.
        if file_coords && grid.f64_points {
            axes.extend(exact_axes.iter().map(|&x| (x - f64::from(x as f32)) as f32));
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let buf = self.dev.upload("grid axes", MemKind::Query, storage, bytemuck::cast_slice(&axes))?;
        self.launcher.desc.write(&[Binding::buffer(B_GRID_AXES, &buf)]);
        self.grid_axes = Some((grid.clone(), file_coords, buf));
        Ok(())
    }

    /// Most points one launch may take: the chunk size (grown for `ordered` launches over large
    /// meshes, [`launch_points`]), capped by the device's dispatch limits.
    fn launch_limit(&self, ordered: bool) -> usize {
        let ctx = self.dev.ctx();
        let l = &ctx.limits;
        let chunk = launch_points(self.opts.chunk_points, self.mesh.n_tets(), ordered, ctx.info().memory_bytes);
        let mut lim = chunk.min(u32::MAX as usize);
        if let (Some(rt), true) = (&ctx.rt, self.plan.locate.ray_tracing()) {
            lim = lim.min(rt.max_dispatch as usize);
        }
        let groups = l.max_workgroup_count[0] as usize * l.max_workgroup_count[1] as usize;
        lim.min(groups.saturating_mul(self.opts.soft_bvh.workgroup_size as usize))
    }

    /// Makes sure the query and result buffers hold `n` points, with `words` 4-byte answers
    /// each ([`Output::words`]), and are bound.
    fn ensure_io(&mut self, n: usize, words: usize) -> VkResult<()> {
        let result_bytes = (n * words * 4) as u64;
        if let Some(io) = self.io.as_mut().filter(|io| io.capacity >= n && io.results.size < result_bytes) {
            // More fields than before: larger results only (the ordering's buffers stay).
            self.launcher.desc.write(&[Binding::buffer(B_OUT, self.dev.unbound())]);
            io.results = self.dev.create_buffer(BufferDesc::io(MemKind::Query, result_bytes), "query results", None)?;
            self.launcher.desc.write(&[Binding::buffer(B_OUT, &io.results)]);
        }
        if self.io.as_ref().is_none_or(|io| io.capacity < n || io.order.is_some() != self.opts.order_queries) {
            self.io = None;
            let queries =
                self.dev.create_buffer(BufferDesc::io(MemKind::Query, (n * 12) as u64), "query points", None)?;
            let results =
                self.dev.create_buffer(BufferDesc::io(MemKind::Query, result_bytes), "query results", None)?;
            self.launcher.desc.write(&[Binding::buffer(B_QUERIES, &queries), Binding::buffer(B_OUT, &results)]);
            let deferred = match self.plan.exact_pass {
                Some(_) => {
                    let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::INDIRECT_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_DST;
                    let desc = BufferDesc::device(MemKind::Query, 16 + (n * 4) as u64, usage);
                    let d = self.dev.create_buffer(desc, "deferred samples", None)?;
                    self.launcher.desc.write(&[Binding::buffer(B_DEFER, &d)]);
                    Some(d)
                }
                None => None,
            };
            let order = match self.opts.order_queries {
                true => {
                    let mut bindings = self.mesh_on_device.bindings(self.dev.unbound());
                    bindings.push(Binding::buffer(B_QUERIES, &queries));
                    // The keys pass never generates grids (they are not ordered).
                    bindings.push(Binding::buffer(B_GRID_AXES, self.dev.unbound()));
                    let past_knee = self.mesh_on_device.point_and_tet_bytes() >= TET_ORDER_MIN_BYTES;
                    let tet_first = self.opts.random_in_tet_order.unwrap_or(past_knee);
                    let o = Ordering::new(&mut self.dev, n, &bindings, tet_first)?;
                    self.launcher
                        .desc
                        .write(&[Binding::buffer(B_ORDER_POINTS, &o.points), Binding::buffer(B_ORDER_PERM, &o.perm)]);
                    Some(o)
                }
                false => None,
            };
            self.io = Some(Io { queries, results, deferred, order, capacity: n });
        }
        Ok(())
    }

    /// Uploads `name` (if not already on the GPU) alone and returns its output mode.
    fn ensure_field(&mut self, name: &str) -> tetloc_core::Result<i32> {
        let out = self.ensure_fields(&[name])?;
        Ok(Output::single(out.cells != 0).mode)
    }

    /// Makes `names` (at most MAX_FIELDS) the bound fields, in that order (uploading those not
    /// on the GPU, freeing the others first, so that one launch's fields are resident), and
    /// returns the output that samples them all.
    pub(crate) fn ensure_fields(&mut self, names: &[&str]) -> tetloc_core::Result<Output> {
        assert!(names.len() <= MAX_FIELDS as usize, "at most MAX_FIELDS fields a launch");
        let mesh = self.mesh.clone();
        let fields = names.iter().map(|n| mesh.field(n)).collect::<tetloc_core::Result<Vec<_>>>()?;
        let cells = (fields.iter().enumerate())
            .filter(|(_, f)| f.location == FieldLocation::Cell)
            .fold(0u32, |m, (j, _)| m | 1 << j);
        let out = Output::fields(names.len() as u32, cells);
        if self.fields.iter().map(|(n, _)| n.as_str()).eq(names.iter().copied()) {
            return Ok(out);
        }
        self.launcher.desc.write(&[Binding::array(B_FIELD, &[], MAX_FIELDS, self.dev.unbound())]);
        let mut old = std::mem::take(&mut self.fields);
        old.retain(|(n, _)| names.contains(&n.as_str()));
        for f in fields {
            let buf = match old.iter().position(|(n, _)| *n == f.name) {
                Some(k) => old.swap_remove(k).1,
                None => {
                    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
                    let data = bytemuck::cast_slice(&f.values);
                    match self.dev.upload(&format!("field {}", f.name), MemKind::Mesh, usage, data) {
                        Ok(b) => b,
                        Err(e) => {
                            self.fields.clear(); // nothing half-bound stays
                            return Err(e.into());
                        }
                    }
                }
            };
            self.fields.push((f.name.clone(), buf));
        }
        let bufs: Vec<&Buffer> = self.fields.iter().map(|(_, b)| b).collect();
        self.launcher.desc.write(&[Binding::array(B_FIELD, &bufs, MAX_FIELDS, self.dev.unbound())]);
        Ok(out)
    }

    /// Ids and the values of `fields` (`fields.len()` a point) at host points (the file's
    /// coordinates) or at `grid`'s points from index `start` (its axes uploaded): one launch a
    /// batch locates each point once and writes its id and every value (up to MAX_FIELDS
    /// fields; more take a pass each MAX_FIELDS).
    fn sample_fields(
        &mut self,
        at: At<'_>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> tetloc_core::Result<()> {
        let frame = self.mesh.info.frame;
        let original = at;
        let working: Vec<Vec3>;
        let at = match at {
            At::Host(p) if !frame.is_identity() => {
                working = p.par_iter().map(|&p| frame.to_working_f32(p)).collect();
                At::Host(&working)
            }
            at => at,
        };
        let run = |loc: &mut Self, out: Output, ids: &mut [i32], values: &mut [f32]| match at {
            At::Host(p) => loc.run_working(p, out, bytemuck::cast_slice_mut(ids), values),
            At::Grid(grid, start) => loc.run_grid(grid, start, out, bytemuck::cast_slice_mut(ids), values),
        };
        let k = fields.len();
        if k <= MAX_FIELDS as usize {
            let out = if k == 0 { Output::IDS } else { self.ensure_fields(fields)? };
            run(self, out, ids, values)?;
        } else {
            let mut part = vec![];
            for (g, group) in fields.chunks(MAX_FIELDS as usize).enumerate() {
                let out = self.ensure_fields(group)?;
                let m = group.len();
                part.resize(ids.len() * m, 0f32);
                run(self, out, ids, &mut part)?;
                let first = g * MAX_FIELDS as usize;
                values
                    .par_chunks_mut(k)
                    .zip(part.par_chunks(m))
                    .for_each(|(v, p)| v[first..first + m].copy_from_slice(p));
            }
        }
        let grid64 = matches!(original, At::Grid(grid, _) if grid.f64_points);
        if self.mesh.wants_f64_points() || grid64 {
            // The points as the kernel had them, made again here (none kept for a grid).
            let point = |i: usize| -> [f64; 3] {
                match original {
                    At::Host(p) => p[i].map(f64::from),
                    At::Grid(grid, start) => grid.point64(start + i),
                }
            };
            // The kernel's points are these rounded to the working frame: a grid's too (its
            // axes are the working coordinates of its points, one coordinate each). Where the
            // kernels mark nothing (a mesh that is its own f32 copy), every answer for a
            // grid's f64 points is checked, as `query` checks f64 points.
            let moved: Vec<usize> = if self.mesh.wants_f64_points() {
                self.certify_marked(&point, ids)
            } else {
                let all = self.certifier.certify_at(&self.mesh, point, ids, false, false);
                all.into_iter().map(|(i, _)| i).collect()
            };
            if k > 0 && !moved.is_empty() {
                // The moved points' values, from the file's data as the other paths compute them.
                let mesh = self.mesh.clone();
                let fields = fields.iter().map(|f| mesh.field(f)).collect::<tetloc_core::Result<Vec<_>>>()?;
                let wide: Vec<[f64; 3]> = moved.iter().map(|&i| point(i)).collect();
                let tets: Vec<i32> = moved.iter().map(|&i| ids[i]).collect();
                let mut fresh = vec![0f32; moved.len() * k];
                mesh.values_at_ids64(&wide, &tets, &fields, &mut fresh);
                for (&i, v) in moved.iter().zip(fresh.chunks(k)) {
                    values[i * k..(i + 1) * k].copy_from_slice(v);
                }
            }
        }
        Ok(())
    }

    /// Checks the kernels' tets for points (`point(i)`: the file's coordinates, which the
    /// kernels had rounded to the working frame) on the file's data and corrects them
    /// ([`certify::Certifier`]) where the kernels decided on a copy; returns the indices whose
    /// tet changed. There the kernels mark each answer they did not prove (-2 - tet,
    /// CERTIFY_DELTA): only those and the points outside are checked.
    fn certify_marked(&self, point: &(impl Fn(usize) -> [f64; 3] + Sync), ids: &mut [i32]) -> Vec<usize> {
        if !self.mesh.wants_f64_points() {
            return vec![];
        }
        self.certifier.certify_at(&self.mesh, point, ids, false, true).into_iter().map(|(i, _)| i).collect()
    }

    /// The k + 1 launches that one launch of [`BatchLocator::query`] replaced for f32 points
    /// and values: the ids, then a launch a field (its value only), each locating the points
    /// again. The same ids and values, bit for bit, where the kernels decide on the file's
    /// data (not certified on the host): kept to compare against (benchmarks, tests).
    pub fn sample_per_field(
        &mut self,
        points: &[Vec3],
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> tetloc_core::Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        if points.is_empty() {
            return Ok(());
        }
        self.run_host(points, Output::IDS, bytemuck::cast_slice_mut(ids), &mut [])?;
        unmark(ids);
        let mut one = vec![0f32; if fields.is_empty() { 0 } else { points.len() }];
        for (j, f) in fields.iter().enumerate() {
            let cell = self.ensure_field(f)? == OUT_CELL;
            self.run_host(points, Output::single(cell), bytemuck::cast_slice_mut(&mut one), &mut [])?;
            values.iter_mut().skip(j).step_by(fields.len()).zip(&one).for_each(|(v, &x)| *v = x);
        }
        Ok(())
    }

    /// Runs host points (the file's coordinates) through `output`: each point's id (or
    /// single value) into `ids` (4 bytes a point) and its fields' values into `values`
    /// (`output.fields` a point). The kernels search the mesh's working frame: points go there
    /// first (nothing to do for the identity frame, almost every mesh).
    fn run_host(&mut self, points: &[Vec3], output: Output, ids: &mut [u8], values: &mut [f32]) -> VkResult<()> {
        let frame = self.mesh.info.frame;
        if frame.is_identity() {
            return self.run_working(points, output, ids, values);
        }
        let working: Vec<Vec3> = points.par_iter().map(|&p| frame.to_working_f32(p)).collect();
        self.run_working(&working, output, ids, values)
    }

    /// [`Self::run_host`] of points already in the working frame.
    fn run_working(&mut self, points: &[Vec3], output: Output, ids: &mut [u8], values: &mut [f32]) -> VkResult<()> {
        let ordered = self.orders(SAMPLE_HOST, points.len());
        let v = Variant { sample: SAMPLE_HOST, output, record: false, ordered };
        // Each launch is one submission: points in, (ordering,) kernel, answers out, 12 bytes a
        // point in and 4 a word out through the staging buffer: 4M points with the default
        // buffer for ids alone, fewer the more fields (the results buffer never outgrows it).
        let per_point = 12 + 4 * output.words();
        let chunk = self.launch_limit(v.ordered).min(self.dev.round_trip_bytes() / per_point).min(points.len()).max(1);
        self.ensure_io(chunk, output.words())?;
        self.pipeline(v)?;
        let m = output.fields as usize;
        let mut value_chunks = values.chunks_mut(chunk * m.max(1));
        for (pts, res) in points.chunks(chunk).zip(ids.chunks_mut(chunk * 4)) {
            let vals: &mut [f32] = if m == 0 { &mut [] } else { value_chunks.next().expect("m values a point") };
            let params = self.params(pts.len(), 0, 0);
            let io = self.io.as_ref().expect("ensure_io made it");
            let launch = self.launcher.launch(v, io.deferred.as_ref().map(|d| d.buffer));
            let order = io.order.as_ref().filter(|_| v.ordered);
            let outs: &mut [&mut [u8]] = &mut [res, bytemuck::cast_slice_mut(vals)];
            self.dev.round_trip((bytemuck::cast_slice(pts), &io.queries), (&io.results, outs), |r| {
                if let Some(o) = order {
                    o.record(r, &params, v.sample);
                }
                launch.record(r, &params)
            })?;
        }
        Ok(())
    }

    /// Locates the points of `grid` (its axes uploaded) from index `start` through `output`
    /// (ids, or single values, 4 bytes a point into `ids`; the fields' values into `values`),
    /// in launches that each begin at a slab and an index within it (the kernel's index is
    /// u32; a slab has fewer than 2^31 points), of a results buffer no larger than ids alone take.
    fn run_grid(
        &mut self,
        grid: &ImageGrid,
        start: usize,
        output: Output,
        ids: &mut [u8],
        values: &mut [f32],
    ) -> VkResult<()> {
        let v = Variant { sample: SAMPLE_GRID, output, record: false, ordered: false };
        let chunk = (self.launch_limit(false) / output.words()).min(1 << 30).min(ids.len() / 4).max(1);
        self.ensure_io(chunk, output.words())?;
        self.pipeline(v)?;
        let [nx, ny, nz] = grid.dims;
        // Where the axes' residuals start (0: none; `ensure_grid_axes`).
        let with_residuals = self.grid_axes.as_ref().is_some_and(|(g, file_coords, _)| *file_coords && g.f64_points);
        let residuals_at = if with_residuals { (nx + ny + nz) as u32 } else { 0 };
        let m = output.fields as usize;
        let mut value_chunks = values.chunks_mut(chunk * m.max(1));
        let mut first = start;
        for res in ids.chunks_mut(chunk * 4) {
            let len = res.len() / 4;
            let vals: &mut [f32] = if m == 0 { &mut [] } else { value_chunks.next().expect("m values a point") };
            let mut params = self.params(len, first % (nx * ny), 0);
            params.grid = [nx as u32, ny as u32, (first / (nx * ny)) as u32, residuals_at];
            let io = self.io.as_ref().expect("ensure_io made it");
            let launch = self.launcher.launch(v, io.deferred.as_ref().map(|d| d.buffer));
            self.dev.run(|r| launch.record(r, &params))?;
            self.dev.download(&io.results, 0, res)?;
            self.dev.download(&io.results, res.len() as u64, bytemuck::cast_slice_mut(vals))?;
            first += len;
        }
        Ok(())
    }

    /// Runs `n` samples generated in the kernel (`kind` not `Host`) with seed `seed`, and
    /// returns the generated points with their tet ids (-1 outside). For checks: benchmarks
    /// time the same kernels without recording points.
    pub fn locate_generated(&mut self, kind: QueryKind, n: usize, seed: u32) -> VkResult<(Vec<Vec3>, Vec<i32>)> {
        let sample = sample_mode(kind);
        if sample == SAMPLE_HOST {
            return Err(VkError::Mesh("locate_generated needs a query set the kernel generates, not host".into()));
        }
        check_generated_count(n)?;
        if kind == QueryKind::Grid {
            self.ensure_grid_axes(&tetloc_core::queries::grid(&self.mesh, n), false)?;
        }
        // Ordered: the ordering's keys pass records the points, the kernel does not.
        let ordered = self.orders(sample, n);
        let v = Variant { sample, output: Output::IDS, record: !ordered, ordered };
        let chunk = self.launch_limit(ordered).min(n.max(1));
        self.ensure_io(chunk, 1)?;
        self.pipeline(v)?;
        let mut points = vec![[0f32; 3]; n];
        let mut ids = vec![0i32; n];
        for base in (0..n).step_by(chunk) {
            let len = chunk.min(n - base);
            let params = self.generated_params(kind, len, base, n, seed);
            let io = self.io.as_ref().expect("ensure_io made it");
            let launch = self.launcher.launch(v, io.deferred.as_ref().map(|d| d.buffer));
            let order = io.order.as_ref().filter(|_| v.ordered);
            self.dev.run(|r| {
                if let Some(o) = order {
                    o.record(r, &params, v.sample);
                }
                launch.record(r, &params)
            })?;
            self.dev.download(&io.queries, 0, bytemuck::cast_slice_mut(&mut points[base..base + len]))?;
            self.dev.download(&io.results, 0, bytemuck::cast_slice_mut(&mut ids[base..base + len]))?;
        }
        unmark(&mut ids);
        Ok((points, ids))
    }
}

impl VulkanLocator {
    /// The order in which the last ordered launch located its first `n` points (each slot's
    /// index in the launch), or `None` when no ordering buffers exist. For tests.
    pub fn last_order(&mut self, n: usize) -> VkResult<Option<Vec<u32>>> {
        let Some(order) = self.io.as_ref().and_then(|io| io.order.as_ref()) else { return Ok(None) };
        let mut perm = vec![0u32; n];
        self.dev.download(&order.perm, 0, bytemuck::cast_slice_mut(&mut perm))?;
        Ok(Some(perm))
    }

    /// Turns query ordering on or off for the next batches (benchmarks compare both).
    pub fn set_order_queries(&mut self, on: bool) {
        self.opts.order_queries = on;
    }

    /// Whether a batch of `n` points of `sample` mode is ordered before it is located: when
    /// the options say so, for host and random points (centres come in mesh order, already
    /// coherent) and batches large enough to pay for the passes.
    fn orders(&self, sample: i32, n: usize) -> bool {
        self.opts.order_queries && sample != SAMPLE_CENTERS && sample != SAMPLE_GRID && n >= ORDER_MIN_POINTS
    }
}

/// Where a launch's points come from: host points (working frame), or a grid's points from
/// an index (its axes uploaded).
#[derive(Clone, Copy)]
enum At<'a> {
    Host(&'a [Vec3]),
    Grid(&'a ImageGrid, usize),
}

/// Every id answer without its mark (CERTIFY_DELTA: -2 - tet, an answer the kernel did not
/// prove on the file's data).
fn unmark(ids: &mut [i32]) {
    ids.par_iter_mut().for_each(|t| *t = certify::unmarked(*t));
}

/// Meshes from this many tets get larger ordered launches ([`launch_points`]).
const GROWN_LAUNCH_TETS: usize = 1 << 25;
/// Ordered launches over large meshes take at least a point per this many tets...
const TETS_A_LAUNCH_POINT: usize = 8;
/// ...but no more points than this, nor more query-buffer bytes (40 a point: points, results,
/// the ordering's copy, permutation and keys) than 1/32 of the device's memory.
const GROWN_LAUNCH_MAX: usize = 1 << 27;

/// Points a launch takes: `chunk`, except that ordered launches over a mesh of at least
/// `GROWN_LAUNCH_TETS` tets take one point per `TETS_A_LAUNCH_POINT` tets (within the caps
/// above), so that points sorted along the Morton curve lie close enough to share the mesh's
/// pages. Past 16 GiB of mesh, a point that opens pages of its own costs a page walk: jets 1B,
/// bbox points, 0.26 G/s in launches of 4M points, 2.63 G/s in launches of 128M (BENCHMARKS.md).
/// Generated sets take it whole; host batches also stay within one staging round trip. The
/// memory cap is of the device's total, not of what the structure leaves free (1/32: 4.4 GB
/// on a 140 GiB card).
fn launch_points(chunk: usize, n_tets: usize, ordered: bool, memory_bytes: u64) -> usize {
    if !ordered || n_tets < GROWN_LAUNCH_TETS {
        return chunk;
    }
    let by_memory = (memory_bytes / 32 / 40) as usize;
    chunk.max((n_tets / TETS_A_LAUNCH_POINT).min(GROWN_LAUNCH_MAX).min(by_memory))
}

/// Bytes of tets and vertices (as uploaded) from which the paper's random points (a random
/// tet and its vertices a point) are made in tet order (`LocatorOptions::random_in_tet_order`):
/// half the H200's address-translation knee (16 GiB, NOTES.md), since below it the counting
/// sort costs more than it saves. Measured on jets (BENCHMARKS.md), random rate off / on:
/// 62M tets (1.1 GB) 2.57 / 1.91 G/s, 250M (4.6 GB) 1.97 / 1.75, 500M (9.2 GB) 0.63 / 1.67,
/// 1B (18.4 GB) 0.06 / 1.50.
const TET_ORDER_MIN_BYTES: u64 = 8 << 30;

/// Generated samples are numbered by a u32 global index in the kernels.
fn check_generated_count(n: usize) -> VkResult<()> {
    if n > u32::MAX as usize {
        return Err(VkError::Mesh(format!("{n} generated samples: the kernels number them in 32 bits")));
    }
    Ok(())
}

/// SAMPLE_* of a query set: generated in the kernel, or host points.
fn sample_mode(kind: QueryKind) -> i32 {
    match kind {
        QueryKind::Centers => SAMPLE_CENTERS,
        QueryKind::Random => SAMPLE_RANDOM,
        QueryKind::Bbox => SAMPLE_BBOX,
        QueryKind::Host => SAMPLE_HOST,
        QueryKind::Grid => SAMPLE_GRID,
    }
}

/// Refuses what the kernels cannot run: a kernel the device lacks, bad options, too many tets.
fn check(ctx: &Context, mesh: &Mesh, kernel: Kernel, opts: &LocatorOptions) -> VkResult<()> {
    if kernel.needs_ray_tracing() && ctx.rt.is_none() {
        return Err(VkError::NoRayTracing { device: ctx.device_name(), kernel: kernel.name().into() });
    }
    opts.validate().map_err(|e| VkError::Mesh(format!("invalid options: {e}")))?;
    if !ctx.info().nonuniform_buffers {
        return Err(VkError::Mesh(format!(
            "{} lacks shaderStorageBufferArrayNonUniformIndexing, which the kernels use to read arrays split over buffers",
            ctx.device_name()
        )));
    }
    if mesh.n_tets() >= i32::MAX as usize {
        return Err(VkError::Mesh(format!("{} tets: more than 32-bit signed ids can name", mesh.n_tets())));
    }
    Ok(())
}

impl MeshOnDevice {
    /// Uploads vertices and tets; `build_input`: the vertices are also an
    /// acceleration-structure build input (the rt kernels' triangles index them); `pack`: the
    /// tets' vertex ids in as many bits as the vertex count needs (at least the bits given),
    /// where that fits one buffer; `cell_boxes`: the kernel takes one box a cell.
    pub(crate) fn upload(
        dev: &mut Device,
        mesh: &Mesh,
        build_input: bool,
        pack: Option<u32>,
        cell_boxes: bool,
    ) -> VkResult<MeshOnDevice> {
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut point_usage = storage;
        if build_input {
            point_usage |= vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        }
        let points =
            dev.upload_split("mesh points", MemKind::Mesh, point_usage, bytemuck::cast_slice(&mesh.points), 12)?;
        // Same element size and count as the vertices: the same split (POINTS_CHUNK).
        let residuals = match mesh.working_residuals() {
            Some(r) => {
                Some(dev.upload_split("mesh residuals", MemKind::Mesh, storage, bytemuck::cast_slice(&r), 12)?)
            }
            None => None,
        };
        let max_vertex = (mesh.points.len() as u64).saturating_sub(1);
        let fields = 4 * mesh.n_tets() as u64;
        let tet_bits = pack.map_or(0, |min| packed::width(max_vertex, fields, min, dev.device_max_buffer()));
        let tets = if tet_bits > 0 {
            Split::whole(packed::upload(
                dev,
                "mesh tets (packed)",
                MemKind::Mesh,
                bytemuck::cast_slice(&mesh.tets),
                tet_bits,
            )?)
        } else {
            dev.upload_split("mesh tets", MemKind::Mesh, storage, bytemuck::cast_slice(&mesh.tets), 16)?
        };
        let high_order = match &mesh.tet_nodes {
            None => None,
            Some(n) => {
                let def = n.cell_type().def();
                let nodes =
                    dev.upload("higher-order nodes", MemKind::Mesh, storage, bytemuck::cast_slice(n.table()))?;
                let lattice: Vec<u32> =
                    tetloc_core::cell::barycentric_lattice(def).iter().map(|a| u32::from_le_bytes(*a)).collect();
                let lattice =
                    dev.upload("higher-order lattice", MemKind::Mesh, storage, bytemuck::cast_slice(&lattice))?;
                let spec = (n.n_extra() as u32, u32::from(def.order()), !def.interpolates_nodes());
                Some(HighOrder { nodes, lattice, spec })
            }
        };
        let cell_tets = match &mesh.cells {
            Some(c) if cell_boxes => {
                Some(dev.upload("cells' first tets", MemKind::Mesh, storage, bytemuck::cast_slice(&c.first_tets()))?)
            }
            _ => None,
        };
        Ok(MeshOnDevice { points, residuals, tets, tet_bits, high_order, cell_tets })
    }

    /// What a kernel's plan builds from.
    pub(crate) fn inputs<'a>(
        &'a self,
        mesh: &'a Arc<Mesh>,
        mesh_bindings: &'a [Binding],
        opts: &'a LocatorOptions,
        f64: bool,
    ) -> Inputs<'a> {
        let (soft_bvh, rt, pack) = (&opts.soft_bvh, &opts.rt, opts.pack());
        Inputs {
            mesh,
            points: &self.points,
            tets: &self.tets,
            tet_bits: self.tet_bits,
            mesh_bindings,
            soft_bvh,
            rt,
            pack,
            f64,
            cell_boxes: self.cell_tets.is_some(),
        }
    }

    pub(crate) fn bindings(&self, unbound: &Buffer) -> Vec<Binding> {
        let mut b = Binding::split(B_POINTS, B_POINTS_HI, Some(&self.points), unbound).to_vec();
        b.extend(Binding::split(B_RESIDUALS, B_RESIDUALS_HI, self.residuals.as_ref(), unbound));
        b.extend(Binding::split(B_TETS, B_TETS_HI, Some(&self.tets), unbound));
        let ho = self.high_order.as_ref();
        b.push(Binding::buffer(B_HO_NODES, ho.map_or(unbound, |h| &h.nodes)));
        b.push(Binding::buffer(B_HO_LATTICE, ho.map_or(unbound, |h| &h.lattice)));
        b.push(Binding::buffer(B_CELL_TETS, self.cell_tets.as_ref().unwrap_or(unbound)));
        b
    }

    /// The higher-order and cell-box specialization constants (linear tets: the defaults).
    fn spec(&self, spec: Spec) -> Spec {
        let spec = spec
            .set(sc::CELL_BOXES, self.cell_tets.is_some() as u32)
            .set(sc::REFINE_BARY, self.residuals.is_some() as u32);
        match &self.high_order {
            None => spec,
            Some(h) => spec.set(sc::HO_NODES, h.spec.0).set(sc::HO_ORDER, h.spec.1).set(sc::HO_BEZIER, h.spec.2 as u32),
        }
    }

    /// Bytes of the vertices and tets as uploaded: what making the paper's random points reads.
    fn point_and_tet_bytes(&self) -> u64 {
        self.points.parts.iter().chain(&self.tets.parts).map(|b| b.size).sum()
    }
}

impl BatchLocator for VulkanLocator {
    fn name(&self) -> &str {
        self.kernel.name()
    }

    /// The mesh and structure stay on the device; the old fields are unbound and freed, and
    /// the new ones uploaded when a launch asks for them.
    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        if !self.mesh.same_geometry(mesh) {
            return false;
        }
        self.launcher.desc.write(&[Binding::array(B_FIELD, &[], MAX_FIELDS, self.dev.unbound())]);
        self.fields.clear();
        self.mesh = mesh.clone();
        true
    }

    /// f32 points with f32 values: one launch a batch locates each point once and writes its
    /// id and every field's value, interpolated on the device where the tet's nodes were just
    /// read (values on the host read the mesh at random from host memory). Otherwise the
    /// kernels write the ids and the values are computed on the host at those tets
    /// ([`Mesh::values_at_ids64`]: the file's values at f64 barycentrics, the CPU's values
    /// bit for bit, rounded for f32 values). f64 points go to the working frame in f64,
    /// then to f32: a mesh far from the origin is searched as precisely as one at it (the
    /// kernels decide on the working f32 copy); where the working copy or the points are not
    /// the file's data exactly (f32 points included, on a mesh stored in f64 or shifted),
    /// each answer is checked (and the rare wrong one corrected, its values recomputed) on
    /// the host.
    fn query(
        &mut self,
        points: Points<'_>,
        fields: &[&str],
        ids: &mut [i32],
        mut values: Values<'_>,
    ) -> tetloc_core::Result<()> {
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        let mesh = self.mesh.clone();
        let fields = fields.iter().map(|f| mesh.field(f)).collect::<tetloc_core::Result<Vec<_>>>()?;
        if points.is_empty() {
            return Ok(());
        }
        // f32 points, f32 values: the kernel interpolates on the device, in the launch that
        // locates (values on the host: 36 M/s end to end at jets 12M on the H200, 2026-12-05;
        // a launch a field after the ids': 140 M/s; the ids alone: 0.91 G/s).
        if let (Points::F32(p), Values::F32(v)) = (points, &mut values) {
            let names: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
            return self.sample_fields(At::Host(p), &names, ids, v);
        }
        match points {
            Points::F32(p) => {
                self.run_host(p, Output::IDS, bytemuck::cast_slice_mut(ids), &mut [])?;
                self.certify_marked(&|i| p[i].map(f64::from), ids);
            }
            Points::F64(p) => {
                let frame = mesh.info.frame;
                let working: Vec<Vec3> = p.par_iter().map(|&q| frame.to_working(q)).collect();
                self.run_working(&working, Output::IDS, bytemuck::cast_slice_mut(ids), &mut [])?;
                if self.mesh.wants_f64_points() {
                    // The kernel's points: `p` in the working frame, as the host's test rounds them.
                    self.certify_marked(&|i| p[i], ids);
                } else if certify::needs_certifying(&mesh, p) {
                    self.certifier.certify(&mesh, p, ids, false);
                }
            }
        }
        if !fields.is_empty() {
            let wide = points.wide(0..points.len());
            match values {
                Values::F32(v) => mesh.values_at_ids64(&wide, ids, &fields, v),
                Values::F64(v) => mesh.values_at_ids64(&wide, ids, &fields, v),
            }
        }
        Ok(())
    }

    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        Some(self)
    }

    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        Some(self)
    }

    /// The kernel's walk from hints (soft-bvh on tets whose f32 copy is the file's data).
    fn hinted_locator(&mut self) -> Option<&mut dyn tetloc_core::locate::HintedLocator> {
        if self.walks_from_hints() {
            Some(self)
        } else {
            None
        }
    }
}

impl GridSampler for VulkanLocator {
    /// The kernel makes the grid's points itself (the `grid` sample set over the grid's axes):
    /// nothing to upload but the axes, the same points as the host's, and their values as
    /// [`BatchLocator::query`] computes them for f32 points.
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: std::ops::Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> tetloc_core::Result<()> {
        check_sample_lengths(range.len(), fields.len(), ids.len(), values.len())?;
        let slab = grid.dims[0] * grid.dims[1];
        if slab >= 1 << 31 {
            // Beyond the kernel's u32 index within a slab: host points.
            return query_grid_points(self, grid, range, fields, ids, values);
        }
        for f in fields {
            self.mesh.field(f)?;
        }
        if range.is_empty() {
            return Ok(());
        }
        self.ensure_grid_axes(grid, true)?;
        // The ids and every value in one launch a batch, as `query` does for f32 points.
        self.sample_fields(At::Grid(grid, range.start), fields, ids, values)
    }
}

impl LineTracer for VulkanLocator {
    /// RK4 lines on the kernel's stream shader (soft-bvh), `None` elsewhere.
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &tetloc_core::streamline::TraceOptions,
        vector: [&str; 3],
        fields: &[&str],
        progress: &mut dyn FnMut(usize) -> tetloc_core::Result<()>,
    ) -> tetloc_core::Result<Option<Vec<tetloc_core::streamline::Line>>> {
        Ok(self.trace_rk4(seeds, o, vector, fields, progress)?.map(|(lines, _)| lines))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::test_context;

    /// Random points made in tet order (the sample indices sorted by tet first) are the same
    /// points, in launches that start mid-set too, with the same answers, on every kernel.
    #[test]
    fn random_points_in_tet_order_are_the_same_points() {
        let Some(ctx) = test_context("random_points_in_tet_order_are_the_same_points") else { return };
        let mesh = Arc::new(
            Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Agulhas, 12_000, 5), "agulhas").unwrap(),
        );
        let n = 3 * ORDER_MIN_POINTS + 17;
        for kernel in [Kernel::SoftBvh, Kernel::RtBvh, Kernel::RtSharedFaces] {
            let mut answers = vec![];
            for (tet_first, chunk) in [(false, 1 << 22), (true, 1 << 22), (true, ORDER_MIN_POINTS + 5)] {
                let opts =
                    LocatorOptions { random_in_tet_order: Some(tet_first), chunk_points: chunk, ..Default::default() };
                let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, opts).unwrap();
                let got = loc.locate_generated(QueryKind::Random, n, 7).unwrap();
                let order = loc.io.as_ref().and_then(|io| io.order.as_ref()).expect("ordering is on");
                assert_eq!(order.tets_first(SAMPLE_RANDOM), tet_first);
                assert!(got.1.iter().all(|&t| t >= 0), "{kernel}: a random point in a tet was lost");
                answers.push(got);
            }
            assert!(answers[1] == answers[0], "{kernel}: tet order changed the points or answers");
            assert!(answers[2] == answers[0], "{kernel}: tet order in short launches changed them");
        }
        assert_eq!(ctx.validation_errors(), 0);
    }

    /// Launches grow only when ordered over a large mesh, to a point per 8 tets within the caps.
    #[test]
    fn launches_grow_for_ordered_points_over_large_meshes() {
        let (chunk, h200) = (1 << 22, 140u64 << 30);
        assert_eq!(launch_points(chunk, 20_000, true, h200), chunk);
        assert_eq!(launch_points(chunk, 1_000_000_000, false, h200), chunk);
        assert_eq!(launch_points(chunk, 62_000_000, true, h200), 7_750_000);
        // jets 1B: 125M points wanted, 117M given (the memory cap: 140 GiB / 32 / 40 B)
        assert_eq!(launch_points(chunk, 1_000_000_000, true, h200), (h200 / 32 / 40) as usize);
        assert_eq!(launch_points(chunk, 4_000_000_000, true, 1 << 40), GROWN_LAUNCH_MAX);
        // A small device keeps the chunk it was given.
        assert_eq!(launch_points(chunk, 1_000_000_000, true, 1 << 30), chunk);
        // A chunk asked for above the growth stays.
        assert_eq!(launch_points(1 << 28, 1_000_000_000, true, h200), 1 << 28);
    }
}
