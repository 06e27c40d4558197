//! Interpolation weights and their spatial gradients, for differentiable sampling
//! (`tetloc.torch`; [`super::weights`] is the CSR map for many time steps): a point's value is `Σ w_i · f[node_i]` over the nodes of the cell that
//! holds it, so the value's gradient with respect to the field is the weights (scattered into
//! the nodes), and with respect to the point `Σ ∇w_i · f[node_i]`.
//!
//! The weights are the ones every value path uses: a tet's f64 barycentrics
//! ([`Mesh::bary64`]), a higher-order tet's shape functions at them, another cell's shape
//! functions at its parametric coordinates (located by its corners, as
//! [`crate::locate::CellLocator`] does). Their gradients follow from the same cell
//! definitions: `∇ₓ N_i = J⁻ᵀ ∇_pc N_i`, with `J` the Jacobian of the map by which the point was
//! located (the corners' linear cell): constant in a linear tet.

use crate::cell::{self, CellDef, CellType, PCoords, Point};
use crate::mesh::Mesh;
use rayon::prelude::*;

/// The weights of a batch of points: `width` entries a point (the most nodes a cell of the
/// mesh has), padded with the cell's first node and weight 0 (so a NaN value reaches only the
/// points whose cells hold it); a point outside (or whose cell could not be inverted) has
/// only zeros and `found == false`.
#[derive(Debug, Default)]
pub struct Weights {
    pub width: usize,
    /// Per point: `width` vertex ids.
    pub nodes: Vec<u32>,
    /// Per point: `width` weights (they sum to 1 inside).
    pub weights: Vec<f64>,
    /// Per point: `width` gradients `∂w_i/∂(x, y, z)`.
    pub gradients: Vec<[f64; 3]>,
    pub found: Vec<bool>,
}

/// The most nodes a cell of `mesh` has: 4 for linear tets.
pub fn width(mesh: &Mesh) -> usize {
    match (&mesh.cells, &mesh.tet_nodes) {
        (Some(cells), _) => {
            let mut seen = [false; 256];
            cells.block.types.iter().for_each(|t| seen[usize::from(t.def().vtk_type())] = true);
            CellType::all()
                .filter(|t| seen[usize::from(t.def().vtk_type())])
                .map(|t| t.def().n_nodes())
                .max()
                .unwrap_or(4)
        }
        (None, Some(nodes)) => nodes.cell_type().def().n_nodes(),
        (None, None) => 4,
    }
}

/// The weights of `points` (the file's coordinates) in the cells `ids` that hold them (what
/// the locators answer: cells of a mixed mesh, else tets; -1 outside).
pub fn weights(mesh: &Mesh, points: &[Point], ids: &[i32]) -> Weights {
    assert_eq!(points.len(), ids.len(), "one id per point");
    let width = width(mesh);
    let n = points.len();
    let mut out = Weights {
        width,
        nodes: vec![0; n * width],
        weights: vec![0.0; n * width],
        gradients: vec![[0.0; 3]; n * width],
        found: vec![false; n],
    };
    out.nodes
        .par_chunks_mut(width)
        .zip(out.weights.par_chunks_mut(width))
        .zip(out.gradients.par_chunks_mut(width))
        .zip(out.found.par_iter_mut())
        .zip(points.par_iter().zip(ids))
        .for_each_init(Scratch::default, |scratch, ((((nodes, w), g), found), (&p, &id))| {
            if id >= 0 {
                *found = point_weights(mesh, id as usize, p, scratch, Row { nodes, w, g });
            }
        });
    out
}

/// A point's nodes, their weights and the weights' gradients ([`PointWeights::at`]).
pub type NodesWeightsGradients<'a> = (&'a [u32], &'a [f64], &'a [[f64; 3]]);

