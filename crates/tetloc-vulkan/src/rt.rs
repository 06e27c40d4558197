//! Acceleration structures for the rt-* kernels: the primitives (one box per tet, four
//! inward-facing triangles per tet, or the unique faces), pre-split into bottom-level
//! structures of at most `split` primitives each (paper 6.1), each compacted after its build,
//! under one top-level structure; plus the tables the shaders use to map hits back to tets.

use crate::context::Context;
use crate::error::{VkError, VkResult};
use crate::memory::{self, Buffer, Commands, Location, MemKind, SharedTracker, Staging};
use ash::vk;
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use std::sync::Arc;
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::Mesh;

/// Which primitives the acceleration structure holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Geometry {
    /// One AABB per tet (rt-bvh).
    Boxes,
    /// Four triangles per tet, each facing into its tet (rt-rep-faces).
    RepFaces,
    /// Each unique face once, with its front and back tets (rt-shared-faces).
    SharedFaces,
}

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
        ctx: &Arc<Context>,
        tracker: &SharedTracker,
        name: String,
        kind: MemKind,
        ty: vk::AccelerationStructureTypeKHR,
        size: u64,
    ) -> VkResult<Accel> {
        let rt = ctx.rt.as_ref().unwrap();
        let usage =
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let buf = Buffer::new(ctx, tracker, name, kind, size, usage, Location::Device)?;
        let info = vk::AccelerationStructureCreateInfoKHR::default().buffer(buf.buffer).size(size).ty(ty);
        // SAFETY: the buffer is large enough and has the storage usage.
        let handle = unsafe { rt.accel.create_acceleration_structure(&info, None) }
            .map_err(VkError::vk("vkCreateAccelerationStructureKHR"))?;
        let address = unsafe {
            rt.accel.get_acceleration_structure_device_address(
                &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(handle),
            )
        };
        Ok(Accel { ctx: ctx.clone(), handle, address, buf })
    }

    pub fn bytes(&self) -> u64 {
        self.buf.size
    }
}

impl Drop for Accel {
    fn drop(&mut self) {
        // SAFETY: no pending work uses it; the buffer is dropped after the handle.
        unsafe { self.ctx.rt.as_ref().unwrap().accel.destroy_acceleration_structure(self.handle, None) };
    }
}

/// Everything an rt kernel binds besides the mesh.
pub(crate) struct RtStructure {
    pub tlas: Accel,
    _blas: Vec<Accel>,
    /// Primitive table: tet per box / per 4 triangles (u32), or (front, back) per face (i32 x 2).
    pub prims: Buffer,
    /// First primitive-table index of each instance (bottom-level structure).
    pub instance_base: Buffer,
    /// Tet neighbours across each face (face kernels: the walk after a rounding miss).
    pub neighbors: Option<Buffer>,
    pub report: AsReport,
}

/// 30-bit Morton code of a point normalised to the box.
fn morton(p: Vec3, lo: Vec3, scale: Vec3) -> u32 {
    let spread = |v: u32| {
        let mut x = v & 0x3ff;
        x = (x | x << 16) & 0x0300_00ff;
        x = (x | x << 8) & 0x0300_f00f;
        x = (x | x << 4) & 0x030c_30c3;
        (x | x << 2) & 0x0924_9249
    };
    let q = |k: usize| (((p[k] - lo[k]) * scale[k]) as u32).min(1023);
    spread(q(0)) | spread(q(1)) << 1 | spread(q(2)) << 2
}

