//! soft-bvh's node layout: the binary `tetloc_core::bvh::Bvh` collapsed into a 4-wide BVH
//! whose child boxes are quantized to one byte per coordinate (the paper's QBVH-like
//! layout): 64-byte nodes instead of four 32-byte binary nodes.

use crate::error::{VkError, VkResult};
use crate::gpu_types::{QNode4, EMPTY, LEAF, LEAF_FIRST_MAX};
use tetloc_core::bvh::{Bvh, BvhNode};

/// A collapsed, quantized BVH ready for upload.
pub(crate) struct QBvh {
    pub nodes: Vec<QNode4>,
    /// Tet ids in leaf order (leaf references index into this); empty when `direct`.
    pub prims: Vec<u32>,
    /// Every leaf holds one tet and its reference holds the tet id itself, saving the
    /// shader one dependent load per leaf.
    pub direct: bool,
    /// Levels of 4-wide nodes on the longest root-to-leaf path.
    pub depth: usize,
    /// For the entry grid: each node's parent (root: itself) and level, and the node whose
    /// child list holds each tet.
    parent: Vec<u32>,
    level: Vec<u8>,
    home: Vec<u32>,
}

impl QBvh {
    /// Traversal stack entries that always suffice: a node pushes at most 3 children.
    pub fn stack_size(&self) -> u32 {
        (3 * self.depth + 1) as u32
    }
}

/// Dequantization as the shader does it: one f32 multiply, then one add (no FMA: `precise`).
#[inline]
pub(crate) fn dequantize(origin: f32, q: u8, scale: f32) -> f32 {
    origin + q as f32 * scale
}

fn area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// The scale for one axis: the smallest step with `origin + 255 * scale >= hi`.
fn axis_scale(lo: f32, hi: f32) -> VkResult<f32> {
    if hi <= lo {
        return Ok(0.0);
    }
    let mut s = (hi - lo) / 255.0;
    while dequantize(lo, 255, s) < hi {
        s = s.next_up();
    }
    if !s.is_finite() {
        return Err(VkError::Mesh(format!("mesh extent {lo}..{hi} is too large for f32 node boxes")));
    }
    Ok(s)
}

/// Conservative bytes for [lo, hi] on an axis: dequantized lower <= lo and upper >= hi.
fn quantize(origin: f32, scale: f32, lo: f32, hi: f32) -> (u8, u8) {
    if scale == 0.0 {
        return (0, 0);
    }
    let mut ql = ((lo - origin) / scale).floor().clamp(0.0, 255.0) as u8;
    while ql > 0 && dequantize(origin, ql, scale) > lo {
        ql -= 1;
    }
    let mut qh = ((hi - origin) / scale).ceil().clamp(0.0, 255.0) as u8;
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
    fn emit(&mut self, i: usize, depth: usize, parent: Option<u32>) -> VkResult<u32> {
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
}

impl Collapse<'_> {
    fn leaf(&self, n: BvhNode) -> VkResult<u32> {
        if self.direct {
            leaf_ref(self.bvh.prim_ids[n.first as usize], 1)
        } else {
            leaf_ref(n.first, n.count)
        }
    }
}

fn leaf_ref(first: u32, count: u32) -> VkResult<u32> {
    if !(1..=4).contains(&count) || first > LEAF_FIRST_MAX {
        return Err(VkError::Mesh(format!(
            "soft-bvh leaf ({count} tets from {first}) does not fit its 32-bit reference (at most 4 tets, first < 2^29)"
        )));
    }
    Ok(LEAF | (count - 1) << 29 | first)
}

/// Collapses a binary BVH (leaves of at most 4 tets) into quantized 4-wide nodes.
pub(crate) fn collapse(bvh: &Bvh) -> VkResult<QBvh> {
    let root = bvh.nodes.first().ok_or_else(|| VkError::Mesh("empty BVH".into()))?;
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
        // A tiny mesh: one node whose only child is the leaf.
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
    Ok(QBvh { nodes: c.nodes, prims, direct, depth: c.depth, parent: c.parent, level: c.level, home: c.home })
}

/// Cell coordinate of `p` on one axis, computed exactly as the shader does (one f32
/// subtraction and one multiplication, no FMA), so that the CPU and the GPU agree on which
/// cell a point is in, and cell(lo) <= cell(p) <= cell(hi) whenever lo <= p <= hi.
#[inline]
pub(crate) fn cell_coord(p: f32, lo: f32, inv: f32, dim: u32) -> u32 {
    ((p - lo) * inv).floor().clamp(0.0, (dim - 1) as f32) as u32
}

