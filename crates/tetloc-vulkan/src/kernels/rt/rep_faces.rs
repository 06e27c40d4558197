//! rt-rep-faces: four triangles per tet, each wound to face into its tet, traced with back
//! faces culled, so the closest hit is a face of the tet the ray starts in; the hit shader
//! confirms it with the point-in-tet test and walks to a neighbour when rounding put the hit
//! one tet off (shaders/rt_faces.rchit with REP_FACES).

use super::{crossing_ray, Geometry, RtKernel, CULL_BACK_FACING, OPAQUE};
use crate::kernels::KernelDef;
use crate::shaders;
use rayon::prelude::*;

/// `cell_boxes` false: triangles of tets on any mesh.
pub(crate) const KERNEL: KernelDef =
    super::kernel_def("rt-rep-faces", false, |dev, input| super::plan(&RT_REP_FACES, dev, input));

const RT_REP_FACES: RtKernel = RtKernel {
    geometry: Geometry::Triangles,
    centres: super::tet_centres,
    prims_per_item: 4,
    input_bytes: 48,
    input: |mesh, tets| {
        let tris: Vec<[u32; 12]> = tets.par_iter().map(|&t| inward_faces(mesh.tets[t as usize])).collect();
        bytemuck::cast_slice(&tris).to_vec()
    },
    // The tet of each group of four triangles.
    table: |_, order| bytemuck::cast_slice(order).to_vec(),
    ray_flags: OPAQUE | CULL_BACK_FACING,
    retry_on_miss: true,
    ray: crossing_ray,
    closest_hit: shaders::RT_REP_RCHIT,
    intersection: None,
};

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

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_core::geom::{self, Vec3};

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
}
