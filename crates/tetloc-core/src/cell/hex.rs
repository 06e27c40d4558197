//! The linear hexahedron (VTK 12, Gmsh 5): vtkHexahedron's trilinear shape functions. Its
//! faces are bilinear and may be warped (non-planar).

use super::scalar::{self, Scalar};
use super::{Bound, CellDef, GmshType, PCoords, Shape};
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

impl CellDef for Hex {
    fn name(&self) -> &'static str {
        "hexahedron"
    }
    fn vtk_type(&self) -> u8 {
        12
    }
    fn gmsh_types(&self) -> &[GmshType] {
        GMSH
    }
    fn shape(&self) -> &'static Shape {
        &SHAPE
    }
    fn order(&self) -> u8 {
        1
    }
    fn node_pcoords(&self) -> &[PCoords] {
        SHAPE.corners
    }
    fn shape_functions(&self, pc: PCoords, w: &mut [f64]) {
        functions(pc, w);
    }
    fn shape_derivatives(&self, pc: PCoords, d: &mut [[f64; 3]]) {
        scalar::derivatives(pc, d, functions);
    }
}
