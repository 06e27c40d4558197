//! Acceleration structures: one bottom-level structure per group of items (the kernel's
//! primitives, uploaded group by group through one build-input buffer), each compacted after
//! its build when asked, under one top-level structure of identity instances.

use super::{Geometry, RtKernel};
use crate::context::Context;
use crate::device::Device;
use crate::error::{VkError, VkResult};
use crate::memory::{Buffer, BufferDesc, MemKind};
use ash::vk;
use std::ops::Range;
use std::sync::Arc;
use tetloc_core::mesh::Mesh;

/// Acceleration-structure sizes, like the paper's Table 2 rows.
#[derive(Clone, Copy, Debug, Default)]
pub struct AsReport {
    /// Bottom-level structures (1 without pre-splitting).
    pub blas_count: usize,
    /// Primitives: boxes or triangles.
    pub primitives: usize,
    /// Bottom-level bytes as built, before compaction.
    pub blas_bytes_built: u64,
    /// Bottom-level bytes resident (after compaction when it is on).
    pub blas_bytes: u64,
    pub tlas_bytes: u64,
}

/// An acceleration structure and the buffer that holds it.
pub(crate) struct Accel {
    ctx: Arc<Context>,
    pub handle: vk::AccelerationStructureKHR,
    pub address: u64,
    buf: Buffer,
}

impl Accel {
    fn new(
        dev: &mut Device,
        name: String,
        kind: MemKind,
        ty: vk::AccelerationStructureTypeKHR,
        size: u64,
    ) -> VkResult<Accel> {
        let ctx = dev.ctx().clone();
        let rt = ctx.rt.as_ref().expect("acceleration structure on a device without ray tracing");
        let usage =
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let buf = dev.create_buffer(BufferDesc::device(kind, size, usage), name, None)?;
        let info = vk::AccelerationStructureCreateInfoKHR::default().buffer(buf.buffer).size(size).ty(ty);
        // SAFETY: the buffer is large enough and has the storage usage.
        let handle = unsafe { rt.accel.create_acceleration_structure(&info, None) }
            .map_err(VkError::vk("vkCreateAccelerationStructureKHR"))?;
        let address_info = vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(handle);
        // SAFETY: the structure was just created on this device.
        let address = unsafe { rt.accel.get_acceleration_structure_device_address(&address_info) };
        Ok(Accel { ctx, handle, address, buf })
    }

    pub fn bytes(&self) -> u64 {
        self.buf.size
    }
}

impl Drop for Accel {
    fn drop(&mut self) {
        let rt = self.ctx.rt.as_ref().expect("acceleration structures exist only with ray tracing");
        // SAFETY: no pending work uses it (every submission is waited for); the buffer is
        // dropped after the handle.
        unsafe { rt.accel.destroy_acceleration_structure(self.handle, None) };
    }
}

/// The structures of one rt kernel.
pub(crate) struct Built {
    pub tlas: Accel,
    _blas: Vec<Accel>,
    pub report: AsReport,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

/// A bottom-level build input: the geometry description of one group of primitives, at
/// device addresses `input` (boxes or indices) and `points` (the vertex buffer).
fn geometry<'a>(kind: Geometry, input: u64, points: u64, n_points: u32) -> vk::AccelerationStructureGeometryKHR<'a> {
    let (ty, data) = match kind {
        Geometry::Boxes => (
            vk::GeometryTypeKHR::AABBS,
            vk::AccelerationStructureGeometryDataKHR {
                aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                    .data(vk::DeviceOrHostAddressConstKHR { device_address: input })
                    .stride(std::mem::size_of::<vk::AabbPositionsKHR>() as u64),
            },
        ),
        Geometry::Triangles => (
            vk::GeometryTypeKHR::TRIANGLES,
            vk::AccelerationStructureGeometryDataKHR {
                triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                    .vertex_format(vk::Format::R32G32B32_SFLOAT)
                    .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: points })
                    .vertex_stride(12)
                    .max_vertex(n_points.saturating_sub(1))
                    .index_type(vk::IndexType::UINT32)
                    .index_data(vk::DeviceOrHostAddressConstKHR { device_address: input }),
            },
        ),
    };
    vk::AccelerationStructureGeometryKHR::default().geometry_type(ty).geometry(data).flags(vk::GeometryFlagsKHR::OPAQUE)
}

/// What kernel `k`'s structures are built from: a bottom-level one per group of `order` (the
/// items in primitive order), compacted when `compact`. `points` is the mesh's vertex buffer
/// (created with build-input usage).
#[derive(Clone, Copy)]
pub(crate) struct Source<'a> {
    pub k: &'a RtKernel,
    pub mesh: &'a Mesh,
    pub points: &'a Buffer,
    pub order: &'a [u32],
    pub groups: &'a [Range<usize>],
    pub compact: bool,
}

