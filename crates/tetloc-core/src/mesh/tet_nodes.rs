//! Higher-order tets: every tet's nodes beyond its corners, kept so that per-vertex fields are
//! interpolated with the tet's own shape functions (the quadratic tet's, the Lagrange or
//! Bezier tet's of its order), not by the corners alone.
//!
//! Tets are *located* by their corners, as linear tets. The parametric coordinates of a point
//! are its corner barycentrics `(r, s, t) = (b1, b2, b3)`: exactly the isoparametric ones when
//! the tet is straight-sided (edge and face nodes on their lattice positions, as in meshes
//! elevated from linear ones), an approximation for curved tets (see the README).

use crate::cell::{self, corner_permutation, CellBlock, CellType, TetPermutations};
use crate::geom::Bary64;
use rayon::prelude::*;
use std::sync::Arc;

/// The nodes of a mesh of higher-order tets, all of one type.
#[derive(Clone, Debug)]
pub struct TetNodes {
    ty: CellType,
    /// Per tet, `n_extra()` node ids: the tet's nodes after its 4 corners, in VTK's node order
    /// for `ty` taken over the tet's *canonical* corners (`Mesh::tets`). Shared by a
    /// series' steps (`Mesh::with_fields`), as the corners are.
    extra: Arc<Vec<u32>>,
}

impl TetNodes {
    /// From a reader's cells (one per tet, in file order, corners `file_tets`), for tets
    /// reordered to `canonical`. `None` when the tets are linear. Errors are messages for
    /// `Error::Mesh`.
    pub(super) fn build(
        cells: &CellBlock,
        file_tets: &[[u32; 4]],
        canonical: &[[u32; 4]],
        n_points: usize,
    ) -> Result<Option<TetNodes>, String> {
        if cells.len() != file_tets.len() {
            return Err(format!("{} cells but {} tets", cells.len(), file_tets.len()));
        }
        let Some(first) = cells.types.iter().find(|t| t.def().order() > 1) else { return Ok(None) };
        let def = first.def();
        let same = |t: &CellType| {
            let d = t.def();
            *t == *first
                || (d.shape().is_tet()
                    && d.interpolates_nodes() == def.interpolates_nodes()
                    && d.node_pcoords() == def.node_pcoords())
        };
        if let Some(i) = cells.types.iter().position(|t| !same(t)) {
            return Err(format!(
                "tet {i} is a {} with {} nodes but tet {} a {} with {}: tetloc interpolates one kind of tet \
                 per mesh (convert the mesh to one order)",
                cells.types[i].def().name(),
                cells.types[i].def().n_nodes(),
                cells.types.iter().position(|t| t == first).unwrap(),
                def.name(),
                def.n_nodes()
            ));
        }
        let n = def.n_nodes();
        if let Some(i) = (0..cells.len()).find(|&i| cells.corners(i) != file_tets[i]) {
            return Err(format!("cell {i}'s corners are not tet {i}'s"));
        }
        if let Some(&id) = cells.conn.par_iter().find_any(|&&id| id as usize >= n_points) {
            return Err(format!("a tet node references vertex {id} but the mesh has only {n_points} vertices"));
        }
        let perms = TetPermutations::new(def);
        let mut extra = vec![0u32; cells.len() * (n - 4)];
        extra.par_chunks_mut(n - 4).enumerate().for_each_init(
            || vec![0u32; n],
            |row, (t, out)| {
                perms.apply(corner_permutation(file_tets[t], canonical[t]), cells.nodes(t), row);
                debug_assert_eq!(row[..4], canonical[t]);
                out.copy_from_slice(&row[4..]);
            },
        );
        Ok(Some(TetNodes { ty: *first, extra: Arc::new(extra) }))
    }

    /// The tets' cell type.
    pub fn cell_type(&self) -> CellType {
        self.ty
    }

    /// Nodes per tet beyond the corners.
    pub fn n_extra(&self) -> usize {
        self.ty.def().n_nodes() - 4
    }

    /// Tet `t`'s nodes after its corners (VTK's order over the canonical corners).
    pub fn extra(&self, t: usize) -> &[u32] {
        let k = self.n_extra();
        &self.extra[t * k..(t + 1) * k]
    }

    /// Every tet's extra nodes, `n_extra()` per tet: what the GPU uploads.
    pub fn table(&self) -> &[u32] {
        &self.extra
    }