/// Indices 0..centroids.len() in Morton order of the centroids: spatially coherent groups.
fn morton_order(centroids: &[Vec3], lo: Vec3, hi: Vec3) -> Vec<u32> {
    let scale: Vec3 = std::array::from_fn(|k| if hi[k] > lo[k] { 1023.0 / (hi[k] - lo[k]) } else { 0.0 });
    let mut keyed: Vec<(u32, u32)> =
        centroids.par_iter().enumerate().map(|(i, &c)| (morton(c, lo, scale), i as u32)).collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The four faces of canonical tet `t` as triangles wound so that Vulkan sees them
/// front-facing from inside the tet: a hit is front-facing when the ray travels against
/// n = (v1 - v0) x (v2 - v0) (spec, "Ray Face Culling"), so n must point into the tet.
fn inward_faces(t: [u32; 4]) -> [u32; 12] {
    // Where orient(face, x) > 0 inside the tet, the tet is on the side n points *away*
    // from (mesh::Face), so the winding is flipped.
    let mut out = [0u32; 12];
    for (i, (f, sign)) in tetloc_core::geom::ascending_faces(t).iter().enumerate() {
        let tri = if *sign > 0.0 { [f[0], f[2], f[1]] } else { *f };
        out[3 * i..3 * i + 3].copy_from_slice(&tri);
    }
    out
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

/// A bottom-level build input: the geometry description of one group of primitives.
fn geometry<'a>(kind: Geometry, input: u64, points: u64, n_points: u32) -> vk::AccelerationStructureGeometryKHR<'a> {
    let data = match kind {
        Geometry::Boxes => vk::AccelerationStructureGeometryDataKHR {
            aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                .data(vk::DeviceOrHostAddressConstKHR { device_address: input })
                .stride(std::mem::size_of::<vk::AabbPositionsKHR>() as u64),
        },
        Geometry::RepFaces | Geometry::SharedFaces => vk::AccelerationStructureGeometryDataKHR {
            triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: points })
                .vertex_stride(12)
                .max_vertex(n_points.saturating_sub(1))
                .index_type(vk::IndexType::UINT32)
                .index_data(vk::DeviceOrHostAddressConstKHR { device_address: input }),
        },
    };
    vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(if kind == Geometry::Boxes {
            vk::GeometryTypeKHR::AABBS
        } else {
            vk::GeometryTypeKHR::TRIANGLES
        })
        .geometry(data)
        .flags(vk::GeometryFlagsKHR::OPAQUE)
}

#[derive(Clone, Copy, Pod, Zeroable)]
#[repr(C)]
struct Aabb([f32; 6]);