/// A uniform grid over the mesh's bounding box whose cells name where traversal may start:
/// the lowest common ancestor of the nodes holding every tet whose box overlaps the cell
/// (so the subtree holds every tet that can contain a point of the cell), or EMPTY.
pub(crate) struct EntryGrid {
    pub dims: [u32; 3],
    pub inv: [f32; 3],
    pub cells: Vec<u32>,
}

impl EntryGrid {
    /// Header (dims, 0, inv as bits, 0) and cells, as uploaded.
    pub fn words(&self) -> Vec<u32> {
        let mut w = vec![self.dims[0], self.dims[1], self.dims[2], 0];
        w.extend(self.inv.map(f32::to_bits));
        w.push(0);
        w.extend_from_slice(&self.cells);
        w
    }

    #[cfg(test)]
    pub fn cell_of(&self, p: [f32; 3], lo: [f32; 3]) -> usize {
        let c: [u32; 3] = std::array::from_fn(|a| cell_coord(p[a], lo[a], self.inv[a], self.dims[a]));
        ((c[2] as usize * self.dims[1] as usize) + c[1] as usize) * self.dims[0] as usize + c[0] as usize
    }
}

impl QBvh {
    fn lca(&self, mut a: u32, mut b: u32) -> u32 {
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

    /// The entry grid over [lo, hi] with about one cell per `tets_per_cell` tets.
    pub fn entry_grid(&self, points: &[[f32; 3]], tets: &[[u32; 4]], lo: [f32; 3], hi: [f32; 3], tets_per_cell: usize) -> EntryGrid {
        let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0) as f64);
        let cells_wanted = (tets.len() / tets_per_cell.max(1)).max(1) as f64;
        let used: Vec<f64> = extent.iter().copied().filter(|&e| e > 0.0).collect();
        let h = if used.is_empty() { 1.0 } else { (used.iter().product::<f64>() / cells_wanted).powf(1.0 / used.len() as f64) };
        let dims: [u32; 3] = std::array::from_fn(|a| ((extent[a] / h).round() as u32).clamp(1, 1024));
        let inv: [f32; 3] = std::array::from_fn(|a| if extent[a] > 0.0 { dims[a] as f32 / (hi[a] - lo[a]) } else { 0.0 });
        let mut grid = EntryGrid { dims, inv, cells: vec![EMPTY; (dims[0] * dims[1] * dims[2]) as usize] };
        for (t, &ids) in tets.iter().enumerate() {
            let (tlo, thi) = tetloc_core::geom::tet_bounds(ids, points);
            let c0: [u32; 3] = std::array::from_fn(|a| cell_coord(tlo[a], lo[a], inv[a], dims[a]));
            let c1: [u32; 3] = std::array::from_fn(|a| cell_coord(thi[a], lo[a], inv[a], dims[a]));
            let home = self.home[t];
            for z in c0[2]..=c1[2] {
                for y in c0[1]..=c1[1] {
                    for x in c0[0]..=c1[0] {
                        let cell = &mut grid.cells[((z * dims[1] + y) * dims[0] + x) as usize];
                        *cell = if *cell == EMPTY { home } else { self.lca(*cell, home) };
                    }
                }
            }
        }
        grid
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_core::bvh::BuildPreset;
    use tetloc_core::geom;

