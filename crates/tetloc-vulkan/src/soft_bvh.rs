//! soft-bvh's node layout: the binary `tetloc_core::bvh::Bvh` collapsed into a 4-wide BVH
//! whose child boxes are quantized to one byte per coordinate (the paper's QBVH-like
//! layout): 64-byte nodes instead of four 32-byte binary nodes.

use crate::error::{VkError, VkResult};
use crate::gpu_types::{QNode4, EMPTY, LEAF, LEAF_FIRST_MAX};
use tetloc_core::bvh::{Bvh, BvhNode};
use tetloc_core::geom;

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
    /// Walk start per cell (`entry_grid(.., starts: true)`): the tet holding the cell's
    /// centre, else a tet whose box overlaps the cell, else EMPTY. Empty without starts.
    pub starts: Vec<u32>,
}

impl EntryGrid {
    /// As uploaded: header (dims, number of cells if walk starts follow else 0, inv as bits,
    /// 0), the cells' entry nodes, then the walk starts if any.
    pub fn words(&self) -> Vec<u32> {
        let starts_at = if self.starts.is_empty() { 0 } else { self.cells.len() as u32 };
        let mut w = vec![self.dims[0], self.dims[1], self.dims[2], starts_at];
        w.extend(self.inv.map(f32::to_bits));
        w.push(0);
        w.extend_from_slice(&self.cells);
        w.extend_from_slice(&self.starts);
        w
    }

    /// The centre of cell `i` (only a hint for where a walk starts: no exactness needed).
    fn centre(&self, i: usize, lo: [f32; 3]) -> [f32; 3] {
        let (nx, ny) = (self.dims[0] as usize, self.dims[1] as usize);
        let c = [i % nx, (i / nx) % ny, i / (nx * ny)];
        std::array::from_fn(|a| if self.inv[a] > 0.0 { lo[a] + (c[a] as f32 + 0.5) / self.inv[a] } else { lo[a] })
    }

    /// Fills `starts`, locating the cell centres with the CPU mirror of the traversal; `any`
    /// holds, per cell, some tet whose box overlaps it (or EMPTY).
    fn fill_starts(&mut self, q: &QBvh, points: &[[f32; 3]], tets: &[[u32; 4]], lo: [f32; 3], any: &[u32]) {
        use rayon::prelude::*;
        let starts = (0..self.cells.len())
            .into_par_iter()
            .map_init(Vec::new, |stack, i| match self.cells[i] {
                EMPTY => EMPTY,
                node => {
                    q.traverse(points, tets, self.centre(i, lo), node, stack, &mut Cost::default()).unwrap_or(any[i])
                }
            })
            .collect();
        self.starts = starts;
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

    /// The entry grid over [lo, hi] with about one cell per `tets_per_cell` tets; with
    /// `starts`, each cell also names the tet a walk starts from.
    pub fn entry_grid(
        &self,
        points: &[[f32; 3]],
        tets: &[[u32; 4]],
        lo: [f32; 3],
        hi: [f32; 3],
        tets_per_cell: usize,
        starts: bool,
    ) -> EntryGrid {
        let extent: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0) as f64);
        let cells_wanted = (tets.len() / tets_per_cell.max(1)).max(1) as f64;
        let used: Vec<f64> = extent.iter().copied().filter(|&e| e > 0.0).collect();
        let h = if used.is_empty() {
            1.0
        } else {
            (used.iter().product::<f64>() / cells_wanted).powf(1.0 / used.len() as f64)
        };
        let dims: [u32; 3] = std::array::from_fn(|a| ((extent[a] / h).round() as u32).clamp(1, 1024));
        let inv: [f32; 3] =
            std::array::from_fn(|a| if extent[a] > 0.0 { dims[a] as f32 / (hi[a] - lo[a]) } else { 0.0 });
        let n_cells = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = EntryGrid { dims, inv, cells: vec![EMPTY; n_cells], starts: vec![] };
        // Per cell, some tet whose box overlaps it (the first in mesh order): the walk start
        // when the cell's centre lies in no tet.
        let mut any = vec![EMPTY; n_cells];
        // Parallel over slabs of z layers: each slab scans every tet and rasterizes only its own
        // layers (the LCA is order-free and `any` keeps the first tet, so the result does not
        // depend on the slabs).
        use rayon::prelude::*;
        let layer = (dims[0] * dims[1]) as usize;
        let per = (dims[2] as usize).div_ceil(rayon::current_num_threads() * 2).max(1);
        grid.cells.par_chunks_mut(per * layer).zip(any.par_chunks_mut(per * layer)).enumerate().for_each(
            |(s, (cells, any))| {
                let (z_first, z_last) = ((s * per) as u32, (s * per + cells.len() / layer - 1) as u32);
                for (t, &ids) in tets.iter().enumerate() {
                    let (tlo, thi) = tetloc_core::geom::tet_bounds(ids, points);
                    let c0: [u32; 3] = std::array::from_fn(|a| cell_coord(tlo[a], lo[a], inv[a], dims[a]));
                    let c1: [u32; 3] = std::array::from_fn(|a| cell_coord(thi[a], lo[a], inv[a], dims[a]));
                    if c1[2] < z_first || c0[2] > z_last {
                        continue;
                    }
                    let home = self.home[t];
                    for z in c0[2].max(z_first)..=c1[2].min(z_last) {
                        for y in c0[1]..=c1[1] {
                            for x in c0[0]..=c1[0] {
                                let i = (((z - z_first) * dims[1] + y) * dims[0] + x) as usize;
                                cells[i] = if cells[i] == EMPTY { home } else { self.lca(cells[i], home) };
                                if any[i] == EMPTY {
                                    any[i] = t as u32;
                                }
                            }
                        }
                    }
                }
            },
        );
        if starts {
            grid.fill_starts(self, points, tets, lo, &any);
        }
        grid
    }
}

