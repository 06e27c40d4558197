//! The wide BVH: a binary [`Bvh`] collapsed into 4-wide nodes whose child boxes are
//! quantized to one byte per coordinate (the paper's QBVH-like layout for soft-bvh): one
//! 64-byte node instead of four 32-byte binary ones.
//!
//! The node format is a contract with the GPU (`tetloc-vulkan`'s soft-bvh shaders read the
//! nodes as four `uvec4` and decode child references with the constants below), and
//! [`WideBvh::traverse`] is the CPU reference of the shader's traversal: the same order, the
//! same dequantization; [`WideBvh::locate`] adds the tie rule (`geom::lowest_claim`), so
//! both find the same primitive.

use super::{Aabb, Bvh, BvhNode};
use crate::error::{Error, Result};
use crate::geom::Vec3;
use bytemuck::{Pod, Zeroable};

/// Child reference bit: a leaf (else an interior node's index).
pub const LEAF: u32 = 0x8000_0000;
/// Child reference of an empty slot (also "no node" in the entry grid).
pub const EMPTY: u32 = 0xFFFF_FFFF;
/// A leaf reference holds `count - 1` (up to 4 primitives) from this bit...
pub const LEAF_COUNT_SHIFT: u32 = 29;
/// ...and its first primitive index below it. A direct leaf (one primitive, no prims array)
/// holds the primitive id in all 31 bits below `LEAF`: ids up to 2^31 - 2, so jets 1B fits.
pub const LEAF_FIRST_MAX: u32 = (1 << LEAF_COUNT_SHIFT) - 1;

/// A 4-wide BVH node with child boxes quantized to 8 bits per coordinate relative to the
/// node's box: child box = origin + q * scale (one multiply, then one add: no FMA, on the
/// CPU and the GPU alike). Read on the GPU as four `uvec4`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QNode4 {
    pub origin: [f32; 3],
    pub scale: [f32; 3],
    /// Per axis a lower and an upper word, one byte per child: lo_x, hi_x, lo_y, hi_y, lo_z, hi_z.
    pub q: [u32; 6],
    /// Child references: node index, `LEAF | (count - 1) << LEAF_COUNT_SHIFT | first`, or `EMPTY`.
    pub child: [u32; 4],
}
const _: () = assert!(std::mem::size_of::<QNode4>() == 64);

impl QNode4 {
    /// The dequantized box of child slot `c`.
    #[inline]
    pub fn child_box(&self, c: usize) -> Aabb {
        let byte = |w: u32| ((w >> (8 * c)) & 0xFF) as u8;
        Aabb {
            min: std::array::from_fn(|a| dequantize(self.origin[a], byte(self.q[2 * a]), self.scale[a])),
            max: std::array::from_fn(|a| dequantize(self.origin[a], byte(self.q[2 * a + 1]), self.scale[a])),
        }
    }
}

/// The reference of a leaf of `count` primitives from `first`.
pub fn leaf_ref(first: u32, count: u32) -> Result<u32> {
    if !(1..=4).contains(&count) || first > LEAF_FIRST_MAX {
        return Err(Error::Invalid(format!(
            "wide BVH leaf ({count} primitives from {first}) does not fit its 32-bit reference (at most 4, first < 2^29)"
        )));
    }
    Ok(LEAF | (count - 1) << LEAF_COUNT_SHIFT | first)
}

/// The reference of a direct leaf: primitive `prim` itself (below 2^31 - 1, never `EMPTY`).
pub fn direct_leaf_ref(prim: u32) -> Result<u32> {
    if prim >= !LEAF {
        return Err(Error::Invalid(format!("wide BVH direct leaf: primitive {prim} is not below 2^31 - 1")));
    }
    Ok(LEAF | prim)
}

/// (first, count) of a leaf reference (`direct`: of a direct leaf, the primitive id and 1).
#[inline]
pub fn leaf_range(r: u32, direct: bool) -> (u32, u32) {
    if direct {
        (r & !LEAF, 1)
    } else {
        (r & LEAF_FIRST_MAX, ((r >> LEAF_COUNT_SHIFT) & 3) + 1)
    }
}

