//! Cutting a mesh into pieces (`tetloc partition`, which `tetloc_io::partition` writes, and the
//! pieces `tetloc-mpi` ranks load): recursive coordinate bisection (RCB) of the cells by their
//! centroids, and the piece meshes.
//!
//! A piece keeps its cells in ascending global id and its vertices in ascending global
//! vertex id, so every cell lists its vertices in the same relative order as in the whole
//! mesh: canonical tet order, the face evaluation order and the mixed cells' decomposition
//! (split along the diagonal through the smallest id) are the same in the piece as in the
//! whole, and so are the answers and the values, bit for bit.

use crate::cell::CellBlock;
use crate::error::{Error, Result};
use crate::geom::Vec3;
use crate::mesh::{FieldLocation, Mesh, RawMesh};
use rayon::prelude::*;

/// The centroid of every cell (the mean of its corners; a mixed mesh's own cells, not their
/// decomposition).
pub fn cell_centroids(mesh: &Mesh) -> Vec<Vec3> {
    let mean = |corners: &mut dyn Iterator<Item = u32>| {
        let (mut c, mut n) = ([0f64; 3], 0);
        for i in corners {
            let p = mesh.points[i as usize];
            (0..3).for_each(|k| c[k] += p[k] as f64);
            n += 1;
        }
        c.map(|x| (x / n as f64) as f32)
    };
    match &mesh.cells {
        Some(cells) => {
            (0..cells.block.len()).into_par_iter().map(|c| mean(&mut cells.block.corners(c).iter().copied())).collect()
        }
        None => mesh.tets.par_iter().map(|t| mean(&mut t.iter().copied())).collect(),
    }
}

/// The part (`0..parts`) of each point by recursive coordinate bisection: the set is cut
/// across the longest side of its points' bounding box, at the point that gives the two
/// halves sizes in proportion to their numbers of parts (any `parts`, not only powers of 2),
/// and each half is cut again. Ties in the coordinate are broken by index: the result
/// depends only on the points.
pub fn rcb(points: &[Vec3], parts: usize) -> Vec<u32> {
    let parts = parts.max(1);
    let mut idx: Vec<u32> = (0..points.len() as u32).collect();
    split(points, &mut idx, parts);
    let mut out = vec![0u32; points.len()];
    let mut start = 0;
    for (part, n) in sizes(points.len(), parts).into_iter().enumerate() {
        idx[start..start + n].iter().for_each(|&i| out[i as usize] = part as u32);
        start += n;
    }
    out
}

/// How many points the left half of `n` gets when it holds `parts / 2` of `parts` parts.
fn left_size(n: usize, parts: usize) -> usize {
    (n as u128 * (parts / 2) as u128 / parts as u128) as usize
}

/// The sizes of the parts [`split`] leaves, in order.
fn sizes(n: usize, parts: usize) -> Vec<usize> {
    if parts == 1 {
        return vec![n];
    }
    let k = left_size(n, parts);
    let mut out = sizes(k, parts / 2);
    out.extend(sizes(n - k, parts - parts / 2));
    out
}

/// Reorders `idx` so that the parts are consecutive runs of the sizes [`sizes`] gives.
fn split(points: &[Vec3], idx: &mut [u32], parts: usize) {
    if parts == 1 || idx.len() < 2 {
        return;
    }
    let (lo, hi) = idx.par_iter().map(|&i| (points[i as usize], points[i as usize])).reduce(
        || ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(a0, a1), (b0, b1)| (std::array::from_fn(|k| a0[k].min(b0[k])), std::array::from_fn(|k| a1[k].max(b1[k]))),
    );
    let ext: [f32; 3] = std::array::from_fn(|k| hi[k] - lo[k]);
    let axis = (0..3).max_by(|&a, &b| ext[a].total_cmp(&ext[b]).then(b.cmp(&a))).unwrap_or(0);
    let k = left_size(idx.len(), parts);
    if k > 0 && k < idx.len() {
        idx.select_nth_unstable_by(k, |&a, &b| {
            points[a as usize][axis].total_cmp(&points[b as usize][axis]).then(a.cmp(&b))
        });
    }
    let (left, right) = idx.split_at_mut(k);
    rayon::join(|| split(points, left, parts / 2), || split(points, right, parts - parts / 2));
}

/// The piece of `mesh` made of `cells` (ascending cell ids): those cells with every node
/// they use, vertices in ascending order, and the fields restricted to them.
pub fn piece(mesh: &Mesh, cells: &[u32], name: &str) -> Result<Mesh> {
    piece_with_points(mesh, cells, name).map(|(m, _)| m)
}