/// What one CPU-mirrored location cost (NOTES.md "counts"): 4-wide nodes loaded,
/// point-in-tet tests, faces decided in f64, walk steps (tets tested by the walk).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Cost {
    pub nodes: u32,
    pub tests: u32,
    pub f64_faces: u32,
    #[cfg_attr(not(test), allow(dead_code))]
    pub walk_steps: u32,
    /// The walk did not settle the point (left the mesh, ran out of steps, or ended on a face).
    #[cfg_attr(not(test), allow(dead_code))]
    pub fallback: bool,
}

/// The point-in-tet test, counting tests and (in the counting tests only, as it costs a second
/// evaluation) the faces whose sign the f64 fallback decides.
fn test_counting(ids: [u32; 4], points: &[[f32; 3]], p: [f32; 3], cost: &mut Cost) -> geom::TetTest {
    cost.tests += 1;
    let r = geom::test_point(ids, points, p);
    if !cfg!(test) {
        return r;
    }
    let evaluated = match r {
        geom::TetTest::Inside(_) => 4,
        geom::TetTest::Outside { face } => {
            let swapped = ids[3] < ids[2];
            // stored index -> ascending index (the same involution), +1 faces evaluated
            (if swapped && face >= 2 { 5 - face } else { face }) + 1
        }
    };
    for (f, _) in geom::ascending_faces(ids).iter().take(evaluated) {
        let v = f.map(|i| points[i as usize]);
        let (det, bound) = geom::orient_f32(v[0], v[1], v[2], p);
        if det.abs() <= bound {
            cost.f64_faces += 1;
        }
    }
    r
}