/// Builds the structure for `kind` over the mesh. `points` is the mesh's vertex buffer
/// (created with build-input usage); `split` caps primitives per bottom-level structure.
#[allow(clippy::too_many_arguments)]
pub(crate) fn build(
    ctx: &Arc<Context>,
    tracker: &SharedTracker,
    staging: &mut Staging,
    cmds: &mut Commands,
    mesh: &Mesh,
    points: &Buffer,
    kind: Geometry,
    split: Option<usize>,
    compact: bool,
) -> VkResult<RtStructure> {
    let rt = ctx.rt.as_ref().unwrap();
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;

    // Primitive order (Morton order of centroids), the primitive table, and the per-item
    // build inputs: 1 box or 4 triangles per tet, or 1 triangle per face.
    let (order, table_bytes, prims_per_item): (Vec<u32>, Vec<u8>, usize) = match kind {
        Geometry::Boxes | Geometry::RepFaces => {
            let centers: Vec<Vec3> = (0..mesh.n_tets()).into_par_iter().map(|t| mesh.tet_center(t)).collect();
            let order = morton_order(&centers, lo, hi);
            let table = bytemuck::cast_slice(&order).to_vec();
            (order, table, if kind == Geometry::Boxes { 1 } else { 4 })
        }
        Geometry::SharedFaces => {
            let faces = &mesh.faces().faces;
            let centers: Vec<Vec3> = faces
                .par_iter()
                .map(|f| {
                    let p = f.v.map(|i| mesh.points[i as usize]);
                    std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0)
                })
                .collect();
            let order = morton_order(&centers, lo, hi);
            let table: Vec<[i32; 2]> =
                order.par_iter().map(|&f| [faces[f as usize].front, faces[f as usize].back]).collect();
            (order, bytemuck::cast_slice(&table).to_vec(), 1)
        }
    };
    let n_items = order.len();
    let prims_total = n_items * prims_per_item;
    if prims_total > u32::MAX as usize {
        return Err(VkError::Mesh(format!("{prims_total} primitives exceed 32-bit primitive indices")));
    }
    let items_per_group = match split {
        Some(s) => (s / prims_per_item).max(1),
        None => n_items.max(1),
    };
    let groups: Vec<std::ops::Range<usize>> =
        (0..n_items).step_by(items_per_group).map(|s| s..(s + items_per_group).min(n_items)).collect();

    let prims = memory::device_buffer_with(
        ctx,
        tracker,
        staging,
        cmds,
        "primitive table",
        MemKind::Structure,
        storage,
        &table_bytes,
    )?;
    drop(table_bytes);
    let bases: Vec<u32> = groups.iter().map(|g| (g.start * prims_per_item) as u32).collect();
    let instance_base = memory::device_buffer_with(
        ctx,
        tracker,
        staging,
        cmds,
        "instance base",
        MemKind::Structure,
        storage,
        bytemuck::cast_slice(&bases),
    )?;
    let neighbors = match kind {
        Geometry::Boxes => None,
        _ => {
            let nb = mesh.neighbors();
            Some(memory::device_buffer_with(
                ctx,
                tracker,
                staging,
                cmds,
                "tet neighbours",
                MemKind::Structure,
                storage,
                bytemuck::cast_slice(nb),
            )?)
        }
    };

    // The build input of one group, as bytes.
    let input_of = |g: &std::ops::Range<usize>| -> Vec<u8> {
        let items = &order[g.clone()];
        match kind {
            Geometry::Boxes => {
                let boxes: Vec<Aabb> = items
                    .par_iter()
                    .map(|&t| {
                        let (l, h) = tetloc_core::geom::tet_bounds(mesh.tets[t as usize], &mesh.points);
                        // One ulp outwards: a point on the box's surface is strictly inside.
                        Aabb([
                            l[0].next_down(),
                            l[1].next_down(),
                            l[2].next_down(),
                            h[0].next_up(),
                            h[1].next_up(),
                            h[2].next_up(),
                        ])
                    })
                    .collect();
                bytemuck::cast_slice(&boxes).to_vec()
            }
            Geometry::RepFaces => {
                let tris: Vec<[u32; 12]> = items.par_iter().map(|&t| inward_faces(mesh.tets[t as usize])).collect();
                bytemuck::cast_slice(&tris).to_vec()
            }
            Geometry::SharedFaces => {
                let faces = &mesh.faces().faces;
                let tris: Vec<[u32; 3]> = items.par_iter().map(|&f| faces[f as usize].v).collect();
                bytemuck::cast_slice(&tris).to_vec()
            }
        }
    };
    let input_bytes_per_item = match kind {
        Geometry::Boxes => 24,
        Geometry::RepFaces => 48,
        Geometry::SharedFaces => 12,
    };

    // Sizes of every bottom-level build, so that scratch is allocated once.
    let mut flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
    if compact {
        flags |= vk::BuildAccelerationStructureFlagsKHR::ALLOW_COMPACTION;
    }
    let blas_sizes: Vec<vk::AccelerationStructureBuildSizesInfoKHR> = groups
        .iter()
        .map(|g| {
            let geo = [geometry(kind, 0, 0, mesh.points.len() as u32)];
            let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                .flags(flags)
                .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                .geometries(&geo);
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            let count = [(g.len() * prims_per_item) as u32];
            // SAFETY: size query with a valid geometry description.
            unsafe {
                rt.accel.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    &info,
                    &count,
                    &mut sizes,
                )
            };
            sizes
        })
        .collect();
    let scratch_align = rt.scratch_alignment.max(1) as u64;
    let scratch_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let max_scratch = blas_sizes.iter().map(|s| s.build_scratch_size).max().unwrap_or(0);
    let scratch = Buffer::new(
        ctx,
        tracker,
        "build scratch",
        MemKind::Scratch,
        max_scratch + scratch_align,
        scratch_usage,
        Location::Device,
    )?;
    let scratch_addr = align_up(scratch.address, scratch_align);
    let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        | vk::BufferUsageFlags::TRANSFER_DST;
    let max_items = groups.iter().map(|g| g.len()).max().unwrap_or(0);
    let input = Buffer::new(
        ctx,
        tracker,
        "build input",
        MemKind::Scratch,
        (max_items * input_bytes_per_item) as u64,
        input_usage,
        Location::Device,
    )?;

    // SAFETY (whole block): all handles are alive; each submission completes before the
    // next starts (Commands::run waits), and every build input outlives its build.
    let query_pool = unsafe {
        ctx.device.create_query_pool(
            &vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR)
                .query_count(1),
            None,
        )
    }
    .map_err(VkError::vk("vkCreateQueryPool"))?;
    struct PoolGuard<'a>(&'a ash::Device, vk::QueryPool);
    impl Drop for PoolGuard<'_> {
        fn drop(&mut self) {
            // SAFETY: no pending work uses the pool.
            unsafe { self.0.destroy_query_pool(self.1, None) };
        }
    }
    let _pool_guard = PoolGuard(&ctx.device, query_pool);

    let mut blas = Vec::with_capacity(groups.len());
    let mut report = AsReport { blas_count: groups.len(), primitives: prims_total, ..Default::default() };
    for (gi, (g, sizes)) in groups.iter().zip(&blas_sizes).enumerate() {
        staging.upload(cmds, &input, 0, &input_of(g))?;
        let built_kind = if compact { MemKind::Scratch } else { MemKind::Structure };
        let built = Accel::new(
            ctx,
            tracker,
            format!("blas {gi}"),
            built_kind,
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            sizes.acceleration_structure_size,
        )?;
        report.blas_bytes_built += built.bytes();
        let geo = [geometry(kind, input.address, points.address, mesh.points.len() as u32)];
        let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
            .flags(flags)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .dst_acceleration_structure(built.handle)
            .geometries(&geo)
            .scratch_data(vk::DeviceOrHostAddressKHR { device_address: scratch_addr });
        let range =
            [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count((g.len() * prims_per_item) as u32)];
        cmds.run(|dev, cmd| unsafe {
            rt.accel.cmd_build_acceleration_structures(cmd, &[info], &[&range]);
            if compact {
                let barrier = vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
                    .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR);
                dev.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::DependencyFlags::empty(),
                    &[barrier],
                    &[],
                    &[],
                );
                // Reset and write the query in the same submission, before anyone waits on it.
                dev.cmd_reset_query_pool(cmd, query_pool, 0, 1);
                rt.accel.cmd_write_acceleration_structures_properties(
                    cmd,
                    &[built.handle],
                    vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR,
                    query_pool,
                    0,
                );
            }
        })?;
        if !compact {
            report.blas_bytes += built.bytes();
            blas.push(built);
            continue;
        }
        // The submission has completed (fence waited), so the result is available: no WAIT flag.
        let mut compacted = [0u64; 1];
        unsafe { ctx.device.get_query_pool_results(query_pool, 0, &mut compacted, vk::QueryResultFlags::TYPE_64) }
            .map_err(VkError::vk("vkGetQueryPoolResults"))?;
        let size = compacted[0].clamp(1, built.bytes());
        let small = Accel::new(
            ctx,
            tracker,
            format!("blas {gi}"),
            MemKind::Structure,
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            size,
        )?;
        let copy = vk::CopyAccelerationStructureInfoKHR::default()
            .src(built.handle)
            .dst(small.handle)
            .mode(vk::CopyAccelerationStructureModeKHR::COMPACT);
        cmds.run(|_, cmd| unsafe { rt.accel.cmd_copy_acceleration_structure(cmd, &copy) })?;
        report.blas_bytes += small.bytes();
        blas.push(small);
    }
    drop(input);

    // The top level: one identity-transform instance per bottom-level structure.
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
    // SAFETY: AccelerationStructureInstanceKHR is a plain 64-byte repr(C) struct.
    let instance_bytes = unsafe {
        std::slice::from_raw_parts(instances.as_ptr() as *const u8, std::mem::size_of_val(instances.as_slice()))
    };
    let instance_buf = memory::device_buffer_with(
        ctx,
        tracker,
        staging,
        cmds,
        "instances",
        MemKind::Scratch,
        input_usage,
        instance_bytes,
    )?;
    let tl_geo = [vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::INSTANCES)
        .geometry(vk::AccelerationStructureGeometryDataKHR {
            instances: vk::AccelerationStructureGeometryInstancesDataKHR::default()
                .data(vk::DeviceOrHostAddressConstKHR { device_address: instance_buf.address }),
        })];
    let mut tl_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&tl_geo);
    let mut tl_sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    let count = [instances.len() as u32];
    unsafe {
        rt.accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &tl_info,
            &count,
            &mut tl_sizes,
        )
    };
    let tlas = Accel::new(
        ctx,
        tracker,
        "tlas".into(),
        MemKind::Structure,
        vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        tl_sizes.acceleration_structure_size,
    )?;
    let tl_scratch = Buffer::new(
        ctx,
        tracker,
        "tlas scratch",
        MemKind::Scratch,
        tl_sizes.build_scratch_size + scratch_align,
        scratch_usage,
        Location::Device,
    )?;
    tl_info = tl_info
        .dst_acceleration_structure(tlas.handle)
        .scratch_data(vk::DeviceOrHostAddressKHR { device_address: align_up(tl_scratch.address, scratch_align) });
    let tl_range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(instances.len() as u32)];
    cmds.run(|_, cmd| unsafe { rt.accel.cmd_build_acceleration_structures(cmd, &[tl_info], &[&tl_range]) })?;
    report.tlas_bytes = tlas.bytes();
    drop((tl_scratch, instance_buf, scratch));
    Ok(RtStructure { tlas, _blas: blas, prims, instance_base, neighbors, report })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_core::geom;

    /// Each inward triangle's normal points at the opposite vertex, for both canonical orders.
    #[test]
    fn rep_faces_point_inwards() {
        let pts: Vec<Vec3> = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.2, -1.0]];
        for ids in [[0, 1, 2, 3], [0, 1, 2, 4], [1, 2, 3, 4]] {
            let (t, _) = geom::canonical_tet(ids, &pts);
            let tris = inward_faces(t);
            for i in 0..4 {
                let tri = [tris[3 * i], tris[3 * i + 1], tris[3 * i + 2]];
                let opposite = *t.iter().find(|v| !tri.contains(v)).unwrap();
                let [a, b, c] = tri.map(|v| pts[v as usize]);
                let sub = |x: Vec3, y: Vec3| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
                let (u, v) = (sub(b, a), sub(c, a));
                let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
                let w = sub(pts[opposite as usize], a);
                assert!(n[0] * w[0] + n[1] * w[1] + n[2] * w[2] > 0.0, "tet {t:?} face {i}");
            }
        }
    }

    #[test]
    fn morton_order_is_a_permutation() {
        let c: Vec<Vec3> = (0..1000).map(|i| [(i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32]).collect();
        let mut o = morton_order(&c, [0.0; 3], [9.0; 3]);
        assert_eq!(o[0], 0);
        o.sort();
        assert!(o.iter().enumerate().all(|(i, &v)| i as u32 == v));
    }
}