/// [`piece`], and the id in `mesh` of each of its vertices (its global point ids).
pub fn piece_with_points(mesh: &Mesh, cells: &[u32], name: &str) -> Result<(Mesh, Vec<u64>)> {
    if cells.windows(2).any(|w| w[0] >= w[1]) {
        return Err(Error::Invalid("a piece's cells must be ascending".into()));
    }
    let block = block_of(mesh);
    let nodes = |c: u32| -> &[u32] {
        match &block {
            Some(b) => b.nodes(c as usize),
            None => &mesh.tets[c as usize],
        }
    };
    let mut used = vec![false; mesh.points.len()];
    for &c in cells {
        nodes(c).iter().for_each(|&i| used[i as usize] = true);
    }
    let mut local = vec![u32::MAX; mesh.points.len()];
    let mut kept = Vec::new();
    for (i, _) in used.iter().enumerate().filter(|(_, &u)| u) {
        local[i] = kept.len() as u32;
        kept.push(i);
    }
    // The file's coordinates (a far mesh's working copy is centred: the piece has its own frame).
    let file: Vec<[f64; 3]> = kept.iter().map(|&i| mesh.vertex64(i as u32)).collect();
    let points = file.iter().map(|p| p.map(|c| c as f32)).collect();
    let points64 = crate::mesh::points64_if_needed(file);
    let fields = mesh
        .fields
        .iter()
        .map(|f| match f.location {
            FieldLocation::Vertex => f.select(|j| kept[j], kept.len()),
            FieldLocation::Cell => f.select(|j| cells[j] as usize, cells.len()),
        })
        .collect();
    let remap = |ids: &[u32]| ids.iter().map(|&i| local[i as usize]).collect::<Vec<u32>>();
    let cell_block = block.as_ref().map(|b| {
        let mut out = CellBlock::default();
        for &c in cells {
            match b.faces_of(c as usize) {
                Some(faces) => {
                    let faces: Vec<Vec<u32>> = faces.map(remap).collect();
                    out.push_polyhedron(faces.iter().map(Vec::as_slice));
                }
                None => out.push(b.types[c as usize], &remap(b.nodes(c as usize))),
            }
        }
        out
    });
    // The piece's own order: a piece of a mixed mesh may hold only its linear cells.
    let higher_order = match &cell_block {
        Some(b) => b.types.iter().map(|t| t.def().order()).max().filter(|&o| o > 1),
        None => None,
    };
    let (tets, cell_block) = match cell_block {
        // A piece of a mixed mesh with tets only is a tet mesh (as a reader would give it).
        Some(b) if b.non_tet_counts().is_none() => {
            let tets = (0..b.len()).map(|c| std::array::from_fn(|k| b.corners(c)[k])).collect();
            (tets, higher_order.map(|_| b))
        }
        Some(b) => (Vec::new(), Some(b)),
        None => (cells.iter().map(|&c| mesh.tets[c as usize].map(|i| local[i as usize])).collect(), None),
    };
    let raw = RawMesh { points, points64, tets, fields, higher_order, cells: cell_block };
    Ok((Mesh::new(raw, name)?, kept.into_iter().map(|i| i as u64).collect()))
}

/// Every cell with all its nodes when a tet list does not say it all: a mixed mesh's cells,
/// or higher-order tets (corners, then the other nodes in VTK's order).
fn block_of(mesh: &Mesh) -> Option<std::borrow::Cow<'_, CellBlock>> {
    if let Some(cells) = &mesh.cells {
        return Some(std::borrow::Cow::Borrowed(&cells.block));
    }
    let nodes = mesh.tet_nodes.as_ref()?;
    let mut out = CellBlock::default();
    let mut all = Vec::new();
    for (t, corners) in mesh.tets.iter().enumerate() {
        all.clear();
        all.extend_from_slice(corners);
        all.extend_from_slice(nodes.extra(t));
        out.push(nodes.cell_type(), &all);
    }
    Some(std::borrow::Cow::Owned(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::KuhnGrid;

    #[test]
    fn rcb_balances_any_number_of_parts() {
        let pts: Vec<Vec3> =
            (0..1000).map(|i| [(i % 10) as f32, (i / 10 % 10) as f32 * 3.0, (i / 100) as f32]).collect();
        for parts in [1, 2, 3, 5, 8] {
            let p = rcb(&pts, parts);
            let mut counts = vec![0usize; parts];
            p.iter().for_each(|&k| counts[k as usize] += 1);
            assert!(counts.iter().all(|&c| c.abs_diff(1000 / parts) <= 1), "{parts}: {counts:?}");
            assert_eq!(p, rcb(&pts, parts), "deterministic");
        }
        // The first cut is across y, the longest side: the lower half in y is part 0.
        let p = rcb(&pts, 2);
        assert!(pts.iter().zip(&p).all(|(q, &k)| (q[1] < 15.0) == (k == 0)));
    }

    #[test]
    fn pieces_keep_fields_and_vertex_order() {
        let m = KuhnGrid::new(4).mesh("cube");
        let parts = rcb(&cell_centroids(&m), 3);
        let mut n = 0;
        for k in 0..3 {
            let cells: Vec<u32> = (0..m.n_cells() as u32).filter(|&c| parts[c as usize] == k).collect();
            let p = piece(&m, &cells, "piece").unwrap();
            n += p.n_cells();
            for (j, &c) in cells.iter().enumerate() {
                let (a, b) = (p.tets[j], m.tets[c as usize]);
                assert_eq!(a.map(|i| p.points[i as usize]), b.map(|i| m.points[i as usize]), "same canonical corners");
            }
            let f = p.field("f").unwrap();
            assert_eq!(f.values.len(), p.points.len());
        }
        assert_eq!(n, m.n_cells());
    }
}
