//! A binary BVH over tets: GPU-ready nodes, a parallel builder, a `validate()` and a
//! one-line build report. Traversal lives with the locators, not here.

mod build;
#[cfg(test)]
mod tests;

use crate::geom::Vec3;
use bytemuck::{Pod, Zeroable};
use serde::Serialize;

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

/// A BVH over the tets of one mesh.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// Tet ids in leaf order.
    pub prim_ids: Vec<u32>,
    pub stats: BvhStats,
}

impl Bvh {
    pub fn build(points: &[Vec3], tets: &[[u32; 4]], preset: BuildPreset) -> Bvh {
        build::build(points, tets, preset)
    }

    /// Checks the invariants: every tet in exactly one leaf, children inside parents,
    /// every leaf box holding its tets, indices in range. Returns the first violation.
    pub fn validate(&self, points: &[Vec3], tets: &[[u32; 4]]) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if tets.is_empty() { Ok(()) } else { Err("no nodes".into()) };
        }
        let mut seen = vec![false; tets.len()];
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
                    if t >= tets.len() || seen[t] {
                        return Err(format!("tet {t} out of range or in two leaves"));
                    }
                    seen[t] = true;
                    let (lo, hi) = crate::geom::tet_bounds(tets[t], points);
                    if !inside(&BvhNode { min: lo, max: hi, ..Default::default() }, n) {
                        return Err(format!("leaf {i} box does not hold tet {t}"));
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
            Some(t) => Err(format!("tet {t} is in no leaf")),
            None => Ok(()),
        }
    }
}
