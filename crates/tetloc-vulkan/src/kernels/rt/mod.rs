//! The ray-tracing kernels (after Wald et al., "RTX Beyond Ray Tracing"): each puts
//! primitives into acceleration structures — one box per tet or cell (`bvh.rs`), four inward-facing
//! triangles per tet (`rep_faces.rs`) or each unique face once (`shared_faces.rs`) — and
//! traces one short ray per point through its hit group. What they share lives here: the
//! primitive order (Morton order of the items' centres), the tables that map a hit back to a
//! tet, pre-splitting into bottom-level structures of at most `split` primitives each (paper
//! 6.1), and the plan; `accel.rs` builds (and compacts) the structures.

pub(crate) mod accel;
pub(crate) mod bvh;
pub(crate) mod rep_faces;
pub(crate) mod shared_faces;

use super::{Inputs, KernelDef, Plan, Ray};
use crate::device::Device;
use crate::error::{VkError, VkResult};
use crate::interface::{sc, B_ACCEL, B_INSTANCES, B_NEIGHBORS, B_NEIGHBORS_HI, B_PRIMS};
use crate::memory::MemKind;
use crate::pipeline::{Binding, Program, Spec};
use crate::shaders::{self, Shader};
use ash::vk;
use std::ops::Range;
use tetloc_core::bvh::morton;
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::Mesh;

pub use accel::AsReport;

/// Which primitives the acceleration structures hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Geometry {
    /// Boxes (`tetloc_core::bvh::Aabb`), decided by an intersection shader.
    Boxes,
    /// Triangles, as indices into the mesh's vertex buffer.
    Triangles,
}

/// One rt kernel: what it puts into the acceleration structures and how its rays find a tet.
pub(crate) struct RtKernel {
    pub geometry: Geometry,
    /// The items (tets, faces, or a mixed mesh's cells): their centres, which order them
    /// (Morton).
    pub centres: fn(&Mesh) -> Vec<Vec3>,
    /// Primitives per item, and build-input bytes per item.
    pub prims_per_item: usize,
    pub input_bytes: usize,
    /// The build input of items (in this order).
    pub input: fn(&Mesh, &[u32]) -> Vec<u8>,
    /// The primitive table (`B_PRIMS`) of all items in order: how a hit finds its tet (or the
    /// cell whose tets it tests).
    pub table: fn(&Mesh, &[u32]) -> Vec<u8>,
    /// Ray flags (SPIR-V RayFlags), and whether a ray that finds nothing is retried in the
    /// opposite direction.
    pub ray_flags: u32,
    pub retry_on_miss: bool,
    /// The rays for a mesh.
    pub ray: fn(&Mesh) -> Ray,
    /// The hit group.
    pub closest_hit: Shader,
    pub intersection: Option<Shader>,
}

/// The registry entry of rt kernel `name`: ray-tracing pipelines, one box a cell of a mixed
/// mesh where `cell_boxes`, and `plan`, which calls [`plan`] with the kernel's [`RtKernel`].
pub(crate) const fn kernel_def(
    name: &'static str,
    cell_boxes: bool,
    plan: fn(&mut Device, &Inputs) -> VkResult<Plan>,
) -> KernelDef {
    KernelDef { name, ray_tracing: true, cell_boxes, plan }
}

/// SPIR-V ray flags.
pub(crate) const OPAQUE: u32 = 0x1;
pub(crate) const TERMINATE_ON_FIRST_HIT: u32 = 0x4;
pub(crate) const CULL_BACK_FACING: u32 = 0x10;

/// Most tets a hit shader's walk visits when the closest hit's tet is off by rounding.
const WALK_MAX: i32 = 16;

/// A long ray for the face kernels: long enough to cross any tet (a chord is at most its
/// longest edge), in a direction that avoids the axis and diagonal planes of structured meshes.
pub(crate) fn crossing_ray(mesh: &Mesh) -> Ray {
    Ray::new(mesh.info.max_edge_length * 1.01 + super::extent(mesh) * 1e-6, [1.0, 0.754_877_7, 0.569_840_3])
}

/// The centre of every tet, in parallel.
pub(crate) fn tet_centres(mesh: &Mesh) -> Vec<Vec3> {
    use rayon::prelude::*;
    (0..mesh.n_tets()).into_par_iter().map(|t| mesh.tet_center(t)).collect()
}

/// The ray-tracing kernels' options: how their acceleration structures are cut and kept.
#[derive(Clone, Debug, PartialEq)]
pub struct RtOptions {
    /// At most this many primitives (boxes or triangles) per bottom-level acceleration
    /// structure, all under one top-level one; `None`: one structure.
    pub split: Option<usize>,
    /// Compact each bottom-level structure after its build.
    pub compact: bool,
}