    /// n^3 cubes, 6 tets each (Kuhn), taller than wide, every vertex jittered; tets made
    /// positive as the locator's BVH expects.
    fn grid(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 4]>) {
        let raw = tetloc_core::testdata::KuhnGrid::new(n).spacing([1.0, 1.0, 1.5]).jitter(0.05, n as u64).jitter_boundary().raw();
        let tets = raw.tets.iter().map(|&t| geom::canonical_tet(t, &raw.points).0).collect();
        (raw.points, tets)
    }

    /// Walks the 4-wide tree on the CPU as the shader does; returns every leaf's tets with
    /// the dequantized box of the reference that led to it.
    fn leaves(q: &QBvh) -> Vec<(u32, [f32; 3], [f32; 3])> {
        let mut out = vec![];
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let n = &q.nodes[i as usize];
            for c in 0..4 {
                let r = n.child[c];
                if r == EMPTY {
                    continue;
                }
                let byte = |w: u32| ((w >> (8 * c)) & 0xFF) as u8;
                let lo: [f32; 3] = std::array::from_fn(|a| dequantize(n.origin[a], byte(n.q[2 * a]), n.scale[a]));
                let hi: [f32; 3] = std::array::from_fn(|a| dequantize(n.origin[a], byte(n.q[2 * a + 1]), n.scale[a]));
                if r & LEAF != 0 {
                    let (first, count) = (r & LEAF_FIRST_MAX, ((r >> 29) & 3) + 1);
                    if q.direct {
                        out.push((first, lo, hi));
                        continue;
                    }
                    for k in first..first + count {
                        out.push((q.prims[k as usize], lo, hi));
                    }
                } else {
                    stack.push(r);
                }
            }
        }
        out
    }

    #[test]
    fn every_tet_in_one_leaf_inside_its_conservative_box() {
        let (pts, tets) = grid(7);
        for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
            let bvh = Bvh::build(&pts, &tets, preset);
            let q = collapse(&bvh).unwrap();
            assert!(q.nodes.len() < bvh.nodes.len() / 2, "{} 4-wide nodes for {} binary", q.nodes.len(), bvh.nodes.len());
            let mut seen = vec![0; tets.len()];
            for (t, lo, hi) in leaves(&q) {
                seen[t as usize] += 1;
                let (tlo, thi) = geom::tet_bounds(tets[t as usize], &pts);
                for a in 0..3 {
                    assert!(lo[a] <= tlo[a] && hi[a] >= thi[a], "tet {t} axis {a}: box {lo:?}..{hi:?} vs {tlo:?}..{thi:?}");
                }
            }
            assert!(seen.iter().all(|&s| s == 1));
            assert_eq!(q.direct, preset == BuildPreset::SingleTetLeaves);
            assert!(q.depth >= 3 && q.depth < bvh.stats.max_depth + 1);
        }
    }

    /// Every tet lies in the subtree of the entry of every cell its box overlaps.
    #[test]
    fn entry_grid_subtrees_hold_their_tets() {
        let (pts, tets) = grid(6);
        for preset in [BuildPreset::Fast, BuildPreset::SingleTetLeaves] {
            let q = collapse(&Bvh::build(&pts, &tets, preset)).unwrap();
            let (lo, hi) = pts.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(l, h), p| {
                (std::array::from_fn(|a| l[a].min(p[a])), std::array::from_fn(|a| h[a].max(p[a])))
            });
            let g = q.entry_grid(&pts, &tets, lo, hi, 4);
            assert!(g.cells.len() > 100 && g.cells.iter().all(|&c| c != EMPTY));
            let below = |mut n: u32, anc: u32| loop {
                if n == anc {
                    return true;
                }
                if q.parent[n as usize] == n {
                    return false;
                }
                n = q.parent[n as usize];
            };
            for (t, &ids) in tets.iter().enumerate() {
                let c = g.cell_of(geom::tet_bounds(ids, &pts).0, lo);
                assert!(below(q.home[t], g.cells[c]), "tet {t} not under the entry of cell {c}");
            }
            // Most cells start below the root (a 1M-tet jets mesh: median level 6-7 of 13).
            let deep = g.cells.iter().filter(|&&c| q.level[c as usize] > 1).count();
            assert!(deep * 2 > g.cells.len(), "{deep} of {} cells start below the root", g.cells.len());
        }
    }

    #[test]
    fn quantization_is_conservative_at_awkward_values() {
        for (lo, hi) in [(0.1f32, 0.7f32), (-3.3e5, 1.7e-3), (1.0, 1.0 + f32::EPSILON), (-1e-30, 1e-30)] {
            let s = axis_scale(lo, hi).unwrap();
            assert!(dequantize(lo, 255, s) >= hi);
            let mid = lo + (hi - lo) * 0.37;
            let (ql, qh) = quantize(lo, s, mid, hi);
            assert!(dequantize(lo, ql, s) <= mid && dequantize(lo, qh, s) >= hi);
        }
    }

    #[test]
    fn single_tet_mesh() {
        let pts = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let tets = vec![geom::canonical_tet([0, 1, 2, 3], &pts).0];
        let q = collapse(&Bvh::build(&pts, &tets, BuildPreset::Fast)).unwrap();
        assert_eq!(leaves(&q).len(), 1);
    }
}