/// One point's weights and gradients at a time, with its own buffers (one per thread): for
/// passes over many points that use each point's weights once (a trace's vorticity), where
/// [`Weights`] for all of them would hold `width` × 36 bytes a point.
pub struct PointWeights {
    scratch: Scratch,
    nodes: Vec<u32>,
    w: Vec<f64>,
    g: Vec<[f64; 3]>,
}

impl PointWeights {
    /// Buffers for `mesh`'s points ([`width`] entries a point).
    pub fn new(mesh: &Mesh) -> PointWeights {
        let width = width(mesh);
        PointWeights {
            scratch: Scratch::default(),
            nodes: vec![0; width],
            w: vec![0.0; width],
            g: vec![[0.0; 3]; width],
        }
    }

    /// Point `p`'s nodes, weights and gradients in cell (or tet) `id`, as [`weights`] gives
    /// them (padded with weight and gradient 0); `None` where it has none.
    pub fn at(&mut self, mesh: &Mesh, id: usize, p: Point) -> Option<NodesWeightsGradients<'_>> {
        self.w.fill(0.0);
        self.g.fill([0.0; 3]);
        let row = Row { nodes: &mut self.nodes, w: &mut self.w, g: &mut self.g };
        point_weights(mesh, id, p, &mut self.scratch, row).then_some((&self.nodes, &self.w, &self.g))
    }
}

/// One point's slots in [`Weights`].
struct Row<'a> {
    nodes: &'a mut [u32],
    w: &'a mut [f64],
    g: &'a mut [[f64; 3]],
}

#[derive(Default)]
struct Scratch {
    nodes: Vec<u32>,
    derivatives: Vec<[f64; 3]>,
}

/// Fills `row` for point `p` in cell (or tet) `id`; false when it has no weights there.
fn point_weights(mesh: &Mesh, id: usize, p: Point, scratch: &mut Scratch, row: Row<'_>) -> bool {
    scratch.nodes.clear();
    let (def, pc): (&dyn CellDef, PCoords) = match (&mesh.cells, &mesh.tet_nodes) {
        (Some(cells), _) => {
            let ty = cells.block.types[id];
            let corners: Vec<Point> = cells.block.corners(id).iter().map(|&i| mesh.vertex64(i)).collect();
            match cell::invert(ty.shape().linear, &corners, p) {
                Ok(pc) => {
                    scratch.nodes.extend_from_slice(cells.block.nodes(id));
                    (ty.def(), pc)
                }
                // Newton failed (a degenerate cell): linearly in the decomposition tet that
                // holds the point, as the value paths do.
                Err(_) => {
                    let held = cells
                        .tets_of(id)
                        .find_map(|t| mesh.bary64(t, p).filter(|b| b.iter().all(|&x| x >= 0.0)).map(|b| (t, b)));
                    let Some((t, b)) = held else { return false };
                    scratch.nodes.extend_from_slice(&mesh.tets[t]);
                    (CellType::tet().def(), [b[1], b[2], b[3]])
                }
            }
        }
        (None, tet_nodes) => {
            let Some(b) = mesh.bary64(id, p) else { return false };
            let corners = mesh.tets[id];
            match tet_nodes {
                Some(extra) => {
                    scratch.nodes.extend(extra.nodes(id, corners));
                    (extra.cell_type().def(), [b[1], b[2], b[3]])
                }
                None => {
                    scratch.nodes.extend_from_slice(&corners);
                    (CellType::tet().def(), [b[1], b[2], b[3]])
                }
            }
        }
    };
    let n = def.n_nodes();
    row.nodes[..n].copy_from_slice(&scratch.nodes);
    row.nodes[n..].fill(scratch.nodes[0]);
    def.shape_functions(pc, &mut row.w[..n]);
    // dpc/dx: the inverse Jacobian of the corners' linear map (the map the point was located by).
    let linear = def.shape().linear;
    let n_corners = linear.n_nodes();
    scratch.derivatives.resize(n.max(n_corners), [0.0; 3]);
    linear.shape_derivatives(pc, &mut scratch.derivatives[..n_corners]);
    let mut jacobian = [[0.0f64; 3]; 3]; // jacobian[c][k] = ∂x_c/∂pc_k
    for (&node, d) in scratch.nodes[..n_corners].iter().zip(&scratch.derivatives) {
        let x = mesh.vertex64(node);
        for c in 0..3 {
            for k in 0..3 {
                jacobian[c][k] += x[c] * d[k];
            }
        }
    }
    let Some(inverse) = invert3(jacobian) else {
        // A flat cell: values, but no gradient with respect to the point.
        return true;
    };
    def.shape_derivatives(pc, &mut scratch.derivatives[..n]);
    for (g, d) in row.g.iter_mut().zip(&scratch.derivatives[..n]) {
        // ∂N/∂x_c = Σ_k ∂N/∂pc_k · ∂pc_k/∂x_c
        *g = std::array::from_fn(|c| (0..3).map(|k| d[k] * inverse[k][c]).sum());
    }
    true
}