/// Builds the structures of `src`: the bottom levels and the top level over them.
pub(crate) fn build(dev: &mut Device, src: Source) -> VkResult<Built> {
    let (blas, blas_bytes_built) = build_bottom(dev, src)?;
    let tlas = build_top(dev, &blas)?;
    let report = AsReport {
        blas_count: blas.len(),
        primitives: src.order.len() * src.k.prims_per_item,
        blas_bytes_built,
        blas_bytes: blas.iter().map(Accel::bytes).sum(),
        tlas_bytes: tlas.bytes(),
    };
    Ok(Built { tlas, _blas: blas, report })
}

/// A query pool for compacted sizes, destroyed on drop.
struct SizeQuery<'a> {
    dev: &'a ash::Device,
    pool: vk::QueryPool,
}

impl<'a> SizeQuery<'a> {
    fn new(dev: &'a ash::Device) -> VkResult<SizeQuery<'a>> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR)
            .query_count(1);
        // SAFETY: plain query-pool creation; destroyed in Drop.
        let pool = unsafe { dev.create_query_pool(&info, None) }.map_err(VkError::vk("vkCreateQueryPool"))?;
        Ok(SizeQuery { dev, pool })
    }
}

impl Drop for SizeQuery<'_> {
    fn drop(&mut self) {
        // SAFETY: no pending work uses the pool (every submission is waited for).
        unsafe { self.dev.destroy_query_pool(self.pool, None) };
    }
}

/// The bottom-level structures, one per group, and their bytes as built (before compaction).
fn build_bottom(dev: &mut Device, src: Source) -> VkResult<(Vec<Accel>, u64)> {
    let Source { k, mesh, points, order, groups, compact } = src;
    let ctx = dev.ctx().clone();
    let rt = ctx.rt.as_ref().expect("acceleration structures on a device without ray tracing");
    let n_points = mesh.points.len() as u32;
    let mut flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
    if compact {
        flags |= vk::BuildAccelerationStructureFlagsKHR::ALLOW_COMPACTION;
    }
    fn build_info<'a>(
        flags: vk::BuildAccelerationStructureFlagsKHR,
        geo: &'a [vk::AccelerationStructureGeometryKHR<'a>],
    ) -> vk::AccelerationStructureBuildGeometryInfoKHR<'a> {
        vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
            .flags(flags)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(geo)
    }
    // Sizes of every build first, so that scratch is allocated once.
    let sizes: Vec<vk::AccelerationStructureBuildSizesInfoKHR> = groups
        .iter()
        .map(|g| {
            let geo = [geometry(k.geometry, 0, 0, n_points)];
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            let count = [(g.len() * k.prims_per_item) as u32];
            let device_build = vk::AccelerationStructureBuildTypeKHR::DEVICE;
            // SAFETY: a size query with a valid geometry description.
            unsafe {
                rt.accel.get_acceleration_structure_build_sizes(
                    device_build,
                    &build_info(flags, &geo),
                    &count,
                    &mut sizes,
                )
            };
            sizes
        })
        .collect();
    let scratch_align = rt.scratch_alignment.max(1) as u64;
    let scratch_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let max_scratch = sizes.iter().map(|s| s.build_scratch_size).max().unwrap_or(0);
    let scratch_desc = BufferDesc::device(MemKind::Scratch, max_scratch + scratch_align, scratch_usage);
    let scratch = dev.create_buffer(scratch_desc, "build scratch", None)?;
    let scratch_addr = align_up(scratch.address, scratch_align);
    let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        | vk::BufferUsageFlags::TRANSFER_DST;
    let max_items = groups.iter().map(|g| g.len()).max().unwrap_or(0);
    let input_desc = BufferDesc::device(MemKind::Scratch, (max_items * k.input_bytes) as u64, input_usage);
    let input = dev.create_buffer(input_desc, "build input", None)?;
    let query = SizeQuery::new(&ctx.device)?;

    let mut blas = Vec::with_capacity(groups.len());
    let mut bytes_built = 0;
    for (gi, (g, sizes)) in groups.iter().zip(&sizes).enumerate() {
        dev.write(&input, 0, &(k.input)(mesh, &order[g.clone()]))?;
        let built_kind = if compact { MemKind::Scratch } else { MemKind::Structure };
        let bottom = vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL;
        let built = Accel::new(dev, format!("blas {gi}"), built_kind, bottom, sizes.acceleration_structure_size)?;
        bytes_built += built.bytes();
        let geo = [geometry(k.geometry, input.address, points.address, n_points)];
        let info = build_info(flags, &geo)
            .dst_acceleration_structure(built.handle)
            .scratch_data(vk::DeviceOrHostAddressKHR { device_address: scratch_addr });
        let range =
            [vk::AccelerationStructureBuildRangeInfoKHR::default()
                .primitive_count((g.len() * k.prims_per_item) as u32)];
        // SAFETY: every handle and build input is alive until the submission completes (run
        // waits); the query is reset and written in the same submission, before anyone waits on it.
        dev.run(|r| unsafe {
            rt.accel.cmd_build_acceleration_structures(r.cmd, &[info], &[&range]);
            if compact {
                r.memory_barrier(
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR,
                );
                r.dev.cmd_reset_query_pool(r.cmd, query.pool, 0, 1);
                rt.accel.cmd_write_acceleration_structures_properties(
                    r.cmd,
                    &[built.handle],
                    vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR,
                    query.pool,
                    0,
                );
            }
        })?;
        blas.push(if compact { compacted(dev, built, &query, gi)? } else { built });
    }
    Ok((blas, bytes_built))
}

