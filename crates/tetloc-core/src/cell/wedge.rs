//! The linear wedge (VTK 13, Gmsh 6 "prism"): vtkWedge's shape functions, linear on the
//! triangle (r, s) times linear in t. Its three quad faces are bilinear and may be warped.
//! The triangle (0, 1, 2) turns counterclockwise seen from (3, 4, 5) in VTK and Gmsh alike.

use super::scalar::Scalar;
use super::{Bound, GmshType, Shape};
use std::borrow::Cow;

pub static SHAPE: Shape = Shape {
    name: "wedge",
    corners: &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]],
    faces: &[&[0, 2, 1], &[3, 4, 5], &[0, 1, 4, 3], &[1, 2, 5, 4], &[2, 0, 3, 5]],
    center: [1.0 / 3.0, 1.0 / 3.0, 0.5],
    // Faces 0..4 are t = 0, t = 1, s = 0, r + s = 1, r = 0.
    domain: &[
        Bound { face: Some(0), offset: 0.0, normal: [0.0, 0.0, 1.0] },
        Bound { face: Some(1), offset: 1.0, normal: [0.0, 0.0, -1.0] },
        Bound { face: Some(2), offset: 0.0, normal: [0.0, 1.0, 0.0] },
        Bound { face: Some(3), offset: 1.0, normal: [-1.0, -1.0, 0.0] },
        Bound { face: Some(4), offset: 0.0, normal: [1.0, 0.0, 0.0] },
    ],
    linear: &Wedge,
};

const GMSH: &[GmshType] = &[GmshType { code: 6, n_nodes: 6, vtk_from_gmsh: Cow::Borrowed(&[0, 1, 2, 3, 4, 5]) }];

pub struct Wedge;

fn functions<T: Scalar>([r, s, t]: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    let u = one - r - s;
    w.copy_from_slice(&[u * (one - t), r * (one - t), s * (one - t), u * t, r * t, s * t]);
}

cell_def!(Wedge { name: "wedge", vtk: 13, shape: &SHAPE, order: 1, nodes: SHAPE.corners });
