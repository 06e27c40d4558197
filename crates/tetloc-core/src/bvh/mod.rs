//! The BVH of tetloc, in the manner of cuBQL: a builder over boxes (one per primitive:
//! tets, triangles, later any cell), a node-format contract, and traversal through
//! callbacks that decide the primitives.
//!
//! - [`Bvh`]: the binary BVH, 32-byte `repr(C)` nodes, a parallel Morton-split builder with
//!   named presets, `validate()` and a one-line build report.
//! - [`wide`]: the binary BVH collapsed into 4-wide nodes with child boxes quantized to a byte
//!   ([`QNode4`], soft-bvh's GPU layout) and its CPU traversal, the reference of the shader's.
//! - [`grid`]: the entry grid that starts a wide traversal below the root, or a walk.
//! - [`morton`]: the one Morton encoding.

mod build;
pub mod grid;
pub mod morton;
#[cfg(test)]
mod tests;
pub mod wide;

pub use grid::EntryGrid;
pub use wide::{QNode4, Traversal, WideBvh};

use crate::geom::Vec3;
use bytemuck::{Pod, Zeroable};
use serde::Serialize;

/// An axis-aligned box, laid out as Vulkan's `VkAabbPositionsKHR` (min xyz, max xyz).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}
const _: () = assert!(std::mem::size_of::<Aabb>() == 24);

impl Aabb {
    /// Whether `p` is in the box (its faces included).
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        (0..3).all(|k| self.min[k] <= p[k] && p[k] <= self.max[k])
    }

    /// The bounds of the tet with vertex ids `ids`.
    #[inline]
    pub fn of_tet(ids: [u32; 4], points: &[Vec3]) -> Aabb {
        let (min, max) = crate::geom::tet_bounds(ids, points);
        Aabb { min, max }
    }

    /// The bounds of a set of points (an empty box, min > max, for none).
    pub fn of_points(points: &[Vec3]) -> Aabb {
        let empty = Aabb { min: [f32::INFINITY; 3], max: [f32::NEG_INFINITY; 3] };
        points.iter().fold(empty, |b, p| b.union(&Aabb { min: *p, max: *p }))
    }

    /// One box per tet, in parallel.
    pub fn of_tets(tets: &[[u32; 4]], points: &[Vec3]) -> Vec<Aabb> {
        use rayon::prelude::*;
        tets.par_iter().map(|&t| Aabb::of_tet(t, points)).collect()
    }

    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: std::array::from_fn(|k| self.min[k].min(o.min[k])),
            max: std::array::from_fn(|k| self.max[k].max(o.max[k])),
        }
    }

    #[inline]
    pub fn centre(&self) -> Vec3 {
        std::array::from_fn(|k| 0.5 * (self.min[k] + self.max[k]))
    }

    /// `o` lies within this box (boundaries included).
    #[inline]
    pub fn holds(&self, o: &Aabb) -> bool {
        (0..3).all(|k| o.min[k] >= self.min[k] && o.max[k] <= self.max[k])
    }
}

/// One BVH node, 32 bytes. Interior node (`count == 0`): left child at `index + 1`
/// (depth-first layout), right child at `first`. Leaf: tets `prim_ids[first .. first + count]`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub min: Vec3,
    pub first: u32,
    pub max: Vec3,
    pub count: u32,
}
const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    #[inline(always)]
    pub fn contains(&self, p: Vec3) -> bool {
        p[0] >= self.min[0]
            && p[0] <= self.max[0]
            && p[1] >= self.min[1]
            && p[1] <= self.max[1]
            && p[2] >= self.min[2]
            && p[2] <= self.max[2]
    }
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Named build presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BuildPreset {
    /// Morton-order (LBVH-style) splits, up to 4 tets a leaf: fastest build.
    Fast,
    /// Morton-order splits with one tet a leaf: the paper's layout, most nodes.
    SingleTetLeaves,
}

impl BuildPreset {
    pub fn max_leaf_size(self) -> usize {
        match self {
            BuildPreset::Fast => 4,
            BuildPreset::SingleTetLeaves => 1,
        }
    }
}

/// Counts from a build, printed as one line by [`BvhStats::report`].
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct BvhStats {
    pub n_prims: usize,
    pub n_nodes: usize,
    pub n_leaves: usize,
    pub max_depth: usize,
    pub build_seconds: f64,
    pub bytes: usize,
}

