//! The nodes of higher-order tets in barycentric terms: each node's lattice multi-index over
//! the four corners, and how the nodes move when the corners are reordered (the mesh stores
//! tets in canonical corner order, so every node row is permuted with its corners).

use super::CellDef;

/// Node `m`'s barycentric lattice index `α` over corners 0..3 (`α` sums to the order `p`):
/// the node sits at `Σ α_j v_j / p`. For VTK's tets corner 0 is the parametric origin, so
/// `α = (p − i − j − k, i, j, k)` for the lattice point `(i, j, k) = p · (r, s, t)`.
pub fn barycentric_lattice(def: &dyn CellDef) -> Vec<[u8; 4]> {
    assert!(def.shape().is_tet(), "{} is not a tet", def.name());
    let p = f64::from(def.order());
    def.node_pcoords()
        .iter()
        .map(|pc| {
            let [i, j, k] = pc.map(|x| (x * p).round() as u8);
            [def.order() - i - j - k, i, j, k]
        })
        .collect()
}

/// Node permutations of a tet type under the 24 reorderings of its corners.
pub struct TetPermutations {
    n_nodes: usize,
    /// Indexed by [`key`]: `None` for the 232 keys that are not permutations.
    tables: Vec<Option<Vec<u16>>>,
}

/// `σ` packed in base 4.
fn key(sigma: [u8; 4]) -> usize {
    sigma.iter().fold(0, |k, &s| 4 * k + usize::from(s))
}

impl TetPermutations {
    pub fn new(def: &dyn CellDef) -> TetPermutations {
        let alpha = barycentric_lattice(def);
        let mut tables = vec![None; 256];
        for sigma in all_permutations() {
            // New node m is the old node whose index, read through σ, is m's.
            let table = alpha
                .iter()
                .map(|a| {
                    let old = alpha
                        .iter()
                        .position(|b| (0..4).all(|j| b[usize::from(sigma[j])] == a[j]))
                        .expect("a tet's lattice is symmetric under its corner permutations");
                    u16::try_from(old).expect("node counts fit u16")
                })
                .collect();
            tables[key(sigma)] = Some(table);
        }
        TetPermutations { n_nodes: alpha.len(), tables }
    }

    /// For corners reordered so that new corner `j` is old corner `sigma[j]`: new node `m` is
    /// old node `table[m]`.
    pub fn table(&self, sigma: [u8; 4]) -> &[u16] {
        self.tables[key(sigma)].as_deref().expect("sigma is a permutation of 0..4")
    }

    /// `nodes` (all of one tet's, old order) reordered for the corner order `sigma`.
    pub fn apply(&self, sigma: [u8; 4], nodes: &[u32], out: &mut [u32]) {
        debug_assert_eq!(nodes.len(), self.n_nodes);
        for (o, &m) in out.iter_mut().zip(self.table(sigma)) {
            *o = nodes[usize::from(m)];
        }
    }
}

fn all_permutations() -> Vec<[u8; 4]> {
    let mut out = Vec::with_capacity(24);
    for a in 0..4u8 {
        for b in (0..4).filter(|&b| b != a) {
            for c in (0..4).filter(|&c| c != a && c != b) {
                out.push([a, b, c, 6 - a - b - c]);
            }
        }
    }
    out
}

/// The corner reordering that takes `from` to `to` (`to[j] = from[sigma[j]]`), `to` being a
/// permutation of `from`; repeated ids (a degenerate tet) are matched in order.
pub fn corner_permutation(from: [u32; 4], to: [u32; 4]) -> [u8; 4] {
    let mut used = [false; 4];
    to.map(|id| {
        let i = (0..4).find(|&i| !used[i] && from[i] == id).expect("`to` is a permutation of `from`");
        used[i] = true;
        i as u8
    })
}
