//! rt-bvh: the hardware (or driver) traverses a BVH over one box per tet, or per cell of a
//! mixed mesh (`CELL_BOXES`); an intersection shader runs the point-in-tet test for each box
//! an infinitesimal ray from the point starts in (on a cell's box, for each of its
//! decomposition tets), and the ray ends at the first tet that holds it (shaders/rt_bvh.rint,
//! rt_bvh.rchit); for a point on that tet's boundary, the ray generation shader finds the
//! lowest tet that holds it through the neighbours (the tie rule; common/trace.glsl).

use super::{Geometry, RtKernel, OPAQUE, TERMINATE_ON_FIRST_HIT};
use crate::kernels::{extent, prim_box, prim_boxes, KernelDef, Ray};
use crate::shaders;
use rayon::prelude::*;
use tetloc_core::bvh::Aabb;

/// `cell_boxes` true: one box a cell of a mixed mesh.
pub(crate) const KERNEL: KernelDef = super::kernel_def("rt-bvh", true, |dev, input| super::plan(&RT_BVH, dev, input));

const RT_BVH: RtKernel = RtKernel {
    geometry: Geometry::Boxes,
    centres: |mesh| match mesh.cells {
        None => super::tet_centres(mesh),
        Some(_) => prim_boxes(mesh).iter().map(Aabb::centre).collect(),
    },
    prims_per_item: 1,
    input_bytes: std::mem::size_of::<Aabb>(),
    input: |mesh, prims| {
        let boxes: Vec<Aabb> = prims
            .par_iter()
            .map(|&p| {
                let b = prim_box(mesh, p);
                // One ulp outwards: a point on the box's surface is strictly inside.
                Aabb { min: b.min.map(f32::next_down), max: b.max.map(f32::next_up) }
            })
            .collect();
        bytemuck::cast_slice(&boxes).to_vec()
    },
    // The prim (tet, or cell) of each box.
    table: |_, order| bytemuck::cast_slice(order).to_vec(),
    ray_flags: OPAQUE | TERMINATE_ON_FIRST_HIT,
    retry_on_miss: false,
    // An infinitesimal ray: it only finds the boxes that contain its origin.
    ray: |mesh| Ray::new(extent(mesh) * 1e-10, [1.0, 1.0, 1.0]),
    closest_hit: shaders::RT_BVH_RCHIT,
    intersection: Some(shaders::RT_BVH_RINT),
};
