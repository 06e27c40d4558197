//! Nearest-hit ray queries against surface triangles: core's BVH over the triangles' boxes
//! (`tetloc_core::bvh`, the builder every BVH of tetloc uses), traversed with a slab test
//! per node and Möller–Trumbore per triangle.

use super::TriMesh;
use crate::camera::Ray;
use crate::vec::{cross, dot, normalize, sub, Vec3};
use tetloc_core::bvh::{Aabb, BuildPreset, Bvh, Visitor};

/// A triangle stored as vertex and two edges, ready for intersection.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
}

/// The nearest surface hit along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Unit geometric normal (either orientation).
    pub normal: Vec3,
}

#[derive(Clone, Debug)]
pub struct SurfaceBvh {
    bvh: Bvh,
    tris: Vec<Tri>,
}

impl SurfaceBvh {
    pub fn build(mesh: &TriMesh) -> SurfaceBvh {
        let p = |i: u32| mesh.positions[i as usize];
        let tris: Vec<Tri> = mesh
            .triangles
            .iter()
            .map(|t| {
                let v0 = p(t[0]);
                Tri { v0, e1: sub(p(t[1]), v0), e2: sub(p(t[2]), v0) }
            })
            .collect();
        // The boxes of the triangles as intersected (vertex plus edges), a few a leaf.
        let boxes: Vec<Aabb> = tris.iter().map(bounds_of).collect();
        SurfaceBvh { bvh: Bvh::build_boxes(&boxes, BuildPreset::Fast), tris }
    }

    /// The nearest hit with `t_min < t < t_max`.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut nearest =
            Nearest { ray, inv: ray.dir.map(|d| 1.0 / d), t_min, t_best: t_max, best: None, tris: &self.tris };
        self.bvh.traverse(&mut nearest);
        nearest.best.map(|i| {
            let tri = &self.tris[i as usize];
            Hit { t: nearest.t_best, normal: normalize(cross(tri.e1, tri.e2)).unwrap_or([0.0, 0.0, 1.0]) }
        })
    }
}

/// The traversal's state: enters boxes the ray meets before the nearest hit so far.
struct Nearest<'a> {
    ray: &'a Ray,
    inv: Vec3,
    t_min: f32,
    t_best: f32,
    best: Option<u32>,
    tris: &'a [Tri],
}

impl Visitor for Nearest<'_> {
    fn enter(&mut self, b: &Aabb) -> bool {
        slab_hit(b, self.ray.origin, self.inv, self.t_min, self.t_best)
    }

    fn prim(&mut self, id: u32) -> bool {
        if let Some(t) = hit_tri(&self.tris[id as usize], self.ray, self.t_min, self.t_best) {
            self.t_best = t;
            self.best = Some(id);
        }
        false // the nearest hit needs every box the ray meets
    }
}

fn bounds_of(t: &Tri) -> Aabb {
    let v1: Vec3 = std::array::from_fn(|k| t.v0[k] + t.e1[k]);
    let v2: Vec3 = std::array::from_fn(|k| t.v0[k] + t.e2[k]);
    Aabb {
        min: std::array::from_fn(|k| t.v0[k].min(v1[k]).min(v2[k])),
        max: std::array::from_fn(|k| t.v0[k].max(v1[k]).max(v2[k])),
    }
}

#[inline]
fn slab_hit(n: &Aabb, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> bool {
    let (mut t0, mut t1) = (t_min, t_max);
    for k in 0..3 {
        let (a, b) = ((n.min[k] - o[k]) * inv[k], (n.max[k] - o[k]) * inv[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    t0 <= t1
}

/// Möller–Trumbore, both sides.
#[inline]
fn hit_tri(tri: &Tri, ray: &Ray, t_min: f32, t_max: f32) -> Option<f32> {
    let p = cross(ray.dir, tri.e2);
    let det = dot(tri.e1, p);
    if det.abs() < 1e-30 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(ray.origin, tri.v0);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, tri.e1);
    let v = dot(ray.dir, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot(tri.e2, q) * inv;
    (t > t_min && t < t_max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Random small triangles; the BVH must agree with testing every triangle.
    #[test]
    fn bvh_matches_brute_force() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut m = TriMesh::default();
        for i in 0..500u32 {
            let c: Vec3 = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
            for _ in 0..3 {
                m.positions.push(std::array::from_fn(|k| c[k] + rng.gen_range(-0.1..0.1)));
            }
            m.triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let bvh = SurfaceBvh::build(&m);
        let mut hits = 0;
        for _ in 0..2000 {
            let origin: Vec3 = std::array::from_fn(|_| rng.gen_range(-2.0..2.0));
            let dir = normalize(std::array::from_fn(|_| rng.gen_range(-1.0..1.0))).unwrap();
            let ray = Ray { origin, dir };
            let brute = bvh.tris.iter().filter_map(|t| hit_tri(t, &ray, 0.0, f32::INFINITY)).min_by(f32::total_cmp);
            let got = bvh.intersect(&ray, 0.0, f32::INFINITY).map(|h| h.t);
            assert_eq!(got, brute);
            hits += got.is_some() as usize;
        }
        assert!(hits > 50, "the test rays should hit something ({hits})");
    }

    #[test]
    fn hit_distance_and_normal() {
        let m = TriMesh {
            positions: vec![[0.0, -1.0, -1.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]],
            triangles: vec![[0, 1, 2]],
        };
        let bvh = SurfaceBvh::build(&m);
        let h = bvh.intersect(&Ray { origin: [-3.0, 0.0, 0.0], dir: [1.0, 0.0, 0.0] }, 0.0, 10.0).unwrap();
        assert!((h.t - 3.0).abs() < 1e-6 && h.normal[0].abs() > 0.999);
        assert!(
            bvh.intersect(&Ray { origin: [-3.0, 0.0, 0.0], dir: [1.0, 0.0, 0.0] }, 0.0, 2.5).is_none(),
            "t_max bounds the hit"
        );
    }
}