/// Dequantization as the shader does it: one f32 multiply, then one add (no FMA: `precise`).
#[inline]
pub fn dequantize(origin: f32, q: u8, scale: f32) -> f32 {
    origin + q as f32 * scale
}

/// A collapsed, quantized BVH.
#[derive(Clone, Debug)]
pub struct WideBvh {
    pub nodes: Vec<QNode4>,
    /// Primitive ids in leaf order (leaf references index into this); empty when `direct`.
    pub prims: Vec<u32>,
    /// Every leaf holds one primitive and its reference holds the primitive id itself, saving
    /// the shader one dependent load per leaf.
    pub direct: bool,
    /// Levels of 4-wide nodes on the longest root-to-leaf path.
    pub depth: usize,
    /// Each node's parent (the root: itself) and level, and the node whose child list holds
    /// each primitive: what the entry grid needs.
    pub(super) parent: Vec<u32>,
    pub(super) level: Vec<u8>,
    pub(super) home: Vec<u32>,
}

/// What one traversal found and cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traversal {
    /// The first primitive in traversal order that the caller accepted (`traverse`); with
    /// the tie rule, the answer (`locate`).
    pub prim: Option<u32>,
    /// 4-wide nodes loaded.
    pub nodes: u32,
}

impl WideBvh {
    /// Collapses a binary BVH (leaves of at most 4 primitives) into quantized 4-wide nodes.
    pub fn collapse(bvh: &Bvh) -> Result<WideBvh> {
        let root = bvh.nodes.first().ok_or_else(|| Error::Invalid("empty BVH".into()))?;
        let direct = bvh.nodes.iter().all(|n| !n.is_leaf() || n.count == 1);
        let mut c = Collapse {
            bvh,
            direct,
            nodes: Vec::with_capacity(bvh.nodes.len() / 3 + 1),
            depth: 0,
            parent: vec![],
            level: vec![],
            home: vec![0; bvh.prim_ids.len()],
        };
        if root.is_leaf() {
            // A tiny input: one node whose only child is the leaf.
            let mut node = QNode4 { origin: root.min, child: [EMPTY; 4], ..Default::default() };
            for a in 0..3 {
                node.scale[a] = axis_scale(root.min[a], root.max[a])?;
                let (ql, qh) = quantize(node.origin[a], node.scale[a], root.min[a], root.max[a]);
                node.q[2 * a] = ql as u32 | 0xFFFF_FF00;
                node.q[2 * a + 1] = qh as u32;
            }
            node.child[0] = c.leaf(*root)?;
            c.nodes.push(node);
            c.parent.push(0);
            c.level.push(1);
            c.depth = 1;
        } else {
            c.emit(0, 1, None)?;
        }
        let prims = if direct { vec![] } else { bvh.prim_ids.clone() };
        Ok(WideBvh { nodes: c.nodes, prims, direct, depth: c.depth, parent: c.parent, level: c.level, home: c.home })
    }

    /// A wide BVH from its parts (read back from a GPU build, say), for traversal and
    /// [`WideBvh::validate`]; it has no links for an entry grid.
    pub fn from_parts(nodes: Vec<QNode4>, prims: Vec<u32>, direct: bool, depth: usize) -> WideBvh {
        WideBvh { nodes, prims, direct, depth, parent: vec![], level: vec![], home: vec![] }
    }

    /// Traversal stack entries that always suffice: a node pushes at most 3 children.
    pub fn stack_size(&self) -> u32 {
        (3 * self.depth + 1) as u32
    }