impl QBvh {
    /// CPU mirror of `tl_traverse` in shaders/common/soft_bvh.glsl (same order: first hit
    /// child continues, the others are pushed in child order), from node `start`.
    pub(crate) fn traverse(
        &self,
        points: &[[f32; 3]],
        tets: &[[u32; 4]],
        p: [f32; 3],
        start: u32,
        stack: &mut Vec<u32>,
        cost: &mut Cost,
    ) -> Option<u32> {
        stack.clear();
        let mut r = start;
        loop {
            if r & LEAF != 0 {
                let (first, count) = (r & LEAF_FIRST_MAX, ((r >> 29) & 3) + 1);
                for k in 0..count {
                    let t = if self.direct { first } else { self.prims[(first + k) as usize] };
                    if let geom::TetTest::Inside(_) = test_counting(tets[t as usize], points, p, cost) {
                        return Some(t);
                    }
                }
            } else {
                cost.nodes += 1;
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
            r = stack.pop()?;
        }
    }
}

/// CPU mirror of `tl_walk` (shaders/common/walk.glsl) with the walk-start rule of
/// `tl_locate`: the walk's answer counts only when the point is strictly inside (no
/// barycentric weight 0), else the caller traverses the BVH.
#[cfg(test)]
pub(crate) fn walk(
    points: &[[f32; 3]],
    tets: &[[u32; 4]],
    neighbors: &[[i32; 4]],
    mut tet: i32,
    p: [f32; 3],
    max_steps: u32,
    cost: &mut Cost,
) -> Option<u32> {
    for _ in 0..max_steps {
        if tet < 0 {
            break;
        }
        cost.walk_steps += 1;
        match test_counting(tets[tet as usize], points, p, cost) {
            geom::TetTest::Inside(b) if b.iter().all(|&w| w != 0.0) => return Some(tet as u32),
            geom::TetTest::Inside(_) => break,
            geom::TetTest::Outside { face } => tet = neighbors[tet as usize][face],
        }
    }
    cost.fallback = true;
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use tetloc_core::bvh::BuildPreset;
    use tetloc_core::geom;

    /// n^3 cubes, 6 tets each (Kuhn), taller than wide, every vertex jittered; tets made
    /// positive as the locator's BVH expects.
    fn grid(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 4]>) {
        let raw =
            tetloc_testdata::KuhnGrid::new(n).spacing([1.0, 1.0, 1.5]).jitter(0.05, n as u64).jitter_boundary().raw();
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
            assert!(
                q.nodes.len() < bvh.nodes.len() / 2,
                "{} 4-wide nodes for {} binary",
                q.nodes.len(),
                bvh.nodes.len()
            );
            let mut seen = vec![0; tets.len()];
            for (t, lo, hi) in leaves(&q) {
                seen[t as usize] += 1;
                let (tlo, thi) = geom::tet_bounds(tets[t as usize], &pts);
                for a in 0..3 {
                    assert!(
                        lo[a] <= tlo[a] && hi[a] >= thi[a],
                        "tet {t} axis {a}: box {lo:?}..{hi:?} vs {tlo:?}..{thi:?}"
                    );
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
            let g = q.entry_grid(&pts, &tets, lo, hi, 4, false);
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

    /// Walk starts hold their cell's centre (or at least overlap the cell), and a walk from
    /// them finds the traversal's tet for points strictly inside, for points anywhere.
    #[test]
    fn walk_starts_lead_to_the_traversal_answer() {
        let mesh =
            tetloc_testdata::KuhnGrid::new(6).spacing([1.0, 1.0, 1.5]).jitter(0.05, 6).jitter_boundary().mesh("grid");
        let (pts, tets) = (&mesh.points, &mesh.tets);
        let q = collapse(&Bvh::build(pts, tets, BuildPreset::SingleTetLeaves)).unwrap();
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let g = q.entry_grid(pts, tets, lo, hi, 1, true);
        assert_eq!(g.starts.len(), g.cells.len());
        assert_eq!(g.words()[3] as usize, g.cells.len());
        let mut held = 0;
        for i in 0..g.cells.len() {
            let t = g.starts[i];
            assert!(t != EMPTY && (t as usize) < tets.len());
            held += geom::point_in_tet(tets[t as usize], pts, g.centre(i, lo)).is_some() as usize;
        }
        assert!(held * 10 >= g.cells.len() * 9, "only {held} of {} starts hold their cell's centre", g.cells.len());
        let nb = mesh.neighbors();
        let (mut walked, mut s) = (0, 7u64);
        for _ in 0..20_000 {
            let p: [f32; 3] = std::array::from_fn(|a| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                lo[a] + (hi[a] - lo[a]) * ((s >> 40) as f32 / (1u64 << 24) as f32 * 1.1 - 0.05)
            });
            let want = q.traverse(pts, tets, p, 0, &mut vec![], &mut Cost::default());
            let c = g.cell_of(p, lo);
            if let Some(t) = walk(pts, tets, nb, g.starts[c] as i32, p, 32, &mut Cost::default()) {
                assert_eq!(Some(t), want, "walk from cell {c} to {p:?}");
                walked += 1;
            }
        }
        assert!(walked > 10_000, "only {walked} walks settled their point");
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
    /// shaders/common/samples.glsl's `random` generator (hash, fold), for the counts.
    fn random_sample(g: u32, seed: u32, points: &[[f32; 3]], tets: &[[u32; 4]]) -> [f32; 3] {
        let hash = |x: u32| {
            let state = x.wrapping_mul(747796405).wrapping_add(2891336453);
            let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
            (word >> 22) ^ word
        };
        let mut st = hash(g ^ hash(seed));
        let t = tets[(hash(st) % tets.len() as u32) as usize];
        let mut unit = || {
            st = hash(st);
            (st >> 8) as f32 * (1.0 / 16777216.0)
        };
        let (a, b, c) = (unit(), unit(), unit());
        let [a, b, c] = tetloc_core::queries::fold_cube_into_tet(a, b, c);
        let w = 1.0 - a - b - c;
        let v = t.map(|i| points[i as usize]);
        std::array::from_fn(|k| w * v[0][k] + a * v[1][k] + b * v[2][k] + c * v[3][k])
    }

    /// Per-sample costs of three ways to locate (NOTES.md "Counts"): traversal from the root,
    /// from the entry grid's node, and a walk from the grid's start tet (BVH from the
    /// entry node as the fallback); averages per sample and, for SIMT, the mean over warps
    /// of 32 consecutive samples of the longest lane's loop iterations.
    #[test]
    #[ignore = "measurement: TETLOC_COUNT_TETS=12000000 cargo test --release -p tetloc-vulkan --lib count_costs -- --ignored --nocapture"]
    fn count_costs() {
        use rayon::prelude::*;
        let n: usize = std::env::var("TETLOC_COUNT_TETS").map_or(3_000_000, |v| v.parse().unwrap());
        let per_cell: usize = std::env::var("TETLOC_TETS_PER_CELL").map_or(2, |v| v.parse().unwrap());
        let max_steps: u32 = std::env::var("TETLOC_WALK_STEPS").map_or(32, |v| v.parse().unwrap());
        let mesh =
            tetloc_core::Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, n, 1), "jets").unwrap();
        let (pts, tets) = (&mesh.points, &mesh.tets);
        let q = collapse(&Bvh::build(pts, tets, BuildPreset::SingleTetLeaves)).unwrap();
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let g = q.entry_grid(pts, tets, lo, hi, per_cell, true);
        let nb = mesh.neighbors();
        println!(
            "jets {} tets, {} nodes, depth {}, grid {:?} ({} tets/cell), walk <= {max_steps} steps",
            tets.len(),
            q.nodes.len(),
            q.depth,
            g.dims,
            per_cell
        );
        let warps = 20_000.min(tets.len() / 32);
        for mode in ["uniform", "random"] {
            // [root, grid, walk] x [nodes, tests, f64 faces, walk steps, fallbacks, iterations, warp-max iterations]
            let sums = (0..warps)
                .into_par_iter()
                .map(|w| {
                    let mut acc = [[0f64; 7]; 3];
                    let mut warp_max = [0u32; 3];
                    let base = (w * (tets.len() / 32 / warps)) * 32;
                    for lane in 0..32 {
                        let i = base + lane;
                        let p =
                            if mode == "uniform" { mesh.tet_center(i) } else { random_sample(i as u32, 1, pts, tets) };
                        let c = g.cell_of(p, lo);
                        let mut costs = [Cost::default(); 3];
                        let stack = &mut vec![];
                        let a = q.traverse(pts, tets, p, 0, stack, &mut costs[0]);
                        let b = q.traverse(pts, tets, p, g.cells[c], stack, &mut costs[1]);
                        let walked = walk(pts, tets, nb, g.starts[c] as i32, p, max_steps, &mut costs[2]);
                        let w = walked.or_else(|| q.traverse(pts, tets, p, g.cells[c], stack, &mut costs[2]));
                        assert!(a.is_some(), "{mode} sample {i} {p:?} lost");
                        assert_eq!(a, b, "{mode} sample {i}: grid start changed the answer");
                        if walked.is_some() {
                            // strictly inside: the one tet that holds the point
                            assert_eq!(walked, a, "{mode} sample {i}: the walk found another tet");
                        }
                        assert!(w.is_some());
                        for (k, cost) in costs.iter().enumerate() {
                            let iters = cost.nodes + cost.tests;
                            let v =
                                [cost.nodes, cost.tests, cost.f64_faces, cost.walk_steps, cost.fallback as u32, iters];
                            for (j, x) in v.iter().enumerate() {
                                acc[k][j] += *x as f64;
                            }
                            warp_max[k] = warp_max[k].max(iters);
                        }
                    }
                    for k in 0..3 {
                        acc[k][6] = warp_max[k] as f64;
                    }
                    acc
                })
                .reduce(
                    || [[0f64; 7]; 3],
                    |mut x, y| {
                        for k in 0..3 {
                            for j in 0..7 {
                                x[k][j] += y[k][j];
                            }
                        }
                        x
                    },
                );
            let samples = (warps * 32) as f64;
            println!("{mode} ({} samples in warps of 32):", warps * 32);
            println!("  start      nodes  tests  f64-faces  walk-steps  fallback  iterations  warp-max-iterations");
            for (k, name) in ["root", "grid node", "grid walk"].iter().enumerate() {
                let m: Vec<f64> = sums[k][..6].iter().map(|x| x / samples).collect();
                println!(
                    "  {name:<10} {:>5.2} {:>6.2} {:>10.4} {:>11.2} {:>8.2}% {:>11.2} {:>20.2}",
                    m[0],
                    m[1],
                    m[2],
                    m[3],
                    100.0 * m[4],
                    m[5],
                    sums[k][6] / warps as f64
                );
            }
        }
    }
}
