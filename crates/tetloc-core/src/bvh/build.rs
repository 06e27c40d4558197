//! Parallel BVH builder over boxes: sort the primitives by the Morton code of their box's
//! centre, then split each range at its highest differing Morton bit (as in Karras' LBVH),
//! in parallel with rayon.

use super::morton::Morton;
use super::{Aabb, BuildPreset, Bvh, BvhNode, BvhStats};
use rayon::prelude::*;
use std::borrow::Cow;
use std::time::Instant;

/// `boxes` may be owned so that it is freed before the nodes are built (the largest meshes).
pub(super) fn build(boxes: Cow<[Aabb]>, preset: BuildPreset) -> Bvh {
    let t0 = Instant::now();
    if boxes.is_empty() {
        return Bvh::default();
    }
    // Morton codes of the box centres, 21 bits an axis over the centres' bounds.
    let (lo, hi) = boxes.par_iter().map(|b| (b.centre(), b.centre())).reduce(
        || ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(a0, a1), (b0, b1)| (std::array::from_fn(|k| a0[k].min(b0[k])), std::array::from_fn(|k| a1[k].max(b1[k]))),
    );
    let morton = Morton::new(lo, hi, 21);
    let mut keyed: Vec<(u64, u32)> =
        boxes.par_iter().enumerate().map(|(i, b)| (morton.code(b.centre()), i as u32)).collect();
    keyed.par_sort_unstable();
    let codes: Vec<u64> = keyed.iter().map(|k| k.0).collect();
    let prim_ids: Vec<u32> = keyed.into_iter().map(|k| k.1).collect();
    let sorted_boxes: Vec<Aabb> = prim_ids.par_iter().map(|&i| boxes[i as usize]).collect();
    let n_prims = boxes.len();
    drop(boxes);

    let ctx = Ctx { codes: &codes, boxes: &sorted_boxes, max_leaf: preset.max_leaf_size() };
    let (mut nodes, max_depth) = ctx.nodes();
    // Right-child links were built relative to their parent; make them absolute.
    nodes.par_iter_mut().enumerate().for_each(|(i, n)| {
        if n.count == 0 {
            n.first += i as u32;
        }
    });
    let n_leaves = nodes.par_iter().filter(|n| n.count > 0).count();
    let stats = BvhStats {
        n_prims,
        n_nodes: nodes.len(),
        n_leaves,
        max_depth,
        build_seconds: t0.elapsed().as_secs_f64(),
        bytes: nodes.len() * std::mem::size_of::<BvhNode>() + prim_ids.len() * 4,
    };
    Bvh { nodes, prim_ids, stats }
}

struct Ctx<'a> {
    codes: &'a [u64],
    boxes: &'a [Aabb],
    max_leaf: usize,
}

/// Below this many prims a subtree is built on one thread.
const PARALLEL_MIN: usize = 16 * 1024;

impl Ctx<'_> {
    /// Every node, depth first. The ranges below [`PARALLEL_MIN`] prims are built in
    /// parallel, each as its own depth-first list whose interior nodes hold their right
    /// child's offset *relative to themselves*; the nodes above them are then laid out around
    /// those lists in one pass, so that each node is copied once. Returns (nodes, depth).
    fn nodes(&self) -> (Vec<BvhNode>, usize) {
        let mut ranges = Vec::new();
        self.parallel_ranges(0, self.codes.len(), 0, &mut ranges);
        let built: Vec<(Vec<BvhNode>, Aabb, usize)> = ranges
            .par_iter()
            .map(|&(s, e, depth)| {
                let mut nodes = Vec::with_capacity(2 * (e - s) / self.max_leaf.max(1) + 1);
                let (b, d) = self.emit(s, e, depth, &mut nodes);
                (nodes, b, d)
            })
            .collect();
        let total = built.iter().map(|b| b.0.len()).sum::<usize>() + ranges.len();
        let mut out = Vec::with_capacity(total);
        let (_, depth) = self.lay_out(0, self.codes.len(), &mut built.iter(), &mut out);
        (out, depth)
    }

    /// The ranges that [`Self::lay_out`] takes whole, in depth-first order, with their depth.
    fn parallel_ranges(&self, s: usize, e: usize, depth: usize, out: &mut Vec<(usize, usize, usize)>) {
        if e - s < PARALLEL_MIN {
            out.push((s, e, depth));
        } else {
            let m = self.split(s, e);
            self.parallel_ranges(s, m, depth + 1, out);
            self.parallel_ranges(m, e, depth + 1, out);
        }
    }

    /// The nodes above the ranges of [`Self::parallel_ranges`] (the same recursion), with
    /// each range's list (`built`, in the same order) copied in where it falls.
    fn lay_out<'b>(
        &self,
        s: usize,
        e: usize,
        built: &mut impl Iterator<Item = &'b (Vec<BvhNode>, Aabb, usize)>,
        out: &mut Vec<BvhNode>,
    ) -> (Aabb, usize) {
        if e - s < PARALLEL_MIN {
            let (nodes, b, d) = built.next().expect("one built list per range");
            out.extend_from_slice(nodes);
            return (*b, *d);
        }
        let me = out.len();
        out.push(BvhNode::default());
        let m = self.split(s, e);
        let (lb, ld) = self.lay_out(s, m, built, out);
        let rel = out.len() - me;
        let (rb, rd) = self.lay_out(m, e, built, out);
        let b = lb.union(&rb);
        out[me] = BvhNode { min: b.min, first: rel as u32, max: b.max, count: 0 };
        (b, ld.max(rd))
    }

    fn emit(&self, s: usize, e: usize, depth: usize, out: &mut Vec<BvhNode>) -> (Aabb, usize) {
        let me = out.len();
        out.push(BvhNode::default());
        if e - s <= self.max_leaf {
            let b = self.boxes[s..e].iter().fold(self.boxes[s], |acc, x| acc.union(x));
            out[me] = BvhNode { min: b.min, first: s as u32, max: b.max, count: (e - s) as u32 };
            return (b, depth);
        }
        let m = self.split(s, e);
        let (lb, ld) = self.emit(s, m, depth + 1, out);
        let rel = out.len() - me;
        let (rb, rd) = self.emit(m, e, depth + 1, out);
        let d = ld.max(rd);
        let b = lb.union(&rb);
        out[me] = BvhNode { min: b.min, first: rel as u32, max: b.max, count: 0 };
        (b, d)
    }

    /// First index of the upper half: where the highest differing Morton bit turns on,
    /// or the middle when all codes in the range are equal.
    fn split(&self, s: usize, e: usize) -> usize {
        let (a, b) = (self.codes[s], self.codes[e - 1]);
        if a == b {
            return (s + e) / 2;
        }
        let bit = 63 - (a ^ b).leading_zeros();
        let prefix_mask = !((1u64 << bit) - 1) & !(1u64 << bit);
        let target = (a & prefix_mask) | (1u64 << bit);
        s + self.codes[s..e].partition_point(|&c| c < target)
    }
}