    /// The CPU reference of soft-bvh's `tl_traverse` (shaders/common/soft_bvh.glsl): depth
    /// first from node reference `start` (0: the root); of the children whose box holds `p`,
    /// the first continues and the others are pushed in child order. `accept` decides each
    /// primitive of each leaf reached; the first it accepts is the answer.
    pub fn traverse(
        &self,
        p: Vec3,
        start: u32,
        stack: &mut Vec<u32>,
        mut accept: impl FnMut(u32) -> bool,
    ) -> Traversal {
        stack.clear();
        let mut t = Traversal::default();
        let mut r = start;
        loop {
            if r & LEAF != 0 {
                let (first, count) = leaf_range(r, self.direct);
                for k in 0..count {
                    let prim = if self.direct { first } else { self.prims[(first + k) as usize] };
                    if accept(prim) {
                        t.prim = Some(prim);
                        return t;
                    }
                }
            } else {
                t.nodes += 1;
                let n = &self.nodes[r as usize];
                let mut next = EMPTY;
                for c in 0..4 {
                    let byte = |w: u32| ((w >> (8 * c)) & 0xFF) as u8;
                    let hit = n.child[c] != EMPTY
                        && (0..3).all(|a| {
                            dequantize(n.origin[a], byte(n.q[2 * a]), n.scale[a]) <= p[a]
                                && p[a] <= dequantize(n.origin[a], byte(n.q[2 * a + 1]), n.scale[a])
                        });
                    if hit {
                        if next == EMPTY {
                            next = n.child[c];
                        } else {
                            stack.push(n.child[c]);
                        }
                    }
                }
                if next != EMPTY {
                    r = next;
                    continue;
                }
            }
            match stack.pop() {
                Some(s) => r = s,
                None => return t,
            }
        }
    }

    /// The CPU reference of soft-bvh's `tl_traverse` with its tie rule (`geom::lowest_claim`):
    /// `claim` says whether a primitive holds `p` (`Some(true)`: strictly inside, which ends
    /// the search; `Some(false)`: on its boundary, the search goes on). The answer is the
    /// strict holder, else the lowest id among the boundary claims.
    pub fn locate(
        &self,
        p: Vec3,
        start: u32,
        stack: &mut Vec<u32>,
        mut claim: impl FnMut(u32) -> Option<bool>,
    ) -> Traversal {
        let mut tie = None;
        let mut t = self.traverse(p, start, stack, |prim| match claim(prim) {
            Some(strict) => {
                if !strict {
                    crate::geom::lowest_claim(&mut tie, (prim, ()));
                }
                strict
            }
            None => false,
        });
        t.prim = t.prim.or(tie.map(|(prim, ())| prim));
        t
    }

    /// Checks the tree against the primitives' boxes: every primitive in exactly one leaf,
    /// every used child box (dequantized as the shader does) holding the boxes of all the
    /// primitives below it, empty slots empty (reference `EMPTY`, lower byte 255 > upper 0),
    /// node references in range and depth levels as counted. Returns the first violation.
    pub fn validate(&self, boxes: &[Aabb]) -> std::result::Result<(), String> {
        let mut seen = vec![false; boxes.len()];
        let mut depth = 0;
        self.validate_node(0, 1, boxes, &mut seen, &mut depth)?;
        if depth != self.depth {
            return Err(format!("depth {} recorded, {depth} found", self.depth));
        }
        match seen.iter().position(|s| !s) {
            Some(t) => Err(format!("primitive {t} is in no leaf")),
            None => Ok(()),
        }
    }

    /// The union of the primitive boxes below node `i` (at `level`), checking as it goes.
    fn validate_node(
        &self,
        i: u32,
        level: usize,
        boxes: &[Aabb],
        seen: &mut [bool],
        depth: &mut usize,
    ) -> std::result::Result<Aabb, String> {
        let n = self.nodes.get(i as usize).ok_or(format!("node {i} out of range"))?;
        *depth = (*depth).max(level);
        let mut all = Aabb { min: [f32::INFINITY; 3], max: [f32::NEG_INFINITY; 3] };
        for c in 0..4 {
            let r = n.child[c];
            let byte = |w: u32| (w >> (8 * c)) & 0xFF;
            if r == EMPTY {
                if (0..3).any(|a| byte(n.q[2 * a]) != 255 || byte(n.q[2 * a + 1]) != 0) {
                    return Err(format!("node {i} slot {c}: empty reference with a non-empty box"));
                }
                continue;
            }
            let below = if r & LEAF != 0 {
                let (first, count) = leaf_range(r, self.direct);
                let mut u = Aabb { min: [f32::INFINITY; 3], max: [f32::NEG_INFINITY; 3] };
                for k in 0..count {
                    let p = if self.direct {
                        first
                    } else {
                        *self.prims.get((first + k) as usize).ok_or(format!("node {i}: prim index out of range"))?
                    };
                    let s = seen.get_mut(p as usize).ok_or(format!("node {i}: primitive {p} out of range"))?;
                    if *s {
                        return Err(format!("primitive {p} is in two leaves"));
                    }
                    *s = true;
                    u = u.union(&boxes[p as usize]);
                }
                u
            } else {
                if r <= i {
                    return Err(format!("node {i} slot {c}: child {r} is not below it in depth-first order"));
                }
                self.validate_node(r, level + 1, boxes, seen, depth)?
            };
            if !n.child_box(c).holds(&below) {
                return Err(format!("node {i} slot {c}: the child box does not hold what is below it"));
            }
            all = all.union(&below);
        }
        Ok(all)
    }