/// A compacted copy of `built`, whose compacted size the completed build wrote to `query`.
fn compacted(dev: &mut Device, built: Accel, query: &SizeQuery, gi: usize) -> VkResult<Accel> {
    let ctx = dev.ctx().clone();
    let rt = ctx.rt.as_ref().expect("acceleration structures on a device without ray tracing");
    // The submission has completed (fence waited), so the result is available: no WAIT flag.
    let mut size = [0u64; 1];
    // SAFETY: the query was written by the completed submission.
    unsafe { ctx.device.get_query_pool_results(query.pool, 0, &mut size, vk::QueryResultFlags::TYPE_64) }
        .map_err(VkError::vk("vkGetQueryPoolResults"))?;
    let size = size[0].clamp(1, built.bytes());
    let bottom = vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL;
    let small = Accel::new(dev, format!("blas {gi}"), MemKind::Structure, bottom, size)?;
    let copy = vk::CopyAccelerationStructureInfoKHR::default()
        .src(built.handle)
        .dst(small.handle)
        .mode(vk::CopyAccelerationStructureModeKHR::COMPACT);
    // SAFETY: both structures are alive until the copy completes (run waits).
    dev.run(|r| unsafe { rt.accel.cmd_copy_acceleration_structure(r.cmd, &copy) })?;
    Ok(small)
}

/// The top level: one identity-transform instance per bottom-level structure.
fn build_top(dev: &mut Device, blas: &[Accel]) -> VkResult<Accel> {
    let ctx = dev.ctx().clone();
    let rt = ctx.rt.as_ref().expect("acceleration structures on a device without ray tracing");
    let instances: Vec<vk::AccelerationStructureInstanceKHR> = blas
        .iter()
        .map(|b| vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR { matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0] },
            instance_custom_index_and_mask: vk::Packed24_8::new(0, 0xff),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                0,
                vk::GeometryInstanceFlagsKHR::FORCE_OPAQUE.as_raw() as u8,
            ),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR { device_handle: b.address },
        })
        .collect();
    // SAFETY: AccelerationStructureInstanceKHR is a plain 64-byte repr(C) struct without padding.
    let instance_bytes = unsafe {
        std::slice::from_raw_parts(instances.as_ptr() as *const u8, std::mem::size_of_val(instances.as_slice()))
    };
    let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        | vk::BufferUsageFlags::TRANSFER_DST;
    let instance_buf = dev.upload("instances", MemKind::Scratch, input_usage, instance_bytes)?;
    let geo = [vk::AccelerationStructureGeometryKHR::default().geometry_type(vk::GeometryTypeKHR::INSTANCES).geometry(
        vk::AccelerationStructureGeometryDataKHR {
            instances: vk::AccelerationStructureGeometryInstancesDataKHR::default()
                .data(vk::DeviceOrHostAddressConstKHR { device_address: instance_buf.address }),
        },
    )];
    let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&geo);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    let count = [instances.len() as u32];
    // SAFETY: a size query with a valid geometry description.
    unsafe {
        rt.accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &info,
            &count,
            &mut sizes,
        )
    };
    let top = vk::AccelerationStructureTypeKHR::TOP_LEVEL;
    let tlas = Accel::new(dev, "tlas".into(), MemKind::Structure, top, sizes.acceleration_structure_size)?;
    let scratch_align = rt.scratch_alignment.max(1) as u64;
    let scratch_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let scratch_desc = BufferDesc::device(MemKind::Scratch, sizes.build_scratch_size + scratch_align, scratch_usage);
    let scratch = dev.create_buffer(scratch_desc, "tlas scratch", None)?;
    let info = info
        .dst_acceleration_structure(tlas.handle)
        .scratch_data(vk::DeviceOrHostAddressKHR { device_address: align_up(scratch.address, scratch_align) });
    let range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(instances.len() as u32)];
    // SAFETY: the instances, the bottom levels and the scratch are alive until the build
    // completes (run waits).
    dev.run(|r| unsafe { rt.accel.cmd_build_acceleration_structures(r.cmd, &[info], &[&range]) })?;
    Ok(tlas)
}
