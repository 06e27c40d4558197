//! rt-shared-faces: each unique face once, with the tets on its two sides; the closest hit's
//! side the ray comes from names the candidate tet, which the hit shader confirms with the
//! point-in-tet test, walking to a neighbour when rounding put the hit one tet off
//! (shaders/rt_faces.rchit with SHARED_FACES).

use super::{crossing_ray, Geometry, RtKernel, OPAQUE};
use crate::kernels::KernelDef;
use crate::shaders;
use rayon::prelude::*;
use tetloc_core::geom::Vec3;

/// `cell_boxes` false: triangles of tets on any mesh.
pub(crate) const KERNEL: KernelDef =
    super::kernel_def("rt-shared-faces", false, |dev, input| super::plan(&RT_SHARED_FACES, dev, input));

const RT_SHARED_FACES: RtKernel = RtKernel {
    geometry: Geometry::Triangles,
    centres: |mesh| {
        mesh.faces()
            .faces
            .par_iter()
            .map(|f| {
                let p = f.v.map(|i| mesh.points[i as usize]);
                std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0)
            })
            .collect::<Vec<Vec3>>()
    },
    prims_per_item: 1,
    input_bytes: 12,
    input: |mesh, faces| {
        let all = &mesh.faces().faces;
        let tris: Vec<[u32; 3]> = faces.par_iter().map(|&f| all[f as usize].v).collect();
        bytemuck::cast_slice(&tris).to_vec()
    },
    // (front, back) tets of each face (tetloc_core::mesh::Face), -1 for none.
    table: |mesh, order| {
        let faces = &mesh.faces().faces;
        let sides: Vec<[i32; 2]> =
            order.par_iter().map(|&f| [faces[f as usize].front, faces[f as usize].back]).collect();
        bytemuck::cast_slice(&sides).to_vec()
    },
    ray_flags: OPAQUE,
    retry_on_miss: true,
    ray: crossing_ray,
    closest_hit: shaders::RT_SHARED_RCHIT,
    intersection: None,
};