    /// The lowest common ancestor of nodes `a` and `b`.
    pub(super) fn lca(&self, mut a: u32, mut b: u32) -> u32 {
        while self.level[a as usize] > self.level[b as usize] {
            a = self.parent[a as usize];
        }
        while self.level[b as usize] > self.level[a as usize] {
            b = self.parent[b as usize];
        }
        while a != b {
            a = self.parent[a as usize];
            b = self.parent[b as usize];
        }
        a
    }
}

fn area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// The scale for one axis: the smallest step with `lo + 255 * scale >= hi`. Defined by
/// `dequantize` alone (monotone in the step), not by the division that estimates it, so that
/// the GPU build (shaders/build/hierarchy.comp), whose division may round differently, finds
/// the same bits.
fn axis_scale(lo: f32, hi: f32) -> Result<f32> {
    if hi <= lo {
        return Ok(0.0);
    }
    let mut s = (hi - lo) / 255.0;
    while s > 0.0 && s.is_finite() && dequantize(lo, 255, s.next_down()) >= hi {
        s = s.next_down();
    }
    while dequantize(lo, 255, s) < hi {
        s = s.next_up();
    }
    if !s.is_finite() {
        return Err(Error::Invalid(format!("extent {lo}..{hi} is too large for f32 node boxes")));
    }
    Ok(s)
}

/// Conservative bytes for [lo, hi] on an axis, the tightest: the largest lower byte whose
/// value is <= lo and the smallest upper byte whose value is >= hi. Like `axis_scale`, defined
/// by `dequantize` alone (the division only estimates), so the GPU build finds the same bytes.
fn quantize(origin: f32, scale: f32, lo: f32, hi: f32) -> (u8, u8) {
    if scale == 0.0 {
        return (0, 0);
    }
    let mut ql = ((lo - origin) / scale).floor().clamp(0.0, 255.0) as u8;
    while ql < 255 && dequantize(origin, ql + 1, scale) <= lo {
        ql += 1;
    }
    while ql > 0 && dequantize(origin, ql, scale) > lo {
        ql -= 1;
    }
    let mut qh = ((hi - origin) / scale).ceil().clamp(0.0, 255.0) as u8;
    while qh > 0 && dequantize(origin, qh - 1, scale) >= hi {
        qh -= 1;
    }
    while qh < 255 && dequantize(origin, qh, scale) < hi {
        qh += 1;
    }
    (ql, qh)
}

struct Collapse<'a> {
    bvh: &'a Bvh,
    direct: bool,
    nodes: Vec<QNode4>,
    depth: usize,
    parent: Vec<u32>,
    level: Vec<u8>,
    home: Vec<u32>,
}