impl BvhStats {
    pub fn report(&self) -> String {
        format!(
            "bvh: {} tets, {} nodes, {} leaves ({:.2} tets/leaf), depth {}, {:.1} MiB, built in {:.3} s ({:.1} M tets/s)",
            self.n_prims,
            self.n_nodes,
            self.n_leaves,
            self.n_prims as f64 / self.n_leaves.max(1) as f64,
            self.max_depth,
            self.bytes as f64 / (1 << 20) as f64,
            self.build_seconds,
            self.n_prims as f64 / self.build_seconds.max(1e-9) / 1e6
        )
    }
}

/// A binary BVH over primitives given by their boxes (the tets of a mesh, triangles, ...).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// Primitive ids in leaf order.
    pub prim_ids: Vec<u32>,
    pub stats: BvhStats,
}

/// What [`Bvh::traverse`] does with a node or a primitive.
pub trait Visitor {
    /// Descend into a node with this box?
    fn enter(&mut self, bounds: &Aabb) -> bool;
    /// Decides primitive `id` of a leaf that was entered; `true` ends the traversal.
    fn prim(&mut self, id: u32) -> bool;
}

impl Bvh {
    /// The BVH over the tets of a mesh.
    pub fn build(points: &[Vec3], tets: &[[u32; 4]], preset: BuildPreset) -> Bvh {
        build::build(Aabb::of_tets(tets, points).into(), preset)
    }

    /// The BVH over primitives `0..boxes.len()` with these bounds.
    pub fn build_boxes(boxes: &[Aabb], preset: BuildPreset) -> Bvh {
        build::build(boxes.into(), preset)
    }

    /// Depth first, the left child first, entering nodes and deciding primitives as `v` says,
    /// until `v.prim` returns `true` (then `true`) or the tree is exhausted (`false`).
    pub fn traverse(&self, v: &mut impl Visitor) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let mut stack = Vec::with_capacity(64);
        stack.push(0u32);
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i as usize];
            if !v.enter(&Aabb { min: n.min, max: n.max }) {
                continue;
            }
            if n.is_leaf() {
                if self.prim_ids[n.first as usize..(n.first + n.count) as usize].iter().any(|&p| v.prim(p)) {
                    return true;
                }
            } else {
                stack.extend([n.first, i + 1]);
            }
        }
        false
    }

    /// Checks the invariants for the tets of a mesh (see [`Bvh::validate_boxes`]).
    pub fn validate(&self, points: &[Vec3], tets: &[[u32; 4]]) -> Result<(), String> {
        self.validate_boxes(&Aabb::of_tets(tets, points))
    }

    /// Checks the invariants: every primitive in exactly one leaf, children inside parents,
    /// every leaf box holding its primitives' boxes, indices in range. Returns the first violation.
    pub fn validate_boxes(&self, boxes: &[Aabb]) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if boxes.is_empty() { Ok(()) } else { Err("no nodes".into()) };
        }
        let mut seen = vec![false; boxes.len()];
        let inside = |inner: &BvhNode, outer: &BvhNode| {
            (0..3).all(|k| inner.min[k] >= outer.min[k] && inner.max[k] <= outer.max[k])
        };
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let n = self.nodes.get(i).ok_or(format!("node index {i} out of range"))?;
            if n.is_leaf() {
                let (s, e) = (n.first as usize, n.first as usize + n.count as usize);
                let ids = self.prim_ids.get(s..e).ok_or(format!("leaf {i} prim range {s}..{e} out of range"))?;
                for &t in ids {
                    let t = t as usize;
                    if t >= boxes.len() || seen[t] {
                        return Err(format!("primitive {t} out of range or in two leaves"));
                    }
                    seen[t] = true;
                    if !(Aabb { min: n.min, max: n.max }).holds(&boxes[t]) {
                        return Err(format!("leaf {i} box does not hold primitive {t}"));
                    }
                }
            } else {
                for c in [i + 1, n.first as usize] {
                    let child = self.nodes.get(c).ok_or(format!("child {c} of node {i} out of range"))?;
                    if !inside(child, n) {
                        return Err(format!("child {c} sticks out of node {i}"));
                    }
                    stack.push(c);
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(t) => Err(format!("primitive {t} is in no leaf")),
            None => Ok(()),
        }
    }
}