/// The inverse of a 3×3 matrix (rows), `None` when it is singular.
fn invert3(m: [[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let cof = |r: usize, c: usize| {
        let (r1, r2, c1, c2) = ((r + 1) % 3, (r + 2) % 3, (c + 1) % 3, (c + 2) % 3);
        m[r1][c1] * m[r2][c2] - m[r1][c2] * m[r2][c1]
    };
    let det = m[0][0] * cof(0, 0) + m[0][1] * cof(0, 1) + m[0][2] * cof(0, 2);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // inverse[i][j] = cofactor(j, i) / det
    Some(std::array::from_fn(|i| std::array::from_fn(|j| cof(j, i) / det)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gen::{generate_spec, CellKind, Shape, Spec};
    use crate::test_support::{grid_mesh, KuhnGrid};

    /// Centres of every `step`-th cell (or tet) and their ids: points inside.
    fn centres(mesh: &Mesh, step: usize) -> (Vec<Point>, Vec<i32>) {
        match &mesh.cells {
            Some(cells) => (0..cells.len())
                .step_by(step)
                .map(|c| {
                    let corners = cells.block.corners(c);
                    let mut x = [0.0; 3];
                    corners
                        .iter()
                        .for_each(|&v| (0..3).for_each(|k| x[k] += mesh.vertex64(v)[k] / corners.len() as f64));
                    (x, c as i32)
                })
                .unzip(),
            None => (0..mesh.n_tets()).step_by(step).map(|t| (mesh.tet_center(t).map(f64::from), t as i32)).unzip(),
        }
    }

    fn value(w: &Weights, i: usize, field: &impl Fn(usize) -> f64) -> f64 {
        (0..w.width).map(|j| w.weights[i * w.width + j] * field(w.nodes[i * w.width + j] as usize)).sum()
    }

    /// The weights sum to 1 and central differences of the interpolant (in the same cell)
    /// agree with the gradients.
    fn check_gradients(mesh: &Mesh, field: impl Fn(usize) -> f64, step: usize) {
        let (points, ids) = centres(mesh, step);
        let at = weights(mesh, &points, &ids);
        let h = 1e-6;
        for (i, &p) in points.iter().enumerate() {
            assert!(at.found[i], "point {i} has no weights");
            let sum: f64 = at.weights[i * at.width..(i + 1) * at.width].iter().sum();
            assert!((sum - 1.0).abs() < 1e-9, "weights sum to {sum}");
            for c in 0..3 {
                let (mut lo, mut hi) = (p, p);
                lo[c] -= h;
                hi[c] += h;
                let both = weights(mesh, &[lo, hi], &[ids[i], ids[i]]);
                let numeric = (value(&both, 1, &field) - value(&both, 0, &field)) / (2.0 * h);
                let analytic: f64 = (0..at.width)
                    .map(|j| at.gradients[i * at.width + j][c] * field(at.nodes[i * at.width + j] as usize))
                    .sum();
                assert!((numeric - analytic).abs() < 1e-5 * (1.0 + analytic.abs()), "{numeric} vs {analytic}");
            }
        }
    }

    #[test]
    fn a_linear_field_has_its_own_gradient_in_linear_tets() {
        let mesh = grid_mesh(4, 0.2, 7);
        let (points, ids) = centres(&mesh, 3);
        let f = |v: usize| {
            let x = mesh.vertex64(v as u32);
            2.0 * x[0] - 3.0 * x[1] + 5.0 * x[2]
        };
        let w = weights(&mesh, &points, &ids);
        assert_eq!(w.width, 4);
        for i in 0..points.len() {
            let g: [f64; 3] = std::array::from_fn(|c| {
                (0..4).map(|j| w.gradients[i * 4 + j][c] * f(w.nodes[i * 4 + j] as usize)).sum()
            });
            for (got, want) in g.iter().zip([2.0, -3.0, 5.0]) {
                assert!((got - want).abs() < 1e-6, "{g:?}");
            }
        }
        check_gradients(&mesh, |v| (v as f64 * 0.37).sin(), 3);
    }

    #[test]
    fn gradients_are_the_interpolants_in_higher_order_tets_and_mixed_cells() {
        let quadratic = KuhnGrid::new(3).jitter(0.1, 3).order(2).mesh("quadratic");
        assert_eq!(width(&quadratic), 10);
        check_gradients(&quadratic, |v| (v as f64 * 0.37).sin(), 5);
        let spec = Spec { shape: Shape::Jets, cells: CellKind::Hybrid };
        let hybrid = Mesh::new(generate_spec(spec, 3000, 1, &|_| {}), "jets-hybrid").expect("mesh");
        assert!(width(&hybrid) >= 8);
        check_gradients(&hybrid, |v| (v as f64 * 0.37).sin(), 7);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(16))]
        /// The maps are isoparametric: interpolating the vertices' own coordinates gives the
        /// point back, and its gradient is the identity, in jittered tets and trilinear hexes.
        #[test]
        fn coordinates_interpolate_to_the_point_with_the_identity_gradient(
            seed in 0u64..1000, jitter in 0.0f32..0.3, hexes in proptest::bool::ANY,
        ) {
            let mesh = if hexes {
                let spec = Spec { shape: Shape::Jets, cells: CellKind::Hexes };
                Mesh::new(generate_spec(spec, 300, seed, &|_| {}), "jets-hex").expect("mesh")
            } else {
                grid_mesh(3, jitter, seed)
            };
            let (points, ids) = centres(&mesh, 5);
            let w = weights(&mesh, &points, &ids);
            for (i, p) in points.iter().enumerate() {
                proptest::prop_assert!(w.found[i]);
                for (c, &pc) in p.iter().enumerate() {
                    let coordinate = |v: usize| mesh.vertex64(v as u32)[c];
                    proptest::prop_assert!((value(&w, i, &coordinate) - pc).abs() < 1e-9 * (1.0 + pc.abs()));
                    for k in 0..3 {
                        let d: f64 = (0..w.width)
                            .map(|j| w.gradients[i * w.width + j][k] * coordinate(w.nodes[i * w.width + j] as usize))
                            .sum();
                        let identity = if c == k { 1.0 } else { 0.0 };
                        proptest::prop_assert!((d - identity).abs() < 1e-7, "∂x{c}/∂x{k} = {d}");
                    }
                }
            }
        }
    }

    #[test]
    fn outside_points_have_no_weights() {
        let mesh = grid_mesh(2, 0.0, 1);
        let w = weights(&mesh, &[[9.0, 9.0, 9.0]], &[-1]);
        assert!(!w.found[0]);
        assert!(w.weights.iter().all(|&x| x == 0.0) && w.gradients.iter().all(|g| *g == [0.0; 3]));
    }
}