impl Collapse<'_> {
    fn children(&self, i: usize) -> [usize; 2] {
        [i + 1, self.bvh.nodes[i].first as usize]
    }

    /// Emits the 4-wide node for binary interior node `i` and its subtree (depth-first order).
    fn emit(&mut self, i: usize, depth: usize, parent: Option<u32>) -> Result<u32> {
        self.depth = self.depth.max(depth);
        // Open the largest interior child until there are four.
        let mut kids: Vec<usize> = self.children(i).to_vec();
        while kids.len() < 4 {
            let open = kids
                .iter()
                .enumerate()
                .filter(|(_, &k)| !self.bvh.nodes[k].is_leaf())
                .max_by(|a, b| area(&self.bvh.nodes[*a.1]).total_cmp(&area(&self.bvh.nodes[*b.1])))
                .map(|(j, _)| j);
            let Some(j) = open else { break };
            let k = kids.swap_remove(j);
            kids.extend(self.children(k));
        }
        let me = self.nodes.len();
        self.nodes.push(QNode4::default());
        self.parent.push(parent.unwrap_or(me as u32));
        self.level.push(depth.min(255) as u8);
        let n = &self.bvh.nodes[i];
        let mut node = QNode4 { origin: n.min, child: [EMPTY; 4], ..Default::default() };
        for a in 0..3 {
            node.scale[a] = axis_scale(n.min[a], n.max[a])?;
        }
        for (c, &k) in kids.iter().enumerate() {
            let kn = self.bvh.nodes[k];
            for a in 0..3 {
                let (ql, qh) = quantize(node.origin[a], node.scale[a], kn.min[a], kn.max[a]);
                node.q[2 * a] |= (ql as u32) << (8 * c);
                node.q[2 * a + 1] |= (qh as u32) << (8 * c);
            }
            node.child[c] = if kn.is_leaf() {
                for &t in &self.bvh.prim_ids[kn.first as usize..(kn.first + kn.count) as usize] {
                    self.home[t as usize] = me as u32;
                }
                self.leaf(kn)?
            } else {
                self.emit(k, depth + 1, Some(me as u32))?
            };
        }
        // Empty slots get an empty box (lower byte 255 > upper byte 0) besides the EMPTY reference.
        for c in kids.len()..4 {
            for a in 0..3 {
                node.q[2 * a] |= 255 << (8 * c);
            }
        }
        self.nodes[me] = node;
        Ok(me as u32)
    }

    fn leaf(&self, n: BvhNode) -> Result<u32> {
        if self.direct {
            direct_leaf_ref(self.bvh.prim_ids[n.first as usize])
        } else {
            leaf_ref(n.first, n.count)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantization_is_conservative_at_awkward_values() {
        for (lo, hi) in [(0.1f32, 0.7f32), (-3.3e5, 1.7e-3), (1.0, 1.0 + f32::EPSILON), (-1e-30, 1e-30)] {
            let s = axis_scale(lo, hi).unwrap();
            assert!(dequantize(lo, 255, s) >= hi);
            let mid = lo + (hi - lo) * 0.37;
            let (ql, qh) = quantize(lo, s, mid, hi);
            assert!(dequantize(lo, ql, s) <= mid && dequantize(lo, qh, s) >= hi);
        }
        assert!(axis_scale(-f32::MAX, f32::MAX).is_err(), "an infinite extent is refused");
    }

    /// The tightest bytes: one step in would no longer hold the interval.
    #[test]
    fn quantization_is_tight() {
        let (lo, hi) = (0.1f32, 0.7f32);
        let s = axis_scale(lo, hi).unwrap();
        assert!(dequantize(lo, 255, s.next_down()) < hi, "the smallest scale that reaches hi");
        for (a, b) in [(0.2f32, 0.3f32), (0.1, 0.7), (0.45, 0.45)] {
            let (ql, qh) = quantize(lo, s, a, b);
            assert!(dequantize(lo, ql, s) <= a && dequantize(lo, qh, s) >= b);
            assert!(ql == 255 || dequantize(lo, ql + 1, s) > a);
            assert!(qh == 0 || dequantize(lo, qh - 1, s) < b);
        }
    }

    #[test]
    fn leaf_references_round_trip_and_refuse_what_does_not_fit() {
        for (first, count) in [(0, 1), (7, 4), (LEAF_FIRST_MAX, 2)] {
            let r = leaf_ref(first, count).unwrap();
            assert!(r & LEAF != 0 && r != EMPTY);
            assert_eq!(leaf_range(r, false), (first, count));
        }
        assert!(leaf_ref(LEAF_FIRST_MAX + 1, 1).is_err());
        assert!(leaf_ref(0, 5).is_err() && leaf_ref(0, 0).is_err());
        // Direct leaves: any id below 2^31 - 1 (a billion tets and more), never EMPTY.
        for prim in [0, LEAF_FIRST_MAX + 1, 1_100_000_000, !LEAF - 1] {
            let r = direct_leaf_ref(prim).unwrap();
            assert!(r & LEAF != 0 && r != EMPTY);
            assert_eq!(leaf_range(r, true), (prim, 1));
        }
        assert!(direct_leaf_ref(!LEAF).is_err());
    }
}
