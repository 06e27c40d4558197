//! The quadratic (13-node) pyramid: VTK 27 (vtkQuadraticPyramid), Gmsh 19 (pyramid13) and Gmsh
//! 14 (pyramid14, whose 14th node, the base centre, VTK's type has no place for: it is dropped).
//! Corners, the midpoints of the base edges (0,1) (1,2) (2,3) (3,0), then of the edges to the
//! apex (0,4) (1,4) (2,4) (3,4).
//!
//! The functions are those of current VTK (polynomial, 2021 on). Its `InterpolationDerivs` was
//! not updated with them; here the derivatives are those of the functions.

use super::scalar::Scalar;
use super::{pyramid, GmshType, PCoords};
use std::borrow::Cow;

const NODES: [PCoords; 13] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.5, 0.0, 0.0],
    [1.0, 0.5, 0.0],
    [0.5, 1.0, 0.0],
    [0.0, 0.5, 0.0],
    [0.0, 0.0, 0.5],
    [1.0, 0.0, 0.5],
    [1.0, 1.0, 0.5],
    [0.0, 1.0, 0.5],
];

/// Gmsh lists the edges as (0,1) (0,3) (0,4) (1,2) (1,4) (2,3) (2,4) (3,4).
pub(super) const GMSH_PYRAMID13: [u16; 13] = [0, 1, 2, 3, 4, 5, 8, 10, 6, 7, 9, 11, 12];

const GMSH: &[GmshType] = &[
    GmshType { code: 19, n_nodes: 13, vtk_from_gmsh: Cow::Borrowed(&GMSH_PYRAMID13) },
    GmshType { code: 14, n_nodes: 14, vtk_from_gmsh: Cow::Borrowed(&GMSH_PYRAMID13) },
];

pub struct QuadraticPyramid;

/// In ξ = 2·pc − 1 ∈ [−1, 1]³ (x, y along the base, z to the apex).
fn functions<T: Scalar>(pc: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    let [x, y, z] = pc.map(|v| v * 2.0 - one);
    let (xm, xp, ym, yp, zm) = (one - x, one + x, one - y, one + y, one - z);
    let (x2, y2, z2) = (one - x * x, one - y * y, one - z * z);
    let c = |v: f64| T::from(v);
    w.copy_from_slice(&[
        -(xm * ym * zm)
            * (c(4.0) + x * 3.0 + y * 3.0 + x * y * 2.0 + z * 2.0 + x * z + y * z + x * y * z * 2.0)
            * (1.0 / 16.0),
        -(xp * ym * zm)
            * (c(4.0) - x * 3.0 + y * 3.0 - x * y * 2.0 + z * 2.0 - x * z + y * z - x * y * z * 2.0)
            * (1.0 / 16.0),
        -(xp * yp * zm)
            * (c(4.0) - x * 3.0 - y * 3.0 + x * y * 2.0 + z * 2.0 - x * z - y * z + x * y * z * 2.0)
            * (1.0 / 16.0),
        -(xm * yp * zm)
            * (c(4.0) + x * 3.0 - y * 3.0 - x * y * 2.0 + z * 2.0 + x * z - y * z - x * y * z * 2.0)
            * (1.0 / 16.0),
        z * (one + z) * 0.5,
        x2 * ym * zm * (c(2.0) + y + y * z) * 0.125,
        xp * y2 * zm * (c(2.0) - x - x * z) * 0.125,
        x2 * yp * zm * (c(2.0) - y - y * z) * 0.125,
        xm * y2 * zm * (c(2.0) + x + x * z) * 0.125,
        xm * ym * z2 * 0.25,
        xp * ym * z2 * 0.25,
        xp * yp * z2 * 0.25,
        xm * yp * z2 * 0.25,
    ]);
}

cell_def!(QuadraticPyramid { name: "quadratic pyramid", vtk: 27, shape: &pyramid::SHAPE, order: 2, nodes: &NODES });
