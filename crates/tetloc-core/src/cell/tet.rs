//! The linear tetrahedron (VTK 10, Gmsh 4): vtkTetra's barycentric shape functions.

use super::scalar::Scalar;
use super::{Bound, GmshType, Shape};
use std::borrow::Cow;

pub static SHAPE: Shape = Shape {
    name: "tetra",
    corners: &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    faces: &[&[0, 1, 3], &[1, 2, 3], &[2, 0, 3], &[0, 2, 1]],
    center: [0.25, 0.25, 0.25],
    // Face 0 is s = 0, face 1 is r + s + t = 1, face 2 is r = 0, face 3 is t = 0.
    domain: &[
        Bound { face: Some(0), offset: 0.0, normal: [0.0, 1.0, 0.0] },
        Bound { face: Some(1), offset: 1.0, normal: [-1.0, -1.0, -1.0] },
        Bound { face: Some(2), offset: 0.0, normal: [1.0, 0.0, 0.0] },
        Bound { face: Some(3), offset: 0.0, normal: [0.0, 0.0, 1.0] },
    ],
    linear: &Tet,
};

const GMSH: &[GmshType] = &[GmshType { code: 4, n_nodes: 4, vtk_from_gmsh: Cow::Borrowed(&[0, 1, 2, 3]) }];

pub struct Tet;

fn functions<T: Scalar>([r, s, t]: [T; 3], w: &mut [T]) {
    w.copy_from_slice(&[T::from(1.0) - r - s - t, r, s, t]);
}

cell_def!(Tet { name: "tetra", vtk: 10, shape: &SHAPE, order: 1, nodes: SHAPE.corners });