    /// Tet `t`'s nodes: the canonical `corners`, then its extra nodes.
    pub fn nodes(&self, t: usize, corners: [u32; 4]) -> impl Iterator<Item = u32> + '_ {
        corners.into_iter().chain(self.extra(t).iter().copied())
    }

    /// A per-vertex field (`value` of a vertex id) at barycentrics `bary` (over the canonical
    /// corners) of tet `t`, with the tet's shape functions, in f64.
    pub fn interpolate_with(&self, t: usize, corners: [u32; 4], bary: Bary64, value: impl Fn(usize) -> f64) -> f64 {
        let pc = [bary[1], bary[2], bary[3]];
        let extra = self.extra(t);
        let node = |i: usize| if i < 4 { corners[i] } else { extra[i - 4] };
        cell::interpolate(self.ty.def(), pc, |i| value(node(i) as usize))
    }

    /// The (vertex, weight) pairs of [`Self::interpolate_with`] (it is Σ weight · value): the
    /// tet's shape functions at `bary`, over its nodes.
    pub fn weights(&self, t: usize, corners: [u32; 4], bary: Bary64, mut push: impl FnMut(u32, f64)) {
        let def = self.ty.def();
        let mut w = vec![0.0; def.n_nodes()];
        def.shape_functions([bary[1], bary[2], bary[3]], &mut w);
        self.nodes(t, corners).zip(w).for_each(|(id, w)| push(id, w));
    }

    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.table())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::barycentric_lattice;
    use crate::mesh::{Mesh, RawMesh};
    use crate::test_support::KuhnGrid;
    use proptest::prelude::*;

    /// The largest distance of a node from its lattice position `Σ α_j v_j / p` over the
    /// canonical corners, relative to the mesh's largest edge: 0 (to rounding) for straight-
    /// sided tets whose node rows were permuted with their corners.
    pub(crate) fn lattice_error(m: &Mesh) -> f64 {
        let nodes = m.tet_nodes.as_ref().expect("higher-order tets");
        let lattice = barycentric_lattice(nodes.cell_type().def());
        let p = f64::from(nodes.cell_type().def().order());
        let mut worst = 0.0f64;
        for (t, &c) in m.tets.iter().enumerate() {
            for (alpha, id) in lattice.iter().zip(nodes.nodes(t, c)) {
                for (k, &xk) in m.points[id as usize].iter().enumerate() {
                    let want: f64 = (0..4).map(|j| f64::from(alpha[j]) * f64::from(m.points[c[j] as usize][k])).sum();
                    worst = worst.max((f64::from(xk) - want / p).abs());
                }
            }
        }
        worst / f64::from(m.info.max_edge_length)
    }

    /// Reorders each tet's corners (and its node row with them) by a permutation from `pick`.
    fn shuffle_corners(raw: &mut RawMesh, pick: &[u8]) {
        let cells = raw.cells.as_mut().unwrap();
        let perms = TetPermutations::new(cells.types[0].def());
        let all: Vec<[u8; 4]> = (0..24u8)
            .map(|k| {
                let mut rest = vec![0u8, 1, 2, 3];
                let (a, b, c) = (rest.remove(usize::from(k / 6)), (k % 6) / 2, k % 2);
                let b = rest.remove(usize::from(b));
                let c = rest.remove(usize::from(c));
                [a, b, c, rest[0]]
            })
            .collect();
        let n = cells.types[0].def().n_nodes();
        for t in 0..raw.tets.len() {
            let sigma = all[usize::from(pick[t % pick.len()]) % 24];
            let old = cells.conn[t * n..(t + 1) * n].to_vec();
            perms.apply(sigma, &old, &mut cells.conn[t * n..(t + 1) * n]);
            raw.tets[t] = sigma.map(|j| old[usize::from(j)]);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        /// Whatever order a file gives a tet's corners in (and its nodes with them), the
        /// canonical node rows put every node at its lattice position over the canonical
        /// corners, and keep the tet's node set.
        #[test]
        fn node_rows_follow_the_canonical_corners(
            order in 2u8..=4,
            seed in 0u64..1000,
            pick in proptest::collection::vec(0u8..24, 1..40),
        ) {
            let mut raw = KuhnGrid::new(2).jitter(0.1, seed).order(order).raw();
            shuffle_corners(&mut raw, &pick);
            let sets: Vec<Vec<u32>> = (0..raw.tets.len())
                .map(|t| { let mut v = raw.cells.as_ref().unwrap().nodes(t).to_vec(); v.sort_unstable(); v })
                .collect();
            let m = Mesh::new(raw, "shuffled").unwrap();
            prop_assert!(lattice_error(&m) < 1e-6, "nodes off their lattice: {}", lattice_error(&m));
            let nodes = m.tet_nodes.as_ref().unwrap();
            for (t, want) in sets.iter().enumerate() {
                let mut got: Vec<u32> = nodes.nodes(t, m.tets[t]).collect();
                got.sort_unstable();
                prop_assert_eq!(&got, want);
            }
        }
    }

    /// The shuffle itself moves nodes off their lattice positions when the rows are not
    /// permuted with the corners (so the property above can fail).
    #[test]
    fn unpermuted_rows_would_be_off_the_lattice() {
        let mut raw = KuhnGrid::new(2).order(2).raw();
        let cells = raw.cells.as_ref().unwrap().clone();
        shuffle_corners(&mut raw, &[5, 17, 9]);
        raw.cells = Some(cells); // corners moved, rows not
        match Mesh::new(raw, "unpermuted") {
            Ok(m) => assert!(lattice_error(&m) > 0.1),
            Err(e) => assert!(e.to_string().contains("corners"), "{e}"),
        }
    }

    /// Quadratic tets elevated from a jittered grid: the nodes sit on their lattices.
    #[test]
    fn elevated_grids_are_straight_sided() {
        for order in [2, 3, 5] {
            let m = KuhnGrid::new(3).jitter(0.15, 4).order(order).mesh("elevated");
            assert_eq!(m.info.higher_order, Some(order));
            let nodes = m.tet_nodes.as_ref().unwrap();
            assert_eq!(nodes.n_extra() + 4, nodes.cell_type().def().n_nodes());
            assert!(lattice_error(&m) < 1e-6);
        }
    }
}
