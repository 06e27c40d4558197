//! A BVH over surface triangles for nearest-hit ray queries: median splits on the widest
//! centroid axis, a few triangles a leaf, Möller–Trumbore intersection.

use super::TriMesh;
use crate::camera::Ray;
use crate::vec::{cross, dot, normalize, sub, Vec3};

const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3,
    max: Vec3,
    /// Leaf: first triangle in `tris`; interior: index of the right child (left is next).
    first: u32,
    /// Triangles in a leaf, 0 for an interior node.
    count: u32,
}

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
    nodes: Vec<Node>,
    tris: Vec<Tri>,
}

impl SurfaceBvh {
    pub fn build(mesh: &TriMesh) -> SurfaceBvh {
        let p = |i: u32| mesh.positions[i as usize];
        let mut tris: Vec<Tri> = mesh
            .triangles
            .iter()
            .map(|t| {
                let v0 = p(t[0]);
                Tri { v0, e1: sub(p(t[1]), v0), e2: sub(p(t[2]), v0) }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 1);
        if !tris.is_empty() {
            build(&mut nodes, &mut tris, 0);
        }
        SurfaceBvh { nodes, tris }
    }

    /// The nearest hit with `t_min < t < t_max`.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = ray.dir.map(|d| 1.0 / d);
        let mut best: Option<(f32, usize)> = None;
        let mut t_best = t_max;
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let n = self.nodes[stack[sp] as usize];
            if !slab_hit(&n, ray.origin, inv, t_min, t_best) {
                continue;
            }
            if n.count > 0 {
                for i in n.first as usize..(n.first + n.count) as usize {
                    if let Some(t) = hit_tri(&self.tris[i], ray, t_min, t_best) {
                        t_best = t;
                        best = Some((t, i));
                    }
                }
            } else {
                // Median splits keep the depth ≤ log2(n) + 1, far below the stack size.
                let here = stack[sp] as usize;
                stack[sp] = n.first;
                stack[sp + 1] = (here + 1) as u32;
                sp += 2;
            }
        }
        best.map(|(t, i)| {
            let tri = &self.tris[i];
            Hit { t, normal: normalize(cross(tri.e1, tri.e2)).unwrap_or([0.0, 0.0, 1.0]) }
        })
    }
}

fn bounds_of(t: &Tri) -> (Vec3, Vec3) {
    let v1: Vec3 = std::array::from_fn(|k| t.v0[k] + t.e1[k]);
    let v2: Vec3 = std::array::from_fn(|k| t.v0[k] + t.e2[k]);
    (std::array::from_fn(|k| t.v0[k].min(v1[k]).min(v2[k])), std::array::from_fn(|k| t.v0[k].max(v1[k]).max(v2[k])))
}

/// Builds the subtree over `tris` (whose first triangle has global index `offset`),
/// appending nodes depth-first. Returns the subtree root's index.
fn build(nodes: &mut Vec<Node>, tris: &mut [Tri], offset: usize) -> usize {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let (mut clo, mut chi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for t in tris.iter() {
        let (a, b) = bounds_of(t);
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
            let c = 0.5 * (a[k] + b[k]);
            clo[k] = clo[k].min(c);
            chi[k] = chi[k].max(c);
        }
    }
    let me = nodes.len();
    nodes.push(Node { min: lo, max: hi, first: offset as u32, count: tris.len() as u32 });
    if tris.len() <= LEAF_SIZE {
        return me;
    }
    let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap();
    let mid = tris.len() / 2;
    let key = |t: &Tri| {
        let (a, b) = bounds_of(t);
        a[axis] + b[axis]
    };
    tris.select_nth_unstable_by(mid, |x, y| key(x).total_cmp(&key(y)));
    let (left, right) = tris.split_at_mut(mid);
    build(nodes, left, offset);
    let r = build(nodes, right, offset + mid);
    nodes[me].first = r as u32;
    nodes[me].count = 0;
    me
}

#[inline]
fn slab_hit(n: &Node, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> bool {
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