impl Default for RtOptions {
    fn default() -> Self {
        RtOptions { split: Some(1 << 20), compact: true }
    }
}

impl RtOptions {
    /// What is wrong with these options, if anything.
    pub fn validate(&self) -> Result<(), String> {
        match self.split {
            Some(0) => Err("rt: split 0 (at least one primitive a structure, or none for one structure)".into()),
            _ => Ok(()),
        }
    }
}

/// Builds kernel `k`'s structures for the mesh and plans its pipelines.
pub(crate) fn plan(k: &RtKernel, dev: &mut Device, input: &Inputs) -> VkResult<Plan> {
    let (mesh, opts) = (input.mesh, input.rt);
    if input.points.parts.len() > 1 {
        return Err(VkError::TooLarge {
            name: "mesh points".into(),
            bytes: mesh.points.len() as u64 * 12,
            limit: dev.max_buffer(),
            what: "one buffer: the ray-tracing kernels build from a single vertex buffer",
        });
    }
    let order = morton::order(&(k.centres)(mesh), mesh.info.bounds_min, mesh.info.bounds_max);
    let prims_total = order.len() * k.prims_per_item;
    if prims_total > u32::MAX as usize {
        return Err(VkError::Mesh(format!("{prims_total} primitives exceed 32-bit primitive indices")));
    }
    let groups = split(order.len(), k.prims_per_item, opts.split);
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let prims = dev.upload("primitive table", MemKind::Structure, storage, &(k.table)(mesh, &order))?;
    let bases: Vec<u32> = groups.iter().map(|g| (g.start * k.prims_per_item) as u32).collect();
    let instance_base = dev.upload("instance base", MemKind::Structure, storage, bytemuck::cast_slice(&bases))?;
    // The face kernels' hit shaders walk through the neighbours (to correct a hit off by
    // rounding), and every kernel settles ties through them (walk.glsl tl_lowest_holder).
    let neighbors =
        dev.upload("tet neighbours", MemKind::Structure, storage, bytemuck::cast_slice(mesh.neighbors()))?;
    let points = &input.points.parts[0];
    let src = accel::Source { k, mesh, points, order: &order, groups: &groups, compact: opts.compact };
    let built = accel::build(dev, src)?;

    let unbound = dev.unbound();
    let [_, neighbors_hi] = Binding::split(B_NEIGHBORS, B_NEIGHBORS_HI, None, unbound);
    let bindings = vec![
        Binding::accel(B_ACCEL, built.tlas.handle),
        Binding::buffer(B_PRIMS, &prims),
        Binding::buffer(B_INSTANCES, &instance_base),
        Binding::buffer(B_NEIGHBORS, &neighbors),
        neighbors_hi,
    ];
    let spec = Spec::default()
        .set(sc::WALK_MAX, WALK_MAX as u32)
        .set(sc::RAY_FLAGS, k.ray_flags)
        .set(sc::RETRY_ON_MISS, k.retry_on_miss as u32);
    let program = |raygen| Program::RayTracing {
        raygen,
        miss: shaders::RT_RMISS,
        closest_hit: k.closest_hit,
        intersection: k.intersection,
    };
    let accel = Some(built.report);
    Ok(Plan {
        _owned: Box::new((built, prims, instance_base, neighbors)),
        bindings,
        spec,
        locate_spec: Spec::default(),
        exact_pass: None,
        locate: program(shaders::RT_RGEN),
        march: program(shaders::MARCH_RGEN),
        // Particles are traced in a compute shader, which cannot trace rays: the batch path.
        stream: None,
        hinted: None,
        march_needs_neighbors: false,
        ray: (k.ray)(mesh),
        accel,
        build_stages: vec![],
    })
}

/// Groups of whole items with at most `split` primitives each (`None`: one group).
fn split(n_items: usize, prims_per_item: usize, split: Option<usize>) -> Vec<Range<usize>> {
    let per_group = match split {
        Some(s) => (s / prims_per_item).max(1),
        None => n_items.max(1),
    };
    (0..n_items).step_by(per_group).map(|s| s..(s + per_group).min(n_items)).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn groups_keep_items_whole() {
        assert_eq!(super::split(10, 4, Some(9)), [0..2, 2..4, 4..6, 6..8, 8..10]);
        assert_eq!(super::split(10, 1, None), vec![(0..10)]);
        assert_eq!(super::split(3, 4, Some(2)), [0..1, 1..2, 2..3], "at least one item a group");
    }
}
