//! The linear pyramid (VTK 14, Gmsh 7): vtkPyramid's shape functions, a hex whose top face is
//! collapsed to the apex. The domain is VTK's `[0,1]³`; its side `t ≤ 1` is the apex, not a
//! face. Only the base quad can be warped: the four sides are triangles.

use super::scalar::Scalar;
use super::{Bound, GmshType, Shape};
use std::borrow::Cow;

pub static SHAPE: Shape = Shape {
    name: "pyramid",
    corners: &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    faces: &[&[0, 3, 2, 1], &[0, 1, 4], &[1, 2, 4], &[2, 3, 4], &[3, 0, 4]],
    // The preimage of the vertex centroid (VTK's GetParametricCenter says (0.4, 0.4, 0.2), off
    // the axis; Newton converges from either).
    center: [0.5, 0.5, 0.2],
    // Faces 0..4 are t = 0, s = 0, r = 1, s = 1, r = 0; t = 1 is the apex.
    domain: &[
        Bound { face: Some(0), offset: 0.0, normal: [0.0, 0.0, 1.0] },
        Bound { face: Some(1), offset: 0.0, normal: [0.0, 1.0, 0.0] },
        Bound { face: Some(2), offset: 1.0, normal: [-1.0, 0.0, 0.0] },
        Bound { face: Some(3), offset: 1.0, normal: [0.0, -1.0, 0.0] },
        Bound { face: Some(4), offset: 0.0, normal: [1.0, 0.0, 0.0] },
        Bound { face: None, offset: 1.0, normal: [0.0, 0.0, -1.0] },
    ],
    linear: &Pyramid,
};

const GMSH: &[GmshType] = &[GmshType { code: 7, n_nodes: 5, vtk_from_gmsh: Cow::Borrowed(&[0, 1, 2, 3, 4]) }];

pub struct Pyramid;

fn functions<T: Scalar>([r, s, t]: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    let (rm, sm, tm) = (one - r, one - s, one - t);
    w.copy_from_slice(&[rm * sm * tm, r * sm * tm, r * s * tm, rm * s * tm, t]);
}

cell_def!(Pyramid { name: "pyramid", vtk: 14, shape: &SHAPE, order: 1, nodes: SHAPE.corners });
