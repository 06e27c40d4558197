//! The linear hexahedron (VTK 12, Gmsh 5): vtkHexahedron's trilinear shape functions. Its
//! faces are bilinear and may be warped (non-planar).

use super::scalar::Scalar;
use super::{Bound, GmshType, Shape};
use std::borrow::Cow;

pub static SHAPE: Shape = Shape {
    name: "hexahedron",
    corners: &[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ],
    faces: &[&[0, 4, 7, 3], &[1, 2, 6, 5], &[0, 1, 5, 4], &[3, 7, 6, 2], &[0, 3, 2, 1], &[4, 5, 6, 7]],
    center: [0.5, 0.5, 0.5],
    // Faces 0..5 are r = 0, r = 1, s = 0, s = 1, t = 0, t = 1.
    domain: &[
        Bound { face: Some(0), offset: 0.0, normal: [1.0, 0.0, 0.0] },
        Bound { face: Some(1), offset: 1.0, normal: [-1.0, 0.0, 0.0] },
        Bound { face: Some(2), offset: 0.0, normal: [0.0, 1.0, 0.0] },
        Bound { face: Some(3), offset: 1.0, normal: [0.0, -1.0, 0.0] },
        Bound { face: Some(4), offset: 0.0, normal: [0.0, 0.0, 1.0] },
        Bound { face: Some(5), offset: 1.0, normal: [0.0, 0.0, -1.0] },
    ],
    linear: &Hex,
};

const GMSH: &[GmshType] = &[GmshType { code: 5, n_nodes: 8, vtk_from_gmsh: Cow::Borrowed(&[0, 1, 2, 3, 4, 5, 6, 7]) }];

pub struct Hex;

/// N_i = ∏_k (x_k or 1 − x_k), by corner i's parametric coordinates.
fn functions<T: Scalar>(pc: [T; 3], w: &mut [T]) {
    let one = T::from(1.0);
    for (wi, c) in w.iter_mut().zip(SHAPE.corners) {
        let f = |k: usize| if c[k] == 1.0 { pc[k] } else { one - pc[k] };
        *wi = f(0) * f(1) * f(2);
    }
}

cell_def!(Hex { name: "hexahedron", vtk: 12, shape: &SHAPE, order: 1, nodes: SHAPE.corners });
