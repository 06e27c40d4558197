//! The quadratic (15-node) wedge: VTK 26 (vtkQuadraticWedge), Gmsh 18 (prism15). Corners, the
//! midpoints of the triangle edges (0,1) (1,2) (2,0) (3,4) (4,5) (5,3), then of the vertical
//! edges (0,3) (1,4) (2,5).

use super::quadratic_hex::corners_and_midpoints;
use super::scalar::Scalar;
use super::{wedge, GmshType, PCoords};
use std::borrow::Cow;

const NODES: [PCoords; 15] = corners_and_midpoints(
    wedge::SHAPE.corners,
    &[[0, 1], [1, 2], [2, 0], [3, 4], [4, 5], [5, 3], [0, 3], [1, 4], [2, 5]],
);

/// Gmsh lists the edges as (0,1) (0,2) (0,3) (1,2) (1,4) (2,5) (3,4) (3,5) (4,5).
pub(super) const GMSH_PRISM15: [u16; 15] = [0, 1, 2, 3, 4, 5, 6, 9, 7, 12, 14, 13, 8, 10, 11];

const GMSH: &[GmshType] = &[GmshType { code: 18, n_nodes: 15, vtk_from_gmsh: Cow::Borrowed(&GMSH_PRISM15) }];

pub struct QuadraticWedge;

fn functions<T: Scalar>([r, s, t]: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    let u = one - r - s;
    let (tm, half, three_halves) = (one - t, T::from(0.5), T::from(1.5));
    w.copy_from_slice(&[
        // corners
        u * tm * (half - r - s - t) * 2.0,
        r * tm * (r - t - half) * 2.0,
        s * tm * (s - t - half) * 2.0,
        u * t * (t - r - s - half) * 2.0,
        r * t * (r + t - three_halves) * 2.0,
        s * t * (s + t - three_halves) * 2.0,
        // triangle edges, bottom then top
        r * u * tm * 4.0,
        r * s * tm * 4.0,
        u * s * tm * 4.0,
        r * u * t * 4.0,
        r * s * t * 4.0,
        u * s * t * 4.0,
        // vertical edges
        u * t * tm * 4.0,
        r * t * tm * 4.0,
        s * t * tm * 4.0,
    ]);
}

cell_def!(QuadraticWedge { name: "quadratic wedge", vtk: 26, shape: &wedge::SHAPE, order: 2, nodes: &NODES });
