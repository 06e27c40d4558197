//! The quadratic (serendipity, 20-node) hexahedron: VTK 25 (vtkQuadraticHexahedron), Gmsh 17
//! (hex20). Corners, then the midpoints of the edges (0,1) (1,2) (2,3) (3,0) (4,5) (5,6) (6,7)
//! (7,4) (0,4) (1,5) (2,6) (3,7).

use super::scalar::Scalar;
use super::{hex, GmshType, PCoords};
use std::borrow::Cow;

const NODES: [PCoords; 20] = corners_and_midpoints(
    hex::SHAPE.corners,
    &[[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]],
);

/// The nodes of a quadratic cell whose mid-edge nodes are the edges' midpoints (this hex's,
/// the quadratic wedge's): `corners`, then the midpoints of `edges`, in that order.
pub(super) const fn corners_and_midpoints<const N: usize>(corners: &[PCoords], edges: &[[usize; 2]]) -> [PCoords; N] {
    assert!(corners.len() + edges.len() == N, "one node per corner and per edge");
    let mut nodes = [[0.0; 3]; N];
    let mut i = 0;
    while i < N {
        nodes[i] = if i < corners.len() {
            corners[i]
        } else {
            let [a, b] = edges[i - corners.len()];
            let (a, b) = (corners[a], corners[b]);
            [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5, (a[2] + b[2]) * 0.5]
        };
        i += 1;
    }
    nodes
}

/// Gmsh lists the edges as (0,1) (0,3) (0,4) (1,2) (1,5) (2,3) (2,6) (3,7) (4,5) (4,7) (5,6) (6,7).
pub(super) const GMSH_HEX20: [u16; 20] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 9, 16, 18, 19, 17, 10, 12, 14, 15];

const GMSH: &[GmshType] = &[GmshType { code: 17, n_nodes: 20, vtk_from_gmsh: Cow::Borrowed(&GMSH_HEX20) }];

pub struct QuadraticHex;

/// In the symmetric coordinates ξ = 2·pc − 1 ∈ [−1, 1]: corners
/// ⅛ (1 + ξξᵢ)(1 + ηηᵢ)(1 + ζζᵢ)(ξξᵢ + ηηᵢ + ζζᵢ − 2), mid-edge nodes ¼ (1 − ξ²)(1 + ηηᵢ)(1 + ζζᵢ)
/// and its permutations.
fn functions<T: Scalar>(pc: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    let x = pc.map(|v| v * 2.0 - one);
    for (wi, node) in w.iter_mut().zip(&NODES) {
        let c = node.map(|v| 2.0 * v - 1.0); // −1, 0 or 1
        let lin = |k: usize| one + x[k] * c[k];
        let bubble = |k: usize| one - x[k] * x[k];
        *wi = match c.iter().position(|&v| v == 0.0) {
            None => lin(0) * lin(1) * lin(2) * (x[0] * c[0] + x[1] * c[1] + x[2] * c[2] - T::from(2.0)) * 0.125,
            Some(k) => {
                let (a, b) = ((k + 1) % 3, (k + 2) % 3);
                bubble(k) * lin(a) * lin(b) * 0.25
            }
        };
    }
}

cell_def!(QuadraticHex { name: "quadratic hexahedron", vtk: 25, shape: &hex::SHAPE, order: 2, nodes: &NODES });
